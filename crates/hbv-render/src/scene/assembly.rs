//! Collecting meshes and the instances that place them, then making the [`Scene`].

use glam::{DAffine3, DVec3, Vec3};
use hbv::geometry::Aabb;
use hbv::scene::InstanceTransform;
use hbv::TriangleMesh;

use super::{RenderSettings, Scene, SceneInstance, SceneMesh, Transform};
use crate::camera::Camera;
use crate::light::Light;
use crate::material::Material;

/// Collects meshes (each kept once) and instances, then makes the [`Scene`].
#[derive(Default)]
pub struct SceneAssembly {
    meshes: Vec<SceneMesh>,
    instances: Vec<SceneInstance>,
    /// Triangles of every instance so far: the next instance's first face.
    faces: u64,
}

impl SceneAssembly {
    /// Adds `mesh` (in its own coordinates) once; instances place it by the index returned.
    pub fn add_mesh(&mut self, name: impl Into<String>, mesh: TriangleMesh) -> u32 {
        let vertex_normals = area_weighted_normals(mesh.positions(), mesh.indices());
        self.meshes.push(SceneMesh {
            name: name.into(),
            mesh,
            vertex_normals,
        });
        self.meshes.len() as u32 - 1
    }

    /// Places mesh `mesh` by `affine` (`world = A · local + b`), made of material `material`.
    /// Fails (adding nothing) for a transform that is not finite or not invertible (the rule of
    /// [`InstanceTransform::new`]), one that takes the mesh's box out of the range of `f32`, or
    /// past `u32` instance ids. Panics for a mesh index this assembly did not hand out.
    pub fn add_instance(
        &mut self,
        mesh: u32,
        affine: DAffine3,
        material: u32,
        smooth: bool,
    ) -> Result<(), String> {
        let transform = InstanceTransform::new(affine).map_err(|e| e.to_string())?;
        let placed = &self.meshes[mesh as usize].mesh;
        let world = world_box(&transform, &placed.bounds());
        if !(world.is_empty() || (world.min.is_finite() && world.max.is_finite())) {
            return Err("the transform takes coordinates out of the range of f32".into());
        }
        if self.instances.len() >= u32::MAX as usize {
            return Err("the scene has more than 2^32 instances".into());
        }
        self.instances.push(SceneInstance {
            mesh,
            material,
            smooth,
            transform,
            first_face: self.faces,
        });
        self.faces += placed.triangle_count() as u64;
        Ok(())
    }

    /// Adds `mesh` and one instance placing it by `transform` (a mesh used once).
    pub fn add(
        &mut self,
        name: impl Into<String>,
        mesh: &TriangleMesh,
        transform: &Transform,
        material: u32,
        smooth: bool,
    ) -> Result<(), String> {
        let id = self.add_mesh(name, mesh.clone());
        self.add_instance(id, transform.to_daffine(), material, smooth)
            .inspect_err(|_| {
                self.meshes.pop();
            })
    }

    /// Triangles of every instance added so far (as seen).
    pub fn triangle_count(&self) -> u64 {
        self.faces
    }

    /// The scene of the meshes and instances added.
    pub fn finish(
        self,
        materials: Vec<Material>,
        camera: Camera,
        lights: Vec<Light>,
        settings: RenderSettings,
    ) -> Scene {
        Scene {
            meshes: self.meshes,
            instances: self.instances,
            materials,
            camera,
            lights,
            settings,
            flat: Default::default(),
        }
    }
}

/// The box of a mesh whose own box is `mesh_box`, placed by `transform`: its eight corners
/// mapped in f64 and rounded to f32 (an empty box stays empty).
pub(super) fn world_box(transform: &InstanceTransform, mesh_box: &Aabb) -> Aabb {
    if mesh_box.is_empty() {
        return Aabb::EMPTY;
    }
    let affine = transform.affine();
    let (lo, hi) = (mesh_box.min.as_dvec3(), mesh_box.max.as_dvec3());
    let corners: Vec<Vec3> = (0..8)
        .map(|k| {
            let pick = |bit: usize, l: f64, h: f64| if k & bit == 0 { l } else { h };
            let c = DVec3::new(
                pick(1, lo.x, hi.x),
                pick(2, lo.y, hi.y),
                pick(4, lo.z, hi.z),
            );
            affine.transform_point3(c).as_vec3()
        })
        .collect();
    Aabb::from_points(&corners)
}

/// Vertex normals as the sum of the adjacent faces' `(p1 − p0) × (p2 − p0)` (area weighting,
/// Gouraud 1971), normalized; zero for vertices of degenerate triangles only.
pub(super) fn area_weighted_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in indices {
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        let n = (pb - pa).cross(pc - pa);
        for i in [a, b, c] {
            normals[i as usize] += n;
        }
    }
    normals
        .into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::ZERO))
        .collect()
}
