use std::path::Path;

use super::{MeshError, TriangleMesh};

pub(super) fn load(path: &Path) -> Result<TriangleMesh, MeshError> {
    Err(MeshError::invalid(path, "file", "gltf loader not written yet"))
}
