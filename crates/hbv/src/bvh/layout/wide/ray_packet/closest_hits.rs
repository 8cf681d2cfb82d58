//! The closest-hit query of a packet: each ray's closest hit so far, shrinking its interval.

use std::arch::x86_64::*;

use super::avx_lanes::{lane_mask, lane_of};
use super::packet_rays::PacketRays;
use super::query::PacketQuery;
use super::triangle_test::{test_triangle, LaneTest};
use super::PACKET_RAYS;
use crate::bvh::layout::wide::kernels::AvxBoxes;
use crate::bvh::layout::wide::lanes::Lanes;
use crate::bvh::layout::wide::leaf::undecided_lane;
use crate::bvh::layout::wide::root_filter::RayColumns;
use crate::bvh::layout::wide::traversal::{Step, Traversal};
use crate::bvh::layout::wide::WideLayout;
use crate::geometry::EdgeRule;
use crate::query::Hit;
use crate::stats::NoCount;

/// The closest hit so far of each ray of a packet. `tmax` is each ray's interval end: its
/// closest hit's `t` once it has one (bit set in `found`), its own `tmax` before.
pub(super) struct ClosestHits {
    tmax: __m256,
    /// `tmax + box_margin`: the end of each ray's interval for box tests.
    box_tmax: __m256,
    prim: __m256i,
    u: __m256,
    v: __m256,
    found: u32,
}

impl ClosestHits {
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(columns: &RayColumns, packet: &PacketRays) -> Self {
        Self {
            tmax: columns.tmax,
            box_tmax: _mm256_add_ps(columns.tmax, packet.box_margin),
            prim: _mm256_setzero_si256(),
            u: _mm256_setzero_ps(),
            v: _mm256_setzero_ps(),
            found: 0,
        }
    }

    /// The closest hit of ray `lane` so far.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn hit(&self, lane: usize) -> Option<Hit> {
        if self.found >> lane & 1 == 0 {
            return None;
        }
        let mut prim = [0u32; PACKET_RAYS];
        // SAFETY: AVX2 is enabled; the store writes eight lanes into an 8-element array.
        unsafe { _mm256_storeu_si256(prim.as_mut_ptr() as *mut __m256i, self.prim) };
        // SAFETY: AVX2 is enabled.
        let lane_of = |x: __m256| unsafe { lane_of(x, lane) };
        Some(Hit {
            t: lane_of(self.tmax),
            prim: prim[lane],
            u: lane_of(self.u),
            v: lane_of(self.v),
        })
    }

    /// Records `hit` for ray `lane` if it is closer than that ray's best
    /// ([`Hit::is_closer_than`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn record_one(&mut self, lane: usize, hit: Hit, packet: &PacketRays) {
        // SAFETY: AVX2 is enabled.
        if !hit.is_closer_than(&unsafe { self.hit(lane) }) {
            return;
        }
        // SAFETY: AVX2 is enabled.
        let only = unsafe { lane_mask(1 << lane) };
        self.tmax = _mm256_blendv_ps(self.tmax, _mm256_set1_ps(hit.t), only);
        self.box_tmax = _mm256_add_ps(self.tmax, packet.box_margin);
        self.u = _mm256_blendv_ps(self.u, _mm256_set1_ps(hit.u), only);
        self.v = _mm256_blendv_ps(self.v, _mm256_set1_ps(hit.v), only);
        self.prim = _mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(self.prim),
            _mm256_castsi256_ps(_mm256_set1_epi32(hit.prim as i32)),
            only,
        ));
        self.found |= 1 << lane;
    }

    /// The hits of `test` in lanes `hit` on triangle `prim`: those nearer than each ray's best
    /// taken at once, those at exactly its `tmax` (a tie, or a hit at the end of the interval)
    /// by the tie rule, one by one.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn record(&mut self, hit: u32, prim: u32, test: &LaneTest, packet: &PacketRays) {
        // SAFETY (this block): AVX2 is enabled.
        unsafe {
            let closer = _mm256_and_ps(
                lane_mask(hit),
                _mm256_cmp_ps::<_CMP_LT_OQ>(test.t, self.tmax),
            );
            let closer_bits = _mm256_movemask_ps(closer) as u32;
            if closer_bits != 0 {
                self.tmax = _mm256_blendv_ps(self.tmax, test.t, closer);
                self.box_tmax = _mm256_add_ps(self.tmax, packet.box_margin);
                self.u = _mm256_blendv_ps(self.u, _mm256_div_ps(test.v, test.det), closer);
                self.v = _mm256_blendv_ps(self.v, _mm256_div_ps(test.w, test.det), closer);
                self.prim = _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(self.prim),
                    _mm256_castsi256_ps(_mm256_set1_epi32(prim as i32)),
                    closer,
                ));
                self.found |= closer_bits;
            }
            let ties = hit & !closer_bits;
            if ties != 0 {
                self.record_ties(ties, prim, test, packet);
            }
        }
    }

    /// [`ClosestHits::record`]'s hits at exactly a ray's `tmax`: rare.
    #[cold]
    #[target_feature(enable = "avx2")]
    unsafe fn record_ties(&mut self, ties: u32, prim: u32, test: &LaneTest, packet: &PacketRays) {
        for lane in Lanes(ties) {
            // SAFETY (this block): AVX2 is enabled.
            unsafe {
                let hit = Hit {
                    t: lane_of(test.t, lane),
                    prim,
                    u: lane_of(test.v, lane) / lane_of(test.det, lane),
                    v: lane_of(test.w, lane) / lane_of(test.det, lane),
                };
                self.record_one(lane, hit, packet);
            }
        }
    }
}

impl PacketQuery for ClosestHits {
    type Answer = Hit;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self {
        // SAFETY: AVX2 is enabled.
        unsafe { Self::new(columns, packet) }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn answer(&self, lane: usize) -> Option<Hit> {
        // SAFETY: AVX2 is enabled.
        unsafe { self.hit(lane) }
    }

    #[inline(always)]
    fn box_tmax(&self) -> __m256 {
        self.box_tmax
    }

    #[inline(always)]
    fn searching(&self) -> u32 {
        0xff
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        lanes: u32,
        packet: &PacketRays,
    ) {
        for triangles in layout.leaf_packets(leaf) {
            for k in 0..4 {
                if triangles.repeats_previous(k) {
                    // Spare lanes repeat the leaf's last triangle, to the end of the packet.
                    break;
                }
                // SAFETY (this block): AVX2 is enabled.
                unsafe {
                    let test = test_triangle(triangles, k, packet, self.tmax);
                    let hit = test.hit & lanes;
                    if hit != 0 {
                        self.record(hit, triangles.ids[k], &test, packet);
                    }
                    for lane in Lanes(test.undecided & lanes) {
                        let ray = packet.alone(lane, lane_of(self.tmax, lane));
                        if let Some(h) = undecided_lane(triangles, k, &ray, EdgeRule::Closed) {
                            let hit = Hit {
                                t: h.t,
                                prim: triangles.ids[k],
                                u: h.u,
                                v: h.v,
                            };
                            self.record_one(lane, hit, packet);
                        }
                    }
                }
            }
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn go_alone(
        &mut self,
        layout: &WideLayout<8>,
        node: u32,
        lane: usize,
        packet: &PacketRays,
    ) {
        // SAFETY: AVX2 is enabled.
        let tmax = unsafe { lane_of(self.tmax, lane) };
        let mut traversal =
            Traversal::in_subtree(&packet.rays[lane], tmax, packet.scene_size, node);
        let mut found = None;
        while let Step::Continue = traversal.step::<8, NoCount, AvxBoxes, true, false>(
            layout,
            &mut NoCount,
            |first, count, ray, counter| {
                layout.closest_hit_in_leaf(first, count, ray, &mut found, counter);
                false
            },
        ) {}
        if let Some(hit) = found {
            // SAFETY: AVX2 is enabled.
            unsafe { self.record_one(lane, hit, packet) };
        }
    }
}
