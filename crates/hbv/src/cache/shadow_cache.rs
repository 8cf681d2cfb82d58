//! The shadow cache: the last occluder of a light, tested first.

use super::CacheStats;
use crate::geometry::{PreparedRay, Ray};
use crate::mesh::TriangleMesh;
use crate::stats::TraversalStats;
use crate::Accelerator;

/// The last triangle that blocked a shadow ray towards one light (Haines & Greenberg 1986,
/// "The light buffer"; the "shadow cache" of Pearce 1991). Neighbouring shading points are
/// usually shadowed by the same triangle, so a shadow ray first tests the cached one and
/// returns at once if it still blocks; only otherwise does it run the accelerator, whose
/// blocking triangle (if any) replaces the cached one.
///
/// One per light and per thread: it is mutable state, owned by the caller; the accelerator and
/// the mesh are shared. The answer is always the accelerator's: a cached triangle is only
/// reported as blocking when the exact triangle test says it is hit within `[tmin, tmax]`.
#[derive(Debug)]
pub struct ShadowCache<'a, A: Accelerator + ?Sized> {
    accelerator: &'a A,
    mesh: &'a TriangleMesh,
    occluder: Option<u32>,
    stats: CacheStats,
}

impl<'a, A: Accelerator + ?Sized> ShadowCache<'a, A> {
    /// An empty cache over `accelerator`, built from `mesh` (whose triangles it tests).
    pub fn new(accelerator: &'a A, mesh: &'a TriangleMesh) -> Self {
        Self {
            accelerator,
            mesh,
            occluder: None,
            stats: CacheStats::default(),
        }
    }

    /// Whether anything blocks the ray: [`Accelerator::occluded`], the cached occluder first.
    pub fn occluded(&mut self, ray: &Ray) -> bool {
        if !ray.is_valid() {
            return false;
        }
        if self.cached_blocks(ray) {
            self.stats.hits += 1;
            return true;
        }
        self.stats.misses += 1;
        self.remember(self.accelerator.occluder(ray))
    }

    /// [`ShadowCache::occluded`], adding the work done to `stats` (the cached test counts as
    /// one triangle test).
    pub fn occluded_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        if !ray.is_valid() {
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
        self.remember(self.accelerator.occluder_counted(ray, stats))
    }

    /// The cache's hits and misses so far.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// The cached occluder's face id.
    pub fn occluder(&self) -> Option<u32> {
        self.occluder
    }

    fn cached_blocks(&self, ray: &Ray) -> bool {
        self.occluder.is_some_and(|prim| {
            let triangle = self.mesh.triangle(prim as usize);
            triangle.intersect(&PreparedRay::new(ray)).is_some()
        })
    }

    /// Keeps a new occluder (an unblocked ray keeps the old one: the next point may be in its
    /// shadow again); returns whether there was one.
    fn remember(&mut self, occluder: Option<u32>) -> bool {
        if occluder.is_some() {
            self.occluder = occluder;
        }
        occluder.is_some()
    }
}
