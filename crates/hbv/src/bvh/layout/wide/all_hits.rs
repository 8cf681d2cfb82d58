//! Every hit along a ray through the wide layout: one traversal that visits every leaf the
//! ray's full interval reaches and keeps every triangle hit.

#[cfg(target_arch = "x86_64")]
use super::kernels::AvxBoxes;
use super::kernels::{BaselineBoxes, BoxKernel, Kernels};
use super::lanes::Lanes;
use super::leaf::undecided_lane;
use super::{TrianglePacket, WideLayout};
use crate::all_hits::{sort_hits, AllHits};
use crate::geometry::{EdgeRule, PreparedRay, Ray};
use crate::query::Hit;
use crate::stats::NoCount;

/// The any-hit traversal order (no sorting of children: every reached leaf is visited anyway)
/// with the interval never shrunk; the SIMD packet test decides what it can and the scalar
/// watertight test the rest, exactly as in the closest-hit query. The spare lanes of a packet
/// repeat its last triangle, so a lane with the previous lane's id is skipped. 4-wide nodes run
/// the baseline kernels.
impl AllHits for WideLayout<4> {
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        if !ray.is_valid() {
            return;
        }
        self.for_each_leaf_reached::<BaselineBoxes>(ray, |packets, prepared| {
            keep_hits(packets, prepared, hits)
        });
        sort_hits(hits);
    }
}

/// As for 4-wide nodes, with AVX where the CPU has it (chosen when the layout is made).
impl AllHits for WideLayout<8> {
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        if !ray.is_valid() {
            return;
        }
        match self.kernels {
            Kernels::Baseline => self
                .for_each_leaf_reached::<BaselineBoxes>(ray, |packets, prepared| {
                    keep_hits(packets, prepared, hits)
                }),
            // SAFETY: the AVX kernels are chosen only on a CPU that reported AVX.
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx | Kernels::AvxRayPackets => unsafe { self.all_hits_avx(ray, hits) },
        }
        sort_hits(hits);
    }
}

impl<const W: usize> WideLayout<W> {
    /// Calls `visit` with the triangle packets of every leaf whose box the ray's whole interval
    /// reaches (the interval is never shrunk), in any-hit order, with box kernel `K`. The ray
    /// is valid (checked by the caller).
    #[inline(always)]
    fn for_each_leaf_reached<K: BoxKernel<W>>(
        &self,
        ray: &Ray,
        mut visit: impl FnMut(&[TrianglePacket], &PreparedRay),
    ) {
        self.traverse::<NoCount, K, false>(ray, &mut NoCount, |first, count, ray, _| {
            visit(&self.packets[first..first + count], ray);
            false
        });
    }
}

#[cfg(target_arch = "x86_64")]
impl WideLayout<8> {
    /// [`AllHits::all_hits`]'s traversal compiled with AVX, with the leaf visit written here:
    /// the traversal calls it out of line, and an out-of-line closure is compiled with the
    /// target features of the function it is written in (written in `all_hits`, it was
    /// baseline SSE2, a fifth of a ray's time).
    ///
    /// # Safety
    /// The CPU has AVX.
    #[target_feature(enable = "avx")]
    unsafe fn all_hits_avx(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        self.for_each_leaf_reached::<AvxBoxes>(ray, |packets, prepared| {
            keep_hits(packets, prepared, hits)
        });
    }
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
