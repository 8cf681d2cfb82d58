//! The rays of a batch that meet the tree's root box, found eight at a time, so that the rest
//! (about 60% of a camera's rays) never reach the traversal's set-up.
//!
//! [`Traversal::restart`](super::traversal::Traversal::restart) decides for each ray whether it
//! meets the root box, in scalar code: the reciprocal of the direction, the ray's error margins
//! ([`PreparedRay::margins`]) and a slab test, about 80 instructions for a ray that then goes
//! nowhere. [`root_candidates_avx`] takes the same IEEE operations in the same order for eight
//! rays in AVX lanes, and so decides every valid ray alike (tested below, on adversarial rays
//! and on intervals that end within the margins). The batches then set up the rays it keeps
//! without testing the root box again
//! ([`Traversal::restart_meeting_root`](super::traversal::Traversal::restart_meeting_root)).
//! Teapot, spot and bunny camera rays from Python, one thread, Zen 3: 10–16% faster; random rays,
//! which all meet the box, within ±5%.

use crate::geometry::{Aabb, PreparedRay, Ray};

/// Goes through a batch's rays, block of eight by block of eight, handing out those that may
/// meet the tree in order.
pub(super) struct RayCursor {
    /// The first ray of the current block, and of the next one.
    block: usize,
    next_block: usize,
    /// The current block's rays still to hand out (bit `i`: ray `block + i`).
    pending: u32,
}

impl RayCursor {
    pub fn new() -> Self {
        Self {
            block: 0,
            next_block: 0,
            pending: 0,
        }
    }

    /// The index of the next ray of `rays` to trace, or `None` when none is left. Each block of
    /// eight rays goes to `filter(first, rays)`, which returns the rays of the block to hand out
    /// (those that may meet the root box: [`root_candidates_avx`]; a batch that traces the block
    /// as a packet answers it there and hands out none); the last, shorter block is handed out
    /// whole.
    #[inline(always)]
    pub fn next(
        &mut self,
        rays: &[Ray],
        mut filter: impl FnMut(usize, &[Ray; 8]) -> u32,
    ) -> Option<usize> {
        while self.pending == 0 {
            self.block = self.next_block;
            if self.block >= rays.len() {
                return None;
            }
            self.next_block = self.block + 8;
            self.pending = match rays.get(self.block..self.next_block) {
                Some(eight) => filter(self.block, eight.try_into().expect("eight rays")),
                None => (1 << (rays.len() - self.block)) - 1,
            };
        }
        let lane = self.pending.trailing_zeros() as usize;
        self.pending &= self.pending - 1;
        Some(self.block + lane)
    }
}

/// Every ray may meet the tree: the filter of kernels without one.
#[inline(always)]
pub(super) fn all_candidates(_: &[Ray; 8], _: &Aabb, _: f32) -> u32 {
    0xff
}

/// Which of eight valid rays meet the box `bounds` (the root's, of [`PreparedRay::scene_size`]
/// `scene_size`) as [`Traversal::restart`](super::traversal::Traversal::restart) decides it: bit
/// `i` for `rays[i]`. For an invalid ray (see [`Ray::is_valid`]) the bit means nothing; the
/// batches reject those rays anyway.
///
/// Lane by lane, the operations of the scalar path ([`PreparedRay::inverse_of`],
/// [`PreparedRay::margins`], `box_scalar`), with SSE's `max(x, acc)` and `min(x, acc)` in
/// place of `f32::max` and `min`: both return `acc` when `x` is NaN (a slab distance `0 · ∞`,
/// which drops out), and the other values of a valid ray are never NaN:
///
/// ```text
///   inv = 1 / d  (NaN where d ≠ 0 and 1/d overflows)
///   x = (max |o| + scene_size) · (1 / max |d|)
///   m = max(2^-126, (2^-18 + 2^-20) x) if finite, else f32::MAX (box margin)
///   s = max(2^-126, 2^-19 x) if x is finite, else ∞              (slab margin)
///   near = max over axes of (near plane − o) inv, and tmin − m
///   far = min over axes of (far plane − o) inv, and tmax + m;   met if near ≤ far + s
/// ```
///
/// The eight rays are read as the rows of an 8 × 8 matrix and transposed in registers
/// ([`RayColumns::of`]); [`RootTest::of`] is the test itself.
///
/// # Safety
/// The CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
pub(super) unsafe fn root_candidates_avx(rays: &[Ray; 8], bounds: &Aabb, scene_size: f32) -> u32 {
    // SAFETY: the caller guarantees AVX.
    unsafe { RootTest::of(&RayColumns::of(rays), bounds, scene_size).met }
}

/// Eight rays as columns, one AVX register per component: lane `i` holds ray `i`'s.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct RayColumns {
    pub origin: [std::arch::x86_64::__m256; 3],
    pub direction: [std::arch::x86_64::__m256; 3],
    pub tmin: std::arch::x86_64::__m256,
    pub tmax: std::arch::x86_64::__m256,
}

#[cfg(target_arch = "x86_64")]
impl RayColumns {
    /// The columns of `rays`, read as the rows of an 8 × 8 matrix (a [`Ray`] is eight floats:
    /// origin, direction, tmin, tmax) and transposed in registers.
    ///
    /// # Safety
    /// The CPU has AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    pub unsafe fn of(rays: &[Ray; 8]) -> Self {
        use std::arch::x86_64::*;
        const _: () = assert!(std::mem::size_of::<Ray>() == 32);
        // SAFETY: the caller guarantees AVX; `Ray` is `repr(C)` with eight `f32` fields (origin
        // x, y, z, direction x, y, z, tmin, tmax), so each of the eight loads reads one ray.
        unsafe {
            let row = |i: usize| _mm256_loadu_ps(&rays[i] as *const Ray as *const f32);
            // Rows of rays -> columns of components.
            let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
            let (r4, r5, r6, r7) = (row(4), row(5), row(6), row(7));
            let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
            let (t2, t3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
            let (t4, t5) = (_mm256_unpacklo_ps(r4, r5), _mm256_unpackhi_ps(r4, r5));
            let (t6, t7) = (_mm256_unpacklo_ps(r6, r7), _mm256_unpackhi_ps(r6, r7));
            let (q0, q1) = (
                _mm256_shuffle_ps::<0x44>(t0, t2),
                _mm256_shuffle_ps::<0xee>(t0, t2),
            );
            let (q2, q3) = (
                _mm256_shuffle_ps::<0x44>(t1, t3),
                _mm256_shuffle_ps::<0xee>(t1, t3),
            );
            let (q4, q5) = (
                _mm256_shuffle_ps::<0x44>(t4, t6),
                _mm256_shuffle_ps::<0xee>(t4, t6),
            );
            let (q6, q7) = (
                _mm256_shuffle_ps::<0x44>(t5, t7),
                _mm256_shuffle_ps::<0xee>(t5, t7),
            );
            Self {
                origin: [
                    _mm256_permute2f128_ps::<0x20>(q0, q4),
                    _mm256_permute2f128_ps::<0x20>(q1, q5),
                    _mm256_permute2f128_ps::<0x20>(q2, q6),
                ],
                direction: [
                    _mm256_permute2f128_ps::<0x20>(q3, q7),
                    _mm256_permute2f128_ps::<0x31>(q0, q4),
                    _mm256_permute2f128_ps::<0x31>(q1, q5),
                ],
                tmin: _mm256_permute2f128_ps::<0x31>(q2, q6),
                tmax: _mm256_permute2f128_ps::<0x31>(q3, q7),
            }
        }
    }
}

/// The root box test of eight rays ([`root_candidates_avx`]), with the constants of each ray
/// it computed on the way: its reciprocal direction ([`PreparedRay::inverse_of`]) and its
/// margins ([`PreparedRay::margins`]), lane by lane the same bits.
#[cfg(target_arch = "x86_64")]
pub(super) struct RootTest {
    /// Bit `i`: ray `i` meets the root box (meaningless for an invalid ray).
    pub met: u32,
    pub inverse: [std::arch::x86_64::__m256; 3],
    pub box_margin: std::arch::x86_64::__m256,
    pub slab_margin: std::arch::x86_64::__m256,
}

#[cfg(target_arch = "x86_64")]
impl RootTest {
    /// The test of `rays` against the box `bounds` (the root's, of
    /// [`PreparedRay::scene_size`] `scene_size`).
    ///
    /// # Safety
    /// The CPU has AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    pub unsafe fn of(rays: &RayColumns, bounds: &Aabb, scene_size: f32) -> Self {
        use std::arch::x86_64::*;
        let RayColumns {
            origin,
            direction,
            tmin,
            tmax,
        } = *rays;
        let sign_bit = _mm256_set1_ps(-0.0);
        let abs = |x: __m256| _mm256_andnot_ps(sign_bit, x);
        let infinity = _mm256_set1_ps(f32::INFINITY);
        let finite = |x: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(abs(x), infinity);
        let tiny = _mm256_set1_ps(f32::MIN_POSITIVE);
        // `PreparedRay::inverse_of`.
        let inverse = direction.map(|d| {
            let inv = _mm256_div_ps(_mm256_set1_ps(1.0), d);
            let overflow = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_EQ_OQ>(abs(inv), infinity),
                _mm256_cmp_ps::<_CMP_NEQ_UQ>(d, _mm256_setzero_ps()),
            );
            _mm256_blendv_ps(inv, _mm256_set1_ps(f32::NAN), overflow)
        });
        // `PreparedRay::margins` (the maxima of finite values, in any order).
        let largest =
            |v: [__m256; 3]| _mm256_max_ps(_mm256_max_ps(abs(v[0]), abs(v[1])), abs(v[2]));
        let x = _mm256_mul_ps(
            _mm256_add_ps(largest(origin), _mm256_set1_ps(scene_size)),
            _mm256_div_ps(_mm256_set1_ps(1.0), largest(direction)),
        );
        let margin = _mm256_mul_ps(
            _mm256_set1_ps(PreparedRay::BOX_SLACK + PreparedRay::BOX_SLACK / 4.0),
            x,
        );
        let box_margin = _mm256_blendv_ps(
            _mm256_set1_ps(f32::MAX),
            _mm256_max_ps(margin, tiny),
            finite(margin),
        );
        let slab_margin = _mm256_blendv_ps(
            infinity,
            _mm256_max_ps(
                _mm256_mul_ps(_mm256_set1_ps(PreparedRay::BOX_SLACK / 2.0), x),
                tiny,
            ),
            finite(x),
        );
        // `box_scalar`: the near plane of each axis is the maximum one for a negative direction
        // (its sign bit, as `is_sign_negative`, selects it).
        let mut near = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut far = infinity;
        for axis in 0..3 {
            let (lo, hi) = (
                _mm256_set1_ps(bounds.min[axis]),
                _mm256_set1_ps(bounds.max[axis]),
            );
            let near_plane = _mm256_blendv_ps(lo, hi, direction[axis]);
            let far_plane = _mm256_blendv_ps(hi, lo, direction[axis]);
            let o = origin[axis];
            let inv = inverse[axis];
            near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(near_plane, o), inv), near);
            far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(far_plane, o), inv), far);
        }
        let near = _mm256_max_ps(near, _mm256_sub_ps(tmin, box_margin));
        let far = _mm256_add_ps(
            _mm256_min_ps(far, _mm256_add_ps(tmax, box_margin)),
            slab_margin,
        );
        Self {
            met: _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32,
            inverse,
            box_margin,
            slab_margin,
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::traversal::Traversal;
    use super::super::WideLayout;
    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, Builder};
    use crate::mesh::procedural::torus;
    use crate::stats::NoCount;
    use glam::Vec3;
    use proptest::prelude::*;

    /// Every valid ray gets the bit that the scalar set-up's test of the root box gives it.
    fn check(layout: &WideLayout<8>, rays: &[Ray; 8]) -> Result<(), TestCaseError> {
        let (_, bounds, scene_size) = layout.root.expect("a tree");
        // SAFETY: checked by the caller.
        let bits = unsafe { root_candidates_avx(rays, &bounds, scene_size) };
        for (i, ray) in rays.iter().enumerate() {
            if ray.is_valid() {
                let met = Traversal::start(layout, ray, &mut NoCount).is_some();
                prop_assert_eq!(bits >> i & 1 == 1, met, "ray {}: {:?}", i, ray);
            }
        }
        Ok(())
    }

    /// Components that exercise the special cases: zeros of both signs (infinite reciprocals,
    /// NaN slab distances from an origin on a plane), subnormals (reciprocals that overflow),
    /// the box's own planes, huge values (margins that overflow) and infinities and NaN (invalid
    /// rays, whose bits mean nothing).
    fn component() -> impl Strategy<Value = f32> {
        prop_oneof![
            Just(0.0f32),
            Just(-0.0),
            Just(1.0),
            Just(-1.0),
            Just(2.0),
            Just(-2.0),
            Just(1e-40),
            Just(-1e-40),
            Just(1e-30),
            Just(3e38),
            Just(-3e38),
            Just(f32::INFINITY),
            Just(f32::NAN),
            -4.0f32..4.0,
            -4.0f32..4.0,
            -4.0f32..4.0,
        ]
    }

    fn ray() -> impl Strategy<Value = Ray> {
        let v = || (component(), component(), component()).prop_map(|(x, y, z)| Vec3::new(x, y, z));
        let t = prop_oneof![
            Just(0.0f32),
            Just(-1.0),
            Just(f32::NEG_INFINITY),
            Just(f32::INFINITY),
            Just(f32::NAN),
            0.0f32..10.0
        ];
        (v(), v(), t.clone(), t).prop_map(|(o, d, a, b)| {
            let (tmin, tmax) = if a <= b { (a, b) } else { (b, a) };
            Ray::new(o, d).with_interval(tmin, tmax)
        })
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(3000))]

        #[test]
        fn the_filter_decides_as_the_scalar_root_test(
            rays in prop::collection::vec(ray(), 8),
            far in prop::bool::ANY,
        ) {
            if !std::arch::is_x86_feature_detected!("avx") {
                return Ok(());
            }
            // A torus about the origin, whose box has planes at ±2 and ±0.5 (some origins and
            // components above lie on them), or one far from it (large margins).
            let centre = if far { Vec3::new(3e5, -2e5, 1e5) } else { Vec3::ZERO };
            let mesh = torus(centre, 1.5, 0.5, 12, 6);
            let layout = WideLayout::<8>::new(&BinnedSahBuilder::default().build(&mesh), &mesh);
            let rays: [Ray; 8] = rays.try_into().unwrap();
            check(&layout, &rays)?;
        }
    }

    /// The slab interval `[entry, exit]` of `ray`'s line in `bounds`, in f64.
    fn slab_interval(ray: &Ray, bounds: &Aabb) -> (f64, f64) {
        let (mut entry, mut exit) = (f64::NEG_INFINITY, f64::INFINITY);
        for axis in 0..3 {
            let (o, d) = (f64::from(ray.origin[axis]), f64::from(ray.direction[axis]));
            let (a, b) = (f64::from(bounds.min[axis]), f64::from(bounds.max[axis]));
            let (t0, t1) = ((a - o) / d, (b - o) / d);
            if !t0.is_nan() && !t1.is_nan() {
                entry = entry.max(t0.min(t1));
                exit = exit.min(t0.max(t1));
            }
        }
        (entry, exit)
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(3000))]

        /// Rays whose interval ends just before the root box, or starts just after it, within
        /// a few times the margins: where the margins decide.
        #[test]
        fn the_filter_keeps_the_margins_of_the_scalar_root_test(
            origins in prop::collection::vec((-6.0f32..6.0, -6.0f32..6.0, -6.0f32..6.0), 8),
            targets in prop::collection::vec((-1.5f32..1.5, -1.5f32..1.5, -0.4f32..0.4), 8),
            offsets in prop::collection::vec((prop::bool::ANY, -40i32..40), 8),
        ) {
            if !std::arch::is_x86_feature_detected!("avx") {
                return Ok(());
            }
            let mesh = torus(Vec3::ZERO, 1.5, 0.5, 12, 6);
            let layout = WideLayout::<8>::new(&BinnedSahBuilder::default().build(&mesh), &mesh);
            let (_, bounds, _) = layout.root.unwrap();
            let rays: Vec<Ray> = (0..8)
                .map(|i| {
                    let o = Vec3::new(origins[i].0, origins[i].1, origins[i].2);
                    let target = Vec3::new(targets[i].0, targets[i].1, targets[i].2);
                    let ray = Ray::new(o, target - o);
                    let (entry, exit) = slab_interval(&ray, &bounds);
                    // Steps of 2^-22 relative: the margins are about 2^-18 of the scene's size.
                    let (before, k) = offsets[i];
                    let shift = 1.0 + f64::from(k) * 2f64.powi(-22);
                    if before {
                        ray.with_interval(0.0, (entry * shift) as f32)
                    } else {
                        ray.with_interval((exit * shift) as f32, f32::INFINITY)
                    }
                })
                .collect();
            check(&layout, &rays.try_into().unwrap())?;
        }
    }

    #[test]
    fn the_cursor_hands_out_every_candidate_once_in_order() {
        let rays = vec![Ray::new(Vec3::ZERO, Vec3::X); 21];
        // Keep rays 1 and 6 of each block of eight; the last block (5 rays) is handed out whole.
        let mut firsts = Vec::new();
        let mut filter = |first: usize, _: &[Ray; 8]| {
            firsts.push(first);
            0b0100_0010
        };
        let mut cursor = RayCursor::new();
        let got: Vec<usize> = std::iter::from_fn(|| cursor.next(&rays, &mut filter)).collect();
        assert_eq!(got, [1, 6, 9, 14, 16, 17, 18, 19, 20]);
        assert_eq!(firsts, [0, 8]);
        let mut cursor = RayCursor::new();
        assert_eq!(cursor.next(&[], |_, _| 0xff), None);
    }
}
