//! Scenes: meshes with materials, a camera, lights, and how to render them.
//!
//! Every object of a scene is merged into one [`TriangleMesh`], so one accelerator traces the
//! whole scene; per-triangle tables map a hit's primitive id back to its object and material.

mod cornell_box;
mod error;
mod file;
mod gltf_scene;
mod transform;

use glam::Vec3;
use hbv::TriangleMesh;

pub use error::SceneError;
pub use file::{load_scene, parse_scene};
pub use gltf_scene::load_gltf_scene;
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

/// A scene ready to render: one merged mesh, what each triangle is made of, camera and lights.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Every object's triangles, placed in the scene, in object order.
    pub mesh: TriangleMesh,
    /// Material (index into `materials`) of each triangle.
    pub triangle_material: Vec<u32>,
    /// Object (index into `objects`) of each triangle.
    pub triangle_object: Vec<u32>,
    /// Area-weighted vertex normals of the merged mesh (used by smooth objects).
    pub vertex_normals: Vec<Vec3>,
    pub objects: Vec<SceneObject>,
    pub materials: Vec<Material>,
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub settings: RenderSettings,
}

/// One entry of the scene: a named mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    pub name: String,
    /// Interpolate vertex normals across triangles (for curved surfaces); flat shading otherwise.
    pub smooth: bool,
    /// Its first triangle in the merged mesh, and how many it has.
    pub first_triangle: u32,
    pub triangle_count: u32,
}

impl Scene {
    /// The built-in Cornell box (see [`cornell_box`](Scene::cornell_box)'s module).
    pub fn cornell_box() -> Scene {
        cornell_box::cornell_box()
    }

    /// The shading normal at barycentric `(u, v)` of triangle `prim`: the interpolated vertex
    /// normal for smooth objects, the face normal otherwise (not yet facing any side).
    pub fn shading_normal(&self, prim: u32, u: f32, v: f32, face_normal: Vec3) -> Vec3 {
        let object = &self.objects[self.triangle_object[prim as usize] as usize];
        if !object.smooth {
            return face_normal;
        }
        let [a, b, c] = self.mesh.indices()[prim as usize];
        let n = (1.0 - u - v) * self.vertex_normals[a as usize]
            + u * self.vertex_normals[b as usize]
            + v * self.vertex_normals[c as usize];
        n.try_normalize().unwrap_or(face_normal)
    }
}

/// Collects objects into one mesh, then makes the [`Scene`].
#[derive(Default)]
pub struct SceneAssembly {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    triangle_material: Vec<u32>,
    triangle_object: Vec<u32>,
    objects: Vec<SceneObject>,
}

impl SceneAssembly {
    /// Appends `mesh`, placed by `transform`, made of material `material`. Fails (adding
    /// nothing) when the placement overflows `f32` or the scene would exceed `u32` ids.
    pub fn add(
        &mut self,
        name: impl Into<String>,
        mesh: &TriangleMesh,
        transform: &Transform,
        material: u32,
        smooth: bool,
    ) -> Result<(), &'static str> {
        let affine = transform.to_affine();
        let placed: Vec<Vec3> = mesh
            .positions()
            .iter()
            .map(|&p| affine.transform_point3(p))
            .collect();
        if placed.iter().any(|p| !p.is_finite()) {
            return Err("the transform takes coordinates out of the range of f32");
        }
        if self.positions.len() + placed.len() > u32::MAX as usize
            || self.indices.len() + mesh.triangle_count() > u32::MAX as usize
        {
            return Err("the scene has more than 2^32 vertices or triangles");
        }
        let base = self.positions.len() as u32;
        let object = self.objects.len() as u32;
        self.positions.extend(placed);
        self.indices.extend(
            mesh.indices()
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
        let n = mesh.triangle_count();
        self.triangle_material
            .extend(std::iter::repeat_n(material, n));
        self.triangle_object.extend(std::iter::repeat_n(object, n));
        self.objects.push(SceneObject {
            name: name.into(),
            smooth,
            first_triangle: self.triangle_object.len() as u32 - n as u32,
            triangle_count: n as u32,
        });
        Ok(())
    }

    /// Triangles added so far.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// The scene of the objects added.
    pub fn finish(
        self,
        materials: Vec<Material>,
        camera: Camera,
        lights: Vec<Light>,
        settings: RenderSettings,
    ) -> Scene {
        let vertex_normals = area_weighted_normals(&self.positions, &self.indices);
        let mesh = TriangleMesh::new(self.positions, self.indices)
            .expect("placed meshes keep finite positions and valid indices");
        Scene {
            mesh,
            triangle_material: self.triangle_material,
            triangle_object: self.triangle_object,
            vertex_normals,
            objects: self.objects,
            materials,
            camera,
            lights,
            settings,
        }
    }
}

/// Vertex normals as the sum of the adjacent faces' `(p1 − p0) × (p2 − p0)` (area weighting,
/// Gouraud 1971), normalized; zero for vertices of degenerate triangles only.
fn area_weighted_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
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
