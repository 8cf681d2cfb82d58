//! Every hit along a ray through the wide layout: one traversal that visits every leaf the
//! ray's full interval reaches and keeps every triangle hit.

use super::wide::WideLayout;
use crate::all_hits::{sort_hits, AllHits};
use crate::geometry::Ray;
use crate::query::Hit;

impl<const W: usize> AllHits for WideLayout<W> {
    /// The any-hit traversal order (no sorting of children: every reached leaf is visited
    /// anyway) with the interval never shrunk; the SIMD packet test filters, the scalar
    /// watertight test decides, exactly as in the closest-hit query. The spare lanes of a
    /// packet repeat its last triangle, so a lane with the previous lane's id is skipped.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        if !ray.is_valid() {
            return;
        }
        self.for_each_leaf_reached(ray, |packets, prepared| {
            for packet in packets {
                for lane in packet.candidate_lanes(prepared) {
                    if lane > 0 && packet.ids[lane] == packet.ids[lane - 1] {
                        continue;
                    }
                    if let Some(h) = packet.triangle(lane).intersect(prepared) {
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
