//! The instruction sets the wide layout's traversals are compiled for, and the choice among them.
//!
//! Each traversal is monomorphized for one way of testing a node's `W` boxes ([`BoxKernel`]):
//! the AVX one sits in functions compiled with AVX, so that its box test is inlined into the
//! loop. Which one a layout's queries run ([`Kernels`]) is decided once, when the layout is made,
//! from what the CPU has; each query branches on it once, at its top, never per node. The AVX
//! kernels exist for 8-wide nodes only (`AvxBoxes` tests `LaneBoxes<8>`), so a 4-wide layout
//! cannot reach them: the compiler checks it.

use super::box_kernels::{self, BoxRay, LaneBoxes};
use super::root_filter;
use crate::geometry::{Aabb, Ray};

/// Which compiled traversals a layout's queries run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kernels {
    /// SSE box tests, four lanes at a time (the x86_64 baseline), or their scalar twin on other
    /// CPUs: every 4-wide layout, and 8-wide ones on a CPU without AVX.
    Baseline,
    /// 8-wide nodes on a CPU with AVX: eight boxes tested at once, every traversal compiled
    /// with AVX.
    #[cfg(target_arch = "x86_64")]
    Avx,
    /// As [`Kernels::Avx`], and batches trace coherent runs of eight rays as packets, one ray
    /// per AVX lane ([`ray_packet`](super::ray_packet)): 8-wide nodes on a CPU with AVX2.
    #[cfg(target_arch = "x86_64")]
    AvxRayPackets,
}

impl Kernels {
    /// The fastest kernels for nodes `width` wide on this CPU, with packets of rays where the
    /// CPU allows them and `ray_packets` asks for them.
    pub fn for_this_cpu(width: usize, ray_packets: bool) -> Self {
        #[cfg(target_arch = "x86_64")]
        if width == 8 && std::arch::is_x86_feature_detected!("avx") {
            return if ray_packets && std::arch::is_x86_feature_detected!("avx2") {
                Self::AvxRayPackets
            } else {
                Self::Avx
            };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (width, ray_packets);
        Self::Baseline
    }

    /// Whether batches trace packets of coherent rays.
    pub fn traces_ray_packets(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self == Self::AvxRayPackets {
            return true;
        }
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

/// AVX, eight lanes at once: 8-wide nodes only, on CPUs with AVX ([`Kernels::Avx`]), from
/// functions compiled with AVX enabled.
#[cfg(target_arch = "x86_64")]
pub(super) struct AvxBoxes;

#[cfg(target_arch = "x86_64")]
impl BoxKernel<8> for AvxBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<8>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; 8]) {
        // SAFETY: this kernel is reached only through the `*_avx` entry points of
        // `WideLayout<8>` (`queries.rs`), which run only when the layout's `Kernels` say AVX,
        // chosen only when the CPU reported it.
        unsafe { box_kernels::boxes_avx(boxes, ray, tmin, tmax) }
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

/// The box kernel of [`Kernels::Baseline`].
#[cfg(target_arch = "x86_64")]
pub(super) type BaselineBoxes = SseBoxes;
/// The box kernel of [`Kernels::Baseline`].
#[cfg(not(target_arch = "x86_64"))]
pub(super) type BaselineBoxes = ScalarBoxes;
