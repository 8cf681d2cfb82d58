//! The shadow cache of a scene: the last occluder of a light, an `(instance, prim)`, tested first.

use super::CacheStats;
use crate::scene::{InstanceId, Scene, SceneRay};
use crate::stats::TraversalStats;

/// [`super::ShadowCache`] for a [`Scene`]: the last triangle that blocked a shadow ray towards
/// one light, named by its instance and its `prim` in that instance's mesh (Haines & Greenberg
/// 1986, "The light buffer"; Pearce 1991). A shadow ray first tests that one triangle, carried
/// into its instance's space ([`Scene::intersect_prim`]), and returns at once if it still
/// blocks; only otherwise does the scene answer, and its blocking triangle (if any) is cached.
///
/// The answer is always [`Scene::occluded`]'s: a cached triangle is reported as blocking only
/// when the scene's own test of that triangle, on the same carried ray, hits it within
/// `[tmin, tmax]` and the ray's mask sees its instance — and then the scene's traversal, which
/// loses no ray at an instance's box, finds a blocker too.
///
/// One per light and per thread; the scene is shared (and cannot change while a cache borrows
/// it).
#[derive(Debug)]
pub struct SceneShadowCache<'a> {
    scene: &'a Scene,
    /// `(instance, prim)` of the last occluder.
    occluder: Option<(u32, u32)>,
    stats: CacheStats,
}

impl<'a> SceneShadowCache<'a> {
    /// An empty cache over `scene`.
    pub fn new(scene: &'a Scene) -> Self {
        Self {
            scene,
            occluder: None,
            stats: CacheStats::default(),
        }
    }

    /// Whether anything the ray sees blocks it: [`Scene::occluded`], the cached occluder first.
    pub fn occluded(&mut self, ray: &SceneRay) -> bool {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return false;
        }
        if self.cached_blocks(ray) {
            self.stats.hits += 1;
            return true;
        }
        self.stats.misses += 1;
        self.remember(self.scene.occluder(ray))
    }

    /// [`SceneShadowCache::occluded`], adding the work done to `stats` as
    /// [`Scene::occluded_counted`] counts it (the cached test counts as one triangle test).
    pub fn occluded_counted(&mut self, ray: &SceneRay, stats: &mut TraversalStats) -> bool {
        if !ray.ray.is_valid() || ray.mask == 0 {
            stats.rays += 1;
            return false;
        }
        stats.triangles_tested += self.occluder.is_some() as u64;
        if self.cached_blocks(ray) {
            self.stats.hits += 1;
            stats.rays += 1;
            return true;
        }
        self.stats.misses += 1;
        self.remember(self.scene.occluder_counted(ray, stats))
    }

    /// The cache's hits and misses so far.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// The cached occluder: its instance and its `prim` in that instance's mesh.
    pub fn occluder(&self) -> Option<(InstanceId, u32)> {
        self.occluder.map(|(i, p)| (InstanceId(i), p))
    }

    fn cached_blocks(&self, ray: &SceneRay) -> bool {
        self.occluder
            .is_some_and(|(instance, prim)| self.scene.prim_blocks(ray, instance, prim))
    }

    /// Keeps a new occluder (an unblocked ray keeps the old one: the next point may be in its
    /// shadow again); returns whether there was one.
    fn remember(&mut self, occluder: Option<(InstanceId, u32)>) -> bool {
        if let Some((instance, prim)) = occluder {
            self.occluder = Some((instance.0, prim));
        }
        occluder.is_some()
    }
}
