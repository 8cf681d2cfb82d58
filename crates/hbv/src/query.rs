//! The queries every acceleration structure answers, single and in parallel batches.

use rayon::prelude::*;

use crate::geometry::{PreparedRay, Ray, Triangle, TriangleHit};
use crate::stats::{Counter, NoCount, TraversalStats};

/// The closest intersection of a ray with a mesh.
///
/// `prim` is the triangle's index in the mesh's face order; the hit point is
/// `ray.at(t) = (1-u-v) p0 + u p1 + v p2` for that triangle's vertices in file order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

impl Hit {
    /// Whether `self` should replace `best` as the closest hit: nearer, or as near with a smaller
    /// primitive id. The tie rule makes every structure's answer independent of its traversal
    /// order, so that two structures can be compared exactly.
    #[inline]
    pub fn is_closer_than(&self, best: &Option<Hit>) -> bool {
        match best {
            None => true,
            Some(b) => self.t < b.t || (self.t == b.t && self.prim < b.prim),
        }
    }
}

/// Tests `triangle` (face id `prim`) for a hit closer than `best`; if there is one, records it
/// and shrinks `ray.tmax` to its `t`, so that everything farther is culled from then on.
/// The step every closest-hit kernel repeats for each triangle it tests.
#[inline]
pub fn record_closer_hit(
    triangle: &Triangle,
    prim: u32,
    ray: &mut PreparedRay,
    best: &mut Option<Hit>,
) {
    if let Some(h) = triangle.intersect(ray) {
        record_hit(h, prim, ray, best);
    }
}

/// Records the hit `h` of triangle `prim` if it is closer than `best` (ties to the smaller id),
/// shrinking `ray.tmax` to its `t`.
#[inline]
pub(crate) fn record_hit(h: TriangleHit, prim: u32, ray: &mut PreparedRay, best: &mut Option<Hit>) {
    let hit = Hit {
        t: h.t,
        prim,
        u: h.u,
        v: h.v,
    };
    if hit.is_closer_than(best) {
        *best = Some(hit);
        ray.tmax = h.t;
    }
}

/// A structure that answers ray queries on one mesh: closest hit and any hit.
///
/// Invalid rays (see [`Ray::is_valid`]) miss. Degenerate triangles are never hit. A hit at `t`
/// counts when `ray.tmin <= t <= ray.tmax`.
pub trait Accelerator: Send + Sync {
    /// The closest hit along the ray, ties broken towards the smaller primitive id.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// Whether anything is hit along the ray; stops at the first hit found.
    fn occluded(&self, ray: &Ray) -> bool;

    /// [`Accelerator::intersect`], adding the work done to `stats`.
    fn intersect_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit>;

    /// [`Accelerator::occluded`], adding the work done to `stats`.
    fn occluded_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> bool;

    /// Any hit, returning the triangle that blocks the ray (not necessarily the nearest): what a
    /// shadow cache remembers. Structures that can report the first triangle found override it;
    /// the default asks for the closest hit, which costs more than [`Accelerator::occluded`].
    fn occluder(&self, ray: &Ray) -> Option<u32> {
        self.intersect(ray).map(|h| h.prim)
    }

    /// [`Accelerator::occluder`], adding the work done to `stats`.
    fn occluder_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<u32> {
        self.intersect_counted(ray, stats).map(|h| h.prim)
    }

    /// Closest hits of `rays` into `hits` (same length), on the calling thread: the answers of
    /// [`Accelerator::intersect`], ray by ray. Structures that trace several independent rays
    /// at once faster (the wide layouts interleave them, to hide memory latency) override it.
    fn intersect_into(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one answer per ray");
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.intersect(ray);
        }
    }

    /// Any-hit answers of `rays` into `occluded` (same length), on the calling thread; as
    /// [`Accelerator::intersect_into`].
    fn occluded_into(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        for (ray, o) in rays.iter().zip(occluded) {
            *o = self.occluded(ray);
        }
    }

    /// Closest hits of many rays, in parallel on the current rayon pool.
    fn intersect_batch(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut hits = vec![None; rays.len()];
        rays.par_chunks(BATCH_GRAIN)
            .zip(hits.par_chunks_mut(BATCH_GRAIN))
            .for_each(|(rays, hits)| self.intersect_into(rays, hits));
        hits
    }

    /// Any-hit answers for many rays, in parallel on the current rayon pool.
    fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        let mut occluded = vec![false; rays.len()];
        rays.par_chunks(BATCH_GRAIN)
            .zip(occluded.par_chunks_mut(BATCH_GRAIN))
            .for_each(|(rays, occluded)| self.occluded_into(rays, occluded));
        occluded
    }
}

/// Rays handed to one rayon task at least: enough to hide the scheduling cost (~1 µs) behind
/// work (~1 µs per ray), few enough to balance load on many cores.
const BATCH_GRAIN: usize = 256;

/// The two traversal kernels of a structure, generic over what they count.
///
/// Implementing this gives [`Accelerator`] for free: the plain queries run the kernels with
/// [`NoCount`] (the counting compiles away) and the counted ones with [`TraversalStats`].
pub trait TraversalKernel: Send + Sync {
    /// Closest hit, counting into `counter`. The ray is valid (checked by the caller).
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit>;

    /// Any hit, counting into `counter`. The ray is valid (checked by the caller).
    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool;

    /// Any hit, returning the blocking triangle, counting into `counter`. The ray is valid.
    /// Default: the closest hit's triangle; kernels that can stop at the first hit override it.
    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        self.closest_hit(ray, counter).map(|h| h.prim)
    }

    /// Closest hits of a batch of independent rays into `hits` (same length); rays may be
    /// invalid (they miss). The answers are [`TraversalKernel::closest_hit`]'s; kernels that can
    /// trace several rays at once faster (interleaved, to hide memory latency) override it.
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        closest_hits_one_by_one(self, rays, hits);
    }

    /// Any-hit answers of a batch of independent rays into `occluders` (same length): a blocking
    /// triangle, or `None`. Rays may be invalid (they miss). As [`TraversalKernel::closest_hits`].
    fn occluders(&self, rays: &[Ray], occluders: &mut [Option<u32>]) {
        occluders_one_by_one(self, rays, occluders);
    }
}

/// [`TraversalKernel::closest_hits`] one ray at a time: the default, and the choice of kernels
/// that interleave only some batches.
pub(crate) fn closest_hits_one_by_one<K: TraversalKernel + ?Sized>(
    kernel: &K,
    rays: &[Ray],
    hits: &mut [Option<Hit>],
) {
    for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
        *hit = if ray.is_valid() {
            kernel.closest_hit(ray, &mut NoCount)
        } else {
            None
        };
    }
}

/// [`TraversalKernel::occluders`] one ray at a time; see [`closest_hits_one_by_one`].
pub(crate) fn occluders_one_by_one<K: TraversalKernel + ?Sized>(
    kernel: &K,
    rays: &[Ray],
    occluders: &mut [Option<u32>],
) {
    for (ray, occluder) in rays.iter().zip(occluders.iter_mut()) {
        *occluder = if ray.is_valid() {
            kernel.any_hit_prim(ray, &mut NoCount)
        } else {
            None
        };
    }
}

impl<K: TraversalKernel> Accelerator for K {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        self.closest_hit(ray, &mut NoCount)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        ray.is_valid() && self.any_hit(ray, &mut NoCount)
    }

    fn intersect_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        stats.rays += 1;
        if !ray.is_valid() {
            return None;
        }
        self.closest_hit(ray, stats)
    }

    fn occluded_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        stats.rays += 1;
        ray.is_valid() && self.any_hit(ray, stats)
    }

    fn intersect_into(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one answer per ray");
        self.closest_hits(rays, hits);
    }

    fn occluded_into(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        let mut occluders = [None; BATCH_GRAIN];
        for (rays, occluded) in rays
            .chunks(BATCH_GRAIN)
            .zip(occluded.chunks_mut(BATCH_GRAIN))
        {
            let occluders = &mut occluders[..rays.len()];
            self.occluders(rays, occluders);
            for (o, b) in occluders.iter().zip(occluded) {
                *b = o.is_some();
            }
        }
    }

    #[inline]
    fn occluder(&self, ray: &Ray) -> Option<u32> {
        if !ray.is_valid() {
            return None;
        }
        self.any_hit_prim(ray, &mut NoCount)
    }

    fn occluder_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<u32> {
        stats.rays += 1;
        if !ray.is_valid() {
            return None;
        }
        self.any_hit_prim(ray, stats)
    }
}
