//! `hbv.Scene`: many meshes placed by instances in one two-level BVH (hbv::scene), NumPy in and
//! out, on all cores with the GIL released. Saving, pickling and `hbv.load_scene` are in
//! `scene_file.rs`.

use std::collections::HashMap;
use std::ffi::CString;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};

use hbv::proximity::{InsideCells, InsideCellsConfig};
use hbv::scene::{InstanceId, MeshId, Scene, SceneError};
use numpy::PyArray1;
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::float_array;
use crate::masks::{one_mask, row_masks, Masks};
use crate::ray_queries::{any_hits, closest_hits, hit_counts, RayArgs};
use crate::scene_arguments::{instance_id, read_transform, MeshKey, NewMesh};
use crate::scene_file;
use crate::scene_queries::{
    every_scene_hit, scene_closest_points, scene_inside, scene_signed_distances, MaskedPoints,
    SceneInsideCells, SceneTracer,
};
use crate::thread_pool::ThreadCount;

/// Meshes placed by instances, each with an id, a transform and a mask, in one two-level BVH.
///
/// Scene() is empty; add(mesh, transform=None, mask=None) places a mesh and returns the
/// instance's id (0, 1, 2, ... in the order of the calls, never reused). The same mesh object
/// added again is one mesh of the scene, instanced again (its BVH is built once).
///
/// Queries answer as `hbv.BVH`'s, with `instance` (int64, -1 on a miss) and `normal` (the unit
/// geometric normal in world space, (N, 3) float32) beside `prim`, `t`, `u`, `v`, which are the
/// instance's mesh's. `mask=` (an integer, or one per ray or point, uint32): a ray sees
/// instance i only if `mask & mask_i != 0`; the default sees every instance whose mask is not 0.
///
/// set_transform, set_mask and remove change the scene; queries see the change at once.
///
/// save(path) writes it to a .hbv scene file, which hbv.load_scene reads back; it pickles as
/// the same bytes. Either way the instances keep their ids (removed ones stay holes), their
/// transforms and masks, and every query answers bit for bit as before; what is not kept is
/// which Python objects were added (the same object added to the scene read back is a new
/// mesh of it).
#[pyclass(name = "Scene", module = "hbv", frozen)]
pub struct PyScene {
    state: Mutex<SceneState>,
}

struct SceneState {
    /// The scene as queries see it. A query holds it for its call without the lock (so that
    /// queries of other threads run beside it); a change made meanwhile changes a copy
    /// (`Arc::make_mut`), and the query answers the scene as it was when it started.
    scene: Arc<Scene>,
    /// Instances were added, moved or removed since the top level was last brought up to date:
    /// the next query updates it first (a refit or a rebuild, `Scene::update`), so that a run
    /// of changes costs one update.
    changed: bool,
    /// The scene's mesh of each object `add` was given (`MeshKey`: its identity).
    meshes_by_key: HashMap<MeshKey, MeshId>,
    /// The objects keyed in `meshes_by_key`, kept alive so that no other object takes their
    /// address (and so their key) while the scene lives.
    key_objects: Vec<Py<PyAny>>,
    /// Whether each mesh is closed, for the meshes `contains` has looked at (a mesh's vertices
    /// never change here).
    closed: Vec<bool>,
    /// The inside grid of the scene as it is, for `contains` and `signed_distance` without a
    /// mask on closed meshes: made by the call that brings the points they asked since the
    /// scene last changed to `INSIDE_CELLS_AFTER_POINTS`; dropped when the scene changes.
    inside_cells: Option<Arc<SceneInsideCells>>,
    /// The points `contains` and `signed_distance` asked without a mask since the scene last
    /// changed.
    inside_points_asked: usize,
}

/// The points asked of the inside tests after which the scene makes its inside grid
/// (`InsideCells`): about the number of exact tests the grid's making costs at 128 cells a side
/// (one per run of free cells), so that a few points never pay for it and many pay once.
const INSIDE_CELLS_AFTER_POINTS: usize = 32_768;

impl PyScene {
    pub(crate) fn from_scene(scene: Scene) -> Self {
        Self {
            state: Mutex::new(SceneState {
                scene: Arc::new(scene),
                changed: false,
                meshes_by_key: HashMap::new(),
                key_objects: Vec::new(),
                closed: Vec::new(),
                inside_cells: None,
                inside_points_asked: 0,
            }),
        }
    }

    /// The state, locked. Never held while waiting for the GIL (a change that takes long, a
    /// mesh's build, runs with the GIL released and the lock held), so no thread holding the
    /// GIL waits for one that waits for it.
    fn lock(&self) -> MutexGuard<'_, SceneState> {
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// What every ray query reads: the rays and their interval, one mask a ray, and the scene
    /// as it is now.
    fn ray_query<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        mask: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(RayArgs<'py>, Masks<'py>, Arc<Scene>)> {
        let args = RayArgs::read(origins, directions, tmin, tmax)?;
        let masks = row_masks(mask, args.batch().len(), "origins")?;
        Ok((args, masks, self.current(py)))
    }

    /// The scene as it is now, its top level brought up to date first if it changed, for a
    /// query to read without the lock.
    pub(crate) fn current(&self, py: Python<'_>) -> Arc<Scene> {
        py.detach(|| {
            let mut state = self.lock();
            Self::bring_up_to_date(&mut state);
            state.scene.clone()
        })
    }

    /// Updates the top level if the scene changed since the last query, dropping what was
    /// made for the scene as it was.
    fn bring_up_to_date(state: &mut SceneState) {
        if state.changed {
            Arc::make_mut(&mut state.scene).update();
            state.changed = false;
            state.inside_cells = None;
            state.inside_points_asked = 0;
        }
    }

    /// The scene as it is now with its inside grid, for an inside test of `rows` points: the
    /// grid only without a mask (`masked` false) and when every mesh is closed (checked by
    /// `warn_if_open` first), made here by the call that brings the points asked to
    /// `INSIDE_CELLS_AFTER_POINTS` (with the GIL released and the lock held, as a change).
    fn current_with_inside_cells(
        &self,
        py: Python<'_>,
        rows: usize,
        masked: bool,
    ) -> (Arc<Scene>, Option<Arc<SceneInsideCells>>) {
        py.detach(|| {
            let mut state = self.lock();
            let state = &mut *state;
            Self::bring_up_to_date(state);
            let all_closed = state.closed.len() == state.scene.mesh_count()
                && state.closed.iter().all(|&closed| closed);
            if masked || !all_closed {
                return (state.scene.clone(), None);
            }
            state.inside_points_asked = state.inside_points_asked.saturating_add(rows);
            if state.inside_cells.is_none()
                && state.inside_points_asked >= INSIDE_CELLS_AFTER_POINTS
            {
                let scene = &state.scene;
                let by_segments = scene.live_instance_count() == 1;
                state.inside_cells = scene.flattened().ok().and_then(|world| {
                    let config = InsideCellsConfig::default();
                    let cells = InsideCells::new(&world.mesh, &config, |centres| {
                        scene.contains_batch(centres, None)
                    })?;
                    Some(Arc::new(SceneInsideCells { cells, by_segments }))
                });
            }
            (state.scene.clone(), state.inside_cells.clone())
        })
    }

    /// Applies `change` to the scene, with the GIL released.
    fn change<T: Send>(
        &self,
        py: Python<'_>,
        change: impl FnOnce(&mut Scene) -> Result<T, SceneError> + Send,
    ) -> PyResult<T> {
        py.detach(|| {
            let mut state = self.lock();
            let result = change(Arc::make_mut(&mut state.scene));
            state.changed |= result.is_ok();
            result
        })
        .map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// Issues a RuntimeWarning, attributed to the Python caller, when a mesh of the scene is
    /// not closed: inside tests are not defined near its open edges (`Mesh.open_edges`).
    fn warn_if_open(&self, py: Python<'_>) -> PyResult<()> {
        let (open, meshes) = py.detach(|| {
            let mut state = self.lock();
            let state = &mut *state;
            for id in state.closed.len()..state.scene.mesh_count() {
                let mesh = state
                    .scene
                    .mesh(MeshId(id as u32))
                    .expect("a mesh id below the count");
                state.closed.push(mesh.is_closed());
            }
            let open: Vec<usize> = (0..state.closed.len())
                .filter(|&i| !state.closed[i])
                .collect();
            (open, state.closed.len())
        });
        if open.is_empty() {
            return Ok(());
        }
        let message = format!(
            "contains: {} of the scene's {meshes} meshes are not closed (mesh ids {:?}, in the \
             order they were added); inside is not defined near their open edges, and points \
             there may be answered either way (see Mesh.open_edges)",
            open.len(),
            open
        );
        let message = CString::new(message).expect("no NUL in the message");
        PyErr::warn(py, &py.get_type::<PyRuntimeWarning>(), &message, 1)
    }

    /// Reads the points and masks of an inside test (`contains`, `signed_distance`), warns
    /// when a mesh is open, and has `answer` answer them on the scene as it is, with its
    /// inside grid where one serves.
    fn inside_query<'py, T>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
        answer: impl FnOnce(&Scene, Option<&SceneInsideCells>, MaskedPoints<'_>) -> PyResult<T>,
    ) -> PyResult<T> {
        let (points, rows) = float_array("points", points, Some(3), None)?;
        let masks = row_masks(mask, rows, "points")?;
        self.warn_if_open(py)?;
        let (scene, cells) = self.current_with_inside_cells(py, rows, mask.is_some());
        let query = MaskedPoints {
            points: points.values(),
            rows,
            masks: masks.as_slice(),
        };
        answer(&scene, cells.as_deref(), query)
    }

    /// The id `instance`, checked to be an integer the scene handed out.
    fn instance(&self, instance: &Bound<'_, PyAny>) -> PyResult<InstanceId> {
        let issued = self.lock().scene.instance_count();
        instance_id(instance, issued)
    }
}

#[pymethods]
impl PyScene {
    #[new]
    fn new() -> Self {
        Self::from_scene(Scene::new())
    }

    /// Places a mesh and returns the new instance's id (int).
    ///
    /// mesh: an hbv.Mesh; an hbv.BVH (its tree is laid out again, not built again); a
    ///     (vertices, faces) pair; or an object with vertices and faces (a trimesh.Trimesh).
    ///     Float64 vertices are stored in float32 relative to their own centre, so that a mesh
    ///     far from the origin keeps float32's precision of its size. The same object (the
    ///     same pair of arrays) added again is the same mesh of the scene: its contents are
    ///     read when it is first added.
    /// transform: None (identity), or a (4, 4) or (3, 4) matrix acting on column vectors
    ///     (x, y, z, 1), read as float64; finite, affine and invertible (ValueError otherwise).
    /// mask: None (every bit) or an integer from 0 to 2**32 - 1.
    #[pyo3(signature = (mesh, transform=None, mask=None))]
    fn add(
        &self,
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        transform: Option<&Bound<'_, PyAny>>,
        mask: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u32> {
        let transform = read_transform(transform)?;
        let mask = one_mask("mask", mask)?;
        let (key, key_objects) = MeshKey::of(mesh);
        let known = self.lock().meshes_by_key.get(&key).copied();
        let new_mesh = match known {
            Some(_) => None,
            None => Some(NewMesh::read(mesh)?),
        };
        let (instance, unused_keys) = py.detach(|| -> PyResult<_> {
            let mut state = self.lock();
            let state = &mut *state;
            // Another thread may have added the same object meanwhile.
            let (mesh, unused_keys) = match (state.meshes_by_key.get(&key), new_mesh) {
                (Some(&id), _) => (id, Some(key_objects)),
                (None, Some(new_mesh)) => {
                    let id = new_mesh.add_to(Arc::make_mut(&mut state.scene))?;
                    state.meshes_by_key.insert(key, id);
                    state.key_objects.extend(key_objects);
                    (id, None)
                }
                (None, None) => unreachable!("a mesh unknown when looked up was read"),
            };
            let instance = Arc::make_mut(&mut state.scene)
                .add_instance(mesh, transform, mask)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            state.changed = true;
            Ok((instance, unused_keys))
        })?;
        // Released with the GIL held.
        drop(unused_keys);
        Ok(instance.0)
    }

    /// Moves instance `instance` to `transform` (as in `add`). ValueError for an id not handed
    /// out or removed, or a transform that is not finite, affine and invertible.
    fn set_transform(
        &self,
        py: Python<'_>,
        instance: &Bound<'_, PyAny>,
        transform: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let instance = self.instance(instance)?;
        let transform = read_transform(Some(transform))?;
        self.change(py, |scene| scene.set_transform(instance, transform))
    }

    /// Sets the mask of instance `instance` (an integer from 0 to 2**32 - 1).
    fn set_mask(
        &self,
        py: Python<'_>,
        instance: &Bound<'_, PyAny>,
        mask: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let instance = self.instance(instance)?;
        let mask = one_mask("mask", Some(mask))?;
        self.change(py, |scene| scene.set_mask(instance, mask))
    }

    /// Removes instance `instance`: it is never hit again, and its id is never handed out
    /// again (every other id keeps its meaning).
    fn remove(&self, py: Python<'_>, instance: &Bound<'_, PyAny>) -> PyResult<()> {
        let instance = self.instance(instance)?;
        self.change(py, |scene| scene.remove_instance(instance))
    }

    /// Saves the scene to `path` as a .hbv scene file (docs/BVH_FILE.md), which
    /// hbv.load_scene and `hbv trace` read back: every mesh with its tree, every instance by id
    /// (removed ones as holes) with its transform and mask. Written atomically (a temporary
    /// file, then renamed into place); FileExistsError if `path` exists, unless
    /// `overwrite=True` (also if it appears while the scene is written).
    #[pyo3(signature = (path, overwrite=false))]
    fn save(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<()> {
        let scene = self.current(py);
        scene_file::save(py, &scene, &path, overwrite)
    }

    /// Pickled as the bytes of its .hbv scene file (see `save`); unpickling lays out the saved
    /// trees, building no mesh again.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let scene = slf.get().current(py);
        scene_file::reduce(py, &scene)
    }

    /// The number of instance ids handed out, removed ones included: ids are 0 to this - 1.
    #[getter]
    fn instance_count(&self) -> usize {
        self.lock().scene.instance_count()
    }

    /// The number of meshes (each built once, however many instances place it).
    #[getter]
    fn mesh_count(&self) -> usize {
        self.lock().scene.mesh_count()
    }

    /// The box of every instance, ((min x, y, z), (max x, y, z)).
    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let b = self.lock().scene.bounds();
        (b.min.to_array(), b.max.to_array())
    }

    /// The number of instances not removed.
    fn __len__(&self) -> usize {
        self.lock().scene.live_instance_count()
    }

    fn __repr__(&self) -> String {
        let state = self.lock();
        let scene = &state.scene;
        format!(
            "hbv.Scene({} meshes, {} instances)",
            scene.mesh_count(),
            scene.live_instance_count()
        )
    }

    /// Closest hits: a dict of arrays `hit` (bool), `t` (float32, inf on a miss), `prim`
    /// (int64, the triangle of the instance's mesh, -1 on a miss), `u`, `v` (float32, 0 on a
    /// miss), `instance` (int64, -1 on a miss), `normal` ((N, 3) float32, the unit geometric
    /// normal in world space, 0 on a miss). Ties: the smaller instance, then the smaller prim.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, mask=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (args, masks, scene) = self.ray_query(py, origins, directions, tmin, tmax, mask)?;
        let tracer = SceneTracer::new(&scene, args.batch(), masks.as_slice());
        closest_hits(py, &tracer, &args, threads)
    }

    /// Any hit: a bool array, true where an instance the ray sees is hit in [tmin, tmax].
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, mask=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let (args, masks, scene) = self.ray_query(py, origins, directions, tmin, tmax, mask)?;
        let tracer = SceneTracer::new(&scene, args.batch(), masks.as_slice());
        any_hits(py, &tracer, &args, threads)
    }

    /// Every hit along each ray: a tuple of arrays (ray index int64, t float32, prim int64,
    /// instance int64, normal (H, 3) float32), in ray order and, within a ray, sorted by t, then
    /// instance, then prim.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, mask=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn intersect_all<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let (args, masks, scene) = self.ray_query(py, origins, directions, tmin, tmax, mask)?;
        every_scene_hit(py, &scene, args.batch(), masks.as_slice(), threads)
    }

    /// The number of hits along each ray (int64): the length of its `intersect_all` list.
    #[pyo3(signature = (origins, directions, tmin=None, tmax=None, mask=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn count<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let (args, masks, scene) = self.ray_query(py, origins, directions, tmin, tmax, mask)?;
        let tracer = SceneTracer::new(&scene, args.batch(), masks.as_slice());
        hit_counts(py, || tracer, &args, threads)
    }

    /// Whether each point lies inside the scene, among the instances its mask sees: a bool
    /// array, true where the point is inside one of those instances (the union of their
    /// solids: overlapping instances do not cancel), each decided by its mesh's exact parity
    /// test (hbv::scene::Scene::contains). Defined on closed meshes; a RuntimeWarning when a
    /// mesh of the scene is not. Points on a surface may go either way. Without a mask, on
    /// closed meshes, the call that brings the points asked since the scene last changed to
    /// 32,768 makes a grid of the cells no triangle touches, each decided once
    /// (hbv::proximity::InsideCells), and later points in those cells are looked up there:
    /// the same answers, most points without a ray.
    #[pyo3(signature = (points, mask=None, threads=None))]
    fn contains<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        self.inside_query(py, points, mask, |scene, cells, query| {
            scene_inside(py, scene, cells, query, threads)
        })
    }

    /// The nearest surface point among the instances each point's mask sees: a dict of arrays
    /// `point` (N, 3) float64, `distance` float64, `prim` int64, `u`, `v` float64 (barycentrics
    /// of the triangle of the instance's mesh) and `instance` int64; ties to the smaller
    /// instance, then the smaller prim. NaN, inf, -1, 0, 0, -1 for a point that is not finite
    /// or sees no triangle.
    #[pyo3(signature = (points, mask=None, threads=None))]
    fn closest_point<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (points, rows) = float_array("points", points, Some(3), None)?;
        let masks = row_masks(mask, rows, "points")?;
        let scene = self.current(py);
        let query = MaskedPoints {
            points: points.values(),
            rows,
            masks: masks.as_slice(),
        };
        scene_closest_points(py, &scene, query, threads)
    }

    /// The distance to the nearest surface among the instances each point's mask sees
    /// (`closest_point`'s `distance`, float64), negative inside (`contains`): the sign of
    /// `hbv.BVH.signed_distance` and Open3D's `compute_signed_distance`, the opposite of
    /// trimesh's. Exact where `contains` is, on closed meshes (a RuntimeWarning otherwise,
    /// where the sign is one ray's parity); a point on a surface gets 0 of either sign; +inf
    /// for a point that is not finite or sees no triangle.
    #[pyo3(signature = (points, mask=None, threads=None))]
    fn signed_distance<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.inside_query(py, points, mask, |scene, cells, query| {
            scene_signed_distances(py, scene, cells, query, threads)
        })
    }
}
