//! The SIMD box kernels of [`WideLayout`](super::WideLayout): several boxes against one ray at
//! once (the triangle kernels are in `wide/triangle_packet.rs`). Each kernel has a scalar twin that defines its answer; the SIMD
//! versions compute the same IEEE operations in the same order, so they return the same bits
//! (tested below), and every layout answers exactly like the scalar reference.

// The kernels index several arrays (near and far sides, origin, direction) with one axis or
// lane counter; iterators over one of them would hide that symmetry.
#![allow(clippy::needless_range_loop)]

use crate::geometry::PreparedRay;

/// Child boxes of a wide node, structure of arrays: `planes[side][axis][lane]`, side 0 the
/// minimum corner and side 1 the maximum. Empty lanes hold the empty box (never hit).
pub(crate) type LaneBoxes<const W: usize> = [[[f32; W]; 3]; 2];

/// The per-ray constants of the box kernel, splat-ready.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxRay {
    origin: [f32; 3],
    inv_direction: [f32; 3],
    /// Which side of `LaneBoxes` is the near plane on each axis: 1 (max) for a negative direction.
    near_side: [usize; 3],
    /// The rows of `LaneBoxes` read as `[[f32; W]; 6]` (`3 · side + axis`) that hold each axis's
    /// near and far planes: always below 6, so the SIMD kernels read them without bounds checks.
    near_row: [usize; 3],
    far_row: [usize; 3],
}

impl BoxRay {
    #[inline]
    pub fn new(ray: &PreparedRay) -> Self {
        let near_side = ray.negative.map(usize::from);
        Self {
            origin: ray.origin.to_array(),
            inv_direction: ray.inv_direction.to_array(),
            near_side,
            near_row: [0, 1, 2].map(|axis| 3 * near_side[axis] + axis),
            far_row: [0, 1, 2].map(|axis| 3 * (1 - near_side[axis]) + axis),
        }
    }

    /// The `W` near-plane coordinates of `axis` in `boxes`.
    #[inline(always)]
    fn near_planes<'b, const W: usize>(
        &self,
        boxes: &'b LaneBoxes<W>,
        axis: usize,
    ) -> &'b [f32; W] {
        // SAFETY: `near_row` holds `3 · side + axis` with side 0 or 1 and axis 0 to 2 (set only
        // in `new`), so the row is in 0..6, inside the 6 rows of `boxes`.
        unsafe { boxes.as_flattened().get_unchecked(self.near_row[axis]) }
    }

    /// The `W` far-plane coordinates of `axis` in `boxes`.
    #[inline(always)]
    fn far_planes<'b, const W: usize>(&self, boxes: &'b LaneBoxes<W>, axis: usize) -> &'b [f32; W] {
        // SAFETY: as in `near_planes`: the row is in 0..6.
        unsafe { boxes.as_flattened().get_unchecked(self.far_row[axis]) }
    }
}

const SLACK: f32 = PreparedRay::BOX_SLACK;

/// Which of the `W` boxes the ray meets within `[tmin, tmax]` (bit `i` of the mask), and the
/// entry distance of each: the slab test of [`crate::geometry::Aabb::intersect_interval`], lane
/// by lane. The scalar definition of the SIMD kernels.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline]
pub(crate) fn boxes_scalar<const W: usize>(
    boxes: &LaneBoxes<W>,
    ray: &BoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; W]) {
    let mut mask = 0;
    let mut entry = [0.0; W];
    for lane in 0..W {
        let mut near = f32::NEG_INFINITY;
        let mut far = f32::INFINITY;
        for axis in 0..3 {
            let side = ray.near_side[axis];
            near =
                ((boxes[side][axis][lane] - ray.origin[axis]) * ray.inv_direction[axis]).max(near);
            far = ((boxes[1 - side][axis][lane] - ray.origin[axis]) * ray.inv_direction[axis])
                .min(far);
        }
        let near = (near * if near > 0.0 { 1.0 - SLACK } else { 1.0 + SLACK }).max(tmin);
        let far = (far * if far > 0.0 { 1.0 + SLACK } else { 1.0 - SLACK }).min(tmax);
        entry[lane] = near;
        mask |= u32::from(near <= far) << lane;
    }
    (mask, entry)
}

/// Four boxes (lanes `offset..offset + 4` of `boxes`) with SSE.
///
/// `maxps(a, b)` returns `b` when either is NaN, so the new distance goes first and the running
/// value (never NaN) second: a NaN distance (an origin on a slab plane with a zero direction
/// component) drops out, as in the scalar twin.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn boxes_sse<const W: usize>(
    boxes: &LaneBoxes<W>,
    offset: usize,
    ray: &BoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; 4]) {
    use std::arch::x86_64::*;
    assert!(offset + 4 <= W);
    // SAFETY: SSE2 is part of the x86_64 baseline; every load reads 4 floats inside a `[f32; W]`
    // array at `offset`, in bounds by the assertion above; `_mm_storeu_ps` writes 4 floats.
    unsafe {
        let mut near = _mm_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm_set1_ps(f32::INFINITY);
        for axis in 0..3 {
            let o = _mm_set1_ps(ray.origin[axis]);
            let inv = _mm_set1_ps(ray.inv_direction[axis]);
            let n = _mm_loadu_ps(ray.near_planes(boxes, axis).as_ptr().add(offset));
            let f = _mm_loadu_ps(ray.far_planes(boxes, axis).as_ptr().add(offset));
            near = _mm_max_ps(_mm_mul_ps(_mm_sub_ps(n, o), inv), near);
            far = _mm_min_ps(_mm_mul_ps(_mm_sub_ps(f, o), inv), far);
        }
        let zero = _mm_setzero_ps();
        let shrink = _mm_set1_ps(1.0 - SLACK);
        let grow = _mm_set1_ps(1.0 + SLACK);
        let near_positive = _mm_cmpgt_ps(near, zero);
        let far_positive = _mm_cmpgt_ps(far, zero);
        let near_factor = _mm_or_ps(
            _mm_and_ps(near_positive, shrink),
            _mm_andnot_ps(near_positive, grow),
        );
        let far_factor = _mm_or_ps(
            _mm_and_ps(far_positive, grow),
            _mm_andnot_ps(far_positive, shrink),
        );
        let near = _mm_max_ps(_mm_mul_ps(near, near_factor), _mm_set1_ps(tmin));
        let far = _mm_min_ps(_mm_mul_ps(far, far_factor), _mm_set1_ps(tmax));
        let mask = _mm_movemask_ps(_mm_cmple_ps(near, far)) as u32;
        let mut entry = [0.0f32; 4];
        _mm_storeu_ps(entry.as_mut_ptr(), near);
        (mask, entry)
    }
}

/// Eight boxes with AVX. The caller checks that the CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
pub(crate) unsafe fn boxes_avx(
    boxes: &LaneBoxes<8>,
    ray: &BoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;
    // SAFETY: the caller guarantees AVX; every load reads the 8 floats of one `[f32; 8]` array
    // and the store writes 8 floats into `entry`.
    unsafe {
        let mut near = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm256_set1_ps(f32::INFINITY);
        for axis in 0..3 {
            let o = _mm256_set1_ps(ray.origin[axis]);
            let inv = _mm256_set1_ps(ray.inv_direction[axis]);
            let n = _mm256_loadu_ps(ray.near_planes(boxes, axis).as_ptr());
            let f = _mm256_loadu_ps(ray.far_planes(boxes, axis).as_ptr());
            near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(n, o), inv), near);
            far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(f, o), inv), far);
        }
        let zero = _mm256_setzero_ps();
        let shrink = _mm256_set1_ps(1.0 - SLACK);
        let grow = _mm256_set1_ps(1.0 + SLACK);
        let near_positive = _mm256_cmp_ps::<_CMP_GT_OQ>(near, zero);
        let far_positive = _mm256_cmp_ps::<_CMP_GT_OQ>(far, zero);
        let near_factor = _mm256_blendv_ps(grow, shrink, near_positive);
        let far_factor = _mm256_blendv_ps(shrink, grow, far_positive);
        let near = _mm256_max_ps(_mm256_mul_ps(near, near_factor), _mm256_set1_ps(tmin));
        let far = _mm256_min_ps(_mm256_mul_ps(far, far_factor), _mm256_set1_ps(tmax));
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        let mut entry = [0.0f32; 8];
        _mm256_storeu_ps(entry.as_mut_ptr(), near);
        (mask, entry)
    }
}

/// The set bits of a lane mask, lowest first. Holds only the mask, so the ray it came from may be
/// changed (its `tmax` shrunk) while the lanes are visited.
pub(crate) struct Lanes(pub u32);

impl Iterator for Lanes {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let lane = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(lane)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::{Aabb, Ray};
    use glam::Vec3;
    use proptest::prelude::*;

    /// Rays of the kernels' property tests (here and in `wide/triangle_packet.rs`): coordinates
    /// that put origins on slab planes and zero direction components, `tmin` 0, tiny or random.
    pub(crate) fn ray_strategy() -> impl Strategy<Value = Ray> {
        let c = || prop_oneof![Just(0.0f32), Just(-0.0), Just(1.0), Just(0.5), -2.0f32..2.0];
        (
            (c(), c(), c()),
            (c(), c(), c()),
            prop_oneof![Just(0.0f32), Just(1e-3), 0.0f32..1.0],
            prop_oneof![Just(f32::INFINITY), 0.5f32..4.0],
        )
            .prop_filter("valid", |((_, _, _), (x, y, z), _, _)| {
                Vec3::new(*x, *y, *z) != Vec3::ZERO
            })
            .prop_map(|((ox, oy, oz), (dx, dy, dz), tmin, tmax)| {
                Ray::new(Vec3::new(ox, oy, oz), Vec3::new(dx, dy, dz)).with_interval(tmin, tmax)
            })
    }

    fn box_strategy() -> impl Strategy<Value = Aabb> {
        let c = || prop_oneof![Just(0.0f32), Just(1.0), Just(0.5), -2.0f32..2.0];
        prop_oneof![
            1 => Just(Aabb::EMPTY),
            6 => ((c(), c(), c()), (c(), c(), c())).prop_map(|((a, b, c), (d, e, f))| {
                let (p, q) = (Vec3::new(a, b, c), Vec3::new(d, e, f));
                Aabb::new(p.min(q), p.max(q))
            }),
        ]
    }

    fn lanes<const W: usize>(boxes: &[Aabb]) -> LaneBoxes<W> {
        let mut l = [[[0.0; W]; 3]; 2];
        for (lane, b) in boxes.iter().enumerate() {
            for axis in 0..3 {
                l[0][axis][lane] = b.min[axis];
                l[1][axis][lane] = b.max[axis];
            }
        }
        l
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn box_kernels_equal_the_scalar_slab_test(ray in ray_strategy(), boxes in prop::collection::vec(box_strategy(), 8)) {
            let prepared = PreparedRay::new(&ray);
            let box_ray = BoxRay::new(&prepared);
            let l8 = lanes::<8>(&boxes);
            let (mask, entry) = boxes_scalar(&l8, &box_ray, ray.tmin, ray.tmax);
            for (lane, b) in boxes.iter().enumerate() {
                prop_assert_eq!(mask >> lane & 1 == 1, b.hit_by(&prepared), "lane {}", lane);
                if let Some((near, _)) = b.intersect_interval(&prepared) {
                    prop_assert_eq!(entry[lane], near);
                }
            }
            #[cfg(target_arch = "x86_64")]
            {
                for offset in [0, 4] {
                    let (m, e) = boxes_sse(&l8, offset, &box_ray, ray.tmin, ray.tmax);
                    prop_assert_eq!(m, mask >> offset & 0xf);
                    for k in 0..4 {
                        if m >> k & 1 == 1 {
                            prop_assert_eq!(e[k], entry[offset + k]);
                        }
                    }
                }
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: AVX was just detected.
                    let (m, e) = unsafe { boxes_avx(&l8, &box_ray, ray.tmin, ray.tmax) };
                    prop_assert_eq!(m, mask);
                    for k in 0..8 {
                        if m >> k & 1 == 1 {
                            prop_assert_eq!(e[k], entry[k]);
                        }
                    }
                }
            }
        }

    }
}
