//! The flattened scene: every instance's triangles copied into one world-space mesh, for the
//! single-mesh accelerators (any BVH layout, the uniform grid) and their object caches.

use glam::Vec3;
use hbv::TriangleMesh;

use super::assembly::area_weighted_normals;
use super::Scene;

/// Every instance's triangles in world space, instance after instance (instance `i`'s triangle
/// `p` is face `first_face[i] + p`), with the tables that map a face back to its instance.
#[derive(Clone, Debug)]
pub struct FlatScene {
    pub mesh: TriangleMesh,
    /// Area-weighted vertex normals of the world-space mesh (used by smooth instances).
    pub vertex_normals: Vec<Vec3>,
    /// The instance of each face.
    pub face_instance: Vec<u32>,
}

impl FlatScene {
    /// Maps each instance's vertices by its transform (in f64, rounded to f32). Fails when the
    /// scene has more than `2^32` vertices or triangles as seen.
    pub fn new(scene: &Scene) -> Result<FlatScene, String> {
        let (mut vertices, mut faces) = (0u64, 0u64);
        for i in &scene.instances {
            let mesh = &scene.meshes[i.mesh as usize].mesh;
            vertices += mesh.positions().len() as u64;
            faces += mesh.triangle_count() as u64;
        }
        if vertices > u32::MAX as u64 || faces > u32::MAX as u64 {
            return Err(format!(
                "flattened, the scene has {vertices} vertices and {faces} triangles: more than \
                 2^32 (trace it as a two-level scene)"
            ));
        }
        let mut positions = Vec::with_capacity(vertices as usize);
        let mut indices = Vec::with_capacity(faces as usize);
        let mut face_instance = Vec::with_capacity(faces as usize);
        for (id, instance) in scene.instances.iter().enumerate() {
            let mesh = &scene.meshes[instance.mesh as usize].mesh;
            let affine = instance.transform.affine();
            let base = positions.len() as u32;
            positions.extend(
                mesh.positions()
                    .iter()
                    .map(|p| affine.transform_point3(p.as_dvec3()).as_vec3()),
            );
            indices.extend(
                mesh.indices()
                    .iter()
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
            face_instance.extend(std::iter::repeat_n(id as u32, mesh.triangle_count()));
        }
        let vertex_normals = area_weighted_normals(&positions, &indices);
        let mesh = TriangleMesh::new(positions, indices).map_err(|e| e.to_string())?;
        Ok(FlatScene {
            mesh,
            vertex_normals,
            face_instance,
        })
    }
}
