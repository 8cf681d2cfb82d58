//! Writing `.hbv` scene files (layout in `scene_format.rs`).

use std::borrow::Cow;
use std::io::{self, Write};

use super::scene_format::{origin_to_bytes, SceneHeader, StoredInstance, StoredStructure};
use super::write::{write, MeshParts};
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// One mesh of a scene being saved: the mesh, its tree (the scene's own, or one built for the
/// save and dropped once written) and its settings line.
pub(crate) struct SceneMeshParts<'a> {
    pub mesh: &'a TriangleMesh,
    pub tree: Cow<'a, BuildTree>,
    pub settings: String,
}

/// Writes a scene file to `out`: the header, the records, then each mesh file in turn as
/// [`BvhFile::write_to`](super::BvhFile::write_to) writes one, each mesh asked of `meshes`
/// only when its turn comes (so at most one tree made for the save is held at a time).
/// `origins` are the meshes' origins, by mesh id: one for each mesh `meshes` gives.
pub(crate) fn write_scene<'a>(
    structure: StoredStructure,
    origins: &[[f64; 3]],
    instances: &[StoredInstance],
    meshes: impl Iterator<Item = SceneMeshParts<'a>>,
    out: &mut impl Write,
) -> io::Result<()> {
    let mut records = structure.to_bytes().to_vec();
    for &origin in origins {
        records.extend_from_slice(&origin_to_bytes(origin));
    }
    for instance in instances {
        records.extend_from_slice(&instance.to_bytes());
    }
    let header = SceneHeader {
        meshes: origins.len() as u64,
        instances: instances.len() as u64,
        records_crc: crc32fast::hash(&records),
    };
    out.write_all(&header.to_bytes())?;
    out.write_all(&records)?;
    for mesh in meshes {
        let parts = MeshParts {
            mesh: mesh.mesh,
            tree: &mesh.tree,
            settings: &mesh.settings,
        };
        write(parts, out)?;
    }
    out.flush()
}
