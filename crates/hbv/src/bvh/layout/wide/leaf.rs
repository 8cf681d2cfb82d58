//! A single ray at a leaf of the wide layout: its triangle packets tested, the SIMD test deciding
//! what it can and the scalar test the lanes it leaves undecided.

use super::lanes::Lanes;
use super::node::leaf_span;
use super::{TrianglePacket, WideLayout};
use crate::geometry::{EdgeRule, PreparedRay, TriangleHit};
use crate::query::{record_hit, Hit};
use crate::stats::Counter;

impl<const W: usize> WideLayout<W> {
    /// Tests the `count` triangle packets from `first` for a hit closer than `best`, shrinking
    /// `ray.tmax`: the SIMD test decides what it can, the scalar test the undecided lanes.
    ///
    /// The first packet is tested before the loop over the others: most leaves hold one packet,
    /// and a loop around it led the compiler to hoist the ray's constants out of it into
    /// registers it then spilled (measured: 26 more instructions per leaf).
    #[inline(always)]
    pub(super) fn closest_hit_in_leaf<C: Counter>(
        &self,
        first: usize,
        count: usize,
        ray: &mut PreparedRay,
        best: &mut Option<Hit>,
        counter: &mut C,
    ) {
        let packets = &self.packets[first..first + count];
        closest_hit_in_packet(&packets[0], ray, best, counter);
        for packet in &packets[1..] {
            closest_hit_in_packet(packet, ray, best, counter);
        }
    }

    /// The triangle packets of leaf reference `leaf`.
    #[inline(always)]
    pub(super) fn leaf_packets(&self, leaf: u32) -> &[TrianglePacket] {
        let (first, count) = leaf_span(leaf);
        &self.packets[first..first + count]
    }

    /// The face id of a triangle of the `count` packets from `first` that the ray hits, if any.
    /// (The first packet before the loop, as in [`WideLayout::closest_hit_in_leaf`].)
    #[inline(always)]
    pub(super) fn any_hit_in_leaf<C: Counter>(
        &self,
        first: usize,
        count: usize,
        ray: &PreparedRay,
        counter: &mut C,
    ) -> Option<u32> {
        let packets = &self.packets[first..first + count];
        if let Some(found) = any_hit_in_packet(&packets[0], ray, counter) {
            return Some(found);
        }
        for packet in &packets[1..] {
            if let Some(found) = any_hit_in_packet(packet, ray, counter) {
                return Some(found);
            }
        }
        None
    }
}

/// [`WideLayout`]'s closest-hit test of one triangle packet: records a hit closer than `best`,
/// shrinking `ray.tmax`. (A function, not a closure: closures in these kernels were left out of
/// line, compiled without the caller's AVX.)
#[inline(always)]
fn closest_hit_in_packet<C: Counter>(
    packet: &TrianglePacket,
    ray: &mut PreparedRay,
    best: &mut Option<Hit>,
    counter: &mut C,
) {
    counter.triangles_tested(4);
    let test = packet.test(ray);
    for lane in Lanes(test.hit) {
        record_hit(test.hit(lane), packet.ids[lane], ray, best);
    }
    for lane in Lanes(test.undecided) {
        if let Some(h) = undecided_lane(packet, lane, ray, EdgeRule::Closed) {
            record_hit(h, packet.ids[lane], ray, best);
        }
    }
}

/// The scalar test ([`crate::geometry::Triangle::intersect_by`]) of a lane the packet test
/// left undecided: a ray within rounding distance of an edge or a vertex, or a hit next to its
/// origin. Rare, and kept out of line: inlined, the scalar test doubled the size of the
/// closest-hit leaf visit (3.5 to 7.2 KB) and made closest hits from Python 2–5 % slower on one
/// thread (measured when it was taken out of line, commit 8a93f5f).
#[cold]
#[inline(never)]
pub(super) fn undecided_lane(
    packet: &TrianglePacket,
    lane: usize,
    ray: &PreparedRay,
    rule: EdgeRule,
) -> Option<TriangleHit> {
    packet.triangle(lane).intersect_by(ray, rule)
}

/// [`WideLayout`]'s any-hit test of one triangle packet: the face id of a triangle the ray hits.
#[inline(always)]
fn any_hit_in_packet<C: Counter>(
    packet: &TrianglePacket,
    ray: &PreparedRay,
    counter: &mut C,
) -> Option<u32> {
    counter.triangles_tested(4);
    let test = packet.test(ray);
    if test.hit != 0 {
        return Some(packet.ids[test.hit.trailing_zeros() as usize]);
    }
    for lane in Lanes(test.undecided) {
        if undecided_lane(packet, lane, ray, EdgeRule::Closed).is_some() {
            return Some(packet.ids[lane]);
        }
    }
    None
}
