//! `FlattenedScene`: the scene as one world-space mesh, and the brute force over it that the
//! scene's property tests compare against.

use glam::{DVec3, Vec3};

use super::{SceneHit, SceneRay};
use crate::geometry::{PreparedRay, Triangle};
use crate::mesh::{MeshError, TriangleMesh};

/// The scene's triangles in world space, instance by instance: instance 0's triangles, then
/// instance 1's, …; face `offsets[i] + prim` is triangle `prim` of instance `i`'s mesh, its
/// vertices mapped by the instance's transform in f64 and rounded to the nearest f32.
#[derive(Clone, Debug)]
pub struct FlattenedScene {
    pub mesh: TriangleMesh,
    /// `offsets[i]`: the first face of instance `i`; one more entry than instances, the last
    /// being the number of faces.
    pub offsets: Vec<u32>,
    /// Each instance's mask.
    pub masks: Vec<u32>,
}

impl FlattenedScene {
    /// Flattens `(mesh, transform, mask)` triples, in instance order; `None` is a removed
    /// instance, a hole of no faces and mask 0, so that the others keep their ids. Fails when a
    /// mapped vertex does not fit in f32.
    pub(crate) fn new<'a>(
        instances: impl IntoIterator<Item = Option<(&'a TriangleMesh, glam::DAffine3, u32)>>,
    ) -> Result<Self, MeshError> {
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        let (mut offsets, mut masks) = (vec![0u32], Vec::new());
        for instance in instances {
            let Some((mesh, affine, mask)) = instance else {
                offsets.push(indices.len() as u32);
                masks.push(0);
                continue;
            };
            let base = positions.len() as u32;
            positions.extend(
                mesh.positions()
                    .iter()
                    .map(|p| affine.transform_point3(p.as_dvec3()).as_vec3()),
            );
            indices.extend(mesh.indices().iter().map(|f| f.map(|v| v + base)));
            offsets.push(indices.len() as u32);
            masks.push(mask);
        }
        Ok(Self {
            mesh: TriangleMesh::new(positions, indices)?,
            offsets,
            masks,
        })
    }

    /// The instance whose faces include `face`, and the face's `prim` within it.
    pub fn instance_of(&self, face: u32) -> (u32, u32) {
        // The last offset not above `face`: holes (equal offsets) are passed over.
        let instance = self.offsets.partition_point(|&o| o <= face) - 1;
        (instance as u32, face - self.offsets[instance])
    }

    /// The closest hit by testing every triangle of every instance the ray sees, in face order,
    /// ties to the smaller face (so to the smaller instance, then the smaller `prim`). The
    /// normal is `normalize(cross(p1 - p0, p2 - p0))` of the stored (rounded) world vertices.
    pub fn intersect(&self, ray: &SceneRay) -> Option<SceneHit> {
        if !ray.ray.is_valid() {
            return None;
        }
        let mut prepared = PreparedRay::new(&ray.ray);
        let mut best: Option<SceneHit> = None;
        for (instance, faces) in self.offsets.windows(2).enumerate() {
            if !ray.sees(self.masks[instance]) {
                continue;
            }
            for face in faces[0]..faces[1] {
                let triangle = self.mesh.triangle(face as usize);
                if triangle.is_degenerate() {
                    continue;
                }
                let Some(h) = triangle.intersect(&prepared) else {
                    continue;
                };
                let prim = face - faces[0];
                if SceneHit::is_closer(h.t, instance as u32, prim, &best) {
                    prepared.tmax = h.t;
                    best = Some(SceneHit {
                        t: h.t,
                        u: h.u,
                        v: h.v,
                        prim,
                        instance: instance as u32,
                        normal: unit_normal(&triangle),
                    });
                }
            }
        }
        best
    }

    /// Whether any triangle of an instance the ray sees is hit.
    pub fn occluded(&self, ray: &SceneRay) -> bool {
        self.intersect(ray).is_some()
    }
}

/// `normalize(cross(p1 - p0, p2 - p0))` in f64, rounded to f32.
fn unit_normal(triangle: &Triangle) -> Vec3 {
    let n: DVec3 = triangle.scaled_normal();
    n.normalize_or_zero().as_vec3()
}
