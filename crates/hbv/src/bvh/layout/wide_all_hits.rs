//! Every hit along a ray through the wide layout: one traversal that visits every leaf the
//! ray's full interval reaches and keeps every triangle hit.

use super::wide::WideLayout;
use super::wide_kernels::Lanes;
use crate::all_hits::{sort_hits, AllHits};
use crate::geometry::Ray;
use crate::query::Hit;

impl<const W: usize> AllHits for WideLayout<W> {
    /// The any-hit traversal order (no sorting of children: every reached leaf is visited
    /// anyway) with the interval never shrunk; the SIMD packet test decides what it can and the
    /// scalar watertight test the rest, exactly as in the closest-hit query. The spare lanes of a
    /// packet repeat its last triangle, so a lane with the previous lane's id is skipped.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        if !ray.is_valid() {
            return;
        }
        self.for_each_leaf_reached(ray, |packets, prepared| {
            for packet in packets {
                let test = packet.test(prepared);
                for lane in Lanes(test.hit | test.undecided) {
                    if packet.repeats_previous(lane) {
                        continue;
                    }
                    let hit = if test.hit >> lane & 1 == 1 {
                        Some(test.hit(lane))
                    } else {
                        packet.triangle(lane).intersect(prepared)
                    };
                    if let Some(h) = hit {
                        hits.push(Hit {
                            t: h.t,
                            prim: packet.ids[lane],
                            u: h.u,
                            v: h.v,
                        });
                    }
                }
            }
        });
        sort_hits(hits);
    }
}
