//! glTF 2.0 files as whole scenes: their meshes with their materials, their camera and their
//! `KHR_lights_punctual` lights, rendered as the file describes them.
//!
//! Materials map onto the Whitted models: `KHR_materials_transmission` (factor ≥ 0.5) is glass of
//! the `KHR_materials_ior` index (default 1.5); metallic ≥ 0.9 with roughness ≤ 0.1 is a mirror of
//! the base colour; anything else is Phong with the base colour, a specular lobe whose exponent
//! falls with roughness (`2/r⁴ − 2`, the Blinn–Beckmann correspondence of Walter et al. 2007,
//! capped at 1000). Spot lights are treated as point lights (their cone is ignored). Intensities
//! are taken as given (candela, lux) as radiometric units.

use std::path::Path;

use std::collections::HashMap;

use glam::{DAffine3, DMat4, Vec3};
use hbv::TriangleMesh;

use super::{RenderSettings, Scene, SceneAssembly, SceneError};
use crate::camera::Camera;
use crate::light::Light;
use crate::material::{Material, Surface};

/// Reads a `.gltf` or `.glb` file as a scene (see the module's documentation). Without a camera
/// the scene is seen from +z, framing its bounds; without lights it gets one directional light
/// from above and behind the viewer.
pub fn load_gltf_scene(path: &Path) -> Result<Scene, SceneError> {
    let error = |place: &str, reason: String| SceneError::Gltf {
        file: path.to_path_buf(),
        place: place.to_string(),
        reason,
    };
    // Read and checked as hbv's mesh loader reads a glTF mesh (`gltf::import` read a buffer URI
    // of /dev/zero for ever, and its accessor reader panicked on short strides).
    let (document, buffers) =
        hbv::mesh::read_gltf(path).map_err(|e| SceneError::GltfFile(Box::new(e)))?;
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| error("scenes", "the file has no scene".into()))?;

    let mut materials: Vec<Material> = document
        .materials()
        .map(|m| {
            let place = format!("material {}", m.index().map_or(-1, |i| i as i64));
            material(&m).map_err(|reason| error(&place, reason))
        })
        .collect::<Result<_, _>>()?;
    let default_material = materials.len() as u32;
    materials.push(Material::default_diffuse());

    let mut assembly = SceneAssembly::default();
    // Each primitive of each glTF mesh becomes one mesh of the scene, made the first time a
    // node uses it; every node using it adds an instance.
    let mut primitive_meshes: HashMap<(usize, usize), u32> = HashMap::new();
    let mut camera = None;
    let mut lights = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> =
        gltf_scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world64 = parent * DMat4::from_cols_array_2d(&local);
        let world = world64.as_mat4();
        let place = format!("node {}", node.index());
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                if primitive.mode() != gltf::mesh::Mode::Triangles {
                    continue; // points and lines have no surface to hit
                }
                let key = (mesh.index(), primitive.index());
                let id = match primitive_meshes.get(&key) {
                    Some(&id) => id,
                    None => {
                        let triangles = primitive_mesh(&primitive, &buffers)
                            .map_err(|reason| error(&place, reason))?;
                        let name = mesh.name().unwrap_or("mesh").to_string();
                        let id = assembly.add_mesh(name, triangles);
                        primitive_meshes.insert(key, id);
                        id
                    }
                };
                let m = primitive
                    .material()
                    .index()
                    .map_or(default_material, |i| i as u32);
                assembly
                    .add_instance(id, DAffine3::from_mat4(world64), m, has_normals(&primitive))
                    .map_err(|reason| error(&place, reason))?;
            }
        }
        if let (None, Some(c)) = (&camera, node.camera()) {
            if let gltf::camera::Projection::Perspective(p) = c.projection() {
                let position = world.transform_point3(Vec3::ZERO);
                let found = Camera {
                    position,
                    look_at: position + world.transform_vector3(-Vec3::Z),
                    up: world.transform_vector3(Vec3::Y),
                    fov_y_degrees: p.yfov().to_degrees(),
                };
                // As a TOML scene's camera is checked (a zero yfov, or a node scaled to 0).
                if let Some(problem) = found.frame_error() {
                    return Err(error(&place, format!("camera {}: {problem}", c.index())));
                }
                camera = Some(found);
            }
        }
        if let Some(light) = node.light() {
            let power = Vec3::from(light.color()) * light.intensity();
            if !(power.is_finite() && power.min_element() >= 0.0) {
                return Err(error(
                    &place,
                    format!(
                        "light {}: color times intensity must be finite and not negative, got {power}",
                        light.index()
                    ),
                ));
            }
            lights.push(match light.kind() {
                gltf::khr_lights_punctual::Kind::Directional => Light::Directional {
                    direction: world
                        .transform_vector3(-Vec3::Z)
                        .try_normalize()
                        .unwrap_or(-Vec3::Y),
                    irradiance: power,
                },
                _ => Light::Point {
                    position: world.transform_point3(Vec3::ZERO),
                    intensity: power,
                },
            });
        }
        stack.extend(node.children().map(|c| (c, world64)));
    }
    if assembly.triangle_count() == 0 {
        return Err(error("meshes", "the scene has no triangles".into()));
    }
    let settings = RenderSettings {
        ambient: Vec3::splat(0.03),
        ..RenderSettings::default()
    };
    let mut scene = assembly.finish(materials, Camera::default_for_bounds(), lights, settings);
    let bounds = scene.bounds();
    let (centre, radius) = (
        (bounds.min + bounds.max) / 2.0,
        ((bounds.max - bounds.min).length() / 2.0).max(1e-6),
    );
    scene.camera = match camera {
        Some(c) => c,
        None => Camera {
            position: centre + Vec3::new(0.0, 0.3 * radius, 2.6 * radius),
            look_at: centre,
            up: Vec3::Y,
            fov_y_degrees: 45.0,
        },
    };
    if scene.lights.is_empty() {
        scene.lights.push(Light::Directional {
            direction: Vec3::new(-0.3, -1.0, -0.5).normalize(),
            irradiance: Vec3::splat(2.5),
        });
    }
    Ok(scene)
}

/// A primitive's triangles in its mesh's own coordinates.
fn primitive_mesh(
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
) -> Result<TriangleMesh, String> {
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or("a primitive has no POSITION")?
        .map(Vec3::from)
        .collect();
    let flat: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    let indices = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    TriangleMesh::new(positions, indices).map_err(|e| e.to_string())
}

/// Smooth shading when the file gives vertex normals (we interpolate our own, area-weighted).
fn has_normals(primitive: &gltf::Primitive) -> bool {
    primitive.get(&gltf::Semantic::Normals).is_some()
}

/// The Whitted material of a glTF material; an error for a non-finite or negative colour or
/// emission, or an index of refraction that is not a positive number (as a TOML scene's).
fn material(m: &gltf::Material) -> Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    let base = Vec3::new(r, g, b);
    let emission = Vec3::from(m.emissive_factor());
    for (name, v) in [("baseColorFactor", base), ("emissiveFactor", emission)] {
        if !(v.is_finite() && v.min_element() >= 0.0) {
            return Err(format!("{name} must be finite and not negative, got {v}"));
        }
    }
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let surface = if transmission >= 0.5 {
        let ior = m.ior().unwrap_or(1.5);
        if !(ior.is_finite() && ior > 0.0) {
            return Err(format!("ior must be a number > 0, got {ior}"));
        }
        Surface::Glass { ior, tint: base }
    } else if pbr.metallic_factor() >= 0.9 && roughness <= 0.1 {
        Surface::Mirror { reflectance: base }
    } else {
        let exponent = (2.0 / roughness.max(0.05).powi(4) - 2.0).clamp(0.0, 1000.0);
        Surface::Phong {
            albedo: base * (1.0 - pbr.metallic_factor().clamp(0.0, 1.0)),
            specular: Vec3::splat(0.04).lerp(base, pbr.metallic_factor().clamp(0.0, 1.0)),
            exponent,
        }
    };
    Ok(Material { surface, emission })
}
