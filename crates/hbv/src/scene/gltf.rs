//! Scene files: a glTF 2.0 file (`.gltf`, `.glb`) as a [`Scene`] of instances, as
//! `RAYS.md`'s "Scenes (glTF)" defines it; any other mesh file as a scene of one instance.
//!
//! - **Instances** are the nodes of the default scene (else scene 0) that carry a mesh, in
//!   depth-first pre-order (roots in the scene's order, children in order); instance ids count
//!   from 0 in that order. A file without any scene places each of its meshes once, untransformed
//!   (as [`TriangleMesh::load`] flattens it).
//! - **Transforms** are the products of the node matrices from the root down, `M_root ··· M_i`,
//!   in f64: a node's `matrix`, else `T · R · S` from its `translation`, `rotation` and `scale`.
//!   Each node's own matrix must be finite and each product a valid [`InstanceTransform`].
//! - **Meshes**: a glTF mesh's triangles are those of its TRIANGLES (mode 4) primitives,
//!   concatenated in primitive order (`prim` is the index in that concatenation); other modes are
//!   ignored. A glTF mesh placed by several nodes is added once (one BVH) and instanced.
//!
//! The nodes are walked and the primitives read by the flattened loader's code
//! (`mesh/gltf.rs`), so both accept and refuse the same files, and [`Scene::flattened`] of a
//! file whose meshes have TRIANGLES primitives only is [`TriangleMesh::load`]'s mesh of it,
//! triangle for triangle, within the f32 rounding of the transforms (the loader multiplies
//! the node matrices in f32, the scene in f64).

use std::path::Path;

use glam::{DMat4, DQuat, DVec3, Mat4};
use gltf::scene::Transform;
use gltf::Node;

use super::{InstanceTransform, MeshId, Scene, SceneStructure};
use crate::mesh::gltf::{
    document_and_buffers, walk_default_scene, MeshParts, PrimitiveReader, TriangleModes,
};
use crate::mesh::{folder_of, read_mesh_file, MeshError, MeshFormat, TriangleMesh};

/// The mask of every instance a scene file places: seen by every ray.
const EVERY_RAY: u32 = u32::MAX;

impl Scene {
    /// Loads a scene file, its meshes built and laid out as [`SceneStructure::default`] says.
    /// See [`Scene::load_with_structure`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, MeshError> {
        Self::load_with_structure(path, SceneStructure::default())
    }

    /// Loads a scene file, choosing the reader by the file's extension, and builds it: a glTF
    /// file (`.gltf`, `.glb`) gives its nodes as instances (module notes); an OBJ or PLY file
    /// gives one instance (id 0, identity) of its mesh. Every instance's mask is all bits.
    ///
    /// Errors name the file, the place in it (node, mesh, primitive, accessor, buffer) and the
    /// reason: those of [`TriangleMesh::load`], and for glTF a node whose own matrix is not
    /// finite, or whose world transform is singular or projective ([`InstanceTransform::new`]).
    pub fn load_with_structure(
        path: impl AsRef<Path>,
        structure: SceneStructure,
    ) -> Result<Self, MeshError> {
        let path = path.as_ref();
        match MeshFormat::from_path(path) {
            Some(MeshFormat::Gltf) => {
                let bytes = read_mesh_file(path)?;
                parse(path, &bytes, Some(folder_of(path)), structure)
            }
            _ => Ok(one_instance(TriangleMesh::load(path)?, structure)),
        }
    }

    /// Parses a scene held in memory, as [`Scene::load_with_structure`] reads a file of that
    /// format. `name` is only used in error messages. Never touches the file system: a glTF
    /// buffer stored in another file is an error.
    pub fn from_bytes(
        format: MeshFormat,
        name: impl AsRef<Path>,
        bytes: &[u8],
        structure: SceneStructure,
    ) -> Result<Self, MeshError> {
        let name = name.as_ref();
        match format {
            MeshFormat::Gltf => parse(name, bytes, None, structure),
            _ => Ok(one_instance(
                TriangleMesh::from_bytes(format, name, bytes)?,
                structure,
            )),
        }
    }
}

/// The scene of one instance of `mesh`: id 0, identity, every mask bit.
fn one_instance(mesh: TriangleMesh, structure: SceneStructure) -> Scene {
    let mut scene = Scene::with_structure(structure);
    let mesh = scene.add_mesh(mesh);
    scene
        .add_instance(mesh, InstanceTransform::IDENTITY, EVERY_RAY)
        .expect("the mesh was just added");
    scene.build();
    scene
}

/// Parses the bytes of a `.gltf` or `.glb` file (`path` names it in errors) as a scene; buffers
/// in other files are read from `folder`, and are an error without one.
fn parse(
    path: &Path,
    bytes: &[u8],
    folder: Option<&Path>,
    structure: SceneStructure,
) -> Result<Scene, MeshError> {
    let (document, buffers) = document_and_buffers(path, bytes, folder)?;
    let reader = PrimitiveReader::new(path, &buffers);
    let mut scene = Scene::with_structure(structure);
    // glTF mesh index -> the scene's mesh, added the first time a node places it.
    let mut added: Vec<Option<MeshId>> = vec![None; document.meshes().len()];
    let mut triangles = 0;
    walk_default_scene(
        path,
        &document,
        DMat4::IDENTITY,
        |parent, node| Ok(*parent * node_matrix(path, node)?),
        |node, mesh, world| {
            let mesh_id = match added[mesh.index()] {
                Some(id) => id,
                None => {
                    let mut parts = MeshParts::default();
                    reader.append_mesh(
                        &mesh,
                        &Mat4::IDENTITY,
                        TriangleModes::TrianglesOnly,
                        &mut parts,
                    )?;
                    let triangle_mesh =
                        TriangleMesh::from_parts(path.into(), parts.positions, parts.triangles)
                            .map_err(|e| in_mesh(e, mesh.index()))?;
                    let id = scene.add_mesh(triangle_mesh);
                    added[mesh.index()] = Some(id);
                    id
                }
            };
            let transform = InstanceTransform::from_mat4(*world).map_err(|e| {
                let node = node.map_or(String::from("file"), |n| format!("node {}", n.index()));
                MeshError::invalid(
                    path,
                    node,
                    format!(
                        "the world transform of mesh {} (the product of the node matrices from \
                         the root down) is refused: {e}",
                        mesh.index()
                    ),
                )
            })?;
            let instance_mesh = scene.mesh(mesh_id).expect("added above");
            triangles += instance_mesh.triangle_count();
            scene
                .add_instance(mesh_id, transform, EVERY_RAY)
                .expect("the mesh was added above");
            Ok(())
        },
    )?;
    if triangles == 0 {
        return Err(MeshError::invalid(
            path,
            "file",
            "no triangles (the scene has no triangle primitives)",
        ));
    }
    scene.build();
    Ok(scene)
}

/// `error` (about a vertex or face of a mesh being built) with the glTF mesh named in its place.
fn in_mesh(error: MeshError, mesh: usize) -> MeshError {
    match error {
        MeshError::Invalid {
            source_name,
            place,
            reason,
        } => MeshError::invalid(source_name, format!("mesh {mesh} {place}"), reason),
        other => other,
    }
}

/// A node's own matrix in f64: its `matrix`, else `T · R · S`. Refused, naming the node, when
/// an entry is not finite (a number beyond f32's range in the file).
fn node_matrix(path: &Path, node: &Node<'_>) -> Result<DMat4, MeshError> {
    let matrix = match node.transform() {
        Transform::Matrix { matrix } => {
            DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)))
        }
        Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let [x, y, z, w] = rotation.map(f64::from);
            // The quaternion is used as given (the `gltf` crate's matrix does the same): a file's
            // rotations are unit to f32 precision only.
            DMat4::from_translation(DVec3::from_array(translation.map(f64::from)))
                * DMat4::from_quat(DQuat::from_xyzw(x, y, z, w))
                * DMat4::from_scale(DVec3::from_array(scale.map(f64::from)))
        }
    };
    if !matrix.is_finite() {
        return Err(MeshError::invalid(
            path,
            format!("node {}", node.index()),
            format!(
                "the node's transform has an entry that is not finite: {:?}",
                matrix.to_cols_array()
            ),
        ));
    }
    Ok(matrix)
}
