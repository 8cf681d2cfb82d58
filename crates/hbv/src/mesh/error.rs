use std::fmt;
use std::path::{Path, PathBuf};

/// Where mesh data came from, for error messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshSource {
    /// A file on disk.
    File(PathBuf),
    /// Arrays handed to [`crate::mesh::TriangleMesh::new`].
    Arrays,
}

impl fmt::Display for MeshSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshSource::File(p) => write!(f, "{}", p.display()),
            MeshSource::Arrays => f.write_str("mesh arrays"),
        }
    }
}

impl From<&Path> for MeshSource {
    fn from(p: &Path) -> Self {
        MeshSource::File(p.to_path_buf())
    }
}

/// Why a mesh could not be loaded or built. Every variant names its source; [`MeshError::Invalid`]
/// also names the place in it (`"face 12"`, `"line 40"`, `"vertex 7"`, `"header"`, ...).
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The message includes `error`'s, so `error` is not also given as the `source()`: error
    /// reports that print the chain (anyhow's `{:#}`) would repeat it.
    #[error("{source_name}: cannot read: {error}")]
    Io {
        source_name: MeshSource,
        error: std::io::Error,
    },
    #[error("{source_name}: unsupported mesh format (expected .obj, .ply, .gltf or .glb)")]
    UnsupportedFormat { source_name: MeshSource },
    #[error("{source_name}: {place}: {reason}")]
    Invalid {
        source_name: MeshSource,
        place: String,
        reason: String,
    },
}

impl MeshError {
    pub fn invalid(
        source_name: impl Into<MeshSource>,
        place: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        MeshError::Invalid {
            source_name: source_name.into(),
            place: place.into(),
            reason: reason.into(),
        }
    }

    pub fn io(path: &Path, error: std::io::Error) -> Self {
        MeshError::Io {
            source_name: path.into(),
            error,
        }
    }
}
