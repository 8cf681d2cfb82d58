//! `Instance`: a mesh placed by a transform, its world box, and rays carried into its space.

use glam::{DVec3, Vec3};

use super::{InstanceTransform, SceneRay};
use crate::geometry::directed_rounding::{f32_above, f32_below};
use crate::geometry::{Aabb, PreparedRay, Ray, Triangle};

/// Where queries find an instance: through the top level, tested in turn, or nowhere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum InstanceState {
    /// Its leaf in the top level holds its current world box.
    Indexed,
    /// Added or moved since the last build or update: queries test it in turn, and skip the
    /// leaf it may still have in the top level (whose box may be stale).
    Pending,
    /// Removed: a hole that is never hit; its id is never handed out again.
    Removed,
}

/// One placement of a mesh of the scene.
///
/// Laid out for the rays' visits, which read `state`, `mask`, `mesh` and the inverse
/// transform: those come first, in the first two cache lines of the record (the record is
/// aligned to a line), and the rest (the forward map, the cofactor for normals, the world box)
/// after them. Ordered by declaration, a visit read four lines, `state` at the record's end
/// (`perf` in BENCHMARKS.md, "Scenes: 10,000 instances").
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Instance {
    pub state: InstanceState,
    pub mask: u32,
    /// Index of the mesh in the scene.
    pub mesh: u32,
    /// Its inverse first ([`InstanceTransform`]).
    pub transform: InstanceTransform,
    /// A box holding every world-space point of the instance's mesh (see [`world_box`]);
    /// [`Aabb::EMPTY`] once removed.
    pub world_box: Aabb,
}

impl Instance {
    /// A new instance, [`InstanceState::Pending`] until the top level is built or updated.
    pub fn new(mesh: u32, transform: InstanceTransform, mask: u32, mesh_box: &Aabb) -> Self {
        Self {
            mesh,
            transform,
            mask,
            world_box: world_box(&transform, mesh_box),
            state: InstanceState::Pending,
        }
    }

    /// What this instance asks of the top level's box growth (module notes of `scene`): its
    /// `κ` and its `|b| + S`, or `None` when nothing can hit it (removed, or an empty mesh).
    pub fn box_growth_terms(&self) -> Option<(f64, f64)> {
        if self.world_box.is_empty() {
            return None;
        }
        let size = f64::from(PreparedRay::scene_size(&self.world_box));
        let offset = self.transform.affine().translation.abs().max_element() + size;
        Some((self.transform.conditioning(), offset))
    }

    /// The world ray `o + t d` in the instance's space: `o' = A^-1 (o - b)`, `d' = A^-1 d`,
    /// computed in f64 and rounded to the nearest f32. `d'` is not normalized, so that `t` is
    /// the same parameter in both spaces (the local point at `t` is `A^-1` of the world one),
    /// and `[tmin, tmax]` carries over unchanged.
    #[inline]
    pub fn carry(&self, ray: &SceneRay) -> Ray {
        let inverse = self.transform.inverse();
        Ray {
            origin: inverse.transform_point3(ray.origin()).as_vec3(),
            direction: (inverse.matrix3 * ray.ray.direction.as_dvec3()).as_vec3(),
            tmin: ray.ray.tmin,
            tmax: ray.ray.tmax,
        }
    }

    /// The unit world-space geometric normal of the local `triangle`:
    /// `normalize(cof(A) · ((p1 - p0) × (p2 - p0)))` in f64, which is
    /// `normalize(cross(A p1 - A p0, A p2 - A p0))` (so a mirroring `A` flips it).
    #[inline]
    pub fn world_normal(&self, triangle: &Triangle) -> Vec3 {
        self.transform
            .world_scaled_normal(triangle.scaled_normal())
            .normalize_or_zero()
            .as_vec3()
    }
}

/// The world box of a mesh whose local box is `mesh_box`, placed by `transform`: the eight
/// corners mapped in f64, each coordinate widened by a bound on its f64 rounding and rounded
/// outwards to f32. The convex hull of the mapped corners holds the mapped box (the map is
/// affine), so every world-space point of the mesh lies in the result, and no ray that meets
/// the instance is culled at its box for rounding.
///
/// The f64 rounding of `w_i = Σ_j a_ij c_j + b_i` (three products, three sums) is at most
/// `γ_4 · (Σ_j |a_ij c_j| + |b_i|)` with `γ_4 < 2^-50` (Higham 2002, §3.1).
fn world_box(transform: &InstanceTransform, mesh_box: &Aabb) -> Aabb {
    if mesh_box.is_empty() {
        return Aabb::EMPTY;
    }
    const ROUNDING: f64 = 1.0 / (1u64 << 50) as f64;
    let affine = transform.affine();
    let magnitude = affine.matrix3.abs();
    let (lo, hi) = (mesh_box.min.as_dvec3(), mesh_box.max.as_dvec3());
    let mut world = Aabb::EMPTY;
    for corner in 0..8 {
        let c = DVec3::new(
            if corner & 1 == 0 { lo.x } else { hi.x },
            if corner & 2 == 0 { lo.y } else { hi.y },
            if corner & 4 == 0 { lo.z } else { hi.z },
        );
        let w = affine.transform_point3(c);
        let error = (magnitude * c.abs() + affine.translation.abs()) * ROUNDING;
        let below = w - error;
        let above = w + error;
        world = world
            .union_point(Vec3::new(
                f32_below(below.x),
                f32_below(below.y),
                f32_below(below.z),
            ))
            .union_point(Vec3::new(
                f32_above(above.x),
                f32_above(above.y),
                f32_above(above.z),
            ));
    }
    world
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DAffine3, DQuat};

    #[test]
    fn world_box_holds_every_mapped_vertex() {
        let transform = InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            DVec3::new(3.0, -0.5, 1e-3),
            DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -2.0),
            DVec3::new(1e5, -0.1, 7.0),
        ))
        .unwrap();
        let points = [
            Vec3::new(-1.0, 0.3, 2.0),
            Vec3::new(0.7, -2.0, 0.1),
            Vec3::new(0.0, 1.0, -1.0),
        ];
        let local = Aabb::from_points(&points);
        let world = world_box(&transform, &local);
        for p in points {
            let w = transform.affine().transform_point3(p.as_dvec3());
            assert!(world.min.as_dvec3().cmple(w).all() && w.cmple(world.max.as_dvec3()).all());
        }
        assert!(world_box(&transform, &Aabb::EMPTY).is_empty());
    }

    #[test]
    fn carried_rays_keep_their_parameter() {
        let transform = InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            DVec3::new(2.0, 2.0, -4.0),
            DQuat::from_rotation_y(0.5),
            DVec3::new(1.0, 2.0, 3.0),
        ))
        .unwrap();
        let instance = Instance::new(0, transform, 1, &Aabb::EMPTY);
        let ray = Ray::new(Vec3::new(0.5, -1.0, 2.0), Vec3::new(1.0, 0.25, -0.5));
        let local = instance.carry(&SceneRay::new(ray));
        let back = transform
            .affine()
            .transform_point3(local.at(3.0).as_dvec3());
        assert!((back - ray.at(3.0).as_dvec3()).length() < 1e-5);
    }
}
