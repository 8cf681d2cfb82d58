//! The queries of `hbv.Scene`: the shared ray queries (`ray_queries.rs`) answered by a scene
//! with each ray's mask, and the answers only a scene has (every hit with its instance and
//! normal, inside tests and nearest points among the instances a mask sees).

use hbv::geometry::Ray;
use hbv::glam::DVec3;
use hbv::proximity::InsideCells;
use hbv::query::Hit;
use hbv::scene::{Scene, SceneHit, SceneRay};
use numpy::{IntoPyArray, PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::array_rows::FloatRows;
use crate::arrays::FloatSlice;
use crate::masks::MaskSlice;
use crate::ray_queries::{HitCounter, RayBatch, RayTracer};
use crate::thread_pool::{fill_rows, one_thread, run_here_or_on_threads, ThreadCount, SERIAL_ROWS};

/// A scene answering a batch of rays, row `i` seen through mask `masks.at(i)`. Float64
/// origins keep what float32 loses of them (`SceneRay::from_f64`): a ray at UTM coordinates
/// is carried into an instance's space to about 2^-48 of its origin, not 2^-24.
pub struct SceneTracer<'a> {
    scene: &'a Scene,
    masks: MaskSlice<'a>,
    /// The rays' origins as given.
    origins: FloatRows<'a>,
}

impl<'a> SceneTracer<'a> {
    /// `scene` answering the rays of `batch` with `masks`.
    pub fn new(scene: &'a Scene, batch: RayBatch<'a>, masks: MaskSlice<'a>) -> Self {
        Self {
            scene,
            masks,
            origins: batch.origins(),
        }
    }

    /// Row `row` of the batch, `ray` (its float32 rounding), as a scene ray.
    #[inline]
    fn ray(&self, row: usize, ray: &Ray) -> SceneRay {
        let scene_ray = match self.origins {
            FloatRows::F32(_) => SceneRay::new(*ray),
            FloatRows::F64(_) => {
                let origin = self.origins.row3_f64(row);
                SceneRay::from_f64(origin, ray.direction.as_dvec3())
                    .with_interval(ray.tmin, ray.tmax)
            }
        };
        scene_ray.with_mask(self.masks.at(row))
    }
}

impl RayTracer for SceneTracer<'_> {
    const INSTANCES: bool = true;

    fn closest_into(&self, first: usize, rays: &[Ray], found: &mut [Option<SceneHit>]) {
        for (k, (ray, found)) in rays.iter().zip(found).enumerate() {
            *found = self.scene.intersect(&self.ray(first + k, ray));
        }
    }

    fn occluded_into(&self, first: usize, rays: &[Ray], occluded: &mut [bool]) {
        for (k, (ray, occluded)) in rays.iter().zip(occluded).enumerate() {
            *occluded = self.scene.occluded(&self.ray(first + k, ray));
        }
    }
}

impl HitCounter for SceneTracer<'_> {
    fn count(&self, row: usize, ray: &Ray, _hits: &mut Vec<Hit>) -> usize {
        self.scene.count(&self.ray(row, ray))
    }
}

/// Every hit along each ray: a tuple of arrays (ray index int64, t float32, prim int64,
/// instance int64, normal (H, 3) float32), in ray order and, within a ray, sorted by t, then
/// instance, then prim (`Scene::intersect_all`).
pub fn every_scene_hit<'py>(
    py: Python<'py>,
    scene: &Scene,
    batch: RayBatch<'_>,
    masks: MaskSlice<'_>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyTuple>> {
    let tracer = SceneTracer::new(scene, batch, masks);
    let rays = |batch: &RayBatch<'_>| -> Vec<SceneRay> {
        let rays = batch.rays();
        rays.iter()
            .enumerate()
            .map(|(row, ray)| tracer.ray(row, ray))
            .collect()
    };
    // Small batches and one thread on the calling thread, with no pool to wake.
    let here = one_thread(threads) || batch.len() <= SERIAL_ROWS;
    let lists = py.detach(|| {
        run_here_or_on_threads(here, threads, || {
            let rays = rays(&batch);
            if here {
                rays.iter().map(|ray| scene.intersect_all(ray)).collect()
            } else {
                scene.intersect_all_batch(&rays)
            }
        })
    })?;
    let total = lists.iter().map(Vec::len).sum();
    let mut ray = Vec::with_capacity(total);
    let (mut t, mut prim) = (Vec::with_capacity(total), Vec::with_capacity(total));
    let (mut instance, mut normal) = (Vec::with_capacity(total), Vec::with_capacity(total));
    for (row, hits) in lists.iter().enumerate() {
        for h in hits {
            ray.push(row as i64);
            t.push(h.t);
            prim.push(i64::from(h.prim));
            instance.push(i64::from(h.instance));
            normal.extend_from_slice(&h.normal.to_array());
        }
    }
    PyTuple::new(
        py,
        [
            ray.into_pyarray(py).into_any(),
            t.into_pyarray(py).into_any(),
            prim.into_pyarray(py).into_any(),
            instance.into_pyarray(py).into_any(),
            normal.into_pyarray(py).reshape([total, 3])?.into_any(),
        ],
    )
}

/// The points of a point query, each with its mask (no GIL needed).
#[derive(Clone, Copy)]
pub struct MaskedPoints<'a> {
    pub points: FloatSlice<'a>,
    pub rows: usize,
    pub masks: MaskSlice<'a>,
}

/// A scene's inside grid, and whether a point of a surface cell may be decided by a segment
/// to a known point nearby (`InsideCells::known_point_near`), the parity of `Scene::count`'s
/// crossings along it: in a scene of one live instance, where that parity is the change of
/// inside (with several, a segment into overlapping solids would count both).
pub struct SceneInsideCells {
    pub cells: InsideCells,
    pub by_segments: bool,
}

/// Whether `point` lies inside the scene among the instances `mask` sees: from `grid` (made
/// for this scene, used only without a mask) where it tells (`InsideCells::decide`: the
/// point's cell, or, where `by_segments`, the parity of `Scene::count` along the segment to a
/// known point); else `Scene::contains_with_mask`, a ray to infinity.
#[inline]
fn inside(scene: &Scene, grid: Option<&SceneInsideCells>, point: DVec3, mask: u32) -> bool {
    if let Some(grid) = grid {
        let mut crossings = |known: DVec3| {
            let segment = SceneRay::from_f64(point, known - point).with_interval(0.0, 1.0);
            scene.count(&segment)
        };
        let segments: Option<&mut dyn FnMut(DVec3) -> usize> =
            grid.by_segments.then_some(&mut crossings);
        if let Some(answer) = grid.cells.decide(point, segments) {
            return answer;
        }
    }
    scene.contains_with_mask(point, mask)
}

/// `answer(point, mask)` for each point of `query`, on the threads `threads` asks for, with
/// the GIL released.
fn answer_each<T: Copy + Default + Send>(
    py: Python<'_>,
    query: MaskedPoints<'_>,
    threads: Option<ThreadCount>,
    answer: impl Fn(DVec3, u32) -> T + Sync,
) -> PyResult<Vec<T>> {
    let MaskedPoints {
        points,
        rows,
        masks,
    } = query;
    let mut answers = vec![T::default(); rows];
    py.detach(|| {
        fill_rows(threads, &mut answers[..], |first, out| {
            for (k, answer_k) in out.iter_mut().enumerate() {
                let row = first + k;
                *answer_k = answer(points.row3_f64(row), masks.at(row));
            }
        })
    })?;
    Ok(answers)
}

/// Whether each point lies inside the scene (`Scene::contains_with_mask`), among the
/// instances its mask sees; `cells` answering the points whose cell knows.
pub fn scene_inside<'py>(
    py: Python<'py>,
    scene: &Scene,
    cells: Option<&SceneInsideCells>,
    query: MaskedPoints<'_>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let answers = answer_each(py, query, threads, |point, mask| {
        inside(scene, cells, point, mask)
    })?;
    Ok(answers.into_pyarray(py))
}

/// The nearest surface point of the instances each point's mask sees: a dict of `point` (N, 3)
/// float64, `distance` float64, `prim` int64, `u`, `v` float64 and `instance` int64; NaN, inf,
/// -1, 0, 0, -1 where there is none (a point not finite, or no triangle seen).
pub fn scene_closest_points<'py>(
    py: Python<'py>,
    scene: &Scene,
    query: MaskedPoints<'_>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyDict>> {
    let MaskedPoints {
        points,
        rows,
        masks,
    } = query;
    let (mut point, mut distance) = (vec![[0.0f64; 3]; rows], vec![0.0f64; rows]);
    let (mut prim, mut instance) = (vec![0i64; rows], vec![0i64; rows]);
    let (mut u, mut v) = (vec![0.0f64; rows], vec![0.0f64; rows]);
    let columns = (
        &mut point[..],
        (
            &mut distance[..],
            (&mut prim[..], (&mut instance[..], (&mut u[..], &mut v[..]))),
        ),
    );
    py.detach(|| {
        let search = scene.nearest_points();
        fill_rows(threads, columns, |first, columns| {
            let (point, (distance, (prim, (instance, (u, v))))) = columns;
            for k in 0..point.len() {
                let row = first + k;
                let found = search.closest_point_with_mask(points.row3_f64(row), masks.at(row));
                point[k] = found.map_or([f64::NAN; 3], |c| c.point.to_array());
                distance[k] = found.map_or(f64::INFINITY, |c| c.distance);
                prim[k] = found.map_or(-1, |c| i64::from(c.prim));
                instance[k] = found.map_or(-1, |c| i64::from(c.instance));
                u[k] = found.map_or(0.0, |c| c.u);
                v[k] = found.map_or(0.0, |c| c.v);
            }
        })
    })?;
    let out = PyDict::new(py);
    let point = point.into_flattened().into_pyarray(py).reshape([rows, 3])?;
    out.set_item("point", point)?;
    out.set_item("distance", distance.into_pyarray(py))?;
    out.set_item("prim", prim.into_pyarray(py))?;
    out.set_item("u", u.into_pyarray(py))?;
    out.set_item("v", v.into_pyarray(py))?;
    out.set_item("instance", instance.into_pyarray(py))?;
    Ok(out)
}

/// The distance of each point to the nearest surface among the instances its mask sees
/// (`scene_closest_points`' `distance`), negative where the point lies inside one of them
/// (`Scene::contains_with_mask`, the exact parity test): as `hbv.BVH.signed_distance` and
/// Open3D's `compute_signed_distance`; `cells` answering the inside tests of the points whose
/// cell knows. `+inf` where there is no nearest point (a point not finite, or no triangle
/// seen).
pub fn scene_signed_distances<'py>(
    py: Python<'py>,
    scene: &Scene,
    cells: Option<&SceneInsideCells>,
    query: MaskedPoints<'_>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let search = scene.nearest_points();
    let signed = answer_each(py, query, threads, |point, mask| {
        let distance = search
            .closest_point_with_mask(point, mask)
            .map_or(f64::INFINITY, |c| c.distance);
        if inside(scene, cells, point, mask) {
            -distance
        } else {
            distance
        }
    })?;
    Ok(signed.into_pyarray(py))
}
