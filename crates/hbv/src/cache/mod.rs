//! Object caches: the last triangle that answered a query, tried first on the next one.
//!
//! | file | concept |
//! | --- | --- |
//! | `shadow_cache.rs` | [`ShadowCache`]: per light and thread, the last occluder; a shadow ray tests it first |
//! | `last_hit_cache.rs` | [`LastHitCache`]: the previous ray's triangle gives the next closest-hit query an early `tmax` |
//! | `scene_shadow_cache.rs` | [`SceneShadowCache`]: the shadow cache of a [`crate::scene::Scene`], keyed by `(instance, prim)` |
//! | `scene_last_hit_cache.rs` | [`SceneLastHitCache`]: the last-hit cache of a scene |
//! | `cache_stats.rs` | [`CacheStats`]: how often the cached triangle answered |
//!
//! The mesh caches wrap any [`crate::Accelerator`], the scene caches a scene; each is owned by
//! one thread (it holds one cached triangle and two counters); they never change an answer,
//! only the work done to find it.

mod cache_stats;
mod last_hit_cache;
mod scene_last_hit_cache;
mod scene_shadow_cache;
mod shadow_cache;

pub use cache_stats::CacheStats;
pub use last_hit_cache::LastHitCache;
pub use scene_last_hit_cache::SceneLastHitCache;
pub use scene_shadow_cache::SceneShadowCache;
pub use shadow_cache::ShadowCache;
