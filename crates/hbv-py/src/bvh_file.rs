//! `BVH.save(path)` and `hbv.load_bvh(path)`: trees in the library's `.hbv` file format
//! (docs/BVH_FILE.md), written atomically and never over an existing file unless asked.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hbv::bvh::file::{BvhFile, BvhFileProblem};
use pyo3::exceptions::{
    PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyNotADirectoryError, PyOSError,
    PyValueError,
};
use pyo3::prelude::*;

use crate::build_options::{BuildOptions, BUILDERS};
use crate::bvh::PyBvh;
use crate::mesh::PyMesh;

/// The settings line saved with a tree, in the command line's words (`hbv build`):
/// `binned-sah (leaf size 4) + reinsertion optimization`.
pub fn describe(options: &BuildOptions) -> String {
    let leaf = options
        .leaf_size
        .map_or("default".to_string(), |k| k.to_string());
    let built = format!("{} (leaf size {leaf})", options.builder);
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
    options.builder = if BUILDERS.contains(&first) {
        first.to_string()
    } else {
        "saved".to_string()
    };
    options.leaf_size = settings
        .split_once("leaf size ")
        .and_then(|(_, rest)| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|k| k.parse().ok());
    options.optimize = settings.contains("+ reinsertion optimization");
    Ok(options)
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, flushed to disk, then
/// renamed over `path` (`overwrite`) or hard-linked to it (which fails, atomically, if `path`
/// exists). On any failure the temporary file is removed and `path` is left as it was.
///
/// A link to a file is written through (the file is replaced, the link kept). A device, pipe
/// or socket is written into in place, with or without `overwrite`: renaming over it would put
/// a regular file where it was (`/dev/null`, as root).
fn write_atomically(path: &Path, bytes: &[u8], overwrite: bool) -> PyResult<()> {
    let linked;
    let path = match fs::metadata(path) {
        Ok(meta) if meta.is_dir() => {
            return Err(PyIsADirectoryError::new_err(format!(
                "{}: cannot save the tree: it is a directory",
                path.display()
            )))
        }
        Ok(meta) if !meta.is_file() => {
            return fs::OpenOptions::new()
                .write(true)
                .open(path)
                .and_then(|mut file| file.write_all(bytes))
                .map_err(|e| {
                    PyOSError::new_err(format!("{}: cannot save the tree: {e}", path.display()))
                });
        }
        Ok(_) if fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) => {
            linked = fs::canonicalize(path).map_err(|e| {
                PyOSError::new_err(format!("{}: cannot save the tree: {e}", path.display()))
            })?;
            linked.as_path()
        }
        _ => path,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(if dir.exists() {
            PyNotADirectoryError::new_err(format!(
                "{}: cannot save the tree: {} is not a directory",
                path.display(),
                dir.display()
            ))
        } else {
            PyFileNotFoundError::new_err(format!(
                "{}: cannot save the tree: directory {} does not exist",
                path.display(),
                dir.display()
            ))
        });
    }
    if !overwrite && path.exists() {
        return Err(PyFileExistsError::new_err(format!(
            "{}: the file exists; pass overwrite=True to replace it",
            path.display()
        )));
    }
    let name = path
        .file_name()
        .ok_or_else(|| PyValueError::new_err(format!("{}: not a file name", path.display())))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let fail = |e: std::io::Error, what: &str| {
        let _ = fs::remove_file(&tmp);
        PyOSError::new_err(format!(
            "{}: cannot save the tree: {what}: {e}",
            path.display()
        ))
    };
    let mut file = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| {
            PyOSError::new_err(format!(
                "{}: cannot save the tree: cannot create {}: {e}",
                path.display(),
                tmp.display()
            ))
        })?;
    file.write_all(bytes).map_err(|e| fail(e, "write"))?;
    file.sync_all().map_err(|e| fail(e, "flush to disk"))?;
    drop(file);
    if overwrite {
        fs::rename(&tmp, path).map_err(|e| fail(e, "rename"))?;
    } else {
        match fs::hard_link(&tmp, path) {
            Ok(()) => {
                let _ = fs::remove_file(&tmp);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let _ = fs::remove_file(&tmp);
                return Err(PyFileExistsError::new_err(format!(
                    "{}: the file exists; pass overwrite=True to replace it",
                    path.display()
                )));
            }
            Err(e) => return Err(fail(e, "link into place")),
        }
    }
    Ok(())
}

/// Saves `bvh` (its mesh, tree and settings) to `path`.
pub fn save(py: Python<'_>, bvh: &PyBvh, path: PathBuf, overwrite: bool) -> PyResult<()> {
    let file = bvh.to_file();
    // Without the GIL: writing may block (a pipe waiting for its reader, a slow disk).
    py.detach(|| write_atomically(&path, &file.to_bytes(), overwrite))
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

/// Unpickling of a loaded BVH: the `.hbv` file's bytes.
#[pyfunction]
#[pyo3(signature = (data, layout=None))]
pub fn _bvh_from_bytes(py: Python<'_>, data: &[u8], layout: Option<&str>) -> PyResult<PyBvh> {
    let loaded = py.detach(|| BvhFile::from_bytes(data, Path::new("<pickled hbv.BVH>")));
    from_loaded(py, loaded, layout)
}

fn from_loaded(
    py: Python<'_>,
    loaded: Result<BvhFile, hbv::bvh::file::BvhFileError>,
    layout: Option<&str>,
) -> PyResult<PyBvh> {
    let file = loaded.map_err(|e| match &e.problem {
        BvhFileProblem::Io(io) if io.kind() == std::io::ErrorKind::NotFound => {
            pyo3::exceptions::PyFileNotFoundError::new_err(e.to_string())
        }
        BvhFileProblem::Io(_) => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    })?;
    let options = options_from_settings(&file.settings, layout)?;
    let triangles = Arc::new(file.mesh);
    let mesh = Py::new(py, PyMesh::new(triangles.clone()))?;
    Ok(PyBvh::from_parts(
        py,
        mesh,
        triangles,
        options,
        file.tree,
        file.settings,
    ))
}
