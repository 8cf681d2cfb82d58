//! The nearest-point search's steps over lanes, in two forms: plain Rust for any CPU, and AVX
//! intrinsics. The search is compiled twice, for AVX2 and for the x86-64 baseline
//! (`batches.rs`, runtime detection), and takes the form as a type parameter, so each
//! build uses the one it may.
//!
//! - **Masks**: which of eight f32 lower bounds pass the search's threshold, as bits (bit `k`
//!   for lane `k`): the step between a node's (or a triangle packet's) eight bounds and the
//!   children (or triangles) the search goes on with. Written lane by lane, LLVM compares and
//!   shifts each lane on its own (about two instructions a lane: 17 per node and 28 per packet
//!   on the bunny, 600 of its 6,700 instructions per query); with AVX it is one compare and
//!   one `vmovmskps`.
//! - **Exact tests** of half a packet, four triangles side by side in f64
//!   (module `point_triangle_lanes`: the scalar routine's bits, branch-free).

// The kernels loop over lanes by index, as the instructions they become do.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

use super::point_triangle_lanes::{closest_points_on_half_portable, LanePoints, PacketVertices};

/// The search's lane steps (module notes).
pub(super) trait SearchLanes {
    /// Bit `k` set when `bounds[k] <= threshold` (clear for a NaN bound: the empty slots of a
    /// node).
    fn within(bounds: &[f32; 8], threshold: f32) -> u32;
    /// Bit `k` set unless `bounds[k] > threshold` (set for a NaN bound, which must not prune a
    /// triangle).
    fn not_beyond(bounds: &[f32; 8], threshold: f32) -> u32;
    /// The nearest points of the four triangles of half `half` of a packet's vertices
    /// (`point_triangle_lanes`).
    fn closest_points_on_half(p: DVec3, vertex: &PacketVertices, half: usize) -> LanePoints;
}

/// Lane by lane, in plain Rust: any CPU.
pub(super) struct PortableLanes;

impl SearchLanes for PortableLanes {
    #[inline(always)]
    fn within(bounds: &[f32; 8], threshold: f32) -> u32 {
        let mut mask = 0;
        for k in 0..8 {
            mask |= ((bounds[k] <= threshold) as u32) << k;
        }
        mask
    }

    #[inline(always)]
    fn not_beyond(bounds: &[f32; 8], threshold: f32) -> u32 {
        let mut mask = 0;
        for k in 0..8 {
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let keep = !(bounds[k] > threshold);
            mask |= (keep as u32) << k;
        }
        mask
    }

    #[inline(always)]
    fn closest_points_on_half(p: DVec3, vertex: &PacketVertices, half: usize) -> LanePoints {
        closest_points_on_half_portable(p, vertex, half)
    }
}

/// AVX intrinsics (a mask is one compare and `vmovmskps`). Only for code compiled with AVX enabled that runs after
/// the CPU was found to have it (`ClosestPointTree::search_run_avx2`, `answer_run_avx2`).
#[cfg(target_arch = "x86_64")]
pub(super) struct AvxLanes;

#[cfg(target_arch = "x86_64")]
impl SearchLanes for AvxLanes {
    #[inline(always)]
    fn within(bounds: &[f32; 8], threshold: f32) -> u32 {
        use std::arch::x86_64::*;
        // SAFETY: `AvxLanes` is used only inside functions compiled for AVX2, called after
        // runtime detection (type notes); the load reads the eight f32 of `bounds`.
        unsafe {
            let b = _mm256_loadu_ps(bounds.as_ptr());
            let le = _mm256_cmp_ps::<_CMP_LE_OQ>(b, _mm256_set1_ps(threshold));
            _mm256_movemask_ps(le) as u32
        }
    }

    #[inline(always)]
    fn not_beyond(bounds: &[f32; 8], threshold: f32) -> u32 {
        use std::arch::x86_64::*;
        // SAFETY: as in `within`.
        unsafe {
            let b = _mm256_loadu_ps(bounds.as_ptr());
            let ngt = _mm256_cmp_ps::<_CMP_NGT_UQ>(b, _mm256_set1_ps(threshold));
            _mm256_movemask_ps(ngt) as u32
        }
    }

    #[inline(always)]
    fn closest_points_on_half(p: DVec3, vertex: &PacketVertices, half: usize) -> LanePoints {
        // SAFETY: as in `within` (AVX2 implies AVX).
        unsafe { super::point_triangle_lanes::avx::closest_points_on_half(p, vertex, half) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX form gives the portable masks, NaN, infinities and ties included.
    #[test]
    fn avx_masks_are_the_portable_masks() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            let values = [
                0.0,
                -0.0,
                1.0,
                1.5,
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                3.0e38,
            ];
            for threshold in values {
                for shift in 0..8 {
                    let mut bounds = [0.0; 8];
                    for k in 0..8 {
                        bounds[k] = values[(k + shift) % 8];
                    }
                    assert_eq!(
                        AvxLanes::within(&bounds, threshold),
                        PortableLanes::within(&bounds, threshold)
                    );
                    assert_eq!(
                        AvxLanes::not_beyond(&bounds, threshold),
                        PortableLanes::not_beyond(&bounds, threshold)
                    );
                }
            }
        }
    }
}
