//! Counts of an object cache.

use std::ops::AddAssign;

/// How often a cache's triangle answered: `hits` (the cached triangle was hit by the new ray)
/// and `misses` (no triangle cached, or not hit).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CacheStats {
    pub hits: u64,
    pub misses: u64,
}

impl CacheStats {
    /// `hits / (hits + misses)`, 0 before any query.
    pub fn hit_rate(&self) -> f64 {
        let total = self.hits + self.misses;
        if total == 0 {
            0.0
        } else {
            self.hits as f64 / total as f64
        }
    }
}

impl AddAssign for CacheStats {
    fn add_assign(&mut self, o: Self) {
        self.hits += o.hits;
        self.misses += o.misses;
    }
}
