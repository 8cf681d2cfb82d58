//! Every hit along a ray, not just the closest: the query behind hit counts, inside tests and
//! "every surface this ray crosses" (trimesh's `intersects_location(multiple_hits=True)`).

use rayon::prelude::*;

use crate::batch_threads::{share_out, Threads};
use crate::geometry::Ray;
use crate::query::Hit;

/// A structure that reports every triangle a ray hits within `[tmin, tmax]`, found in one
/// traversal that never shrinks the ray's interval (no re-casting from each hit).
///
/// Answers are sorted by `t`, equal `t` by primitive id, so any two structures (and
/// [`BruteForce`](crate::BruteForce), the reference) give identical lists. Invalid rays (see
/// [`Ray::is_valid`]) and degenerate triangles give no hits. A ray passing exactly through an
/// edge or a vertex hits the triangles there as [`EdgeRule::HalfOpen`] says: where it crosses
/// the surface, exactly one of them (decided exactly), so a count is a count of crossings and
/// its parity is right on closed meshes; where it only touches the surface, none or two.
///
/// [`EdgeRule::HalfOpen`]: crate::geometry::EdgeRule::HalfOpen
pub trait AllHits: Send + Sync {
    /// Replaces the contents of `hits` with every hit along `ray`, sorted by `(t, prim)`.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>);

    /// The number of hits along `ray`: `all_hits(ray).len()`.
    fn count_hits(&self, ray: &Ray) -> usize {
        let mut hits = Vec::new();
        self.all_hits(ray, &mut hits);
        hits.len()
    }

    /// Every hit of every ray, as one flat list of `(ray index, hit)` in ray order and, within
    /// a ray, sorted by `(t, prim)`. Runs of rays are shared between the calling thread, which
    /// starts on them at once, and the current rayon pool's other threads as they wake (a
    /// parallel iterator left the calling thread waiting for them: from Python, batches of up
    /// to 8,192 random rays on the Cornell box took longer on two threads than on one); up to
    /// two runs stay on the calling thread.
    fn all_hits_batch(&self, rays: &[Ray]) -> Vec<(u32, Hit)> {
        let threads = if rays.len() <= 2 * ALL_HITS_GRAIN {
            Threads::Here
        } else {
            Threads::Pool
        };
        all_hits_batch_with(self, rays, threads)
    }

    /// [`AllHits::all_hits_batch`] on the calling thread alone, with no rayon task: the same
    /// list, for a caller that wants one thread (`threads=1` from Python).
    fn all_hits_batch_here(&self, rays: &[Ray]) -> Vec<(u32, Hit)> {
        all_hits_batch_with(self, rays, Threads::Here)
    }

    /// Hit counts of many rays, in parallel on the current rayon pool.
    fn count_hits_batch(&self, rays: &[Ray]) -> Vec<u32> {
        rays.par_iter()
            .with_min_len(ALL_HITS_GRAIN)
            .map_init(Vec::new, |hits, ray| {
                self.all_hits(ray, hits);
                hits.len() as u32
            })
            .collect()
    }
}

/// Rays per rayon task in the batch forms.
const ALL_HITS_GRAIN: usize = 256;

/// The batch forms' list of every hit: runs of [`ALL_HITS_GRAIN`] rays taken as `threads` says
/// (module `batch_threads`), their hits concatenated in ray order.
fn all_hits_batch_with<A: AllHits + ?Sized>(
    structure: &A,
    rays: &[Ray],
    threads: Threads,
) -> Vec<(u32, Hit)> {
    let mut parts: Vec<Vec<(u32, Hit)>> = vec![Vec::new(); rays.len().div_ceil(ALL_HITS_GRAIN)];
    let runs: Vec<_> = parts
        .iter_mut()
        .zip(rays.chunks(ALL_HITS_GRAIN))
        .enumerate()
        .collect();
    share_out(threads, runs, |(run, (out, rays))| {
        let mut hits = Vec::new();
        for (k, ray) in rays.iter().enumerate() {
            structure.all_hits(ray, &mut hits);
            let index = (run * ALL_HITS_GRAIN + k) as u32;
            out.extend(hits.iter().map(|&h| (index, h)));
        }
    });
    parts.concat()
}

/// Sorts hits by `t`, then by primitive id: the order every [`AllHits`] answer is given in.
pub fn sort_hits(hits: &mut [Hit]) {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
}
