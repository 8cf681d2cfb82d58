//! Why a scene could not be read: always the file, the line and the key.

use std::path::PathBuf;

use hbv::MeshError;

/// An error in a scene file. Every variant names the file; those about its content also name
/// the line (1-based) and the key (`materials.glass.ior`, `mesh[2].file`, ...).
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{}: cannot read: {error}", file.display())]
    Io {
        file: PathBuf,
        // Not a `#[source]`: the message holds it already, and a report of the error chain
        // (`{:#}`) printed it twice.
        error: std::io::Error,
    },
    /// The file is not UTF-8 text (TOML is): the first byte that is not, and where it is.
    #[error(
        "{}: line {line}, column {column} (byte offset {offset}): not UTF-8 text (byte \
         0x{byte:02X}); scene files must be saved as UTF-8",
        file.display()
    )]
    NotUtf8 {
        file: PathBuf,
        line: usize,
        /// 1-based, in bytes.
        column: usize,
        /// 0-based, from the start of the file.
        offset: usize,
        byte: u8,
    },
    #[error("{}: line {line}: {key}: {reason}", file.display())]
    Invalid {
        file: PathBuf,
        line: usize,
        key: String,
        reason: String,
    },
    #[error("{}: {place}: {reason}", file.display())]
    Gltf {
        file: PathBuf,
        /// `node 3`, `meshes`, ...
        place: String,
        reason: String,
    },
    /// A glTF scene file the mesh loader's checks refused (its message names the file and the
    /// place).
    #[error("{0}")]
    GltfFile(Box<MeshError>),
    #[error("{}: line {line}: {key}: cannot load mesh: {error}", file.display())]
    Mesh {
        file: PathBuf,
        line: usize,
        key: String,
        // In the message, not a `#[source]` (as `Io`).
        error: Box<MeshError>,
    },
}

impl SceneError {
    /// The line the error is on, for errors about the file's content.
    pub fn line(&self) -> Option<usize> {
        match self {
            SceneError::Io { .. } | SceneError::Gltf { .. } | SceneError::GltfFile(_) => None,
            SceneError::Invalid { line, .. }
            | SceneError::Mesh { line, .. }
            | SceneError::NotUtf8 { line, .. } => Some(*line),
        }
    }

    /// The key the error is about, for errors about the file's content.
    pub fn key(&self) -> Option<&str> {
        match self {
            SceneError::Io { .. }
            | SceneError::Gltf { .. }
            | SceneError::GltfFile(_)
            | SceneError::NotUtf8 { .. } => None,
            SceneError::Invalid { key, .. } | SceneError::Mesh { key, .. } => Some(key),
        }
    }
}
