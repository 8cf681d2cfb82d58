//! `.hbv` files: a built tree saved with its mesh and the settings that built it, loaded back
//! without building again (version 1, [`BvhFile`]); or a scene, its meshes each so saved and
//! the instances placing them (version 2, [`Scene::save`](crate::scene::Scene::save)). The
//! byte layouts are in `format.rs`, `scene_format.rs` and `docs/BVH_FILE.md`.
//!
//! Loading trusts nothing in the file: the magic number, version and byte order are checked,
//! every declared size is checked against the file's length before anything is allocated,
//! header and payload each carry a CRC-32, and the tree is checked node by node (every child
//! range inside the file, children after their parent, each node reached once, every triangle
//! id and vertex index in range, every box containing what is below it). A bad file gives a
//! [`BvhFileError`] naming the file and what is wrong; it never panics.

mod error;
mod format;
mod read;
mod scene_format;
mod scene_read;
mod scene_write;
mod write;

use std::path::Path;

pub use error::{BvhFileError, BvhFileProblem};
pub use format::{BvhFileKind, FORMAT_VERSION, MAGIC, MESH_FORMAT_VERSION, SCENE_FORMAT_VERSION};
pub(crate) use read::read_file;
pub(crate) use scene_format::{StoredInstance, StoredStructure};
pub(crate) use scene_read::{parse_scene, StoredScene};
pub(crate) use scene_write::{write_scene, SceneMeshParts};

use crate::atomic_file::{write_atomically, Replace};
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// The contents of a `.hbv` file: a mesh, a tree over its triangles, and a free-form line of
/// the settings that built the tree (e.g. `binned-sah (leaf size 4) + reinsertion optimization`).
#[derive(Clone, Debug, PartialEq)]
pub struct BvhFile {
    pub mesh: TriangleMesh,
    pub tree: BuildTree,
    pub settings: String,
}

impl BvhFile {
    /// Reads and checks the file at `path`. It is read into memory whole (not memory-mapped, so
    /// a file truncated or rewritten while it loads is an error, never a crash); a device or a
    /// socket is refused.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, BvhFileError> {
        read::load(path.as_ref())
    }

    /// Reads a file's bytes; `source` names it in errors.
    pub fn from_bytes(bytes: &[u8], source: &Path) -> Result<Self, BvhFileError> {
        read::parse(bytes, source)
    }

    /// Saves the file at `path`, atomically ([`crate::atomic_file`]): a reader never sees half
    /// a tree, a failed save leaves `path` as it was, and with [`Replace::Never`] a file at
    /// `path` (even one created while the tree is written) is never replaced. Returns the
    /// number of bytes written. This is the one way `hbv build` and Python's `BVH.save` save.
    pub fn save(&self, path: impl AsRef<Path>, replace: Replace) -> std::io::Result<u64> {
        save_counted(path.as_ref(), replace, |mut out| self.write_to(&mut out))
    }

    /// Writes the file to `out` ([`BvhFile::save`] makes it atomic on disk). The tree is saved in breadth-first order; loading gives back the same tree
    /// after [`BuildTree::compact`] on both sides.
    pub fn write_to(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        write::write(self.into(), out)
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = Vec::new();
        self.write_to(&mut bytes).expect("writing to memory");
        bytes
    }
}

/// Writes the file at `path` through `write`, atomically ([`crate::atomic_file`]), and returns
/// the number of bytes written: the one way `.hbv` files of either kind are saved.
pub(crate) fn save_counted(
    path: &Path,
    replace: Replace,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> std::io::Result<u64> {
    let mut bytes = 0;
    write_atomically(path, replace, |file| {
        let mut counted = write::CountedWriter::new(file);
        write(&mut counted)?;
        bytes = counted.bytes();
        Ok(())
    })?;
    Ok(bytes)
}

/// The kind of `.hbv` file `bytes` are (its header checked: magic, version, byte order,
/// header CRC-32), without reading further.
pub fn kind_of_bytes(bytes: &[u8]) -> Result<BvhFileKind, BvhFileProblem> {
    format::check_preamble(bytes)
}

/// Whether the file at `path` starts with the `.hbv` magic number, whatever its name (a mesh
/// file or a scene file: [`kind_of_bytes`] tells which).
pub fn is_bvh_file(path: impl AsRef<Path>) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok_and(|()| magic == MAGIC)
}
