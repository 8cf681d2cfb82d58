//! The SIMD box kernels of [`WideLayout`](super::WideLayout): several boxes against one ray at
//! once (the triangle kernels are in `triangle_packet.rs`). Each kernel has a scalar twin that
//! defines its answer; the SIMD versions compute the same IEEE operations in the same order, so
//! they return the same bits (tested below), and every layout answers exactly like the scalar
//! reference.

// The kernels index several arrays (near and far sides, origin, direction) with one axis or
// lane counter; iterators over one of them would hide that symmetry.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

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
    near_side: [u8; 3],
    /// Where each axis's near and far planes start in an 8-wide node's `LaneBoxes`, in bytes:
    /// row `3 · side + axis` of 32 bytes (half that in a 4-wide node). Precomputed so that a
    /// node's six loads need no address arithmetic; always within the 6 rows.
    near_offset: [u32; 3],
    far_offset: [u32; 3],
    /// [`PreparedRay`]'s slab margin `s`: the widening of each box's exit distance.
    slab_margin: f32,
}

impl BoxRay {
    #[inline]
    pub fn new(ray: &PreparedRay) -> Self {
        Self::from_parts(
            ray.origin,
            ray.direction,
            ray.inv_direction,
            ray.slab_margin,
        )
    }

    /// [`BoxRay::new`] from the parts of a [`PreparedRay`] it uses: origin, direction, inverse
    /// direction ([`PreparedRay::inverse_of`]) and slab margin ([`PreparedRay::margins`]).
    #[inline]
    pub fn from_parts(
        origin: Vec3,
        direction: Vec3,
        inv_direction: Vec3,
        slab_margin: f32,
    ) -> Self {
        let near_side =
            [direction.x, direction.y, direction.z].map(|d| u8::from(d.is_sign_negative()));
        let row_offset = |side: u8, axis: u32| (3 * u32::from(side) + axis) * 32;
        Self {
            origin: origin.to_array(),
            inv_direction: inv_direction.to_array(),
            near_side,
            near_offset: [0, 1, 2].map(|axis| row_offset(near_side[axis as usize], axis)),
            far_offset: [0, 1, 2].map(|axis| row_offset(1 - near_side[axis as usize], axis)),
            slab_margin,
        }
    }

    /// The `W` near-plane coordinates of `axis` in `boxes`.
    #[inline(always)]
    fn near_planes<const W: usize>(&self, boxes: &LaneBoxes<W>, axis: usize) -> *const f32 {
        Self::row(boxes, self.near_offset[axis])
    }

    /// The `W` far-plane coordinates of `axis` in `boxes`.
    #[inline(always)]
    fn far_planes<const W: usize>(&self, boxes: &LaneBoxes<W>, axis: usize) -> *const f32 {
        Self::row(boxes, self.far_offset[axis])
    }

    /// The row at `offset8` bytes of an 8-wide node, or half that in a 4-wide one.
    #[inline(always)]
    fn row<const W: usize>(boxes: &LaneBoxes<W>, offset8: u32) -> *const f32 {
        let offset = offset8 as usize * W / 8;
        // SAFETY: the offset is that of one of the 6 rows of `W` floats of `boxes` (`new` sets
        // it to `(3 · side + axis) · 32` with side 0 or 1 and axis 0 to 2; `W / 8` scales a row
        // of 8 floats to one of `W`), so the pointer stays inside `boxes`.
        unsafe { (boxes as *const LaneBoxes<W> as *const u8).add(offset) as *const f32 }
    }
}

/// Which of the `W` boxes the ray meets within `[tmin, tmax]` (bit `i` of the mask), and the
/// entry distance of each. The scalar definition of the SIMD kernels.
///
/// The slab test of [`crate::geometry::Aabb::intersect_interval`] (Kay & Kajiya 1986; a NaN
/// distance, from an origin on a slab plane with a zero direction component, drops out), but
/// widened by an absolute margin instead of a relative one (Ize 2013 scales both ends by
/// `1 ± 2^-18`, which needs a test of each end's sign):
///
/// ```text
///   entry = max(near, tmin),   exit = min(far, tmax) + s,   met if entry ≤ exit
/// ```
///
/// with `s` the ray's slab margin, at least twice the rounding error of any slab distance that
/// matters inside the scene ([`PreparedRay::bound_errors_within`] proves it): a box the ray
/// meets is never lost, and `entry` exceeds the exact entry by at most `s / 2`, which the ray's
/// box margin covers when `tmax` culls postponed children.
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
        let corners = [0, 1].map(|side| Vec3::from_array(boxes[side].map(|axis| axis[lane])));
        let (met, near) = box_scalar(corners, ray, tmin, tmax);
        entry[lane] = near;
        mask |= u32::from(met) << lane;
    }
    (mask, entry)
}

/// [`boxes_scalar`] for one box, given as its `[min, max]` corners: whether the ray meets it,
/// and the entry distance. (The wide layouts' test of the root box, before a ray's first step.)
#[inline]
pub(crate) fn box_scalar(corners: [Vec3; 2], ray: &BoxRay, tmin: f32, tmax: f32) -> (bool, f32) {
    let mut near = f32::NEG_INFINITY;
    let mut far = f32::INFINITY;
    for axis in 0..3 {
        let side = usize::from(ray.near_side[axis]);
        near = ((corners[side][axis] - ray.origin[axis]) * ray.inv_direction[axis]).max(near);
        far = ((corners[1 - side][axis] - ray.origin[axis]) * ray.inv_direction[axis]).min(far);
    }
    let near = near.max(tmin);
    let far = far.min(tmax) + ray.slab_margin;
    (near <= far, near)
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
            let n = _mm_loadu_ps(ray.near_planes(boxes, axis).add(offset));
            let f = _mm_loadu_ps(ray.far_planes(boxes, axis).add(offset));
            near = _mm_max_ps(_mm_mul_ps(_mm_sub_ps(n, o), inv), near);
            far = _mm_min_ps(_mm_mul_ps(_mm_sub_ps(f, o), inv), far);
        }
        let near = _mm_max_ps(near, _mm_set1_ps(tmin));
        let far = _mm_add_ps(
            _mm_min_ps(far, _mm_set1_ps(tmax)),
            _mm_set1_ps(ray.slab_margin),
        );
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
            let n = _mm256_loadu_ps(ray.near_planes(boxes, axis));
            let f = _mm256_loadu_ps(ray.far_planes(boxes, axis));
            near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(n, o), inv), near);
            far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(f, o), inv), far);
        }
        let near = _mm256_max_ps(near, _mm256_set1_ps(tmin));
        let far = _mm256_add_ps(
            _mm256_min_ps(far, _mm256_set1_ps(tmax)),
            _mm256_set1_ps(ray.slab_margin),
        );
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        let mut entry = [0.0f32; 8];
        _mm256_storeu_ps(entry.as_mut_ptr(), near);
        (mask, entry)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::{Aabb, Ray};
    use glam::Vec3;
    use proptest::prelude::*;

    /// Rays of the kernels' property tests (here and in `triangle_packet.rs`): coordinates
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

    /// Where the ray enters `b` within its `[tmin, tmax]`, decided exactly, or `None` when it
    /// does not meet it there. The f64 differences of f32 coordinates are exact (or, across
    /// extreme exponents, rounded far below the kernels' margins), and the correctly rounded
    /// quotients keep the order of the exact slab distances (rounding is monotone): the
    /// comparisons decide as exact arithmetic does, but for distances within an ulp of f64.
    fn exact_entry(b: &Aabb, ray: &Ray) -> Option<f64> {
        if b.is_empty() {
            return None;
        }
        let (mut near, mut far) = (ray.tmin as f64, ray.tmax as f64);
        for axis in 0..3 {
            let (o, d) = (ray.origin[axis] as f64, ray.direction[axis] as f64);
            let (lo, hi) = (b.min[axis] as f64, b.max[axis] as f64);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        (near <= far).then_some(near)
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(2000))]

        #[test]
        fn box_kernels_never_lose_a_box_and_agree_with_their_scalar_twin(
            ray in ray_strategy(),
            boxes in prop::collection::vec(box_strategy(), 8),
            scale in prop_oneof![Just(1.0f32), Just(2f32.powi(-70)), Just(2f32.powi(70))],
            direction_scale in prop_oneof![Just(1.0f32), Just(2f32.powi(-50)), Just(2f32.powi(50))],
            aim in prop::option::of((0usize..8, prop::array::uniform3(0u8..3), 0.0f32..1.0)),
        ) {
            // The same configuration at another scale of coordinates and of direction lengths.
            let boxes: Vec<Aabb> = boxes
                .iter()
                .map(|b| if b.is_empty() { *b } else { Aabb::new(b.min * scale, b.max * scale) })
                .collect();
            let origin = ray.origin * scale;
            let mut direction = ray.direction;
            // Or aimed at a corner or an edge of one of the boxes, where the line grazes the box
            // within rounding and only the margin keeps it.
            if let Some((lane, sides, fraction)) = aim {
                let b = boxes[lane];
                if !b.is_empty() {
                    let target = Vec3::from_array(std::array::from_fn(|axis| match sides[axis] {
                        0 => b.min[axis],
                        1 => b.max[axis],
                        _ => b.min[axis] + fraction * (b.max[axis] - b.min[axis]),
                    }));
                    if target != origin {
                        direction = (target - origin) / scale;
                    }
                }
            }
            let ray = Ray::new(origin, direction * direction_scale).with_interval(ray.tmin, ray.tmax);
            prop_assume!(ray.is_valid());
            let mut prepared = PreparedRay::new(&ray);
            // Every box coordinate is within 2 · scale of zero.
            prepared.bound_errors_within_size(2.0 * scale);
            let box_ray = BoxRay::new(&prepared);
            let (tmin, tmax) = (prepared.box_tmin(), prepared.box_tmax());
            let l8 = lanes::<8>(&boxes);
            let (mask, entry) = boxes_scalar(&l8, &box_ray, tmin, tmax);
            for (lane, b) in boxes.iter().enumerate() {
                if let Some(exact_entry) = exact_entry(b, &ray) {
                    prop_assert!(mask >> lane & 1 == 1, "lane {} lost", lane);
                    // (An entry beyond f32's range overflows to infinity: no finite hit lies
                    // there, and the bound is not claimed.)
                    prop_assert!(
                        exact_entry > f64::from(f32::MAX) / 2.0
                            || entry[lane] as f64 <= exact_entry + prepared.box_margin as f64,
                        "lane {}: entry {} beyond the exact {} and the margin", lane, entry[lane], exact_entry
                    );
                }
            }
            #[cfg(target_arch = "x86_64")]
            {
                for offset in [0, 4] {
                    let (m, e) = boxes_sse(&l8, offset, &box_ray, tmin, tmax);
                    prop_assert_eq!(m, mask >> offset & 0xf);
                    for k in 0..4 {
                        if m >> k & 1 == 1 {
                            prop_assert_eq!(e[k].to_bits(), entry[offset + k].to_bits());
                        }
                    }
                }
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: AVX was just detected.
                    let (m, e) = unsafe { boxes_avx(&l8, &box_ray, tmin, tmax) };
                    prop_assert_eq!(m, mask);
                    for k in 0..8 {
                        if m >> k & 1 == 1 {
                            prop_assert_eq!(e[k].to_bits(), entry[k].to_bits());
                        }
                    }
                }
            }
        }
    }
}
