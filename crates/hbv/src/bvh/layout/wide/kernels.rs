//! The instruction sets the wide layout's traversals are compiled for: how a traversal tests the
//! `W` boxes of a node ([`BoxKernel`]), per instruction set.

use super::box_kernels::{self, BoxRay, LaneBoxes};
use super::root_filter;
use crate::geometry::{Aabb, Ray};

pub(super) fn detect_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx") && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

pub(super) fn detect_avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// How a traversal tests the `W` boxes of a node. The traversal is compiled once per kernel, so
/// the AVX one is compiled with AVX enabled and its box test inlined into the loop.
pub(super) trait BoxKernel<const W: usize> {
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]);

    /// Whether [`BoxKernel::root_candidates`] decides every valid ray exactly as
    /// [`Traversal::restart`](super::traversal::Traversal::restart) does, so that the batches
    /// may skip that test of the root box.
    const ROOT_FILTER_EXACT: bool = false;

    /// Which of eight rays may meet the root box `bounds` (bit `i` for `rays[i]`): a ray left
    /// out is one the traversal's set-up would reject ([`root_filter`]). All eight by default.
    #[inline(always)]
    fn root_candidates(rays: &[Ray; 8], bounds: &Aabb, scene_size: f32) -> u32 {
        root_filter::all_candidates(rays, bounds, scene_size)
    }
}

/// SSE, four lanes at a time: the x86_64 baseline.
#[cfg(target_arch = "x86_64")]
pub(super) struct SseBoxes;

#[cfg(target_arch = "x86_64")]
impl<const W: usize> BoxKernel<W> for SseBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        let mut mask = 0;
        let mut entry = [0.0f32; W];
        for offset in (0..W).step_by(4) {
            let (m, e) = box_kernels::boxes_sse(boxes, offset, ray, tmin, tmax);
            mask |= m << offset;
            entry[offset..offset + 4].copy_from_slice(&e);
        }
        (mask, entry)
    }
}

/// AVX, eight lanes at once; used only for `W == 8` on CPUs with AVX, from functions compiled
/// with AVX enabled.
#[cfg(target_arch = "x86_64")]
pub(super) struct AvxBoxes;

#[cfg(target_arch = "x86_64")]
impl<const W: usize> BoxKernel<W> for AvxBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        assert!(W == 8);
        // SAFETY: W == 8, so the cast is to the same type; the AVX kernel is only reached through
        // `WideLayout::*_avx`, which run only when the CPU reported AVX.
        let boxes8 = unsafe { &*(boxes as *const LaneBoxes<W> as *const LaneBoxes<8>) };
        let (mask, e) = unsafe { box_kernels::boxes_avx(boxes8, ray, tmin, tmax) };
        let mut entry = [0.0f32; W];
        entry.copy_from_slice(&e);
        (mask, entry)
    }

    const ROOT_FILTER_EXACT: bool = true;

    #[inline(always)]
    fn root_candidates(rays: &[Ray; 8], bounds: &Aabb, scene_size: f32) -> u32 {
        // SAFETY: as for `test`, reached only when the CPU reported AVX.
        unsafe { root_filter::root_candidates_avx(rays, bounds, scene_size) }
    }
}

/// The portable fallback.
#[cfg(not(target_arch = "x86_64"))]
pub(super) struct ScalarBoxes;

#[cfg(not(target_arch = "x86_64"))]
impl<const W: usize> BoxKernel<W> for ScalarBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        box_kernels::boxes_scalar(boxes, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) type DefaultBoxes = SseBoxes;
#[cfg(not(target_arch = "x86_64"))]
pub(super) type DefaultBoxes = ScalarBoxes;
