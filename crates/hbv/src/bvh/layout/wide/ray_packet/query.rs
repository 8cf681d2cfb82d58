//! What a packet's traversal looks for, ray by ray: the interface of its two queries.

use std::arch::x86_64::*;

use super::packet_rays::PacketRays;
use crate::bvh::layout::wide::root_filter::RayColumns;
use crate::bvh::layout::wide::WideLayout;

/// What a packet's traversal looks for, and keeps, ray by ray: the closest hit
/// ([`ClosestHits`](super::closest_hits::ClosestHits)) or a blocking triangle
/// ([`Occluders`](super::occluders::Occluders)).
pub(super) trait PacketQuery {
    /// What the query answers for a ray.
    type Answer;

    /// The query's state for a packet of rays (`columns`) before any node is visited.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self;

    /// The answer for ray `lane`, once the traversal is over.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn answer(&self, lane: usize) -> Option<Self::Answer>;

    /// The end of each ray's interval for box tests: `tmax` (shrunk to the closest hit so far)
    /// plus its box margin.
    fn box_tmax(&self) -> __m256;

    /// The rays still searching (a lane mask): all but those an any-hit query has answered.
    fn searching(&self) -> u32;

    /// Tests the triangles of leaf reference `leaf` against the rays of `lanes`.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        lanes: u32,
        packet: &PacketRays,
    );

    /// Ray `lane` alone through the subtree at reference `node` (a node or a leaf).
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn go_alone(
        &mut self,
        layout: &WideLayout<8>,
        node: u32,
        lane: usize,
        packet: &PacketRays,
    );
}
