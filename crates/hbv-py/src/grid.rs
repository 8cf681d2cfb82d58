//! `hbv.Grid`: the uniform grid over a mesh, answering the ray queries.

use std::sync::Arc;
use std::time::Instant;

use hbv::grid::{GridConfig, UniformGrid};
use hbv::TriangleMesh;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::mesh::PyMesh;
use crate::ray_queries::{
    any_hits, closest_hits, every_hit, hit_counts, inside, MeshCounter, MeshTracer, RayArgs,
};
use crate::thread_pool::ThreadCount;

/// A uniform grid over a mesh (cells of equal size, each listing the triangles that overlap it,
/// walked cell by cell along the ray: 3D-DDA of Amanatides & Woo 1987, with mailboxes).
///
/// Grid(mesh, lam=None)
///
/// lam: density λ, λ·N^(1/3) cells along the longest axis (Cleary & Wyvill 1988; default 2).
///
/// Answers are identical to the BVH's (and brute force's): intersect, occluded, intersect_all,
/// count and contains. There is no closest_point: a grid has no distance-ordered search (cells
/// are visited along a ray, not outward from a point); use hbv.BVH for it. The grid is fast to
/// build but slow on scenes of very uneven density (a "teapot in a stadium"), where the BVH wins.
#[pyclass(name = "Grid", module = "hbv", frozen)]
pub struct PyGrid {
    mesh: Py<PyMesh>,
    triangles: Arc<TriangleMesh>,
    grid: UniformGrid,
    build_seconds: f64,
}

#[pymethods]
impl PyGrid {
    #[new]
    #[pyo3(signature = (mesh, lam=None))]
    fn new(py: Python<'_>, mesh: &Bound<'_, PyAny>, lam: Option<f64>) -> PyResult<Self> {
        let mesh = PyMesh::from_argument(mesh)?;
        let mut config = GridConfig::default();
        if let Some(lam) = lam {
            if !(lam.is_finite() && lam > 0.0) {
                return Err(PyValueError::new_err(format!(
                    "lam: expected a positive finite density, got {lam}"
                )));
            }
            config.lambda = lam;
        }
        let triangles = mesh.get().mesh.clone();
        let (grid, build_seconds) = py.detach(|| {
            let start = Instant::now();
            let grid = UniformGrid::new(&triangles, config);
            (grid, start.elapsed().as_secs_f64())
        });
        Ok(Self {
            mesh: mesh.clone().unbind(),
            triangles,
            grid,
            build_seconds,
        })
    }

    /// The mesh the grid was built over.
    #[getter]
    fn mesh(&self, py: Python<'_>) -> Py<PyMesh> {
        self.mesh.clone_ref(py)
    }

    /// The density λ the grid was built with.
    #[getter]
    fn lam(&self) -> f64 {
        self.grid.config().lambda
    }

    /// Closest hits, as `BVH.intersect`: a dict of arrays `hit`, `t`, `prim`, `u`, `v`, `normal`.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, threads=None))]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let args = RayArgs::read(origins, directions, tmin, tmax)?;
        let tracer = MeshTracer {
            accel: &self.grid,
            mesh: &self.triangles,
        };
        closest_hits(py, &tracer, &args, threads)
    }

    /// Any hit, as `BVH.occluded`: a bool array.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, threads=None))]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let args = RayArgs::read(origins, directions, tmin, tmax)?;
        let tracer = MeshTracer {
            accel: &self.grid,
            mesh: &self.triangles,
        };
        any_hits(py, &tracer, &args, threads)
    }

    /// Every hit along each ray in one walk through the cells, as `BVH.intersect_all`: a tuple
    /// (ray index int64, t float32, prim int64), sorted by ray, then t, then prim.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, threads=None))]
    fn intersect_all<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let args = RayArgs::read(origins, directions, tmin, tmax)?;
        every_hit(py, || &self.grid, &args, threads)
    }

    /// The number of hits along each ray (int64), as `BVH.count`.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, threads=None))]
    fn count<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let args = RayArgs::read(origins, directions, tmin, tmax)?;
        hit_counts(py, || MeshCounter(&self.grid), &args, threads)
    }

    /// Whether each point lies inside the (closed) mesh, as `BVH.contains`.
    #[pyo3(signature = (points, threads=None))]
    fn contains<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        inside(py, self.mesh.get(), || &self.grid, points, threads)
    }

    /// The grid's shape and size, as a dict: `lam`, `mailbox`, `triangles`, `resolution`
    /// (cells per axis), `cells`, `listed` (cell-list entries), `triangles_per_cell` (listed /
    /// cells), `memory_bytes`, `build_seconds`.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        let config = self.grid.config();
        out.set_item("lam", config.lambda)?;
        out.set_item("mailbox", config.mailbox)?;
        out.set_item("triangles", self.triangles.triangle_count())?;
        out.set_item("degenerate_triangles", self.triangles.degenerate_count())?;
        let (resolution, cells) = self
            .grid
            .shape()
            .map_or(([0u32; 3], 0), |s| (s.resolution, s.cell_count()));
        out.set_item("resolution", resolution)?;
        out.set_item("cells", cells)?;
        out.set_item("listed", self.grid.listed())?;
        out.set_item(
            "triangles_per_cell",
            self.grid.listed() as f64 / cells.max(1) as f64,
        )?;
        out.set_item("memory_bytes", self.grid.memory_bytes())?;
        out.set_item("build_seconds", self.build_seconds)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "hbv.Grid({} triangles, lam={})",
            self.triangles.triangle_count(),
            self.grid.config().lambda
        )
    }

    /// Pickled as its mesh and density; unpickling rebuilds the grid (the same grid).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let me = slf.get();
        let args = (me.mesh.clone_ref(py), me.grid.config().lambda).into_pyobject(py)?;
        PyTuple::new(py, [slf.get_type().into_any(), args.into_any()])
    }
}
