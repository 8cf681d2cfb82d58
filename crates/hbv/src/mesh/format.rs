//! Which reader a mesh file needs, from its name.

use std::path::Path;

/// A mesh file format that [`crate::TriangleMesh`] can read.
///
/// [`MeshFormat::from_path`] picks it from the file name's extension; with
/// [`crate::TriangleMesh::from_bytes`] the caller names it for data that never was a file
/// (network, archive member, fuzzer input).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Wavefront OBJ (`.obj`): `v` and `f` lines.
    Obj,
    /// Stanford PLY (`.ply`): ascii, binary little or big endian.
    Ply,
    /// glTF 2.0: JSON (`.gltf`) or binary (`.glb`); the two are told apart by their content.
    Gltf,
}

impl MeshFormat {
    /// The format of a file named `path`, by its extension (any letter case): `.obj`, `.ply`,
    /// `.gltf` or `.glb`; `None` for anything else.
    pub fn from_path(path: impl AsRef<Path>) -> Option<Self> {
        let ext = path.as_ref().extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "gltf" | "glb" => Some(MeshFormat::Gltf),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extension_picks_the_format_in_any_case() {
        assert_eq!(MeshFormat::from_path("a/b.OBJ"), Some(MeshFormat::Obj));
        assert_eq!(MeshFormat::from_path("scan.ply"), Some(MeshFormat::Ply));
        assert_eq!(MeshFormat::from_path("s.glb"), Some(MeshFormat::Gltf));
        assert_eq!(MeshFormat::from_path("s.gltf"), Some(MeshFormat::Gltf));
        assert_eq!(MeshFormat::from_path("s.stl"), None);
        assert_eq!(MeshFormat::from_path("obj"), None);
    }
}
