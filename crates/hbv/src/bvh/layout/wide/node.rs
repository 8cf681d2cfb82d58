//! The wide layout's storage: a node holds up to `W` child boxes as SIMD lanes and a reference
//! to each child, another node or a leaf's run of triangle packets.

use super::box_kernels::LaneBoxes;
use crate::geometry::Aabb;

/// Bit 31 of a child reference: the child is a leaf.
const LEAF: u32 = 1 << 31;
/// A leaf reference: bits 27..31 hold the number of triangle packets minus one (1 to 16
/// packets), bits 0..27 the first packet.
const LEAF_COUNT_SHIFT: u32 = 27;
const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;
/// Most triangles in one leaf: 16 packets of 4.
pub(super) const MAX_LEAF_TRIANGLES: usize = 64;

/// Whether child reference `reference` names a leaf (otherwise it is a node's index).
#[inline(always)]
pub(super) fn is_leaf(reference: u32) -> bool {
    reference & LEAF != 0
}

/// The reference of a leaf of `count` triangle packets (1 to 16) from packet `first`.
pub(super) fn leaf_reference(first: u32, count: u32) -> u32 {
    assert!(
        first <= LEAF_FIRST_MASK,
        "too many triangle packets for the wide layout"
    );
    LEAF | ((count - 1) << LEAF_COUNT_SHIFT) | first
}

/// The first triangle packet of leaf reference `leaf`, and how many it holds.
#[inline(always)]
pub(super) fn leaf_span(leaf: u32) -> (usize, usize) {
    let first = (leaf & LEAF_FIRST_MASK) as usize;
    let count = ((leaf & !LEAF) >> LEAF_COUNT_SHIFT) as usize + 1;
    (first, count)
}

/// A node with up to `W` children: their boxes in structure-of-arrays form (one SIMD load per
/// axis and side), and a reference to each (a node, or a leaf's triangle packets).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct WideNode<const W: usize> {
    pub boxes: LaneBoxes<W>,
    pub children: [u32; W],
}

impl<const W: usize> WideNode<W> {
    pub fn empty() -> Self {
        Self {
            boxes: [[[f32::INFINITY; W]; 3], [[f32::NEG_INFINITY; W]; 3]],
            children: [0; W],
        }
    }

    pub fn set_box(&mut self, lane: usize, bounds: &Aabb) {
        for axis in 0..3 {
            self.boxes[0][axis][lane] = bounds.min[axis];
            self.boxes[1][axis][lane] = bounds.max[axis];
        }
    }
}
