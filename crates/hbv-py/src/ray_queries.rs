//! The ray and point queries that `hbv.BVH`, `hbv.Grid` and `hbv.Scene` share: arguments read
//! and checked once, answered by a [`RayTracer`] (a mesh's [`Accelerator`], or a scene) and a
//! [`HitCounter`] on all cores with the GIL released.

use hbv::geometry::{Ray, Triangle};
use hbv::proximity::contains_by_majority;
use hbv::query::Hit;
use hbv::scene::SceneHit;
use hbv::{Accelerator, AllHits, TriangleMesh};
use numpy::{IntoPyArray, PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::array_rows::{float_rows, FloatRowValues, FloatRows, RowSlice};
use crate::arrays::{interval_bound, BoundSlice, Coordinate, FloatSlice, IntervalBound};
use crate::mesh::PyMesh;
use crate::mesh_inside::{inside_closed, InsideCellsOnDemand};
use crate::output_column::OutputColumn;
use crate::thread_pool::{fill_rows, one_thread, run_on_threads, ThreadCount, GRAIN};

/// The ray arguments of a query, read and checked.
pub struct RayArgs<'py> {
    origins: FloatRowValues<'py>,
    directions: FloatRowValues<'py>,
    tmin: IntervalBound<'py>,
    tmax: IntervalBound<'py>,
    len: usize,
}

/// The rays of a query as slices the worker threads read (no GIL needed).
#[derive(Clone, Copy)]
pub struct RayBatch<'a> {
    origins: FloatRows<'a>,
    directions: FloatRows<'a>,
    tmin: BoundSlice<'a>,
    tmax: BoundSlice<'a>,
    len: usize,
}

impl<'py> RayArgs<'py> {
    pub fn read(
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        // Read in place also as halves of an (N, 6) array of rays (`RowValues`).
        let (origins, len) = float_rows("origins", origins, None)?;
        let (directions, _) = float_rows("directions", directions, Some((len, "origins")))?;
        Ok(Self {
            origins,
            directions,
            tmin: interval_bound("tmin", tmin, 0.0, len)?,
            tmax: interval_bound("tmax", tmax, f32::INFINITY, len)?,
            len,
        })
    }

    pub fn batch(&self) -> RayBatch<'_> {
        RayBatch {
            origins: self.origins.rows(),
            directions: self.directions.rows(),
            tmin: self.tmin.as_slice(),
            tmax: self.tmax.as_slice(),
            len: self.len,
        }
    }
}

impl RayBatch<'_> {
    /// The number of rays.
    pub fn len(&self) -> usize {
        self.len
    }

    #[inline]
    pub fn ray(&self, i: usize) -> Ray {
        Ray {
            origin: self.origins.row3(i),
            direction: self.directions.row3(i),
            tmin: self.tmin.at(i),
            tmax: self.tmax.at(i),
        }
    }

    /// Replaces `rays` with rays `range`: the arrays' dtypes, and whether each bound is one
    /// value for all rays, are matched once per run, not per ray, and the rows are read without
    /// a row stride each (a match per ray cost 3.5 ns of a camera ray's 29 on the teapot;
    /// reading rows by index with both bounds matched per ray, 4% of a teapot camera ray's
    /// time from Python on a Zen 3 VM).
    fn rays_into(&self, range: std::ops::Range<usize>, rays: &mut Vec<Ray>) {
        use FloatRows::{F32, F64};
        rays.clear();
        let (tmin, tmax) = (self.tmin.constant(0.0), self.tmax.constant(f32::INFINITY));
        let rows = range.clone();
        match (self.origins, self.directions) {
            (F32(o), F32(d)) => push_rays(o, d, rows, tmin, tmax, rays),
            (F32(o), F64(d)) => push_rays(o, d, rows, tmin, tmax, rays),
            (F64(o), F32(d)) => push_rays(o, d, rows, tmin, tmax, rays),
            (F64(o), F64(d)) => push_rays(o, d, rows, tmin, tmax, rays),
        }
        if let BoundSlice::PerRay(values) = self.tmin {
            set_bounds(values, range.clone(), rays, |ray, x| ray.tmin = x);
        }
        if let BoundSlice::PerRay(values) = self.tmax {
            set_bounds(values, range, rays, |ray, x| ray.tmax = x);
        }
    }

    /// Every ray, on the calling thread: a copy (a few ns a ray) that a parallel iterator would
    /// make the calling thread wait for the pool's threads to wake for.
    pub fn rays(&self) -> Vec<Ray> {
        (0..self.len).map(|i| self.ray(i)).collect()
    }
}

impl<'a> RayBatch<'a> {
    /// The origins as given (float32 or float64).
    pub fn origins(&self) -> FloatRows<'a> {
        self.origins
    }
}

/// Appends the rays of rows `rows` of `origins` and `directions` to `rays`, each with the
/// interval `[tmin, tmax]`: row i's origin at `stride·i` of the origins, its direction at
/// `stride·i` of the directions, each stride that of its own array.
#[inline(always)]
fn push_rays<O: Coordinate, D: Coordinate>(
    origins: RowSlice<'_, O>,
    directions: RowSlice<'_, D>,
    rows: std::ops::Range<usize>,
    tmin: f32,
    tmax: f32,
    rays: &mut Vec<Ray>,
) {
    rays.extend(rows.map(|i| Ray {
        origin: origins.row3(i),
        direction: directions.row3(i),
        tmin,
        tmax,
    }));
}

/// Sets one bound of `rays` (rays `range` of the batch) from its per-ray `values`.
#[inline(always)]
fn set_bounds(
    values: FloatSlice<'_>,
    range: std::ops::Range<usize>,
    rays: &mut [Ray],
    set: impl Fn(&mut Ray, f32),
) {
    match values {
        FloatSlice::F32(v) => rays.iter_mut().zip(&v[range]).for_each(|(r, &x)| set(r, x)),
        FloatSlice::F64(v) => rays
            .iter_mut()
            .zip(&v[range])
            .for_each(|(r, &x)| set(r, x as f32)),
    }
}

/// What answers the closest- and any-hit queries of a batch: a mesh's [`Accelerator`]
/// ([`MeshTracer`]), or a scene with its rays' masks (`scene_queries.rs`). Called with runs of
/// at most [`GRAIN`] rays.
pub trait RayTracer: Sync {
    /// Whether the answers carry an `instance` column (a scene's do).
    const INSTANCES: bool;

    /// The closest hit of each of `rays`, rows `first..` of the batch, with its unit normal in
    /// world space.
    fn closest_into(&self, first: usize, rays: &[Ray], found: &mut [Option<SceneHit>]);

    /// Whether anything lies along each of `rays`, rows `first..` of the batch.
    fn occluded_into(&self, first: usize, rays: &[Ray], occluded: &mut [bool]);
}

/// A mesh's closest and any hits, traced by one of its layouts.
pub struct MeshTracer<'a> {
    pub accel: &'a dyn Accelerator,
    pub mesh: &'a TriangleMesh,
}

impl RayTracer for MeshTracer<'_> {
    const INSTANCES: bool = false;

    fn closest_into(&self, _first: usize, rays: &[Ray], found: &mut [Option<SceneHit>]) {
        let mut hits = [None::<Hit>; GRAIN];
        let hits = &mut hits[..rays.len()];
        self.accel.intersect_into(rays, hits);
        for (found, hit) in found.iter_mut().zip(hits.iter()) {
            *found = hit.map(|h| SceneHit {
                t: h.t,
                u: h.u,
                v: h.v,
                prim: h.prim,
                instance: 0,
                normal: unit_normal(&self.mesh.triangle(h.prim as usize)),
            });
        }
    }

    fn occluded_into(&self, _first: usize, rays: &[Ray], occluded: &mut [bool]) {
        self.accel.occluded_into(rays, occluded);
    }
}

/// The unit geometric normal `normalize(cross(p1 - p0, p2 - p0))`, in f64 rounded to f32, as
/// docs/RAYS.md defines a hit's `normal` (a triangle that is hit is not degenerate).
fn unit_normal(triangle: &Triangle) -> hbv::glam::Vec3 {
    triangle.scaled_normal().normalize_or_zero().as_vec3()
}

/// Closest hits: a dict of arrays `hit` (bool), `t` (float32, inf on a miss), `prim` (int64,
/// -1 on a miss), `u`, `v` (float32 barycentrics, 0 on a miss), for a scene `instance` (int64,
/// -1 on a miss), and `normal` ((N, 3) float32 unit geometric normal in world space, 0 on a
/// miss), as docs/RAYS.md.
pub fn closest_hits<'py, T: RayTracer>(
    py: Python<'py>,
    tracer: &T,
    args: &RayArgs<'py>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyDict>> {
    let batch = args.batch();
    let n = batch.len;
    let (mut hit, mut t, mut prim) = (
        OutputColumn::<bool>::new(n),
        OutputColumn::<f32>::new(n),
        OutputColumn::<i64>::new(n),
    );
    let (mut u, mut v) = (OutputColumn::<f32>::new(n), OutputColumn::<f32>::new(n));
    let mut normal = OutputColumn::<[f32; 3]>::new(n);
    let mut instance = T::INSTANCES.then(|| OutputColumn::<i64>::new(n));
    let columns = (
        hit.rows(),
        (
            t.rows(),
            (
                prim.rows(),
                (
                    u.rows(),
                    (
                        v.rows(),
                        (normal.rows(), instance.as_mut().map(|c| c.rows())),
                    ),
                ),
            ),
        ),
    );
    py.detach(|| {
        fill_rows(threads, columns, |first, columns| {
            let (hit, (t, (prim, (u, (v, (normal, mut instance)))))) = columns;
            // In runs of GRAIN rays: the accelerator traces a run together (the wide layouts
            // interleave its rays).
            let mut rays = Vec::with_capacity(GRAIN);
            let mut found = vec![None; GRAIN];
            for start in (0..hit.len()).step_by(GRAIN) {
                let end = (start + GRAIN).min(hit.len());
                batch.rays_into(first + start..first + end, &mut rays);
                let found = &mut found[..end - start];
                tracer.closest_into(first + start, &rays, found);
                for (k, found) in (start..end).zip(found.iter()) {
                    hit[k].write(found.is_some());
                    t[k].write(found.map_or(f32::INFINITY, |h| h.t));
                    prim[k].write(found.map_or(-1, |h| h.prim as i64));
                    u[k].write(found.map_or(0.0, |h| h.u));
                    v[k].write(found.map_or(0.0, |h| h.v));
                    normal[k].write(found.map_or([0.0; 3], |h| h.normal.to_array()));
                    if let Some(instance) = instance.as_deref_mut() {
                        instance[k].write(found.map_or(-1, |h| h.instance as i64));
                    }
                }
            }
        })
    })?;
    // SAFETY: `fill_rows` called the closure on runs covering every row once, and it wrote
    // every row of its run in each column (`fill_rows` returns only once every run is done;
    // were a run to panic, nothing here would be reached).
    let (hit, t, prim, u, v, normal) = unsafe {
        (
            hit.into_filled(),
            t.into_filled(),
            prim.into_filled(),
            u.into_filled(),
            v.into_filled(),
            normal.into_filled(),
        )
    };
    let out = PyDict::new(py);
    out.set_item("hit", hit.into_pyarray(py))?;
    out.set_item("t", t.into_pyarray(py))?;
    out.set_item("prim", prim.into_pyarray(py))?;
    out.set_item("u", u.into_pyarray(py))?;
    out.set_item("v", v.into_pyarray(py))?;
    if let Some(instance) = instance {
        // SAFETY: as above, the closure wrote every row of the instance column when it has one.
        let instance = unsafe { instance.into_filled() };
        out.set_item("instance", instance.into_pyarray(py))?;
    }
    let normal = normal.into_flattened().into_pyarray(py).reshape([n, 3])?;
    out.set_item("normal", normal)?;
    Ok(out)
}

/// Any hit: a bool array, true where anything lies in [tmin, tmax] along the ray.
pub fn any_hits<'py, T: RayTracer>(
    py: Python<'py>,
    tracer: &T,
    args: &RayArgs<'py>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let batch = args.batch();
    let mut occluded = vec![false; batch.len];
    py.detach(|| {
        fill_rows(threads, &mut occluded[..], |first, out| {
            let mut rays = Vec::with_capacity(GRAIN);
            for (start, out) in (0..).step_by(GRAIN).zip(out.chunks_mut(GRAIN)) {
                let from = first + start;
                batch.rays_into(from..from + out.len(), &mut rays);
                tracer.occluded_into(from, &rays, out);
            }
        })
    })?;
    Ok(occluded.into_pyarray(py))
}

/// Every hit along each ray, in one traversal per ray: a tuple of arrays (ray index int64,
/// t float32, prim int64), in ray order and, within a ray, sorted by t (equal t by prim).
/// `structure` is called off the GIL (it may build the structure on first use).
pub fn every_hit<'py, 's, A: AllHits + ?Sized + 's>(
    py: Python<'py>,
    structure: impl FnOnce() -> &'s A + Send,
    args: &RayArgs<'py>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyTuple>> {
    let batch = args.batch();
    let hits = py.detach(|| {
        if one_thread(threads) {
            // One thread is the calling thread itself, not a pool of one to wake.
            return Ok(structure().all_hits_batch_here(&batch.rays()));
        }
        run_on_threads(threads, || {
            let rays = batch.rays();
            structure().all_hits_batch(&rays)
        })
    })?;
    let ray: Vec<i64> = hits.iter().map(|(r, _)| *r as i64).collect();
    let t: Vec<f32> = hits.iter().map(|(_, h)| h.t).collect();
    let prim: Vec<i64> = hits.iter().map(|(_, h)| h.prim as i64).collect();
    PyTuple::new(
        py,
        [
            ray.into_pyarray(py).into_any(),
            t.into_pyarray(py).into_any(),
            prim.into_pyarray(py).into_any(),
        ],
    )
}

/// What counts the hits along one ray of a batch: a mesh's [`AllHits`] structure
/// ([`MeshCounter`]), or a scene with its rays' masks (`scene_queries.rs`).
pub trait HitCounter: Sync {
    /// The number of hits along `ray`, row `row` of the batch; `hits` is scratch space that a
    /// run of rays reuses.
    fn count(&self, row: usize, ray: &Ray, hits: &mut Vec<Hit>) -> usize;
}

/// A mesh's hit counts: the length of its [`AllHits`] list.
pub struct MeshCounter<'a, A: AllHits + ?Sized>(pub &'a A);

impl<A: AllHits + ?Sized> HitCounter for MeshCounter<'_, A> {
    fn count(&self, _row: usize, ray: &Ray, hits: &mut Vec<Hit>) -> usize {
        self.0.all_hits(ray, hits);
        hits.len()
    }
}

/// The number of hits along each ray (int64): the length of its `intersect_all` list.
/// `counter` is called off the GIL (it may build the structure on first use).
pub fn hit_counts<'py, C: HitCounter>(
    py: Python<'py>,
    counter: impl FnOnce() -> C + Send,
    args: &RayArgs<'py>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let batch = args.batch();
    let mut counts = vec![0i64; batch.len];
    py.detach(|| {
        let counter = counter();
        fill_rows(threads, &mut counts[..], |first, out| {
            let mut hits = Vec::new();
            for (k, c) in out.iter_mut().enumerate() {
                *c = counter.count(first + k, &batch.ray(first + k), &mut hits) as i64;
            }
        })
    })?;
    Ok(counts.into_pyarray(py))
}

/// Whether each point lies inside the (closed) mesh: bool array. One ray's parity, exact
/// (hbv::proximity::contains); points on the surface may go either way. When `mesh` is not
/// closed: a RuntimeWarning, and the majority of three rays' parities
/// (hbv::proximity::contains_by_majority), steadier where inside is not defined.
pub fn inside<'py, 's, A: AllHits + ?Sized + 's>(
    py: Python<'py>,
    mesh: &PyMesh,
    structure: impl FnOnce() -> &'s A + Send,
    points: &Bound<'py, PyAny>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    inside_with_cells(py, mesh, structure, None, points, threads)
}

/// [`inside`], a closed mesh's points answered through `cells` (`mesh_inside.rs`) once it has
/// made its grid: the same answers.
pub fn inside_with_cells<'py, 's, A: AllHits + ?Sized + 's>(
    py: Python<'py>,
    mesh: &PyMesh,
    structure: impl FnOnce() -> &'s A + Send,
    cells: Option<&InsideCellsOnDemand>,
    points: &Bound<'py, PyAny>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let (points, rows) = float_rows("points", points, None)?;
    let closed = mesh.warn_if_open(py, "contains")?;
    let points = points.rows();
    let mut result = vec![false; rows];
    py.detach(|| {
        let structure = structure();
        let cells = cells
            .filter(|_| closed)
            .and_then(|c| c.cells(rows, &mesh.mesh, structure));
        fill_rows(threads, &mut result[..], |first, out| {
            let mut hits = Vec::new();
            for (k, o) in out.iter_mut().enumerate() {
                let point = points.row3(first + k);
                *o = if closed {
                    inside_closed(structure, cells, point, &mut hits)
                } else {
                    contains_by_majority(structure, point)
                };
            }
        })
    })?;
    Ok(result.into_pyarray(py))
}
