//! Every hit along a ray through the wide layout: one traversal that visits every leaf the
//! ray's full interval reaches and keeps every triangle hit.

use super::box_kernels::Lanes;
use super::leaf::undecided_lane;
use super::{TrianglePacket, WideLayout};
use crate::all_hits::{sort_hits, AllHits};
use crate::geometry::{EdgeRule, PreparedRay, Ray};
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
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: the layout traverses with AVX only when the CPU reported it.
            unsafe { all_hits_avx(self, ray, hits) };
            sort_hits(hits);
            return;
        }
        self.for_each_leaf_reached(ray, |packets, prepared| keep_hits(packets, prepared, hits));
        sort_hits(hits);
    }
}

/// [`AllHits::all_hits`]'s traversal with the leaf visit compiled with AVX: the closure is
/// written here, in a function compiled with AVX, because the traversal calls it out of line,
/// and an out-of-line closure is compiled with the target features of the function it is
/// written in (written in `all_hits`, it was baseline SSE2, a fifth of a ray's time).
///
/// # Safety
/// The CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn all_hits_avx<const W: usize>(layout: &WideLayout<W>, ray: &Ray, hits: &mut Vec<Hit>) {
    layout.for_each_leaf_reached(ray, |packets, prepared| keep_hits(packets, prepared, hits));
}

/// Appends every hit of `packets` along `ray` to `hits` (a lane repeating the previous one is
/// padding, and skipped).
#[inline(always)]
fn keep_hits(packets: &[TrianglePacket], ray: &PreparedRay, hits: &mut Vec<Hit>) {
    for packet in packets {
        let test = packet.test(ray);
        for lane in Lanes(test.hit | test.undecided) {
            if packet.repeats_previous(lane) {
                continue;
            }
            let hit = if test.hit >> lane & 1 == 1 {
                Some(test.hit(lane))
            } else {
                undecided_lane(packet, lane, ray, EdgeRule::HalfOpen)
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
}
