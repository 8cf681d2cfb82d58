use glam::Vec3;

use super::Aabb;

/// A ray `o + t d` with its valid interval: a hit at `t` counts when `tmin <= t <= tmax`.
///
/// `direction` need not be unit length; `t` is measured in its units (as in Embree and
/// `docs/RAYS.md`).
///
/// `repr(C)`: eight floats in this order, which the wide layouts' batches read eight rays at a
/// time as the rows of a matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

impl Ray {
    /// A ray over `[0, +inf]`.
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Self {
            origin,
            direction,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }

    /// The same ray restricted to `[tmin, tmax]`.
    pub fn with_interval(self, tmin: f32, tmax: f32) -> Self {
        Self { tmin, tmax, ..self }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.direction
    }

    /// Whether the ray can hit anything at all. Rays that cannot are answered as misses, never as
    /// errors: a NaN or infinite origin or direction component, a NaN bound, or a direction whose
    /// largest component is zero or subnormal (its reciprocal overflows, and any hit would lie
    /// beyond `f32::MAX` times the scene's size).
    pub fn is_valid(&self) -> bool {
        let d = self.direction.abs().max_element();
        self.origin.is_finite()
            && self.direction.is_finite()
            && d >= f32::MIN_POSITIVE
            && !self.tmin.is_nan()
            && !self.tmax.is_nan()
    }
}

/// A ray with the per-ray constants of the box and triangle tests computed once, before traversal.
///
/// - For the slab test: `1/d` per axis and the sign of each direction component.
/// - For the watertight triangle test (Woop, Benthin & Wald 2013): the dominant axis `kz` of the
///   direction, the two others `kx`, `ky`, and the shear `(Sx, Sy, Sz) = (dx/dz, dy/dz, 1/dz)` that
///   maps the ray onto the +z axis of a unit-length coordinate frame.
///
/// `tmax` is mutable state of a closest-hit traversal: it shrinks as hits are found.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRay {
    pub origin: Vec3,
    pub direction: Vec3,
    /// `1/d` per axis; NaN where `d` is not zero but `1/d` overflows (the slab tests then leave
    /// the axis unconstrained).
    pub inv_direction: Vec3,
    pub negative: [bool; 3],
    pub tmin: f32,
    pub tmax: f32,
    /// Always a permutation of 0, 1, 2 (set only by [`PreparedRay::new`]): kernels index
    /// 3-arrays with them unchecked.
    pub(crate) kx: usize,
    pub(crate) ky: usize,
    pub(crate) kz: usize,
    /// The origin's coordinates on the axes `kx`, `ky`, `kz`.
    pub(crate) origin_k: [f32; 3],
    pub(crate) shear: Vec3,
    /// Absolute widening of `[tmin, tmax]` for box tests; see [`PreparedRay::bound_errors_within`].
    pub(crate) box_margin: f32,
    /// Absolute bound on twice the rounding error of a slab distance of a box inside the scene,
    /// for the wide layouts' box kernels; see [`PreparedRay::bound_errors_within`]. `+inf` (every
    /// box is met) until a scene is given.
    pub(crate) slab_margin: f32,
}

impl PreparedRay {
    /// Relative widening of a box's slab interval (2^-18 ≈ 3.8e-6); see [`crate::geometry::Aabb::intersect_interval`].
    pub const BOX_SLACK: f32 = 1.0 / 262_144.0;

    /// Prepares a ray. The caller checks [`Ray::is_valid`] first; an invalid ray prepares into
    /// constants that make no promise (they never produce a finite hit, but that is not a contract).
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        Self::with_inverse(ray, Self::inverse_of(ray.direction))
    }

    /// `1/d` per axis, as [`PreparedRay::inv_direction`] holds it (NaN where a nonzero `d`
    /// overflows).
    #[inline]
    pub(crate) fn inverse_of(direction: Vec3) -> Vec3 {
        let c = direction.to_array();
        let [ix, iy, iz, _] = invert4([c[0], c[1], c[2], 1.0]);
        Vec3::new(ix, iy, iz)
    }

    /// [`PreparedRay::new`] given the ray's [`PreparedRay::inverse_of`] its direction (a
    /// traversal that tested the root box with it first).
    #[inline]
    pub(crate) fn with_inverse(ray: &Ray, inv_direction: Vec3) -> Self {
        let d = ray.direction;
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let c = d.to_array();
        // The six quotients, each one correctly rounded IEEE division: two 4-wide divisions.
        let [sx, sy, sz, _] = divide4([c[kx], c[ky], 1.0, 1.0], [c[kz], c[kz], c[kz], 1.0]);
        let shear = Vec3::new(sx, sy, sz);
        Self {
            origin: ray.origin,
            direction: d,
            inv_direction,
            negative: [
                d.x.is_sign_negative(),
                d.y.is_sign_negative(),
                d.z.is_sign_negative(),
            ],
            tmin: ray.tmin,
            tmax: ray.tmax,
            kx,
            ky,
            kz,
            origin_k: {
                let o = ray.origin.to_array();
                [o[kx], o[ky], o[kz]]
            },
            shear,
            box_margin: 0.0,
            slab_margin: f32::INFINITY,
        }
    }

    /// Prepares the ray's box tests for triangles inside `scene` (a tree's root box).
    ///
    /// A triangle test accepts a hit when its *computed* `t` lies in `[tmin, tmax]`; the computed
    /// `t` differs from the exact one by up to a few ulps of the triangle's coordinates relative to
    /// the origin, scaled by the shear `1/|d_kz|` (Woop et al. 2013, §4; pbrt-v4 §6.8.4 bounds the
    /// same error). For a hit much nearer than those coordinates are large — a ray leaving a
    /// surface, a short shadow segment — that error exceeds the relative widening of the box test
    /// ([`PreparedRay::BOX_SLACK`]): a box entered at the hit point could then be culled by a
    /// `tmax` set to the computed `t`. The box tests therefore use `[tmin - m, tmax + m]` with
    ///
    /// ```text
    ///   m = (2^-18 + 2^-20) · X,   X = (max |o| + max |scene|) / |d_kz|
    /// ```
    ///
    /// (2^-18 is 32 ulps of 1: several times the triangle test's error bound; the 2^-20 covers
    /// the slab error `δ` below, which the wide kernels' entry distances carry). The margin only
    /// lets the traversal visit a little more; the triangle tests keep the exact interval.
    ///
    /// **Slab margin** (the wide layouts' box kernels, `bvh/layout/wide/box_kernels.rs`): every point
    /// of the ray inside a box of the scene has `|t| ≤ T = √3 X` (it lies within `√3 max |scene|`
    /// of the origin's `√3 max |o|`, and `|d| ≥ |d_kz|`), and a computed slab distance
    /// `fl(fl(b − o) · fl(1/d))` is within `δ = 3.01 u T + 3 · 2^-150` of the exact one for every
    /// distance that matters (an axis whose `1/d` overflows is NaN and dropped, see
    /// [`PreparedRay::new`]) (`u = 2^-24`; the second term covers subnormal results). Widening a
    /// box's exit by `s ≥ 2δ` — added, not scaled, so one addition per box and no test of signs —
    /// then never loses a box the ray meets:
    ///
    /// ```text
    ///   s = max(2^-19 · X, 2^-126)   ≥ 2δ   (2^-19 X ≈ 3.07 · 2 · 3.01 u √3 X)
    /// ```
    ///
    /// Both are at least `2^-126` (the subnormal term of `δ`). An overflowing `X` (a direction
    /// of tiny length far from the scene) gives `m = f32::MAX` and `s = +inf`: every box the
    /// ray's line meets is met and none is culled by the interval, and the answers stay exact.
    pub fn bound_errors_within(&mut self, scene: &Aabb) {
        self.bound_errors_within_size(Self::scene_size(scene));
    }

    /// The largest coordinate magnitude of `scene`, `max |scene|` of
    /// [`PreparedRay::bound_errors_within`]: computed once per tree by layouts that trace many
    /// rays through it.
    pub fn scene_size(scene: &Aabb) -> f32 {
        scene.min.abs().max(scene.max.abs()).max_element()
    }

    /// [`PreparedRay::bound_errors_within`] for a scene of [`PreparedRay::scene_size`] `scene_size`.
    #[inline]
    pub fn bound_errors_within_size(&mut self, scene_size: f32) {
        (self.box_margin, self.slab_margin) =
            Self::margins(self.origin, self.direction, scene_size);
    }

    /// The box margin `m` and the slab margin `s` of [`PreparedRay::bound_errors_within`], from
    /// the ray's origin and direction alone (so that a traversal can test the root box before
    /// preparing the rest of the ray).
    #[inline]
    pub(crate) fn margins(origin: Vec3, direction: Vec3, scene_size: f32) -> (f32, f32) {
        let origin_size = origin.abs().max_element();
        // `1 / |d_kz|`: the same bits as `|shear.z|`.
        let x = (origin_size + scene_size) * (1.0 / direction.abs().max_element());
        let margin = (Self::BOX_SLACK + Self::BOX_SLACK / 4.0) * x;
        // An empty scene (infinite bounds: no box to test) or an overflowing `X`: the interval
        // is not narrowed at all, by the largest finite margin (not ∞, so that `tmin - m` is
        // never `∞ - ∞`). A margin of 0 there let a box entered a few ulps before a hit at
        // t ≈ 1e37 be culled by it: the slab distances' rounding, relative to `t`, is then
        // what `X` would have bounded.
        let box_margin = if margin.is_finite() {
            margin.max(f32::MIN_POSITIVE)
        } else {
            f32::MAX
        };
        let slab_margin = if x.is_finite() {
            (Self::BOX_SLACK / 2.0 * x).max(f32::MIN_POSITIVE)
        } else {
            f32::INFINITY
        };
        (box_margin, slab_margin)
    }

    /// The lower end of the interval the box tests use.
    #[inline]
    pub fn box_tmin(&self) -> f32 {
        self.tmin - self.box_margin
    }

    /// The upper end of the interval the box tests use.
    #[inline]
    pub fn box_tmax(&self) -> f32 {
        self.tmax + self.box_margin
    }
}

/// `1 / d` lane by lane (one SSE division on x86_64), but NaN where `d` is not zero and `1 / d`
/// overflows (below 2^-128): the slab distances of such an axis would come out infinite
/// although the ray crosses its planes at finite `t`, whereas NaN distances are dropped by
/// every slab test, which leaves the axis unconstrained (conservative; such rays are rare). An
/// exact zero keeps its infinity: the ray is parallel to the planes, and the infinities are
/// right.
#[inline(always)]
fn invert4(d: [f32; 4]) -> [f32; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let mut q = [0.0f32; 4];
        // SAFETY: SSE is part of the x86_64 baseline; the load and the store touch 4 floats of
        // 4-float arrays.
        unsafe {
            let d = _mm_loadu_ps(d.as_ptr());
            let inv = _mm_div_ps(_mm_set1_ps(1.0), d);
            let magnitude = _mm_andnot_ps(_mm_set1_ps(-0.0), inv);
            let overflow = _mm_and_ps(
                _mm_cmpeq_ps(magnitude, _mm_set1_ps(f32::INFINITY)),
                _mm_cmpneq_ps(d, _mm_setzero_ps()),
            );
            let inv = _mm_or_ps(
                _mm_andnot_ps(overflow, inv),
                _mm_and_ps(overflow, _mm_set1_ps(f32::NAN)),
            );
            _mm_storeu_ps(q.as_mut_ptr(), inv);
        }
        q
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        d.map(|d| {
            let inv = 1.0 / d;
            if d != 0.0 && inv.is_infinite() {
                f32::NAN
            } else {
                inv
            }
        })
    }
}

/// `a / b` lane by lane (one SSE division on x86_64; each lane is the correctly rounded quotient,
/// as the scalar division gives).
#[inline(always)]
fn divide4(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_div_ps, _mm_loadu_ps, _mm_storeu_ps};
        let mut q = [0.0f32; 4];
        // SAFETY: SSE is part of the x86_64 baseline; the loads and the store touch 4 floats of
        // 4-float arrays.
        unsafe {
            _mm_storeu_ps(
                q.as_mut_ptr(),
                _mm_div_ps(_mm_loadu_ps(a.as_ptr()), _mm_loadu_ps(b.as_ptr())),
            )
        };
        q
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::array::from_fn(|k| a[k] / b[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validity() {
        let ok = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(ok.is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::ZERO).is_valid());
        assert!(!Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X).is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)).is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::splat(1e-40)).is_valid());
        assert!(!ok.with_interval(f32::NAN, 1.0).is_valid());
        assert!(ok.with_interval(0.0, f32::INFINITY).is_valid());
    }

    #[test]
    fn shear_maps_direction_to_dominant_axis() {
        let r = PreparedRay::new(&Ray::new(Vec3::ZERO, Vec3::new(1.0, -4.0, 2.0)));
        assert_eq!((r.kz, r.kx, r.ky), (1, 2, 0));
        assert_eq!(r.shear, Vec3::new(-0.5, -0.25, -0.25));
    }
}
