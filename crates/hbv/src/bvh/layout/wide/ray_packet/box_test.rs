//! The packet's box test: a node's eight child boxes against the packet's eight rays, with the
//! bits the single-ray test gives each.

use std::arch::x86_64::*;

use super::packet_rays::PacketRays;
use crate::bvh::layout::wide::box_kernels::LaneBoxes;

/// The eight children's boxes of a node against the rays of `rays` (a lane mask), whose box
/// intervals end at `box_tmax`: for each child, the rays that meet it and their entry
/// distances, by the single-ray slab test
/// ([`box_scalar`](super::super::box_kernels::box_scalar)) lane by lane. (Every slot is
/// tested, empty ones too: skipping them cost more in branches than it saved.)
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn test_children(
    boxes: &LaneBoxes<8>,
    packet: &PacketRays,
    box_tmax: __m256,
    rays: u32,
) -> ([u32; 8], [__m256; 8]) {
    let mut met = [0u32; 8];
    let mut entry = [_mm256_setzero_ps(); 8];
    let (o, inv) = (packet.origin, packet.inv_direction);
    for child in 0..8 {
        let mut near = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm256_set1_ps(f32::INFINITY);
        for axis in 0..3 {
            let side = packet.near_side[axis];
            let n = _mm256_set1_ps(boxes[side][axis][child]);
            let f = _mm256_set1_ps(boxes[1 - side][axis][child]);
            near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(n, o[axis]), inv[axis]), near);
            far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(f, o[axis]), inv[axis]), far);
        }
        let near = _mm256_max_ps(near, packet.box_tmin);
        let far = _mm256_add_ps(_mm256_min_ps(far, box_tmax), packet.slab_margin);
        met[child] = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32 & rays;
        entry[child] = near;
    }
    (met, entry)
}
