use glam::Vec3;

use super::PreparedRay;

/// An axis-aligned bounding box, closed on both sides: a point on a face is inside.
///
/// The empty box has `min = +inf` and `max = -inf`, so that it is the identity of [`Aabb::union`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The box that contains nothing.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box containing all `points`.
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> Self {
        points
            .into_iter()
            .fold(Self::EMPTY, |b, p| b.union_point(*p))
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    #[inline]
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    #[inline]
    pub fn union_point(&self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// Whether `other` lies inside this box (faces included). The empty box lies inside every box.
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }

    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Surface area `2 (dx dy + dy dz + dz dx)`; 0 for the empty box.
    ///
    /// By Crofton's formula (Santaló 1976) the measure of the lines that meet a convex body is
    /// proportional to its surface area, so `SA(child) / SA(parent)` is the probability that a
    /// uniformly distributed line through the parent also meets the child. This is the whole basis
    /// of the tree cost E\[X\] (Goldsmith & Salmon 1987) and of the SAH (MacDonald & Booth 1990).
    #[inline]
    pub fn surface_area(&self) -> f32 {
        let d = self.extent();
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The parameter interval `[near, far]` over which `ray` is inside the box, clipped to the
    /// ray's own `[tmin, tmax]`, or `None` when the two do not overlap.
    ///
    /// Slab test (Kay & Kajiya 1986) with the near and far plane of each axis chosen by the sign of
    /// the direction. Two details make it exact enough to never lose a triangle hit:
    /// - A zero direction component gives `1/d = ±inf`; an origin exactly on that slab's plane then
    ///   gives `0 · inf = NaN`, and `f32::max`/`f32::min` drop the NaN, so the axis does not
    ///   constrain the interval (the ray runs inside the plane of the face, which is inside a closed box).
    /// - The interval is widened by a relative [`PreparedRay::BOX_SLACK`] on both ends, well above the
    ///   rounding error of the slab distances (Ize 2013, "Robust BVH ray traversal") and of the
    ///   triangle test's `t`, so that a triangle touching a face, edge or corner of its box, or a hit
    ///   at exactly `tmin` or `tmax`, is never culled by rounding.
    #[inline]
    pub fn intersect_interval(&self, ray: &PreparedRay) -> Option<(f32, f32)> {
        let (near, far) = self.slab_distances(ray);
        // Scaling (not adding |x| · slack) keeps infinities infinite instead of making NaN.
        const SLACK: f32 = PreparedRay::BOX_SLACK;
        let near = (near * if near > 0.0 { 1.0 - SLACK } else { 1.0 + SLACK }).max(ray.box_tmin());
        let far = (far * if far > 0.0 { 1.0 + SLACK } else { 1.0 - SLACK }).min(ray.box_tmax());
        (near <= far).then_some((near, far))
    }

    /// The plain slab test, without the widening of [`Aabb::intersect_interval`]: whether the
    /// ray's computed interval meets the box. For measuring how many boxes a line meets (where
    /// the widening, relative to `t`, would inflate small boxes far from the origin), never for
    /// finding hits.
    #[inline]
    pub fn hit_by_unwidened(&self, ray: &PreparedRay) -> bool {
        let (near, far) = self.slab_distances(ray);
        near.max(ray.tmin) <= far.min(ray.tmax)
    }

    /// Whether the ray meets the box inside its `[tmin, tmax]`; see [`Aabb::intersect_interval`].
    #[inline]
    pub fn hit_by(&self, ray: &PreparedRay) -> bool {
        self.intersect_interval(ray).is_some()
    }

    /// Entry and exit distances of the ray's line through the three slabs, unclipped.
    ///
    /// Written as a running maximum (minimum) from `-inf` (`+inf`) with the new distance as the
    /// first operand of `max` (`min`): `f32::max` drops a NaN operand, and so does the SIMD
    /// `maxps` in that operand order, so the wide layouts' kernels compute the same values.
    #[inline]
    fn slab_distances(&self, ray: &PreparedRay) -> (f32, f32) {
        let o = ray.origin;
        let inv = ray.inv_direction;
        let (lo, hi) = (self.min, self.max);
        let mut near = f32::NEG_INFINITY;
        let mut far = f32::INFINITY;
        for axis in 0..3 {
            // Near plane of each axis: `min` when the direction is positive, `max` when negative.
            let (near_plane, far_plane) = if ray.negative[axis] {
                (hi[axis], lo[axis])
            } else {
                (lo[axis], hi[axis])
            };
            near = ((near_plane - o[axis]) * inv[axis]).max(near);
            far = ((far_plane - o[axis]) * inv[axis]).min(far);
        }
        (near, far)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    fn unit() -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::ONE)
    }

    #[test]
    fn surface_area_of_unit_cube_and_flat_box() {
        assert_eq!(unit().surface_area(), 6.0);
        let flat = Aabb::new(Vec3::ZERO, Vec3::new(2.0, 3.0, 0.0));
        assert_eq!(flat.surface_area(), 12.0);
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
    }

    #[test]
    fn union_with_empty_is_identity() {
        assert_eq!(unit().union(&Aabb::EMPTY), unit());
        assert!(unit().contains(&Aabb::EMPTY));
        assert!(Aabb::EMPTY.is_empty());
    }

    #[test]
    fn ray_through_box_interval() {
        let r = PreparedRay::new(&Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X));
        let (n, f) = unit().intersect_interval(&r).unwrap();
        assert!((n - 1.0).abs() < 1e-5 && (f - 2.0).abs() < 1e-5);
    }

    #[test]
    fn ray_in_face_plane_with_zero_component_hits() {
        // Origin exactly on the plane y = 0 of the box, direction with y = 0 (and -0.0).
        for dy in [0.0f32, -0.0] {
            let r = PreparedRay::new(&Ray::new(
                Vec3::new(-1.0, 0.0, 0.5),
                Vec3::new(1.0, dy, 0.0),
            ));
            assert!(unit().hit_by(&r), "dy = {dy:?}");
            let r = PreparedRay::new(&Ray::new(
                Vec3::new(-1.0, 1.0, 0.5),
                Vec3::new(1.0, dy, 0.0),
            ));
            assert!(unit().hit_by(&r), "on max face, dy = {dy:?}");
        }
        let outside = PreparedRay::new(&Ray::new(Vec3::new(-1.0, 1.5, 0.5), Vec3::X));
        assert!(!unit().hit_by(&outside));
    }

    #[test]
    fn flat_box_hit_edge_on_and_through() {
        let flat = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        let through = PreparedRay::new(&Ray::new(Vec3::new(0.5, 0.5, 1.0), -Vec3::Z));
        assert!(flat.hit_by(&through));
        let corner = PreparedRay::new(&Ray::new(Vec3::new(1.0, 1.0, 1.0), -Vec3::Z));
        assert!(flat.hit_by(&corner));
    }

    #[test]
    fn interval_respects_tmin_tmax() {
        let r = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        assert!(!unit().hit_by(&PreparedRay::new(&r.with_interval(0.0, 0.5))));
        assert!(!unit().hit_by(&PreparedRay::new(&r.with_interval(2.5, 9.0))));
        assert!(unit().hit_by(&PreparedRay::new(&r.with_interval(0.0, 1.0))));
        assert!(unit().hit_by(&PreparedRay::new(&r.with_interval(2.0, 9.0))));
    }
}
