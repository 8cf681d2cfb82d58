//! `trimesh_hits`: hbv's hits arranged as trimesh's Embree intersector lists them, with each
//! hit's location where the ray meets the plane of the triangle it hit, in float64 from the
//! mesh's float64 vertices (`hbv.trimesh`'s `intersects_id` and `intersects_location`).
//!
//! Done here rather than in NumPy because on a million rays the ordering and the locations took
//! 14 % and 67 % of the traversal's own time in NumPy (gathers and a sort); here they are two
//! passes over the hits, the second on all cores.

use std::sync::atomic::{AtomicUsize, Ordering};

use hbv::glam::DVec3;
use numpy::ndarray::ArrayView2;
use numpy::{
    IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{as_ndarray, float_array, shape_text, FloatSlice};
use crate::thread_pool::{fill_rows, ThreadCount};

/// Hits of one ray closer than this fraction of (their distance along the ray + the mesh's
/// size) are one hit: coincident faces hit at one place, reported once as trimesh reports a
/// place once (its Embree intersector steps 1e-6 of the mesh's size past each hit; float32 `t`
/// tells hits apart to about 1e-7 of that sum).
const SAME_PLACE: f64 = 1.0 / (1u64 << 20) as f64;

/// hbv's hit list `(index_ray, t, prim)` (grouped by ray, each ray's hits nearest first, as
/// `BVH.intersect_all` returns them; or one hit per ray, as from `BVH.intersect`) in trimesh's
/// Embree order: every ray's first hit (by ray), then every ray's second hit, and so on, at most
/// `max_hits` per ray (None: all), a hit at the place of the ray's previous one left out (see
/// [`SAME_PLACE`]). Returns `(index_tri, index_ray, locations)`: int64, int64, and, when
/// `vertices` and `faces` are given, the (H, 3) float64 locations (else None).
///
/// A location is where the ray `o + s·d` meets the plane of its triangle, with float64 corners
/// `p0, p1, p2` and normal `n = (p1 - p0) × (p2 - p0)`: `s = n·(p0 - o) / n·d`, location
/// `o + s·d`, each step rounded once in float64, so its error is a few float64 ulps of
/// `|p0 - o|` (over the cosine between ray and normal), not float32's of a traced `t`. Where the
/// plane gives no finite point (a ray in the plane) it is `o + t·d`.
///
/// index_ray, prim: (H,) int64; t: (H,) float32; origins, directions: (N, 3) float32 or float64;
/// size: the mesh's size (its box's diagonal); vertices: (V, 3) float64 and faces: (F, 3)
/// int64, C-ordered. Indices out of range raise `ValueError` naming the argument and the row.
#[pyfunction]
#[pyo3(signature = (index_ray, t, prim, origins, directions, size, max_hits=None, vertices=None, faces=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn trimesh_hits<'py>(
    py: Python<'py>,
    index_ray: &Bound<'py, PyAny>,
    t: &Bound<'py, PyAny>,
    prim: &Bound<'py, PyAny>,
    origins: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    size: f64,
    max_hits: Option<usize>,
    vertices: Option<&Bound<'py, PyAny>>,
    faces: Option<&Bound<'py, PyAny>>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyTuple>> {
    let index_ray = c_array1::<i64>("index_ray", index_ray, "int64")?;
    let hits = index_ray.len();
    if hits >= u32::MAX as usize {
        return Err(PyValueError::new_err(format!(
            "index_ray: {hits} hits, more than the {} this function orders",
            u32::MAX - 1
        )));
    }
    let t = c_array1::<f32>("t", t, "float32")?;
    let prim = c_array1::<i64>("prim", prim, "int64")?;
    for (name, len) in [("t", t.len()), ("prim", prim.len())] {
        if len != hits {
            return Err(PyValueError::new_err(format!(
                "{name}: expected {hits} rows, as index_ray has, got {len}"
            )));
        }
    }
    let (origins, rays) = float_array("origins", origins, Some(3), None)?;
    let (directions, _) = float_array("directions", directions, Some(3), Some((rays, "origins")))?;
    let planes = match (vertices, faces) {
        (Some(v), Some(f)) => Some((
            c_array2::<f64>("vertices", v, "float64")?,
            c_array2::<i64>("faces", f, "int64")?,
        )),
        (None, None) => None,
        _ => {
            return Err(PyValueError::new_err(
                "vertices, faces: give both (for locations) or neither",
            ))
        }
    };
    let planes = planes.as_ref().map(|(v, f)| PlaneMesh {
        vertices: v.as_array(),
        faces: f.as_array(),
    });
    let (index_ray, t, prim) = (index_ray.as_slice()?, t.as_slice()?, prim.as_slice()?);
    check_indices("index_ray", index_ray, rays)?;
    if let Some(planes) = &planes {
        check_indices("prim", prim, planes.faces.nrows())?;
    }
    let list = HitList {
        index_ray,
        t,
        prim,
        origins: origins.values(),
        directions: directions.values(),
    };
    let (tri, ray, locations) = py.detach(|| {
        let source = list.depth_major(size, max_hits.unwrap_or(usize::MAX));
        list.gather(&source, planes.as_ref(), threads)
    })?;
    let locations = match locations {
        Some(l) => {
            let rows = l.len();
            l.into_flattened()
                .into_pyarray(py)
                .reshape([rows, 3])?
                .into_any()
        }
        None => py.None().into_bound(py),
    };
    PyTuple::new(
        py,
        [
            tri.into_pyarray(py).into_any(),
            ray.into_pyarray(py).into_any(),
            locations,
        ],
    )
}

/// The hits of a query as hbv lists them, and the rays they are on.
struct HitList<'a> {
    index_ray: &'a [i64],
    t: &'a [f32],
    prim: &'a [i64],
    origins: FloatSlice<'a>,
    directions: FloatSlice<'a>,
}

/// Output columns: triangle, ray, and (when asked) location of each hit.
type Columns = (Vec<i64>, Vec<i64>, Option<Vec<[f64; 3]>>);

impl HitList<'_> {
    /// The hits to keep, in trimesh's Embree order: the source row of each output row. A
    /// counting sort by rank within the ray: one pass ranks the hits (leaving out repeats of a
    /// place and ranks from `max_hits` on) and counts each rank, a second places each hit after
    /// the hits of lower rank and the earlier hits of its rank.
    fn depth_major(&self, size: f64, max_hits: usize) -> Vec<u32> {
        const LEFT_OUT: u32 = u32::MAX;
        let (index_ray, t) = (self.index_ray, self.t);
        let mut rank = vec![LEFT_OUT; index_ray.len()];
        let mut per_rank: Vec<u32> = Vec::new();
        let (mut next_rank, mut kept_t, mut speed) = (0usize, 0.0f64, f64::NAN);
        for k in 0..index_ray.len() {
            let t_k = f64::from(t[k]);
            if k == 0 || index_ray[k] != index_ray[k - 1] {
                (next_rank, speed) = (0, f64::NAN);
            } else {
                if speed.is_nan() {
                    speed = self.directions.row3_f64(index_ray[k] as usize).length();
                }
                if (t_k - kept_t) * speed <= SAME_PLACE * (t_k * speed + size) {
                    continue;
                }
            }
            if next_rank < max_hits {
                rank[k] = next_rank as u32;
                if per_rank.len() == next_rank {
                    per_rank.push(0);
                }
                per_rank[next_rank] += 1;
                next_rank += 1;
                kept_t = t_k;
            }
        }
        // per_rank[r] becomes the next output row of rank r.
        let mut first = 0;
        for count in &mut per_rank {
            (*count, first) = (first, first + *count);
        }
        let mut source = vec![0u32; first as usize];
        for (k, &r) in rank.iter().enumerate() {
            if r != LEFT_OUT {
                let row = &mut per_rank[r as usize];
                source[*row as usize] = k as u32;
                *row += 1;
            }
        }
        source
    }

    /// The output columns of the `source` rows, with locations on `planes`' triangles when
    /// given; on all cores. A ValueError naming the first face hit whose vertex index is out of
    /// range.
    fn gather(
        &self,
        source: &[u32],
        planes: Option<&PlaneMesh<'_>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Columns> {
        let mut tri = vec![0i64; source.len()];
        let mut ray = vec![0i64; source.len()];
        let mut locations = planes.map(|_| vec![[0.0f64; 3]; source.len()]);
        let bad_face = AtomicUsize::new(usize::MAX);
        let rows = (
            tri.as_mut_slice(),
            (ray.as_mut_slice(), locations.as_deref_mut()),
        );
        fill_rows(threads, rows, |first, (tri, (ray, locations))| {
            let source = &source[first..first + tri.len()];
            for (j, &k) in source.iter().enumerate() {
                tri[j] = self.prim[k as usize];
                ray[j] = self.index_ray[k as usize];
            }
            if let (Some(locations), Some(planes)) = (locations, planes) {
                for (row, &k) in locations.iter_mut().zip(source) {
                    match self.location(k as usize, planes) {
                        Some(p) => *row = p.to_array(),
                        None => {
                            bad_face.fetch_min(self.prim[k as usize] as usize, Ordering::Relaxed);
                        }
                    }
                }
            }
        })?;
        match (bad_face.into_inner(), planes) {
            (usize::MAX, _) | (_, None) => Ok((tri, ray, locations)),
            (face, Some(planes)) => Err(PyValueError::new_err(format!(
                "faces: row {face}: a vertex index outside 0..{}",
                planes.vertices.nrows()
            ))),
        }
    }

    /// Where hit `k`'s ray meets its triangle's plane (see [`trimesh_hits`]); None when the
    /// triangle has a vertex index out of range.
    #[inline]
    fn location(&self, k: usize, planes: &PlaneMesh<'_>) -> Option<DVec3> {
        let ray = self.index_ray[k] as usize;
        let o = self.origins.row3_f64(ray);
        let d = self.directions.row3_f64(ray);
        let [p0, p1, p2] = planes.corners(self.prim[k] as usize)?;
        let n = (p1 - p0).cross(p2 - p0);
        let on_plane = o + (n.dot(p0 - o) / n.dot(d)) * d;
        Some(if on_plane.is_finite() {
            on_plane
        } else {
            o + f64::from(self.t[k]) * d
        })
    }
}

/// The float64 mesh whose triangles' planes locate the hits.
struct PlaneMesh<'a> {
    vertices: ArrayView2<'a, f64>,
    faces: ArrayView2<'a, i64>,
}

impl PlaneMesh<'_> {
    /// The corners of triangle `face`, or None if one of its vertex indices is out of range.
    #[inline]
    fn corners(&self, face: usize) -> Option<[DVec3; 3]> {
        let corner = |c: usize| {
            let v = usize::try_from(self.faces[[face, c]]).ok()?;
            (v < self.vertices.nrows()).then(|| {
                DVec3::new(
                    self.vertices[[v, 0]],
                    self.vertices[[v, 1]],
                    self.vertices[[v, 2]],
                )
            })
        };
        Some([corner(0)?, corner(1)?, corner(2)?])
    }
}

/// A C-ordered array of shape (N, 3) and element type `T`, borrowed.
fn c_array2<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<PyReadonlyArray2<'py, T>> {
    let array = typed::<T>(name, obj, dtype, 2)?;
    if array.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 3), got {}",
            shape_text(array.shape())
        )));
    }
    Ok(array.cast_into::<numpy::PyArray2<T>>()?.readonly())
}

/// A C-ordered 1-D array of element type `T`, borrowed.
fn c_array1<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<PyReadonlyArray1<'py, T>> {
    let array = typed::<T>(name, obj, dtype, 1)?;
    Ok(array.cast_into::<PyArray1<T>>()?.readonly())
}

/// `obj` as a C-ordered array of element type `T` and `dims` dimensions, as `hbv.trimesh`
/// prepares them (no conversion); a TypeError or ValueError naming the argument otherwise.
fn typed<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
    dims: usize,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let array = as_ndarray(name, obj)?;
    if array.cast::<numpy::PyArrayDyn<T>>().is_err() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected dtype {dtype}, got {}",
            array.dtype().str()?
        )));
    }
    if array.ndim() != dims {
        let want = if dims == 1 { "(H,)" } else { "(N, 3)" };
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {want}, got {}",
            shape_text(array.shape())
        )));
    }
    if !array.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a C-ordered array"
        )));
    }
    Ok(array)
}

/// Every index in `0..len`; a ValueError naming the argument and the first row outside.
fn check_indices(name: &str, indices: &[i64], len: usize) -> PyResult<()> {
    match indices
        .iter()
        .position(|&i| usize::try_from(i).map_or(true, |i| i >= len))
    {
        Some(row) => Err(PyValueError::new_err(format!(
            "{name}: row {row}: index {} outside 0..{len}",
            indices[row]
        ))),
        None => Ok(()),
    }
}
