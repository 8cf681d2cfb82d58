//! The any-hit query of a packet: a blocking triangle for each ray, each ray leaving the packet
//! once it has one.

use std::arch::x86_64::*;

use super::avx_lanes::lane_of;
use super::packet_rays::PacketRays;
use super::query::PacketQuery;
use super::triangle_test::test_triangle;
use super::PACKET_RAYS;
use crate::bvh::layout::wide::kernels::AvxBoxes;
use crate::bvh::layout::wide::lanes::Lanes;
use crate::bvh::layout::wide::leaf::undecided_lane;
use crate::bvh::layout::wide::root_filter::RayColumns;
use crate::bvh::layout::wide::traversal::{Step, Traversal};
use crate::bvh::layout::wide::WideLayout;
use crate::geometry::EdgeRule;
use crate::stats::NoCount;

/// The blocking triangle found so far for each ray of a packet (bit set in `blocked`).
pub(super) struct Occluders {
    tmax: __m256,
    box_tmax: __m256,
    blocked: u32,
    occluder: [u32; PACKET_RAYS],
}

impl Occluders {
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(columns: &RayColumns, packet: &PacketRays) -> Self {
        Self {
            tmax: columns.tmax,
            box_tmax: _mm256_add_ps(columns.tmax, packet.box_margin),
            blocked: 0,
            occluder: [0; PACKET_RAYS],
        }
    }

    fn block(&mut self, lane: usize, prim: u32) {
        self.blocked |= 1 << lane;
        self.occluder[lane] = prim;
    }
}

impl PacketQuery for Occluders {
    type Answer = u32;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self {
        // SAFETY: AVX2 is enabled.
        unsafe { Self::new(columns, packet) }
    }

    #[inline]
    unsafe fn answer(&self, lane: usize) -> Option<u32> {
        (self.blocked >> lane & 1 == 1).then_some(self.occluder[lane])
    }

    #[inline(always)]
    fn box_tmax(&self) -> __m256 {
        self.box_tmax
    }

    #[inline(always)]
    fn searching(&self) -> u32 {
        !self.blocked & 0xff
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        mut lanes: u32,
        packet: &PacketRays,
    ) {
        for triangles in layout.leaf_packets(leaf) {
            for k in 0..4 {
                if triangles.repeats_previous(k) {
                    break;
                }
                // SAFETY (this block): AVX2 is enabled.
                unsafe {
                    let test = test_triangle(triangles, k, packet, self.tmax);
                    for lane in Lanes(test.hit & lanes) {
                        self.block(lane, triangles.ids[k]);
                    }
                    for lane in Lanes(test.undecided & lanes & !test.hit) {
                        let ray = packet.alone(lane, lane_of(self.tmax, lane));
                        if undecided_lane(triangles, k, &ray, EdgeRule::Closed).is_some() {
                            self.block(lane, triangles.ids[k]);
                        }
                    }
                }
                lanes &= !self.blocked;
                if lanes == 0 {
                    return;
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
                found = layout.any_hit_in_leaf(first, count, ray, counter);
                found.is_some()
            },
        ) {}
        if let Some(prim) = found {
            self.block(lane, prim);
        }
    }
}
