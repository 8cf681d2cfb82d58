//! The last-hit cache of a scene: the previous ray's `(instance, prim)` bounds the next
//! closest-hit query.

use super::CacheStats;
use crate::scene::{InstanceId, Scene, SceneHit, SceneRay};
use crate::stats::TraversalStats;

/// [`super::LastHitCache`] for a [`Scene`]: the triangle the previous ray hit, named by its
/// instance and `prim`, is tested first on the next ray (carried into its instance's space, as
/// [`Scene::intersect_prim`] does); when it is hit at `t_c`, the scene is asked with `tmax`
/// lowered to just past `t_c`, which culls every instance and node beyond it.
///
/// Why the answer is unchanged: the scene computes `t_c` for that triangle bit for bit as the
/// cache does (same carried ray, same test), so its closest hit has `t ≤ t_c`, inside the
/// lowered interval; the slack past `t_c` covers the rounding of the boxes on the way to it
/// (bound in `scene/cached_queries.rs`), and ties at equal `t` are decided by the same order
/// (smaller instance, then smaller `prim`), all of them within the interval.
///
/// One per thread and per stream of coherent rays; the scene is shared.
#[derive(Debug)]
pub struct SceneLastHitCache<'a> {
    scene: &'a Scene,
    /// `(instance, prim)` of the last hit.
    last: Option<(u32, u32)>,
    stats: CacheStats,
}

impl<'a> SceneLastHitCache<'a> {
    /// An empty cache over `scene`.
    pub fn new(scene: &'a Scene) -> Self {
        Self {
            scene,
            last: None,
            stats: CacheStats::default(),
        }
    }

    /// The closest hit: [`Scene::intersect`], bounded first by the cached triangle.
    pub fn intersect(&mut self, ray: &SceneRay) -> Option<SceneHit> {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return None;
        }
        let bounded = self.bounded(ray);
        let hit = self.scene.intersect(&bounded);
        self.remember(hit)
    }

    /// [`SceneLastHitCache::intersect`], adding the work done to `stats` as
    /// [`Scene::intersect_counted`] counts it (the cached test counts as one triangle test).
    pub fn intersect_counted(
        &mut self,
        ray: &SceneRay,
        stats: &mut TraversalStats,
    ) -> Option<SceneHit> {
        if !ray.ray.is_valid() || ray.mask == 0 {
            stats.rays += 1;
            return None;
        }
        stats.triangles_tested += self.last.is_some() as u64;
        let bounded = self.bounded(ray);
        let hit = self.scene.intersect_counted(&bounded, stats);
        self.remember(hit)
    }

    /// The cache's hits (the cached triangle was hit, lowering `tmax`) and misses.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// The cached triangle: its instance and its `prim` in that instance's mesh.
    pub fn last(&self) -> Option<(InstanceId, u32)> {
        self.last.map(|(i, p)| (InstanceId(i), p))
    }

    /// The ray, its `tmax` lowered to the cached triangle's bound if that triangle is hit.
    fn bounded(&mut self, ray: &SceneRay) -> SceneRay {
        let bound = self
            .last
            .and_then(|(instance, prim)| self.scene.closest_hit_bound(ray, instance, prim));
        match bound {
            Some(tmax) => {
                self.stats.hits += 1;
                ray.with_interval(ray.ray.tmin, tmax.min(ray.ray.tmax))
            }
            None => {
                self.stats.misses += 1;
                *ray
            }
        }
    }

    /// Keeps the triangle hit (a missing ray keeps the old one); returns the hit.
    fn remember(&mut self, hit: Option<SceneHit>) -> Option<SceneHit> {
        if let Some(h) = hit {
            self.last = Some((h.instance, h.prim));
        }
        hit
    }
}
