//! The wide layout's storage: a node holds up to `W` child boxes as SIMD lanes and a reference
//! to each child, another node or a leaf's run of triangle packets.

use super::box_kernels::LaneBoxes;
use crate::geometry::Aabb;

/// Bit 31 of a child reference: the child is a leaf.
pub(super) const LEAF: u32 = 1 << 31;
/// A leaf reference: bits 27..31 hold the number of triangle packets minus one (1 to 16
/// packets), bits 0..27 the first packet.
pub(super) const LEAF_COUNT_SHIFT: u32 = 27;
pub(super) const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;
/// Most triangles in one leaf: 16 packets of 4.
pub(super) const MAX_LEAF_TRIANGLES: usize = 64;

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
