//! Scenes: meshes placed by instances with materials, a camera, lights, and how to render them.
//!
//! A scene keeps each mesh once, in its own coordinates, and places it by any number of
//! instances (an affine map in f64, a material, flat or smooth shading). It is traced either as
//! a two-level [`hbv::scene::Scene`] ([`Scene::two_level`]: each mesh's BVH built once, a top
//! level over the instances) or flattened ([`Scene::flat`]: every instance's triangles copied
//! into one world-space [`TriangleMesh`], for any [`hbv::Accelerator`]). Hits of either are
//! turned into shading geometry by [`Scene::surface`].

mod assembly;
mod cornell_box;
mod error;
mod file;
mod flat;
mod gltf_scene;
mod instance_entry;
mod surface;
mod transform;
mod two_level;

use std::sync::OnceLock;

use glam::Vec3;
use hbv::geometry::Aabb;
use hbv::scene::InstanceTransform;
use hbv::TriangleMesh;

pub use assembly::SceneAssembly;
pub use error::SceneError;
pub use file::{load_scene, parse_scene};
pub use flat::FlatScene;
pub use gltf_scene::load_gltf_scene;
pub use surface::{HitFace, SurfaceHit, SurfacePoint};
pub use transform::Transform;

use crate::camera::Camera;
use crate::light::Light;
use crate::material::Material;

/// How a scene asks to be rendered; the command line may override each field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples (primary rays) per pixel.
    pub spp: u32,
    /// Most bounces of reflected and transmitted rays after the primary ray.
    pub max_depth: u32,
    /// Radiance of rays that leave the scene.
    pub background: Vec3,
    /// Constant light added to diffuse and Phong surfaces (`ambient · albedo`), standing in for
    /// the indirect light a Whitted tracer does not compute.
    pub ambient: Vec3,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 480,
            spp: 1,
            max_depth: 5,
            background: Vec3::ZERO,
            ambient: Vec3::ZERO,
        }
    }
}

/// A scene ready to render: meshes, the instances placing them, materials, camera and lights.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Each mesh once, in its own coordinates.
    pub meshes: Vec<SceneMesh>,
    /// The placed copies of the meshes, in the order of their ids (`SceneHit::instance`).
    pub instances: Vec<SceneInstance>,
    pub materials: Vec<Material>,
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub settings: RenderSettings,
    /// The flattened scene, made on first use ([`Scene::flat`]).
    flat: OnceLock<Result<FlatScene, String>>,
}

/// A mesh of the scene, in its own coordinates.
#[derive(Clone, Debug)]
pub struct SceneMesh {
    pub name: String,
    pub mesh: TriangleMesh,
    /// Area-weighted vertex normals (used by smooth instances).
    pub vertex_normals: Vec<Vec3>,
}

/// One placed copy of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneInstance {
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Interpolate vertex normals across triangles (for curved surfaces); flat shading otherwise.
    pub smooth: bool,
    /// `world = A · local + b`, checked (finite, invertible) and kept in f64.
    pub transform: InstanceTransform,
    /// The flattened scene's id of this instance's first triangle: instances' triangles follow
    /// each other in instance order.
    pub first_face: u64,
}

impl Scene {
    /// The built-in Cornell box (see [`cornell_box`](Scene::cornell_box)'s module).
    pub fn cornell_box() -> Scene {
        cornell_box::cornell_box()
    }

    /// Triangles as seen: every instance's triangles, shared meshes counted once per instance.
    pub fn triangle_count(&self) -> u64 {
        self.instances.last().map_or(0, |i| {
            i.first_face + self.meshes[i.mesh as usize].mesh.triangle_count() as u64
        })
    }

    /// Triangles as stored: each mesh's once.
    pub fn stored_triangle_count(&self) -> u64 {
        self.meshes
            .iter()
            .map(|m| m.mesh.triangle_count() as u64)
            .sum()
    }

    /// Whether some mesh is placed by more than one instance.
    pub fn shares_meshes(&self) -> bool {
        let mut uses = vec![0u32; self.meshes.len()];
        self.instances.iter().any(|i| {
            uses[i.mesh as usize] += 1;
            uses[i.mesh as usize] > 1
        })
    }

    /// A box holding every instance's world-space vertices (each mesh's box mapped in f64 and
    /// rounded outwards).
    pub fn bounds(&self) -> Aabb {
        self.instances.iter().fold(Aabb::EMPTY, |b, i| {
            b.union(&assembly::world_box(
                &i.transform,
                &self.meshes[i.mesh as usize].mesh.bounds(),
            ))
        })
    }

    /// The scene flattened into one world-space mesh, made on first use and kept; an error when
    /// it would exceed `u32` vertex or triangle ids.
    pub fn flat(&self) -> Result<&FlatScene, String> {
        self.flat
            .get_or_init(|| FlatScene::new(self))
            .as_ref()
            .map_err(Clone::clone)
    }

    /// The flattened scene's mesh (see [`Scene::flat`]). Panics when the scene is too large to
    /// flatten: for scenes known to be small (the built-in ones, tests).
    pub fn flat_mesh(&self) -> &TriangleMesh {
        &self
            .flat()
            .unwrap_or_else(|e| panic!("the scene cannot be flattened: {e}"))
            .mesh
    }

    /// The material of a hit's instance.
    pub fn material_of(&self, instance: u32) -> &Material {
        &self.materials[self.instances[instance as usize].material as usize]
    }
}
