//! `hbv.Mesh` and `hbv.load`.

use std::ffi::CString;
use std::sync::{Arc, OnceLock};

use hbv::glam::Vec3;
use hbv::{MeshError, TriangleMesh};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeWarning, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{float_array, index_array};

/// A triangle mesh: vertices (V, 3) float32 and faces (F, 3) indices into them.
///
/// Mesh(vertices, faces): vertices float32 or float64 (converted), faces any integer dtype.
/// Indices are checked to be in range and coordinates finite (ValueError otherwise).
/// Degenerate (zero-area) triangles are kept, so that triangle ids are the face order, and are
/// never hit.
#[pyclass(name = "Mesh", module = "hbv", frozen)]
pub struct PyMesh {
    pub mesh: Arc<TriangleMesh>,
    /// [`TriangleMesh::open_edge_count`], counted on first use.
    open_edges: OnceLock<usize>,
}

impl PyMesh {
    pub fn new(mesh: Arc<TriangleMesh>) -> Self {
        Self {
            mesh,
            open_edges: OnceLock::new(),
        }
    }

    /// The `mesh` argument of a structure's constructor (`hbv.BVH`, `hbv.Grid`) as an
    /// `hbv.Mesh`; a TypeError naming the type it got otherwise.
    pub fn from_argument<'a, 'py>(mesh: &'a Bound<'py, PyAny>) -> PyResult<&'a Bound<'py, Self>> {
        mesh.cast::<Self>().map_err(|_| {
            PyTypeError::new_err(format!(
                "mesh: expected an hbv.Mesh (hbv.Mesh(vertices, faces) or hbv.load(path)), got {}",
                mesh.get_type()
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            ))
        })
    }

    /// The number of open edges, counted (off the GIL) on first use.
    pub fn open_edge_count(&self, py: Python<'_>) -> usize {
        py.detach(|| *self.open_edges.get_or_init(|| self.mesh.open_edge_count()))
    }

    /// Issues a RuntimeWarning, attributed to the Python caller of `query`, when the mesh is
    /// not closed: inside tests are not defined near its open edges. Returns whether it is
    /// closed.
    pub fn warn_if_open(&self, py: Python<'_>, query: &str) -> PyResult<bool> {
        let open = self.open_edge_count(py);
        if open == 0 {
            return Ok(true);
        }
        let message = format!(
            "{query}: the mesh is not closed ({open} open edges, each shared by an odd number \
             of triangles: the rims of holes); inside is not defined near them, and points \
             there may be answered either way (see Mesh.open_edges)"
        );
        let message = CString::new(message).expect("no NUL in the message");
        PyErr::warn(py, &py.get_type::<PyRuntimeWarning>(), &message, 1)?;
        Ok(false)
    }
}

pub fn mesh_error(e: MeshError) -> PyErr {
    match e {
        MeshError::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

#[pymethods]
impl PyMesh {
    #[new]
    fn from_arrays(vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (floats, rows) = float_array("vertices", vertices, Some(3), None)?;
        let values = floats.values();
        let positions: Vec<Vec3> = (0..rows).map(|i| values.row3(i)).collect();
        let indices = index_array("faces", faces)?;
        let mesh = TriangleMesh::new(positions, indices).map_err(mesh_error)?;
        Ok(Self::new(Arc::new(mesh)))
    }

    /// Vertex positions, (V, 3) float32 (a copy).
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat: Vec<f32> = self
            .mesh
            .positions()
            .iter()
            .flat_map(|p| p.to_array())
            .collect();
        flat.into_pyarray(py)
            .reshape([self.mesh.positions().len(), 3])
    }

    /// Triangles, (F, 3) int64 indices into `vertices` (a copy).
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let flat: Vec<i64> = self
            .mesh
            .indices()
            .iter()
            .flat_map(|t| t.map(i64::from))
            .collect();
        flat.into_pyarray(py)
            .reshape([self.mesh.triangle_count(), 3])
    }

    /// Number of triangles (degenerate ones included).
    #[getter]
    fn triangle_count(&self) -> usize {
        self.mesh.triangle_count()
    }

    /// Number of zero-area triangles (kept for their ids, never hit).
    #[getter]
    fn degenerate_count(&self) -> usize {
        self.mesh.degenerate_count()
    }

    /// Number of open edges: edges shared by an odd number of the mesh's non-degenerate
    /// triangles (the rims of holes, fins), vertices compared by position (so that vertices
    /// split at seams join). 0 for a closed mesh; a T-junction counts as open. Counted once.
    #[getter]
    fn open_edges(&self, py: Python<'_>) -> usize {
        self.open_edge_count(py)
    }

    /// Whether the mesh is closed (no open edges): it bounds a volume, and `contains` is
    /// defined everywhere but on the surface.
    #[getter]
    fn is_closed(&self, py: Python<'_>) -> bool {
        self.open_edge_count(py) == 0
    }

    /// The bounding box as ((min x, y, z), (max x, y, z)).
    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let b = self.mesh.bounds();
        (b.min.to_array(), b.max.to_array())
    }

    fn __len__(&self) -> usize {
        self.mesh.triangle_count()
    }

    fn __repr__(&self) -> String {
        format!(
            "hbv.Mesh({} vertices, {} triangles)",
            self.mesh.positions().len(),
            self.mesh.triangle_count()
        )
    }

    /// Pickled as its arrays.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let me = slf.get();
        let args = PyTuple::new(py, [me.vertices(py)?.into_any(), me.faces(py)?.into_any()])?;
        PyTuple::new(py, [slf.get_type().into_any(), args.into_any()])
    }
}

/// load(path) -> Mesh: reads .obj, .ply (ascii or binary), .gltf or .glb. Polygons are
/// fan-triangulated in place, so triangle ids follow the file's face order.
///
/// Raises OSError when the file cannot be read, ValueError when it is not a valid mesh; the
/// message names the file, the place in it and the reason.
#[pyfunction]
pub fn load(py: Python<'_>, path: std::path::PathBuf) -> PyResult<PyMesh> {
    let mesh = py
        .detach(|| TriangleMesh::load(&path))
        .map_err(mesh_error)?;
    Ok(PyMesh::new(Arc::new(mesh)))
}
