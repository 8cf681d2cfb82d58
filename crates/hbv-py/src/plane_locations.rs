//! `plane_locations`: where rays meet the planes of the triangles they hit, in float64 from the
//! mesh's float64 vertices, so that a hit's location is as exact as its input (`hbv.trimesh`'s
//! locations, which trimesh's Embree intersector also takes from the hit triangle's plane).

use hbv::glam::DVec3;
use numpy::ndarray::ArrayView2;
use numpy::{
    IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{as_ndarray, float_array, shape_text};
use crate::thread_pool::{fill_rows, ThreadCount};

/// The point where ray `index_ray[k]` meets the plane of triangle `prim[k]`, for each hit `k`:
/// an (H, 3) float64 array.
///
/// With the triangle's float64 corners `p0, p1, p2`, its normal `n = (p1 - p0) × (p2 - p0)`, and
/// the ray `o + s·d`, the plane is met at `s = n·(p0 - o) / n·d` and the location is `o + s·d`,
/// each step rounded once in float64: the error is a few float64 ulps of `|p0 - o|` (divided by
/// the cosine between ray and normal), not the float32 of a traced `t`. Where the plane gives no
/// finite point (a degenerate triangle, a ray in the plane) the location is `o + t[k]·d`.
///
/// vertices: (V, 3) float64, C-ordered; faces: (F, 3) int64, C-ordered; prim, index_ray: (H,)
/// int64; origins, directions: (N, 3) float32 or float64; t: (H,) float32. Indices out of
/// range raise `ValueError` naming the argument and the row.
#[pyfunction]
#[pyo3(signature = (vertices, faces, prim, index_ray, origins, directions, t, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn plane_locations<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    prim: &Bound<'py, PyAny>,
    index_ray: &Bound<'py, PyAny>,
    origins: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    t: &Bound<'py, PyAny>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let vertices = c_array2::<f64>("vertices", vertices, "float64")?;
    let faces = c_array2::<i64>("faces", faces, "int64")?;
    let prim = c_array1::<i64>("prim", prim, "int64")?;
    let index_ray = c_array1::<i64>("index_ray", index_ray, "int64")?;
    let (origins, rays) = float_array("origins", origins, Some(3), None)?;
    let (directions, _) = float_array("directions", directions, Some(3), Some((rays, "origins")))?;
    let hits = prim.len();
    for (name, len) in [("index_ray", index_ray.len()), ("t", t_len(t)?)] {
        if len != hits {
            return Err(PyValueError::new_err(format!(
                "{name}: expected {hits} rows, as prim has, got {len}"
            )));
        }
    }
    let t = c_array1::<f32>("t", t, "float32")?;
    let mesh = PlaneMesh {
        vertices: vertices.as_array(),
        faces: faces.as_array(),
    };
    let (prim, index_ray, t) = (prim.as_slice()?, index_ray.as_slice()?, t.as_slice()?);
    check_indices("prim", prim, mesh.faces.nrows())?;
    check_indices("index_ray", index_ray, rays)?;
    let (origins, directions) = (origins.values(), directions.values());
    let mut out = vec![[0.0f64; 3]; hits];
    let bad_face = std::sync::atomic::AtomicUsize::new(usize::MAX);
    py.detach(|| {
        fill_rows(threads, out.as_mut_slice(), |first, rows| {
            for (k, row) in (first..).zip(rows.iter_mut()) {
                let ray = index_ray[k] as usize;
                let o = origins.row3_f64(ray);
                let d = directions.row3_f64(ray);
                match mesh.plane_hit(prim[k] as usize, o, d) {
                    Some(Some(p)) => *row = p.to_array(),
                    Some(None) => *row = (o + f64::from(t[k]) * d).to_array(),
                    None => {
                        bad_face.fetch_min(prim[k] as usize, std::sync::atomic::Ordering::Relaxed);
                    }
                }
            }
        })
    })?;
    let bad_face = bad_face.into_inner();
    if bad_face != usize::MAX {
        return Err(PyValueError::new_err(format!(
            "faces: row {bad_face}: a vertex index outside 0..{}",
            mesh.vertices.nrows()
        )));
    }
    out.into_flattened().into_pyarray(py).reshape([hits, 3])
}

/// The float64 mesh whose triangles' planes locate the hits.
struct PlaneMesh<'a> {
    vertices: ArrayView2<'a, f64>,
    faces: ArrayView2<'a, i64>,
}

impl PlaneMesh<'_> {
    /// Where `o + s·d` meets the plane of triangle `face` (see [`plane_locations`]); `Some(None)`
    /// where the plane gives no finite point, `None` where the face has a vertex index out of
    /// range.
    #[inline]
    fn plane_hit(&self, face: usize, o: DVec3, d: DVec3) -> Option<Option<DVec3>> {
        let corner = |c: usize| -> Option<DVec3> {
            let v = usize::try_from(self.faces[[face, c]]).ok()?;
            (v < self.vertices.nrows()).then(|| {
                DVec3::new(
                    self.vertices[[v, 0]],
                    self.vertices[[v, 1]],
                    self.vertices[[v, 2]],
                )
            })
        };
        let (p0, p1, p2) = (corner(0)?, corner(1)?, corner(2)?);
        let n = (p1 - p0).cross(p2 - p0);
        let s = n.dot(p0 - o) / n.dot(d);
        let p = o + s * d;
        Some(p.is_finite().then_some(p))
    }
}

/// A C-ordered 2-D array of shape (N, 3) and element type `T`, borrowed.
fn c_array2<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<PyReadonlyArray2<'py, T>> {
    let array = typed::<T>(name, obj, dtype)?;
    let shape = array.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 3), got {}",
            shape_text(&shape)
        )));
    }
    let array = array.cast_into::<numpy::PyArray2<T>>()?.readonly();
    if !array.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a C-ordered array"
        )));
    }
    Ok(array)
}

/// A C-ordered 1-D array of element type `T`, borrowed.
fn c_array1<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<PyReadonlyArray1<'py, T>> {
    let array = typed::<T>(name, obj, dtype)?;
    let shape = array.shape().to_vec();
    if shape.len() != 1 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (H,), got {}",
            shape_text(&shape)
        )));
    }
    let array = array.cast_into::<numpy::PyArray1<T>>()?.readonly();
    if !array.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a C-ordered array"
        )));
    }
    Ok(array)
}

/// `obj` as an array of element type `T` exactly (no conversion: these are the arrays
/// `hbv.trimesh` prepares); a TypeError naming the argument otherwise.
fn typed<'py, T: numpy::Element>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let array = as_ndarray(name, obj)?;
    if array.cast::<numpy::PyArrayDyn<T>>().is_err() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected dtype {dtype}, got {}",
            array.dtype().str()?
        )));
    }
    Ok(array)
}

/// The length of `t` before its dtype is checked (so that a wrong length is named first).
fn t_len(t: &Bound<'_, PyAny>) -> PyResult<usize> {
    Ok(as_ndarray("t", t)?.shape().first().copied().unwrap_or(0))
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
