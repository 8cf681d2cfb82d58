//! Indexed triangle meshes and the loaders that make them from OBJ, PLY and glTF files.
//!
//! The triangle order is the file's face order (polygons fan-triangulated in place), so a hit's
//! primitive id can be compared with any other tool ray by ray.

mod error;
mod format;
pub(crate) mod gltf;
mod obj;
mod ply;
pub mod procedural;
mod topology;

use std::path::Path;

use glam::Vec3;

use crate::geometry::{Aabb, Triangle};
pub use error::{MeshError, MeshSource};
pub use format::MeshFormat;

/// An indexed triangle mesh: f32 positions and, per triangle, three u32 vertex indices.
///
/// Construction checks that every index is in range and every position is finite, so every
/// consumer may rely on both. Degenerate (zero-area) triangles are kept, so that ids match the
/// file, and counted; accelerators never report them as hit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    degenerate: usize,
}

/// The largest vertex coordinate a mesh may have, in magnitude: `f32::MAX / 2`. Beyond it the
/// difference of two coordinates, and with it a ray's distance to a vertex or a box's extent,
/// may overflow, and the structures' conservative tests no longer hold (found by a new user's
/// sweep: on a box with corners at ±3e38 some layouts missed hits that others found).
pub const MAX_COORDINATE: f32 = f32::MAX / 2.0;

impl TriangleMesh {
    /// Builds a mesh from positions and triangles, checking indices and coordinates: every
    /// coordinate finite and at most [`MAX_COORDINATE`] in magnitude, every index in range.
    pub fn new(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        Self::from_parts(MeshSource::Arrays, positions, indices)
    }

    /// Builds a mesh whose errors name `source` (used by the loaders).
    pub(crate) fn from_parts(
        source: MeshSource,
        positions: Vec<Vec3>,
        indices: Vec<[u32; 3]>,
    ) -> Result<Self, MeshError> {
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::invalid(
                source,
                format!("vertex {i}"),
                format!("coordinate is not finite: {}", positions[i]),
            ));
        }
        if let Some(i) = positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_COORDINATE)
        {
            return Err(MeshError::invalid(
                source,
                format!("vertex {i}"),
                format!(
                    "coordinate beyond ±{MAX_COORDINATE:e} (f32::MAX / 2), where the differences \
                     of coordinates overflow: {}",
                    positions[i]
                ),
            ));
        }
        let n = positions.len();
        for (f, tri) in indices.iter().enumerate() {
            if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::invalid(
                    source,
                    format!("face {f}"),
                    format!("vertex index {bad} out of range (the mesh has {n} vertices)"),
                ));
            }
        }
        let mut mesh = Self {
            positions,
            indices,
            degenerate: 0,
        };
        mesh.degenerate = mesh.triangles().filter(Triangle::is_degenerate).count();
        Ok(mesh)
    }

    /// Loads a mesh, choosing the reader by the file's extension: `.obj`, `.ply`, `.gltf`, `.glb`.
    ///
    /// The whole file is read, then parsed as by [`TriangleMesh::from_bytes`]; glTF buffers
    /// in other files are read from the file's folder. Errors name the file, the place in it
    /// and the reason; no input makes this panic or allocate more than the file can fill.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, MeshError> {
        let path = path.as_ref();
        let format = MeshFormat::from_path(path).ok_or_else(|| MeshError::UnsupportedFormat {
            source_name: path.into(),
        })?;
        let bytes = read_mesh_file(path)?;
        match format {
            MeshFormat::Obj => obj::parse(path, &bytes),
            MeshFormat::Ply => ply::parse(path, &bytes),
            MeshFormat::Gltf => gltf::parse(path, &bytes, Some(folder_of(path))),
        }
    }

    /// Parses a mesh held in memory. `name` is only used in error messages (as a file name
    /// would be). Never touches the file system: a glTF buffer stored in another file is an
    /// error (GLB binary chunks and `data:` URIs are read).
    pub fn from_bytes(
        format: MeshFormat,
        name: impl AsRef<Path>,
        bytes: &[u8],
    ) -> Result<Self, MeshError> {
        let name = name.as_ref();
        match format {
            MeshFormat::Obj => obj::parse(name, bytes),
            MeshFormat::Ply => ply::parse(name, bytes),
            MeshFormat::Gltf => gltf::parse(name, bytes, None),
        }
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Triangle `i` (its vertices in file order). Panics when `i` is out of range, like indexing.
    #[inline]
    pub fn triangle(&self, i: usize) -> Triangle {
        let [a, b, c] = self.indices[i];
        Triangle::new(
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        )
    }

    /// All triangles in face order.
    pub fn triangles(&self) -> impl ExactSizeIterator<Item = Triangle> + '_ {
        (0..self.indices.len()).map(|i| self.triangle(i))
    }

    /// Number of zero-area triangles (kept, never hit).
    pub fn degenerate_count(&self) -> usize {
        self.degenerate
    }

    /// The box of the vertices used by triangles (unused vertices do not count).
    pub fn bounds(&self) -> Aabb {
        self.triangles()
            .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()))
    }
}

/// A glTF file's document and buffers, read and checked as [`TriangleMesh::load`] reads a
/// glTF mesh (devices refused, buffers from regular files only and only their declared bytes,
/// every mesh primitive's POSITION and indices accessors checked so that the `gltf` crate's
/// reader can be trusted with them), for callers that walk the scene themselves: the renderer's
/// glTF scenes (materials, cameras, lights). `gltf::import` reads a buffer URI naming
/// `/dev/zero` for ever and panics on some malformed files.
pub fn read_gltf(path: &Path) -> Result<(::gltf::Document, Vec<::gltf::buffer::Data>), MeshError> {
    gltf::read_checked(path)
}

/// The bytes of a mesh file, devices refused ([`refuse_devices`]).
pub(crate) fn read_mesh_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    refuse_devices(path, "a mesh file").map_err(|e| MeshError::io(path, e))?;
    std::fs::read(path).map_err(|e| MeshError::io(path, e))
}

/// The folder holding `path`, where a glTF file's external buffers are looked for.
pub(crate) fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Refuses a path that names a device or a socket (through any symlinks): `/dev/zero` or
/// `/dev/urandom` would be read forever. Regular files and pipes (`<(...)`, FIFOs, which end
/// when their writer closes) are read. `expected` names what the file should have been
/// (`a mesh file`), for the message.
pub(crate) fn refuse_devices(path: &Path, expected: &str) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::metadata(path)?.file_type();
        if kind.is_char_device() || kind.is_block_device() || kind.is_socket() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("a device or a socket, not {expected}"),
            ));
        }
    }
    let _ = (path, expected);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_out_of_range_index_naming_the_face() {
        let err = TriangleMesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 2], [0, 1, 3]]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "mesh arrays: face 1: vertex index 3 out of range (the mesh has 3 vertices)"
        );
    }

    #[test]
    fn rejects_non_finite_vertex() {
        let err =
            TriangleMesh::new(vec![Vec3::ZERO, Vec3::new(0.0, f32::NAN, 0.0)], vec![]).unwrap_err();
        assert!(err
            .to_string()
            .starts_with("mesh arrays: vertex 1: coordinate is not finite"));
    }

    #[test]
    fn counts_degenerate_triangles() {
        let m = TriangleMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0],
            vec![[0, 1, 2], [0, 1, 3], [2, 2, 2]],
        )
        .unwrap();
        assert_eq!(m.triangle_count(), 3);
        assert_eq!(m.degenerate_count(), 2);
    }

    #[test]
    fn unknown_extension_is_an_error() {
        let err = TriangleMesh::load("scene.stl").unwrap_err();
        assert!(matches!(err, MeshError::UnsupportedFormat { .. }));
        assert!(err.to_string().contains("scene.stl"));
    }
}
