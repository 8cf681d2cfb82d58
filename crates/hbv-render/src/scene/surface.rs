//! Hits turned into what shading needs: the point, the geometric and shading normals, the side.

use glam::{DMat3, Vec3};
use hbv::geometry::Ray;

use super::Scene;

/// A closest hit as a tracer found it, on the flattened scene or on the two-level one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// Barycentric coordinates of the hit in the triangle: `(1 − u − v) p0 + u p1 + v p2`.
    pub u: f32,
    pub v: f32,
    pub face: HitFace,
}

/// Which triangle a hit is on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HitFace {
    /// Face `face` of the flattened scene ([`super::FlatScene`]).
    Flat(u32),
    /// Triangle `prim` of the mesh of instance `instance`, as [`hbv::scene::SceneHit`] gives
    /// it, with its unit geometric normal in world space (`SceneHit::normal`).
    Instanced {
        instance: u32,
        prim: u32,
        normal: Vec3,
    },
}

/// A hit turned into what shading needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub position: Vec3,
    /// Unit geometric normal on the side the ray came from.
    pub geometric: Vec3,
    /// Shading normal on the same side.
    pub shading: Vec3,
    /// Whether the ray hit the front side (the side of `(p1 − p0) × (p2 − p0)` in world space).
    pub front: bool,
    /// The instance hit (its material is the surface's).
    pub instance: u32,
    /// The face's id in the flattened scene's numbering (`first_face` of the instance plus
    /// `prim`), the same whichever way the scene was traced.
    pub face: u64,
}

impl Scene {
    /// The surface at `hit` of `ray`: the point as the barycentric combination of the triangle's
    /// world-space vertices (closer to the surface than `o + t·d`), the geometric normal, and the
    /// shading normal: the face's for flat instances, for smooth ones the vertex normals
    /// interpolated at `(u, v)` and normalized. On an instance the point is the local one mapped
    /// by its transform, the normal `SceneHit::normal`, and each vertex normal `n` is carried as
    /// `normalize(cof(A) · n)` (`cof(A) = det(A) A^-T`, which maps a local `e1 × e2` to the world
    /// one, so mirrored instances keep their winding).
    pub fn surface(&self, ray: &Ray, hit: &SurfaceHit) -> SurfacePoint {
        let (u, v) = (hit.u, hit.v);
        let (position, face_normal, shading, instance, face) = match hit.face {
            HitFace::Flat(face) => {
                let flat = self
                    .flat()
                    .expect("a flat hit comes from the flattened scene");
                let [a, b, c] = flat.mesh.indices()[face as usize];
                let p = flat.mesh.positions();
                let (p0, p1, p2) = (p[a as usize], p[b as usize], p[c as usize]);
                let position = (1.0 - u - v) * p0 + u * p1 + v * p2;
                let normal = (p1 - p0).cross(p2 - p0).normalize();
                let instance = flat.face_instance[face as usize];
                let shading = if self.instances[instance as usize].smooth {
                    let n = &flat.vertex_normals;
                    interpolate([n[a as usize], n[b as usize], n[c as usize]], u, v, normal)
                } else {
                    normal
                };
                (position, normal, shading, instance, face as u64)
            }
            HitFace::Instanced {
                instance,
                prim,
                normal,
            } => {
                let placed = &self.instances[instance as usize];
                let mesh = &self.meshes[placed.mesh as usize];
                let [a, b, c] = mesh.mesh.indices()[prim as usize];
                let p = mesh.mesh.positions();
                let (u64, v64) = (f64::from(u), f64::from(v));
                let local = (1.0 - u64 - v64) * p[a as usize].as_dvec3()
                    + u64 * p[b as usize].as_dvec3()
                    + v64 * p[c as usize].as_dvec3();
                let affine = placed.transform.affine();
                let position = affine.transform_point3(local).as_vec3();
                let shading = if placed.smooth {
                    let cofactor = cofactor(&affine.matrix3);
                    let world = |i: u32| {
                        (cofactor * mesh.vertex_normals[i as usize].as_dvec3())
                            .normalize_or_zero()
                            .as_vec3()
                    };
                    interpolate([world(a), world(b), world(c)], u, v, normal)
                } else {
                    normal
                };
                (
                    position,
                    normal,
                    shading,
                    instance,
                    placed.first_face + prim as u64,
                )
            }
        };
        let front = face_normal.dot(ray.direction) < 0.0;
        let side = if front { 1.0 } else { -1.0 };
        SurfacePoint {
            position,
            geometric: face_normal * side,
            shading: shading * side,
            front,
            instance,
            face,
        }
    }
}

/// `normalize((1 − u − v) n0 + u n1 + v n2)`, or `fallback` where that is zero.
fn interpolate(n: [Vec3; 3], u: f32, v: f32, fallback: Vec3) -> Vec3 {
    ((1.0 - u - v) * n[0] + u * n[1] + v * n[2])
        .try_normalize()
        .unwrap_or(fallback)
}

/// `cof(A) = det(A) A^-T`, column by column: `(a1 × a2, a2 × a0, a0 × a1)`.
fn cofactor(a: &DMat3) -> DMat3 {
    DMat3::from_cols(
        a.y_axis.cross(a.z_axis),
        a.z_axis.cross(a.x_axis),
        a.x_axis.cross(a.y_axis),
    )
}
