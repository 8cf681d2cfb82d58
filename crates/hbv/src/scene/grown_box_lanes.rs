//! The top level's box test: the `W` child boxes of a wide node, each grown by the ray's pad,
//! against one ray, four lanes at a time (SSE on x86_64, a scalar twin elsewhere that computes
//! the same IEEE operations in the same order, so both return the same bits: tested below).

// The kernel indexes several arrays (planes, origin, inverse direction, pads) by one axis
// counter; iterators over one of them would hide that symmetry.
#![allow(clippy::needless_range_loop)]

use crate::bvh::layout::LaneBoxes;
use crate::geometry::PreparedRay;

/// What the kernel needs of one ray, set once per walk: the ray's origin and inverse
/// direction, which side of each axis is the near plane, and the pad as it is added to each
/// side's planes.
#[derive(Clone, Copy, Debug)]
pub(super) struct GrownBoxRay {
    origin: [f32; 3],
    inv_direction: [f32; 3],
    /// 1 where the direction is negative: the maximum plane is met first.
    near_side: [usize; 3],
    /// `-pad` on a minimum plane, `+pad` on a maximum one: what the near and far planes of each
    /// axis are moved by.
    near_pad: [f32; 3],
    far_pad: [f32; 3],
    /// The ray's slab margin `s` (see [`PreparedRay::bound_errors_within`]).
    slab_margin: f32,
}

impl GrownBoxRay {
    /// The kernel's constants for `ray` (whose margins are set for the grown root box) and
    /// boxes grown by `pad` on every side.
    pub fn new(ray: &PreparedRay, pad: f32) -> Self {
        let near_side = ray.negative.map(usize::from);
        let toward = |side: usize| if side == 0 { -pad } else { pad };
        Self {
            origin: ray.origin.to_array(),
            inv_direction: ray.inv_direction.to_array(),
            near_side,
            near_pad: near_side.map(toward),
            far_pad: near_side.map(|side| toward(1 - side)),
            slab_margin: ray.slab_margin,
        }
    }
}

/// Which of the `W` boxes, each grown to `[min - pad, max + pad]`, the ray meets within
/// `[tmin, tmax]` (bit `i` for lane `i`), and the entry distance of each.
///
/// The slab test of Kay & Kajiya (1986) on the grown planes, each computed in f32 as
/// `plane ± pad` (the same rounding as growing the box first), then
///
/// ```text
///   entry = max(near, tmin),   exit = min(far, tmax) + s,   met if entry ≤ exit
/// ```
///
/// with `s` the ray's slab margin, at least twice the rounding error of any slab distance of a
/// box inside the grown root box ([`PreparedRay::bound_errors_within`]): a grown box the ray
/// meets is never lost, and `entry` exceeds the exact entry by at most `s / 2`, within the
/// box margin that `tmax` culls postponed children with. A NaN slab distance (an origin on a
/// plane with a zero direction component, or an overflowing `1/d`) drops out of the running
/// maximum and minimum, leaving its axis unconstrained.
#[inline]
pub(super) fn grown_boxes<const W: usize>(
    boxes: &LaneBoxes<W>,
    ray: &GrownBoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; W]) {
    let mut mask = 0;
    let mut entry = [0.0f32; W];
    for offset in (0..W).step_by(4) {
        #[cfg(target_arch = "x86_64")]
        let (m, e) = four_sse(boxes, offset, ray, tmin, tmax);
        #[cfg(not(target_arch = "x86_64"))]
        let (m, e) = four_scalar(boxes, offset, ray, tmin, tmax);
        mask |= m << offset;
        entry[offset..offset + 4].copy_from_slice(&e);
    }
    (mask, entry)
}

/// Lanes `offset..offset + 4` of [`grown_boxes`], one at a time: the definition the SSE kernel
/// reproduces bit for bit. `f32::max` and `min` return the other operand when one is NaN, as
/// `maxps` / `minps` do when the NaN is their first operand.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn four_scalar<const W: usize>(
    boxes: &LaneBoxes<W>,
    offset: usize,
    ray: &GrownBoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; 4]) {
    let mut mask = 0;
    let mut entry = [0.0f32; 4];
    for k in 0..4 {
        let lane = offset + k;
        let mut near = f32::NEG_INFINITY;
        let mut far = f32::INFINITY;
        for axis in 0..3 {
            let side = ray.near_side[axis];
            let n = boxes[side][axis][lane] + ray.near_pad[axis];
            let f = boxes[1 - side][axis][lane] + ray.far_pad[axis];
            near = ((n - ray.origin[axis]) * ray.inv_direction[axis]).max(near);
            far = ((f - ray.origin[axis]) * ray.inv_direction[axis]).min(far);
        }
        let near = near.max(tmin);
        let far = far.min(tmax) + ray.slab_margin;
        mask |= u32::from(near <= far) << k;
        entry[k] = near;
    }
    (mask, entry)
}

/// Lanes `offset..offset + 4` of [`grown_boxes`] with SSE (the x86_64 baseline). The new
/// distance goes first into `maxps` / `minps` and the running value second, so that a NaN
/// distance drops out as in [`four_scalar`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn four_sse<const W: usize>(
    boxes: &LaneBoxes<W>,
    offset: usize,
    ray: &GrownBoxRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; 4]) {
    use std::arch::x86_64::*;
    let row = |side: usize, axis: usize| boxes[side][axis][offset..offset + 4].as_ptr();
    // SAFETY: SSE2 is part of the x86_64 baseline; each load reads the four floats of a slice
    // of length 4 and the store writes the four of `entry`.
    unsafe {
        let mut near = _mm_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm_set1_ps(f32::INFINITY);
        for axis in 0..3 {
            let side = ray.near_side[axis];
            let o = _mm_set1_ps(ray.origin[axis]);
            let inv = _mm_set1_ps(ray.inv_direction[axis]);
            let n = _mm_add_ps(
                _mm_loadu_ps(row(side, axis)),
                _mm_set1_ps(ray.near_pad[axis]),
            );
            let f = _mm_add_ps(
                _mm_loadu_ps(row(1 - side, axis)),
                _mm_set1_ps(ray.far_pad[axis]),
            );
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Aabb, Ray};
    use glam::Vec3;
    use proptest::prelude::*;

    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(-0.0), Just(1.0), Just(0.5), -2.0f32..2.0]
    }

    fn corner() -> impl Strategy<Value = Vec3> {
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn lanes_of(boxes: &[Aabb; 8]) -> LaneBoxes<8> {
        let mut lanes = [[[0.0; 8]; 3]; 2];
        for (lane, b) in boxes.iter().enumerate() {
            for axis in 0..3 {
                lanes[0][axis][lane] = b.min[axis];
                lanes[1][axis][lane] = b.max[axis];
            }
        }
        lanes
    }

    proptest! {
        /// The kernel answers as its scalar twin, bit for bit, and meets every grown box the
        /// ray's line meets within its interval (decided on the grown box by the plain slab
        /// test in f64).
        #[test]
        fn sse_equals_scalar_and_keeps_every_met_box(
            corners in prop::collection::vec((corner(), corner()), 8),
            origin in corner(),
            direction in corner().prop_filter("nonzero", |d| *d != Vec3::ZERO),
            pad in prop_oneof![Just(0.0f32), Just(1e-3), 0.0f32..0.5],
            tmax in prop_oneof![Just(f32::INFINITY), 0.5f32..4.0],
        ) {
            let mut boxes = [Aabb::EMPTY; 8];
            for (lane, (p, q)) in corners.iter().enumerate().skip(1) {
                boxes[lane] = Aabb::new(p.min(*q), p.max(*q));
            }
            let lanes = lanes_of(&boxes);
            let ray = Ray::new(origin, direction).with_interval(0.0, tmax);
            let mut prepared = PreparedRay::new(&ray);
            let pad3 = Vec3::splat(pad);
            let root = boxes
                .iter()
                .fold(Aabb::EMPTY, |r, b| r.union(&Aabb::new(b.min - pad3, b.max + pad3)));
            prepared.bound_errors_within(&root);
            let kernel_ray = GrownBoxRay::new(&prepared, pad);
            let (tmin, tmax) = (prepared.box_tmin(), prepared.box_tmax());
            let (mask, entry) = grown_boxes(&lanes, &kernel_ray, tmin, tmax);
            for offset in [0, 4] {
                let (m, e) = four_scalar(&lanes, offset, &kernel_ray, tmin, tmax);
                prop_assert_eq!(m, (mask >> offset) & 0xf);
                for k in 0..4 {
                    prop_assert_eq!(e[k].to_bits(), entry[offset + k].to_bits());
                }
            }
            prop_assert_eq!(mask & 1, 0, "the empty lane is never met");
            for (lane, b) in boxes.iter().enumerate().skip(1) {
                let grown = Aabb::new(b.min - pad3, b.max + pad3);
                let (mut near, mut far) = (ray.tmin as f64, ray.tmax as f64);
                for axis in 0..3 {
                    let (o, d) = (origin[axis] as f64, direction[axis] as f64);
                    let (lo, hi) = (grown.min[axis] as f64, grown.max[axis] as f64);
                    if d == 0.0 {
                        if o < lo || o > hi {
                            near = f64::INFINITY;
                        }
                        continue;
                    }
                    let (t0, t1) = ((lo - o) / d, (hi - o) / d);
                    near = near.max(t0.min(t1));
                    far = far.min(t0.max(t1));
                }
                if near <= far {
                    prop_assert!(mask & (1 << lane) != 0, "lane {} lost", lane);
                }
            }
        }
    }
}
