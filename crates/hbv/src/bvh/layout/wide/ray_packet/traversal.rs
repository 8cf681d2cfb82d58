//! A packet's walk through the 8-wide layout: children taken nearest first with the rays that meet
//! them, each ray dropping out where its own interval ends, and the rays going on alone once
//! few of them reach a node.

use std::arch::x86_64::*;

use super::avx_lanes::{horizontal_min, lane_mask};
use super::beam::{is_coherent, BeamLimit};
use super::box_test::test_children;
use super::packet_rays::PacketRays;
use super::query::PacketQuery;
use super::PACKET_RAYS;
use crate::bvh::layout::stack::TraversalStack;
use crate::bvh::layout::wide::lanes::Lanes;
use crate::bvh::layout::wide::node::is_leaf;
use crate::bvh::layout::wide::root_filter::{RayColumns, RootTest};
use crate::bvh::layout::wide::WideLayout;
use crate::geometry::Ray;

/// A node reached by fewer of a packet's rays than this is searched by each of them alone (two
/// and three measured alike in instructions per ray on camera rays; one and four or more cost
/// 2–7 % more).
pub(super) const SINGLE_BELOW: u32 = 3;

/// One stack entry: a child postponed with the rays that meet its box and their entry distances.
#[derive(Clone, Copy)]
struct Postponed {
    node: u32,
    rays: u32,
    entry: __m256,
}

impl WideLayout<8> {
    /// The block filter of the batches with packets ([`WideLayout::trace_batch`]): the eight
    /// rays against the root box at once; if they are coherent ([`is_coherent`] within
    /// `limit`, [`WideLayout::beam_limit`]), traced as a
    /// packet for query `Q`, their answers written to `answers` (eight), and none handed on;
    /// otherwise those that meet the root box handed on, to be traced alone. The caller checks
    /// that the CPU has AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn packet_block<Q: PacketQuery>(
        &self,
        rays: &[Ray; PACKET_RAYS],
        answers: &mut [Option<Q::Answer>],
        limit: &BeamLimit,
    ) -> u32 {
        let Some((root, bounds, scene_size)) = self.root else {
            return 0;
        };
        // SAFETY (this block): AVX2 is enabled.
        unsafe {
            let columns = RayColumns::of(rays);
            let test = RootTest::of(&columns, &bounds, scene_size);
            if test.met == 0 {
                return 0;
            }
            let Some(coherent) = is_coherent(&columns, limit) else {
                return test.met;
            };
            let packet = PacketRays::new(rays, &columns, &test, &coherent, scene_size);
            let mut query = Q::start(&columns, &packet);
            self.trace_packet(root, test.met, &packet, &mut query);
            for (lane, answer) in answers.iter_mut().enumerate() {
                *answer = query.answer(lane);
            }
        }
        0
    }

    /// The packet traversal (module notes) of the rays `active` from the root reference `root`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn trace_packet<Q: PacketQuery>(
        &self,
        root: u32,
        active: u32,
        packet: &PacketRays,
        query: &mut Q,
    ) {
        let mut stack: TraversalStack<Postponed, 64> = TraversalStack::new();
        let (mut current, mut lanes) = (root, active);
        'walk: loop {
            lanes &= query.searching();
            // SAFETY (this block): AVX2 is enabled.
            unsafe {
                if lanes.count_ones() < SINGLE_BELOW {
                    for lane in Lanes(lanes) {
                        query.go_alone(self, current, lane, packet);
                    }
                } else if is_leaf(current) {
                    query.visit_leaf(self, current, lanes, packet);
                } else {
                    let node = &self.nodes[current as usize];
                    let (met, entry) = test_children(&node.boxes, packet, query.box_tmax(), lanes);
                    if let Some(next) =
                        self.descend_packet(&node.children, &met, &entry, &mut stack)
                    {
                        (current, lanes) = next;
                        continue;
                    }
                }
            }
            loop {
                let searching = query.searching();
                let Some(p) = stack.pop().filter(|_| searching != 0) else {
                    break 'walk;
                };
                let within = _mm256_cmp_ps::<_CMP_LE_OQ>(p.entry, query.box_tmax());
                let rays = p.rays & searching & _mm256_movemask_ps(within) as u32;
                if rays != 0 {
                    (current, lanes) = (p.node, rays);
                    break;
                }
            }
        }
    }

    /// The step from a node to its children for a packet: of the children some ray meets
    /// (`met[child]`, its rays), returns the nearest — by the least entry distance of its rays —
    /// with its rays, and pushes the others farthest first (and asks for their memory early);
    /// `None` when no ray meets any child.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn descend_packet(
        &self,
        children: &[u32; 8],
        met: &[u32; 8],
        entry: &[__m256; 8],
        stack: &mut TraversalStack<Postponed, 64>,
    ) -> Option<(u32, u32)> {
        let mut order = [(0.0f32, 0usize); 8];
        let mut n = 0;
        for child in 0..8 {
            if met[child] == 0 {
                continue;
            }
            // SAFETY: AVX2 is enabled.
            let key = unsafe {
                let inside = lane_mask(met[child]);
                horizontal_min(_mm256_blendv_ps(
                    _mm256_set1_ps(f32::INFINITY),
                    entry[child],
                    inside,
                ))
            };
            // Insertion by decreasing key: the nearest ends last.
            let mut k = n;
            while k > 0 && order[k - 1].0 < key {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = (key, child);
            n += 1;
        }
        if n == 0 {
            return None;
        }
        for &(_, child) in &order[..n - 1] {
            self.prefetch(children[child]);
            stack.push(Postponed {
                node: children[child],
                rays: met[child],
                entry: entry[child],
            });
        }
        let nearest = order[n - 1].1;
        Some((children[nearest], met[nearest]))
    }
}
