//! `hbv.BVH`: a tree over a mesh and every query on it, NumPy in and out, on all cores with the
//! GIL released.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use hbv::bvh::file::BvhFile;
use hbv::bvh::layout::Wide8Layout;
use hbv::bvh::{expected_tests, sah_cost, BuildTree, SahWeights};
use hbv::proximity::{
    BatchThreads, ClosestPointColumns, ClosestPointTree, ClosestPointsOnDemand, FlatPoints,
    NearestPointSearch,
};
use hbv::{Accelerator, TriangleMesh};
use numpy::{IntoPyArray, PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::{float_array, FloatSlice};
use crate::build_options::{BuildOptions, FirstBuild};
use crate::bvh_file::{describe, save};
use crate::mesh::PyMesh;
use crate::mesh_inside::InsideCellsOnDemand;
use crate::ray_queries::{
    any_hits, closest_hits, every_hit, hit_counts, inside_with_cells, MeshCounter, MeshTracer,
    RayArgs,
};
use crate::thread_pool::{one_thread, run_here_or_on_threads, ThreadCount};

/// A bounding volume hierarchy over a mesh, answering ray and point queries.
///
/// BVH(mesh, builder=None, layout=None, optimize=None, leaf_size=None, quality="medium")
///
/// quality: "low" (LBVH: the fastest build, for rebuilding often), "medium" (default: binned
///     SAH) or "high" (binned SAH + reinsertion optimization: the fastest rays); builder,
///     optimize and leaf_size given with it replace its choices.
/// builder: "binned-sah" (quality medium's and high's), "sweep-sah", "insertion", "median",
///     "lbvh" (quality low's) or "ploc".
/// layout: "wide8" (default, the fastest), "wide4", "ordered", "recursive" or "skip".
/// optimize: reinsertion optimization (Bittner et al. 2013) after building: True, False, or
///     None (default): the quality's choice, and at any quality for meshes of at most 1,024
///     triangles, where it costs about a millisecond and makes modelled scenes (walls around
///     furniture) up to 1.4x faster to trace. Larger modelled scenes gain too (True); scanned
///     meshes gain nothing from it.
///
/// save(path) writes the tree with its mesh to a `.hbv` file; hbv.load_bvh(path) reads it back
/// without building again.
/// leaf_size: most triangles per leaf (1 to 255; default: the builder's).
///
/// Built here (`stats()["build_seconds"]`): with binned SAH without optimization into a wide
/// layout (quality "medium") on meshes of 8,192 triangles or more, the layout itself, straight
/// from the mesh; otherwise the tree. What each kind of query walks is made on that kind's first
/// call: the layout on the first intersect or occluded, the wide-8 layout on the first
/// intersect_all, count or contains. closest_point and signed_distance walk the tree itself
/// for their first 32 √triangles points, then make a nearest-point tree in the call that would
/// pass that count. The tree, where the layout was built without it, is built (the same tree
/// as ever) on the first call that needs it: closest_point, save, stats, a layout other than
/// the one built, adding the BVH to a Scene. Every answer is the same either way.
#[pyclass(name = "BVH", module = "hbv", frozen)]
pub struct PyBvh {
    mesh: Py<PyMesh>,
    triangles: Arc<TriangleMesh>,
    options: BuildOptions,
    /// The build tree: built by the constructor, or on first use where the constructor built
    /// the layout straight from the mesh (`BuildOptions::build_first`).
    tree: OnceLock<Arc<BuildTree>>,
    /// The tree laid out as `options.layout` says, for the closest- and any-hit queries: made
    /// on the first of them, so that a BVH asked only for nearest points never lays out a ray
    /// structure (the dragon's wide-8 layout takes a third of its build's time).
    accel: OnceLock<Arc<dyn Accelerator>>,
    /// The wide-8 layout of the same tree: the all-hits queries' structure (made on first use;
    /// `accel` too when it is the layout).
    wide: OnceLock<Arc<Wide8Layout>>,
    /// The nearest-point queries: walks of `tree` at first, the search tree once it pays
    /// (`ClosestPointsOnDemand`); made on the first of them.
    closest: OnceLock<ClosestPointsOnDemand>,
    /// The inside tests' grid on a closed mesh, once enough points have been asked
    /// (`InsideCellsOnDemand`).
    inside_cells: InsideCellsOnDemand,
    build_seconds: f64,
    /// The settings line saved with the tree (`hbv build`'s words), or read from its file.
    settings: String,
}

/// The (N, 3) rows of a checked point array.
fn rows_of<T>(values: &[T]) -> FlatPoints<'_, T> {
    FlatPoints::new(values).expect("float_array checked the shape (N, 3)")
}

impl PyBvh {
    /// A BVH over a tree built elsewhere (loaded from a file), or built here in
    /// `build_seconds`; its structures are laid out on first use.
    pub fn from_parts(
        mesh: Py<PyMesh>,
        triangles: Arc<TriangleMesh>,
        options: BuildOptions,
        tree: BuildTree,
        build_seconds: f64,
        settings: String,
    ) -> Self {
        let first = FirstBuild::Tree(tree);
        Self::with_first_build(mesh, triangles, options, first, build_seconds, settings)
    }

    /// A BVH holding what was built first (the tree, or a layout straight from the mesh);
    /// everything else is made on first use.
    fn with_first_build(
        mesh: Py<PyMesh>,
        triangles: Arc<TriangleMesh>,
        options: BuildOptions,
        first: FirstBuild,
        build_seconds: f64,
        settings: String,
    ) -> Self {
        let (tree, accel, wide) = (OnceLock::new(), OnceLock::new(), OnceLock::new());
        let set = match first {
            FirstBuild::Tree(built) => tree.set(Arc::new(built)).is_ok(),
            FirstBuild::Wide8(built) => wide.set(Arc::new(built)).is_ok(),
            FirstBuild::Layout(built) => accel.set(built).is_ok(),
        };
        debug_assert!(set, "a new lock takes its first value");
        Self {
            mesh,
            triangles,
            options,
            tree,
            accel,
            wide,
            closest: OnceLock::new(),
            inside_cells: InsideCellsOnDemand::default(),
            build_seconds,
            settings,
        }
    }

    /// The `.hbv` file's contents: the mesh, the tree and the settings line.
    pub fn to_file(&self) -> BvhFile {
        BvhFile {
            mesh: (*self.triangles).clone(),
            tree: (**self.tree_off_gil()).clone(),
            settings: self.settings.clone(),
        }
    }

    /// The mesh and the tree built over it (what `hbv.Scene.add` lays out again).
    pub fn mesh_and_tree(&self) -> (&Arc<TriangleMesh>, &Arc<BuildTree>) {
        (&self.triangles, self.tree_off_gil())
    }

    /// The build tree, built now (by the options, deterministically: the tree the constructor
    /// would have kept) if the constructor laid the mesh out without one.
    fn tree(&self) -> &Arc<BuildTree> {
        self.tree
            .get_or_init(|| Arc::new(self.options.build(&self.triangles)))
    }

    /// [`PyBvh::tree`] for a caller holding the GIL: released while the tree is built.
    fn tree_off_gil(&self) -> &Arc<BuildTree> {
        match self.tree.get() {
            Some(tree) => tree,
            None => Python::attach(|py| py.detach(|| self.tree())),
        }
    }

    fn wide(&self) -> &Arc<Wide8Layout> {
        self.wide
            .get_or_init(|| Arc::new(Wide8Layout::new(self.tree(), &self.triangles)))
    }

    /// The nearest-point queries' state, made (with the tree, if it is still to be built) on
    /// the first of them.
    fn closest(&self) -> &ClosestPointsOnDemand {
        self.closest
            .get_or_init(|| ClosestPointsOnDemand::new(self.tree().clone(), self.triangles.clone()))
    }

    /// The structure of the closest- and any-hit queries, laid out now if this is the first
    /// (with the GIL released: other Python threads go on meanwhile).
    fn accel(&self, py: Python<'_>) -> &dyn Accelerator {
        let laid_out =
            || (self.options).lay_out(|| self.tree(), &self.triangles, || self.wide().clone());
        match self.accel.get() {
            Some(accel) => &**accel,
            None => &**py.detach(|| self.accel.get_or_init(laid_out)),
        }
    }
}

#[pymethods]
impl PyBvh {
    #[new]
    #[pyo3(signature = (
        mesh, builder=None, layout=None, optimize=None, leaf_size=None, quality="medium"
    ))]
    fn new(
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        builder: Option<&str>,
        layout: Option<&str>,
        optimize: Option<bool>,
        leaf_size: Option<usize>,
        quality: &str,
    ) -> PyResult<Self> {
        let mesh = PyMesh::from_argument(mesh)?;
        let triangles = mesh.get().mesh.clone();
        let options = BuildOptions::from_arguments(
            quality,
            builder,
            layout,
            optimize,
            leaf_size,
            triangles.triangle_count(),
        )?;
        let (built, build_seconds) = py.detach(|| {
            let start = Instant::now();
            let built = options.build_first(&triangles);
            (built, start.elapsed().as_secs_f64())
        });
        let settings = describe(&options);
        let mesh = mesh.clone().unbind();
        Ok(Self::with_first_build(
            mesh,
            triangles,
            options,
            built,
            build_seconds,
            settings,
        ))
    }

    /// The mesh the tree was built over.
    #[getter]
    fn mesh(&self, py: Python<'_>) -> Py<PyMesh> {
        self.mesh.clone_ref(py)
    }

    #[getter]
    fn builder(&self) -> &str {
        self.options.builder_name()
    }

    #[getter]
    fn layout(&self) -> &str {
        self.options.layout.name()
    }

    /// Closest hits: a dict of arrays `hit` (bool), `t` (float32, inf on a miss), `prim`
    /// (int64, -1 on a miss), `u`, `v` (float32 barycentrics, 0 on a miss), `normal` ((N, 3)
    /// float32, the unit geometric normal normalize(cross(p1 - p0, p2 - p0)) of the triangle
    /// hit, 0 on a miss), as docs/RAYS.md.
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
            accel: self.accel(py),
            mesh: &self.triangles,
        };
        closest_hits(py, &tracer, &args, threads)
    }

    /// Any hit: a bool array, true where anything lies in [tmin, tmax] along the ray.
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
            accel: self.accel(py),
            mesh: &self.triangles,
        };
        any_hits(py, &tracer, &args, threads)
    }

    /// Every hit along each ray, found in one traversal per ray: a tuple of arrays
    /// (ray index int64, t float32, prim int64), in ray order and, within a ray, sorted by t
    /// (equal t by prim). A ray crossing the surface exactly through an edge or vertex lists
    /// one of the triangles there (decided exactly), so a closed mesh is crossed an even
    /// number of times by a ray from outside.
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
        every_hit(py, || &**self.wide(), &args, threads)
    }

    /// The number of hits along each ray (int64): the length of its `intersect_all` list, so
    /// a crossing through an edge or vertex counts once.
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
        hit_counts(py, || MeshCounter(&**self.wide()), &args, threads)
    }

    /// Whether each point lies inside the (closed) mesh: bool array. One ray's parity, exact:
    /// a ray through an edge or vertex counts a crossing once (see hbv::proximity::inside);
    /// points on the surface may go either way. A RuntimeWarning when the mesh is not closed
    /// (`Mesh.open_edges` > 0): inside is then not defined near its open edges, and the
    /// majority of three rays' parities answers (steadier there than one ray).
    ///
    /// On a closed mesh, the call that brings the points asked (of `contains` and
    /// `signed_distance`, all calls together) to 32,768 makes an inside grid
    /// (hbv::proximity::InsideCells), and later points are answered through it: by a lookup in
    /// the cells that no triangle touches, by a short segment to such a cell near the surface,
    /// by the ray elsewhere. The answers are the same whichever answers them.
    #[pyo3(signature = (points, threads=None))]
    fn contains<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let structure = || &**self.wide();
        let cells = Some(&self.inside_cells);
        inside_with_cells(py, self.mesh.get(), structure, cells, points, threads)
    }

    /// The nearest surface point to each point: a dict of arrays `point` (N, 3) float64,
    /// `distance` float64, `prim` int64 (the triangle), `u`, `v` float64 barycentrics (point =
    /// (1-u-v) p0 + u p1 + v p2). Exact in f64 (equal to a float64 brute force); ties go to the
    /// smallest triangle id. Non-finite points (or an empty mesh) give NaN, inf, -1, 0, 0.
    ///
    /// The first 32 √triangles points (all calls together) are answered by walking the BVH's
    /// own tree; the call that would pass that count makes a search tree,
    /// faster per point, and every later call uses it: a few points never pay for the search
    /// tree, many pay for it once. On meshes of few large triangles (rooms, boxes) a candidate
    /// grid that answers most points from a short list is made once about 130,000 points have
    /// been asked of the search tree (the call that reaches it included), when its cost has
    /// been paid back. The answers are the same whichever answers them.
    #[pyo3(signature = (points, threads=None))]
    fn closest_point<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyDict>> {
        // Read in place where the array allows, exactly (float64 stays float64).
        let (points, n) = float_array("points", points, Some(3), None)?;
        let points = points.values();
        let (mut point, mut distance) = (vec![[0.0f64; 3]; n], vec![0.0f64; n]);
        let (mut prim, mut u, mut v) = (vec![0i64; n], vec![0.0f64; n], vec![0.0f64; n]);
        // One thread is the calling thread itself (`BatchThreads::CALLING_THREAD`), not a pool
        // of one to wake; so is one run of points whatever `threads` says (a batch answers it
        // in place).
        let here = one_thread(threads);
        let batch_threads = if here {
            BatchThreads::CALLING_THREAD
        } else {
            BatchThreads::POOL
        };
        py.detach(|| {
            let answer = || {
                let columns = ClosestPointColumns {
                    point: &mut point,
                    distance: &mut distance,
                    prim: &mut prim,
                    u: &mut u,
                    v: &mut v,
                };
                match points {
                    FloatSlice::F32(values) => self.closest().closest_points_into_with(
                        &rows_of(values),
                        columns,
                        batch_threads,
                    ),
                    FloatSlice::F64(values) => self.closest().closest_points_into_with(
                        &rows_of(values),
                        columns,
                        batch_threads,
                    ),
                }
            };
            run_here_or_on_threads(here || n <= ClosestPointTree::RUN, threads, answer)
        })?;
        let point = point.into_flattened();
        let out = PyDict::new(py);
        out.set_item("point", point.into_pyarray(py).reshape([n, 3])?)?;
        out.set_item("distance", distance.into_pyarray(py))?;
        out.set_item("prim", prim.into_pyarray(py))?;
        out.set_item("u", u.into_pyarray(py))?;
        out.set_item("v", v.into_pyarray(py))?;
        Ok(out)
    }

    /// The signed distance of each point to the surface (float64): `closest_point`'s distance,
    /// negative inside the mesh (`contains`), as Open3D's `compute_signed_distance` and most SDF
    /// code (trimesh's `signed_distance` has the opposite sign). Exact where `contains` is: on a
    /// closed mesh (`Mesh.is_closed`); otherwise `contains` warns, and the sign is the majority
    /// of three rays' parities. A point on the surface gets 0 (of either sign); a point without
    /// a nearest point (not finite, or an empty mesh) +inf, as in `closest_point`. The inside
    /// tests are `contains`', its inside grid included.
    #[pyo3(signature = (points, threads=None))]
    fn signed_distance<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let distance = self
            .closest_point(py, points, threads)?
            .get_item("distance")?
            .expect("closest_point answers a distance")
            .cast_into::<PyArray1<f64>>()?;
        let inside = self.contains(py, points, threads)?;
        {
            let (inside, mut signed) = (inside.try_readonly()?, distance.try_readwrite()?);
            for (d, &inside) in signed.as_slice_mut()?.iter_mut().zip(inside.as_slice()?) {
                if inside {
                    *d = -*d;
                }
            }
        }
        Ok(distance)
    }

    /// Saves the tree with its mesh to `path` in the `.hbv` format (docs/BVH_FILE.md), for
    /// `hbv.load_bvh(path)` or the `hbv` command line. Written atomically (a temporary file,
    /// then renamed into place); FileExistsError if `path` exists, unless `overwrite=True`
    /// (also if it appears while the tree is written).
    #[pyo3(signature = (path, overwrite=false))]
    fn save(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<()> {
        save(py, self, path, overwrite)
    }

    /// The tree's expected number of intersection tests per random line, E[X] =
    /// Σ_n a_n · SA(n) / SA(root) (a_n: child boxes, or triangles of a leaf, tested at n).
    fn expected_tests(&self, py: Python<'_>) -> f64 {
        py.detach(|| expected_tests(self.tree()))
    }

    /// The SAH cost (MacDonald & Booth 1990) with weights C_t (traversal) and C_i
    /// (intersection): Σ_internal C_t·SA(n)/SA(root) + Σ_leaf C_i·|n|·SA(n)/SA(root).
    #[pyo3(signature = (traversal=1.0, intersection=1.0))]
    fn sah_cost(&self, py: Python<'_>, traversal: f64, intersection: f64) -> PyResult<f64> {
        if !(traversal.is_finite() && intersection.is_finite()) {
            return Err(PyValueError::new_err(
                "sah_cost: the weights must be finite numbers",
            ));
        }
        let weights = SahWeights {
            traversal,
            intersection,
        };
        Ok(py.detach(|| sah_cost(self.tree(), weights)))
    }

    /// The tree's shape and costs, and how it was built, as a dict.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let tree = py.detach(|| self.tree());
        let shape = tree.shape();
        let out = PyDict::new(py);
        out.set_item("builder", self.options.builder_name())?;
        out.set_item("layout", self.options.layout.name())?;
        out.set_item("optimize", self.options.optimize)?;
        out.set_item("leaf_size", self.options.leaf_size)?;
        out.set_item("triangles", self.triangles.triangle_count())?;
        out.set_item("degenerate_triangles", self.triangles.degenerate_count())?;
        out.set_item("nodes", shape.nodes)?;
        out.set_item("leaves", shape.leaves)?;
        out.set_item("depth_max", shape.depth_max)?;
        out.set_item("depth_mean", shape.depth_mean)?;
        out.set_item("expected_tests", expected_tests(tree))?;
        out.set_item("sah_cost", sah_cost(tree, SahWeights::default()))?;
        out.set_item("build_seconds", self.build_seconds)?;
        out.set_item("settings", &self.settings)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "hbv.BVH({} triangles, builder={:?}, layout={:?}, optimize={}, leaf_size={})",
            self.triangles.triangle_count(),
            self.options.builder_name(),
            self.options.layout.name(),
            if self.options.optimize {
                "True"
            } else {
                "False"
            },
            self.options
                .leaf_size
                .map_or("None".to_string(), |k| k.to_string())
        )
    }

    /// Pickled as its mesh and options; unpickling rebuilds the tree (deterministically: the
    /// same tree and the same answers).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let me = slf.get();
        if me.options.builder.is_none() {
            // Loaded from a file that names no builder of this package: pickled as the file.
            let bytes = pyo3::types::PyBytes::new(py, &me.to_file().to_bytes());
            let from_bytes = py.import("hbv._hbv")?.getattr("_bvh_from_bytes")?;
            let args = (bytes, me.options.layout.name()).into_pyobject(py)?;
            return PyTuple::new(py, [from_bytes, args.into_any()]);
        }
        let args = (
            me.mesh.clone_ref(py),
            me.options.builder_name(),
            me.options.layout.name(),
            me.options.optimize,
            me.options.leaf_size,
        )
            .into_pyobject(py)?;
        PyTuple::new(py, [slf.get_type().into_any(), args.into_any()])
    }
}
