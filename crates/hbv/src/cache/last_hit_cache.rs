//! The last-hit cache: the previous ray's triangle bounds the next closest-hit query.

use super::CacheStats;
use crate::geometry::{PreparedRay, Ray};
use crate::mesh::TriangleMesh;
use crate::query::Hit;
use crate::stats::TraversalStats;
use crate::Accelerator;

/// The triangle that the previous ray hit, tested first on the next one: for coherent rays
/// (neighbouring pixels, rays in their primary's order) it is often hit again, and its `t`
/// becomes the accelerator's `tmax`, which culls everything farther from the first box test
/// on (the "ray coherence" caches of Amanatides' and Pearce's era; here in the form that keeps
/// answers exact).
///
/// Why the answer is unchanged: the cached triangle's hit `t_c` lies in `[tmin, tmax]`, so the
/// true closest hit (with `t ≤ t_c`) lies in `[tmin, t_c]` (widened a little for rounding, see
/// `bounded`), where the accelerator finds the same triangle with the same `t`, `u`, `v` and the
/// same tie rule — a triangle's test does not depend on `tmax` except through the final
/// comparison `t ≤ tmax`, which is closed.
///
/// One per thread (and per stream of coherent rays); the accelerator and mesh are shared.
#[derive(Debug)]
pub struct LastHitCache<'a, A: Accelerator + ?Sized> {
    accelerator: &'a A,
    mesh: &'a TriangleMesh,
    last: Option<u32>,
    stats: CacheStats,
}

impl<'a, A: Accelerator + ?Sized> LastHitCache<'a, A> {
    /// An empty cache over `accelerator`, built from `mesh` (whose triangles it tests).
    pub fn new(accelerator: &'a A, mesh: &'a TriangleMesh) -> Self {
        Self {
            accelerator,
            mesh,
            last: None,
            stats: CacheStats::default(),
        }
    }

    /// The closest hit: [`Accelerator::intersect`], bounded first by the cached triangle.
    pub fn intersect(&mut self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let bounded = self.bounded(ray);
        let hit = self.accelerator.intersect(&bounded);
        self.remember(hit)
    }

    /// [`LastHitCache::intersect`], adding the work done to `stats` (the cached test counts as
    /// one triangle test).
    pub fn intersect_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        if !ray.is_valid() {
            stats.rays += 1;
            return None;
        }
        stats.triangles_tested += self.last.is_some() as u64;
        let bounded = self.bounded(ray);
        let hit = self.accelerator.intersect_counted(&bounded, stats);
        self.remember(hit)
    }

    /// The cache's hits (the cached triangle was hit, shrinking `tmax`) and misses.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// The ray, its `tmax` lowered to just past the cached triangle's hit if it has one.
    ///
    /// Just past, not at: the accelerator's box tests widen intervals by a relative 2^-18
    /// (`PreparedRay::BOX_SLACK`), less than the error of a triangle test's `t` when the
    /// vertices are far from the origin compared with `t` (a few ulps of `|p − o| / max |d_i|`).
    /// With `tmax` exactly at the cached `t` a box could then cull the very triangle that made
    /// it. The new bound is
    ///
    /// ```text
    ///   tmax' = min(tmax, t_c + 2^-16 |t_c| + 64 ε max_k ‖p_k − o‖∞ / max_i |d_i|)
    /// ```
    ///
    /// still at or beyond every `t` the accelerator can compute for the closest hit.
    fn bounded(&mut self, ray: &Ray) -> Ray {
        let cached = self.last.and_then(|prim| {
            let triangle = self.mesh.triangle(prim as usize);
            triangle
                .intersect(&PreparedRay::new(ray))
                .map(|h| (h.t, triangle))
        });
        match cached {
            Some((t, triangle)) => {
                self.stats.hits += 1;
                let reach = [triangle.p0, triangle.p1, triangle.p2]
                    .map(|p| (p - ray.origin).abs().max_element())
                    .into_iter()
                    .fold(0.0f32, f32::max);
                let slack = t.abs() * (1.0 / 65_536.0)
                    + 64.0 * f32::EPSILON * reach / ray.direction.abs().max_element();
                ray.with_interval(ray.tmin, (t + slack).min(ray.tmax))
            }
            None => {
                self.stats.misses += 1;
                *ray
            }
        }
    }

    /// Keeps the triangle hit (a missing ray keeps the old one); returns the hit.
    fn remember(&mut self, hit: Option<Hit>) -> Option<Hit> {
        if let Some(h) = hit {
            self.last = Some(h.prim);
        }
        hit
    }
}
