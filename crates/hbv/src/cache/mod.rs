//! Object caches: the last triangle that answered a query, tried first on the next one.
//!
//! | file | concept |
//! | --- | --- |
//! | `shadow_cache.rs` | [`ShadowCache`]: per light and thread, the last occluder; a shadow ray tests it first |
//! | `last_hit_cache.rs` | [`LastHitCache`]: the previous ray's triangle gives the next closest-hit query an early `tmax` |
//! | `cache_stats.rs` | [`CacheStats`]: how often the cached triangle answered |
//!
//! Both wrap any [`crate::Accelerator`] and are owned by one thread (they hold one `Option<u32>`
//! and two counters); they never change an answer, only the work done to find it.

mod cache_stats;
mod last_hit_cache;
mod shadow_cache;

pub use cache_stats::CacheStats;
pub use last_hit_cache::LastHitCache;
pub use shadow_cache::ShadowCache;
