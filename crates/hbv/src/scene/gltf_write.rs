//! Writing a [`Scene`] as a binary glTF 2.0 file (`.glb`) that [`Scene::load`] and other glTF
//! readers read back as the same scene, as `RAYS.md`'s "Scenes (glTF)" defines one.
//!
//! - **Meshes**: one glTF mesh per scene mesh, in [`MeshId`](super::MeshId) order, with one
//!   TRIANGLES primitive (float32 positions, uint32 indices), so `prim` keeps its meaning. A mesh
//!   without triangles gets a POINTS primitive instead (glTF accessors may not be empty), which
//!   scene readers ignore: its instances are placed but cannot be hit.
//! - **Instances**: one root node per instance id, in id order, so that ids survive the round
//!   trip. A removed instance is written as an instance of an empty mesh (never hit), keeping the
//!   ids after it. Masks are not part of glTF: a file's instances are seen by every ray.
//! - **Transforms**: glTF's numbers are read as float32 (by this crate's reader too), which is
//!   decimetres at UTM coordinates. So a node's matrix holds `A` and the float32 rounding error
//!   of the translation `b`, and its parent node holds the translation's float32 value: readers
//!   that multiply the node matrices in f64, as [`Scene::load`] does, recover `b` to about
//!   `2^-48 |b|`. Where `b` is a float32 triple, the parent is left out.
//!   A sheared `A` is written as is, though strict validators want matrices that are `T·R·S`.

use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::Path;

use glam::{DAffine3, DMat4, Vec3};

use super::instance::InstanceState;
use super::Scene;
use crate::atomic_file::{write_atomically, Replace};
use crate::mesh::TriangleMesh;

/// glTF's component types and modes, from the specification's tables.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const MODE_POINTS: u32 = 0;
const MODE_TRIANGLES: u32 = 4;

impl Scene {
    /// Writes the scene as a `.glb` file (module notes), atomically: a failed write leaves
    /// whatever was at `path`; with [`Replace::Never`] an existing file is refused. Errors name
    /// the path.
    pub fn write_gltf(&self, path: impl AsRef<Path>, replace: Replace) -> io::Result<()> {
        let bytes = self.to_glb();
        write_atomically(path.as_ref(), replace, |file| file.write_all(&bytes))
    }

    /// The scene as the bytes of a `.glb` file (see [`Scene::write_gltf`]).
    pub fn to_glb(&self) -> Vec<u8> {
        let mut glb = GlbWriter::default();
        for mesh in &self.meshes {
            glb.add_mesh(&mesh.mesh);
        }
        let empty_mesh = self.meshes.len();
        let mut empty_mesh_used = false;
        for instance in &self.instances {
            if instance.state == InstanceState::Removed {
                empty_mesh_used = true;
                glb.add_instance(empty_mesh, DAffine3::IDENTITY);
            } else {
                glb.add_instance(instance.mesh as usize, instance.transform.affine());
            }
        }
        if empty_mesh_used {
            glb.add_mesh(&TriangleMesh::default());
        }
        glb.finish()
    }
}

/// The JSON arrays and the binary buffer of a `.glb` file being written.
#[derive(Default)]
struct GlbWriter {
    buffer: Vec<u8>,
    buffer_views: Vec<String>,
    accessors: Vec<String>,
    meshes: Vec<String>,
    nodes: Vec<String>,
    /// The root nodes, in instance order.
    roots: Vec<usize>,
}

impl GlbWriter {
    /// Appends `bytes` to the buffer as a new buffer view (4-byte aligned) and returns its index.
    fn add_view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.buffer.len().is_multiple_of(4) {
            self.buffer.push(0);
        }
        let offset = self.buffer.len();
        self.buffer.extend_from_slice(bytes);
        self.buffer_views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{},"target":{target}}}"#,
            bytes.len()
        ));
        self.buffer_views.len() - 1
    }

    /// Adds `mesh` as a glTF mesh of one primitive (module notes).
    fn add_mesh(&mut self, mesh: &TriangleMesh) {
        // An accessor may not be empty: a mesh without vertices gets one at the origin.
        let positions: Vec<Vec3> = match mesh.positions() {
            [] => vec![Vec3::ZERO],
            p => p.to_vec(),
        };
        let (min, max) = positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        let bytes: Vec<u8> = positions
            .iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let view = self.add_view(&bytes, ARRAY_BUFFER);
        self.accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":{FLOAT},"count":{},"type":"VEC3","min":[{}],"max":[{}]}}"#,
            positions.len(),
            numbers(min.to_array().map(f64::from)),
            numbers(max.to_array().map(f64::from)),
        ));
        let position_accessor = self.accessors.len() - 1;
        let primitive = if mesh.indices().is_empty() {
            format!(r#"{{"attributes":{{"POSITION":{position_accessor}}},"mode":{MODE_POINTS}}}"#)
        } else {
            let bytes: Vec<u8> = mesh
                .indices()
                .iter()
                .flatten()
                .flat_map(|i| i.to_le_bytes())
                .collect();
            let view = self.add_view(&bytes, ELEMENT_ARRAY_BUFFER);
            self.accessors.push(format!(
                r#"{{"bufferView":{view},"componentType":{UNSIGNED_INT},"count":{},"type":"SCALAR"}}"#,
                mesh.indices().len() * 3
            ));
            format!(
                r#"{{"attributes":{{"POSITION":{position_accessor}}},"indices":{},"mode":{MODE_TRIANGLES}}}"#,
                self.accessors.len() - 1
            )
        };
        self.meshes
            .push(format!(r#"{{"primitives":[{primitive}]}}"#));
    }

    /// Adds a root node placing glTF mesh `mesh` by `affine`, split in two nodes where its
    /// translation is not a float32 triple (module notes).
    fn add_instance(&mut self, mesh: usize, affine: DAffine3) {
        let b = affine.translation;
        let rounded = b.as_vec3().as_dvec3();
        if rounded == b || !rounded.is_finite() {
            // The translation is exact in float32 (or cannot be split): one node.
            let cols = DMat4::from(affine).to_cols_array();
            self.nodes
                .push(format!(r#"{{"mesh":{mesh},"matrix":[{}]}}"#, numbers(cols)));
        } else {
            let child = DAffine3 {
                translation: b - rounded,
                ..affine
            };
            let cols = DMat4::from(child).to_cols_array();
            self.nodes
                .push(format!(r#"{{"mesh":{mesh},"matrix":[{}]}}"#, numbers(cols)));
            let child_index = self.nodes.len() - 1;
            self.nodes.push(format!(
                r#"{{"translation":[{}],"children":[{child_index}]}}"#,
                numbers(rounded.to_array())
            ));
        }
        self.roots.push(self.nodes.len() - 1);
    }

    /// The file: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
    fn finish(mut self) -> Vec<u8> {
        while !self.buffer.len().is_multiple_of(4) {
            self.buffer.push(0);
        }
        let roots = self.roots.iter().fold(String::new(), |mut s, r| {
            if !s.is_empty() {
                s.push(',');
            }
            let _ = write!(s, "{r}");
            s
        });
        let mut json = format!(
            r#"{{"asset":{{"version":"2.0","generator":"hbv {}"}},"scene":0,"scenes":[{{"nodes":[{roots}]}}],"nodes":[{}],"meshes":[{}],"accessors":[{}],"bufferViews":[{}],"buffers":[{{"byteLength":{}}}]}}"#,
            env!("CARGO_PKG_VERSION"),
            self.nodes.join(","),
            self.meshes.join(","),
            self.accessors.join(","),
            self.buffer_views.join(","),
            self.buffer.len(),
        )
        .into_bytes();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let total = 12 + 8 + json.len() + 8 + self.buffer.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(self.buffer.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.buffer);
        out
    }
}

/// Numbers as JSON, comma-separated, each the shortest text that reads back as the same f64.
fn numbers<const N: usize>(values: [f64; N]) -> String {
    values
        .iter()
        .map(|v| format!("{v:?}"))
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;
    use crate::mesh::procedural::icosphere;
    use crate::mesh::MeshFormat;
    use crate::scene::{InstanceTransform, SceneRay};
    use glam::{DQuat, DVec3};

    #[test]
    fn a_written_scene_reads_back_with_the_same_ids_and_answers() {
        let mut scene = Scene::new();
        let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
        let empty = scene.add_mesh(TriangleMesh::default());
        let far = DVec3::new(500_000.3, 5_000_000.7, 12.1);
        let transforms = [
            DAffine3::from_translation(DVec3::new(-3.0, 0.0, 0.0)),
            DAffine3::from_scale_rotation_translation(
                DVec3::new(-2.0, 1.0, 1.5),
                DQuat::from_rotation_y(0.7),
                DVec3::new(3.0, 0.5, 0.0),
            ),
            DAffine3::from_translation(far),
        ];
        for t in transforms {
            let t = InstanceTransform::new(t).unwrap();
            scene.add_instance(sphere, t, u32::MAX).unwrap();
        }
        scene
            .add_instance(empty, InstanceTransform::IDENTITY, u32::MAX)
            .unwrap();
        let gone = scene
            .add_instance(sphere, InstanceTransform::IDENTITY, u32::MAX)
            .unwrap();
        scene.remove_instance(gone).unwrap();
        scene.build();

        let bytes = scene.to_glb();
        let read =
            Scene::from_bytes(MeshFormat::Gltf, "written.glb", &bytes, Default::default()).unwrap();
        assert_eq!(read.instance_count(), scene.instance_count());
        for (id, t) in transforms.iter().enumerate() {
            let back = read.instances[id].transform.affine();
            assert!(back.matrix3.abs_diff_eq(t.matrix3, 1e-6), "instance {id}");
            let error = (back.translation - t.translation).abs().max_element();
            assert!(
                error <= 1e-9 * t.translation.abs().max_element().max(1.0),
                "{error}"
            );
        }
        assert_eq!(
            read.instance_bounds(crate::scene::InstanceId(4)),
            Some(crate::geometry::Aabb::EMPTY)
        );
        for target in [DVec3::new(-3.0, 0.0, 0.0), DVec3::new(3.0, 0.5, 0.0)] {
            let ray = SceneRay::new(Ray::new(
                (target + DVec3::new(0.1, 0.2, 10.0)).as_vec3(),
                -Vec3::Z,
            ));
            let (a, b) = (
                scene.intersect(&ray).unwrap(),
                read.intersect(&ray).unwrap(),
            );
            assert_eq!((a.instance, a.prim), (b.instance, b.prim));
            assert!((a.t - b.t).abs() < 1e-4);
        }
    }
}
