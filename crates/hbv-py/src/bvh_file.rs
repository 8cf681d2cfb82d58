//! `BVH.save(path)` and `hbv.load_bvh(path)`: trees in the library's `.hbv` file format
//! (docs/BVH_FILE.md), written atomically and never over an existing file unless asked.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hbv::atomic_file::Replace;
use hbv::bvh::file::{BvhFile, BvhFileError, BvhFileProblem};
use pyo3::exceptions::{
    PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyNotADirectoryError, PyOSError,
    PyPermissionError, PyValueError,
};
use pyo3::prelude::*;

use crate::arrays::Bytes;
use crate::build_options::BuildOptions;
use crate::bvh::PyBvh;
use crate::mesh::PyMesh;
use hbv::bvh::build::BuilderKind;

/// The settings line saved with a tree, in the command line's words (`hbv build`):
/// `binned-sah (leaf size 4) + reinsertion optimization`.
pub fn describe(options: &BuildOptions) -> String {
    let leaf = options
        .leaf_size
        .map_or("default".to_string(), |k| k.to_string());
    let built = format!("{} (leaf size {leaf})", options.builder_name());
    if options.optimize {
        built + " + reinsertion optimization"
    } else {
        built
    }
}

/// The build options a settings line names, as far as it names them: the builder (`"saved"`
/// when the line names none this package knows), the leaf size, and the optimization.
fn options_from_settings(settings: &str, layout: Option<&str>) -> PyResult<BuildOptions> {
    let mut options = BuildOptions::new("binned-sah", layout, false, None)?;
    let first = settings.split([' ', '(']).next().unwrap_or("");
    options.builder = BuilderKind::ALL.into_iter().find(|k| k.name() == first);
    options.leaf_size = settings
        .split_once("leaf size ")
        .and_then(|(_, rest)| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|k| k.parse().ok());
    options.optimize = settings.contains("+ reinsertion optimization");
    Ok(options)
}

/// Saves `bvh` (its mesh, tree and settings) to `path` through the library's atomic writer
/// ([`BvhFile::save`], as `hbv build` does), replacing a file only with `overwrite`.
pub fn save(py: Python<'_>, bvh: &PyBvh, path: PathBuf, overwrite: bool) -> PyResult<()> {
    let file = bvh.to_file();
    // Without the GIL: writing may block (a pipe waiting for its reader, a slow disk).
    py.detach(|| file.save(&path, replace_policy(overwrite)))
        .map(|_bytes| ())
        .map_err(|e| save_error(&path, e, "tree"))
}

/// The library's replace policy of `overwrite=`.
pub fn replace_policy(overwrite: bool) -> Replace {
    if overwrite {
        Replace::Always
    } else {
        Replace::Never
    }
}

/// The Python exception of a failed save of a `what` (a tree, a scene): the `OSError` subclass
/// of its kind, with the writer's message (which names the path and the reason); a file in the
/// way says how to replace it.
pub fn save_error(path: &Path, e: io::Error, what: &str) -> PyErr {
    let message = format!("cannot save the {what}: {e}");
    match e.kind() {
        io::ErrorKind::AlreadyExists => PyFileExistsError::new_err(format!(
            "{}: the file exists; pass overwrite=True to replace it",
            path.display()
        )),
        io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        io::ErrorKind::NotADirectory => PyNotADirectoryError::new_err(message),
        io::ErrorKind::IsADirectory => PyIsADirectoryError::new_err(message),
        io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        io::ErrorKind::InvalidInput => PyValueError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// Loads a BVH saved by `BVH.save` or `hbv build` (a `.hbv` file: mesh, tree and settings),
/// without building again; `layout` as in `hbv.BVH` (default "wide8").
///
/// Raises FileNotFoundError / OSError when the file cannot be read, ValueError naming the file
/// and what is wrong when it is not a valid `.hbv` file (wrong magic number, newer version,
/// truncated, checksum mismatch, a tree that does not fit its mesh).
#[pyfunction]
#[pyo3(signature = (path, layout=None))]
pub fn load_bvh(py: Python<'_>, path: PathBuf, layout: Option<&str>) -> PyResult<PyBvh> {
    let loaded = py.detach(|| BvhFile::load(&path));
    from_loaded(py, loaded, layout)
}

/// Unpickling of a loaded BVH: the `.hbv` file's bytes (`bytes`, or a uint8 array).
#[pyfunction]
#[pyo3(signature = (data, layout=None))]
pub fn _bvh_from_bytes(
    py: Python<'_>,
    data: &Bound<'_, PyAny>,
    layout: Option<&str>,
) -> PyResult<PyBvh> {
    let data = Bytes::read("data", data)?;
    let data = data.as_slice();
    let loaded = py.detach(|| BvhFile::from_bytes(data, Path::new("<pickled hbv.BVH>")));
    from_loaded(py, loaded, layout)
}

fn from_loaded(
    py: Python<'_>,
    loaded: Result<BvhFile, BvhFileError>,
    layout: Option<&str>,
) -> PyResult<PyBvh> {
    let file = loaded.map_err(load_error)?;
    let options = options_from_settings(&file.settings, layout)?;
    let triangles = Arc::new(file.mesh);
    let mesh = Py::new(py, PyMesh::new(triangles.clone()))?;
    Ok(PyBvh::from_parts(
        mesh,
        triangles,
        options,
        file.tree,
        0.0,
        file.settings,
    ))
}

/// The Python exception of a `.hbv` file that cannot be loaded: FileNotFoundError or OSError
/// when it cannot be read, ValueError when its contents are wrong; the message names the file
/// and what is wrong.
pub fn load_error(e: BvhFileError) -> PyErr {
    match &e.problem {
        BvhFileProblem::Io(cause) if cause.kind() == io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        BvhFileProblem::Io(_) => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}
