//! `Scene.save(path)`, the pickling of `hbv.Scene`, and `hbv.load_scene(path)`: scenes in the
//! library's `.hbv` scene files (format version 2, docs/BVH_FILE.md), read back without building
//! any mesh again, and glTF, OBJ and PLY files read as scenes.
//!
//! What a scene file holds is the library's scene: its meshes and their trees, and every
//! instance by id with its transform, mask and whether it was removed. What `hbv.Scene` keeps
//! beside it is not saved: the identity of the objects `add` was given (a scene read back makes
//! a new mesh of an object added again) and which meshes are closed (looked at again).

use std::path::{Path, PathBuf};

use hbv::bvh::file::{is_bvh_file, BvhFile, BvhFileError};
use hbv::mesh::MeshError;
use hbv::scene::{AnyBvhFile, InstanceTransform, Scene};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

use crate::arrays::Bytes;
use crate::bvh_file::{load_error, replace_policy, save_error};
use crate::mesh::mesh_error;
use crate::scene::PyScene;

/// The name unpickled scenes are read under, in error messages.
const PICKLED: &str = "<pickled hbv.Scene>";

/// Saves `scene` to `path` as a `.hbv` scene file through the library's atomic writer
/// ([`Scene::save`], as `hbv build SCENE.glb` does), replacing a file only with `overwrite`.
pub fn save(py: Python<'_>, scene: &Scene, path: &Path, overwrite: bool) -> PyResult<()> {
    // Without the GIL: saving builds each mesh's tree again, and writing may block.
    py.detach(|| scene.save(path, replace_policy(overwrite)))
        .map(|_bytes| ())
        .map_err(|e| save_error(path, e, "scene"))
}

/// `__reduce__` of a scene: `(hbv._hbv._scene_from_bytes, (its .hbv scene file's bytes,))`.
pub fn reduce<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyTuple>> {
    let bytes = py.detach(|| scene.to_hbv_bytes());
    let from_bytes = py.import("hbv._hbv")?.getattr("_scene_from_bytes")?;
    let args = (PyBytes::new(py, &bytes),).into_pyobject(py)?;
    PyTuple::new(py, [from_bytes, args.into_any()])
}

/// Unpickling of a scene: the bytes of its `.hbv` scene file (`bytes`, or a uint8 array).
#[pyfunction]
pub fn _scene_from_bytes(py: Python<'_>, data: &Bound<'_, PyAny>) -> PyResult<PyScene> {
    let data = Bytes::read("data", data)?;
    let data = data.as_slice();
    let scene = py
        .detach(|| Scene::from_hbv_bytes(data, Path::new(PICKLED)))
        .map_err(load_error)?;
    Ok(PyScene::from_scene(scene))
}

/// Why a file could not be read as a scene.
enum SceneLoadError {
    /// A `.hbv` file (by its magic number or its name) that cannot be read or is not valid.
    Hbv(BvhFileError),
    /// A glTF, OBJ or PLY file that cannot be read or is not valid.
    Mesh(MeshError),
    /// A `.hbv` mesh file whose tree could not be placed (not expected: the file was checked).
    Place(String),
}

/// load_scene(path) -> Scene: reads a scene, told by the file's content for `.hbv` files
/// (whatever their name) and by its name otherwise:
///
/// - a `.hbv` scene file (`Scene.save`, `hbv build SCENE.glb`): the saved scene, every instance
///   by its id (removed ones stay holes), its transform and mask, no mesh built again;
/// - a `.hbv` mesh file (`BVH.save`, `hbv build MESH`): a scene of one instance (id 0, every
///   mask bit) of its mesh, its saved tree laid out, not built again;
/// - a glTF file (.gltf, .glb): its nodes with meshes as instances (ids in depth-first order of
///   the default scene's nodes, a mesh shared by several nodes built once, every mask all bits),
///   as docs/RAYS.md "Scenes (glTF)" says;
/// - an .obj or .ply file: a scene of one instance (id 0).
///
/// Raises FileNotFoundError / OSError when the file cannot be read, ValueError when it is not a
/// valid scene; the message names the file, the place in it and the reason.
#[pyfunction]
pub fn load_scene(py: Python<'_>, path: PathBuf) -> PyResult<PyScene> {
    let scene = py.detach(|| read_scene(&path)).map_err(|e| match e {
        SceneLoadError::Hbv(e) => load_error(e),
        SceneLoadError::Mesh(e) => mesh_error(e),
        SceneLoadError::Place(reason) => {
            PyValueError::new_err(format!("{}: {reason}", path.display()))
        }
    })?;
    Ok(PyScene::from_scene(scene))
}

fn read_scene(path: &Path) -> Result<Scene, SceneLoadError> {
    // By the magic number, or the name: a damaged `.hbv` file is then told apart as such, not
    // as a mesh of an unsupported format.
    let named_hbv = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("hbv"));
    if !(named_hbv || is_bvh_file(path)) {
        return Scene::load(path).map_err(SceneLoadError::Mesh);
    }
    match AnyBvhFile::load(path).map_err(SceneLoadError::Hbv)? {
        AnyBvhFile::Scene(scene) => Ok(scene),
        AnyBvhFile::Mesh(file) => scene_of_one(file).map_err(SceneLoadError::Place),
    }
}

/// A scene of one instance of the mesh of `file`, placed by the identity with every mask bit,
/// the saved tree laid out as a new scene lays out its meshes.
fn scene_of_one(file: BvhFile) -> Result<Scene, String> {
    let mut scene = Scene::new();
    let mesh = scene.add_built_mesh(file.mesh, &file.tree);
    scene
        .add_instance(mesh, InstanceTransform::IDENTITY, u32::MAX)
        .map_err(|e| e.to_string())?;
    scene.build();
    Ok(scene)
}
