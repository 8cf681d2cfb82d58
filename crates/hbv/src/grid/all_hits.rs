//! Every hit along a ray from the uniform grid: the closest-hit walk without its early exit.

use super::{CellWalk, Mailbox, UniformGrid};
use crate::all_hits::{sort_hits, AllHits};
use crate::geometry::{EdgeRule, PreparedRay, Ray};
use crate::query::Hit;

impl AllHits for UniformGrid {
    /// Walks every cell the ray crosses between `tmin` and `tmax` (widened by
    /// a margin (`UniformGrid::t_margin`), as the closest-hit walk), testing each listed triangle once
    /// (a final dedup after sorting catches what the mailbox misses) and keeping every hit; then sorts by
    /// `(t, prim)`. A triangle hit within `[tmin, tmax]` is listed in a cell the walk visits (the
    /// closest-hit walk's argument, with no cell skipped), so the list is brute force's.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        let Some(shape) = self.shape() else {
            return;
        };
        if !ray.is_valid() {
            return;
        }
        let prepared = PreparedRay::new(ray);
        let (triangles, prims) = self.listed_triangles();
        let mut record = |local: usize| {
            if let Some(h) = triangles[local].intersect_by(&prepared, EdgeRule::HalfOpen) {
                hits.push(Hit {
                    t: h.t,
                    prim: prims[local],
                    u: h.u,
                    v: h.v,
                });
            }
        };
        if self.beyond_f64(shape, ray) {
            (0..triangles.len()).for_each(record);
            sort_hits(hits);
            return;
        }
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let from = tmin - self.t_margin(ray, tmin);
        let to = tmax + self.t_margin(ray, tmax);
        let Some(mut walk) = CellWalk::new(shape, ray, from, to) else {
            return;
        };
        let mut mailbox = Mailbox::new();
        let mailboxed = self.config().mailbox;
        loop {
            for &local in self.cell_items(walk.cell()) {
                if !mailboxed || !mailbox.seen_or_post(local) {
                    record(local as usize);
                }
            }
            if !walk.advance() {
                break;
            }
        }
        sort_hits(hits);
        // A triangle spanning several cells is found once per cell without a mailbox, and may
        // be found again with one (the mailbox is a small cache that forgets).
        hits.dedup_by(|a, b| a.prim == b.prim && a.t == b.t);
    }
}
