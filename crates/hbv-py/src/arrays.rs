//! NumPy arguments: checked for shape and dtype with errors that name the argument, read in
//! place when they are C-contiguous float32 or float64, converted otherwise (strided, integer).

use hbv::glam::{DVec3, Vec3};
use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// The values of a float argument: the caller's float32 or float64 array, borrowed, or a copy
/// in the same precision (float64 for integers).
pub enum Floats<'py> {
    Borrowed(PyReadonlyArrayDyn<'py, f32>),
    BorrowedF64(PyReadonlyArrayDyn<'py, f64>),
    Owned(Vec<f32>),
    OwnedF64(Vec<f64>),
}

impl Floats<'_> {
    /// The values as the query loops read them (no GIL needed).
    pub fn values(&self) -> FloatSlice<'_> {
        match self {
            Floats::Borrowed(a) => FloatSlice::F32(a.as_slice().expect("checked contiguous")),
            Floats::BorrowedF64(a) => FloatSlice::F64(a.as_slice().expect("checked contiguous")),
            Floats::Owned(v) => FloatSlice::F32(v),
            Floats::OwnedF64(v) => FloatSlice::F64(v),
        }
    }
}

/// Float values in place, float32 or float64. Ray queries read them as float32, each value
/// rounded to nearest when it is read; `closest_point` reads them exactly, as float64. Converting a float64 array up front took longer than tracing a camera ray
/// (ndarray's n-dimensional iterator: 9 ns a ray), and ran on one thread with the GIL
/// held; read in place, the conversion is spread over the query's threads.
#[derive(Clone, Copy)]
pub enum FloatSlice<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl FloatSlice<'_> {
    /// Value `i` as float32.
    #[inline]
    pub fn at(&self, i: usize) -> f32 {
        match self {
            FloatSlice::F32(v) => v[i],
            FloatSlice::F64(v) => v[i] as f32,
        }
    }

    /// Row `i` of an `(N, 3)` array as a float64 vector, exactly.
    #[inline]
    pub fn row3_f64(&self, i: usize) -> DVec3 {
        match self {
            FloatSlice::F32(v) => Vec3::from_slice(&v[3 * i..3 * i + 3]).as_dvec3(),
            FloatSlice::F64(v) => DVec3::from_slice(&v[3 * i..3 * i + 3]),
        }
    }

    /// Row `i` of an `(N, 3)` array as a vector (in loops, match the slice once outside and
    /// use [`Coordinate::row3`]).
    #[inline]
    pub fn row3(&self, i: usize) -> Vec3 {
        match self {
            FloatSlice::F32(v) => f32::row3(v, i),
            FloatSlice::F64(v) => f64::row3(v, i),
        }
    }
}

/// An element type of a float array read in place.
pub trait Coordinate: Copy {
    /// Row `i` of an `(N, 3)` array of this type, each value rounded to nearest float32.
    fn row3(values: &[Self], i: usize) -> Vec3;
}

impl Coordinate for f32 {
    #[inline(always)]
    fn row3(values: &[f32], i: usize) -> Vec3 {
        Vec3::from_slice(&values[3 * i..3 * i + 3])
    }
}

impl Coordinate for f64 {
    #[inline(always)]
    fn row3(values: &[f64], i: usize) -> Vec3 {
        let r = &values[3 * i..3 * i + 3];
        Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32)
    }
}

/// `obj` as a NumPy array (lists and other sequences through `numpy.asarray`).
pub fn as_ndarray<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        return Ok(a.clone());
    }
    let converted = obj
        .py()
        .import("numpy")?
        .call_method1("asarray", (obj,))
        .map_err(|e| {
            // NumPy's own reason: a ragged list ("inhomogeneous shape"), an object it cannot
            // read.
            PyTypeError::new_err(format!(
                "{name}: expected a NumPy array or a sequence NumPy reads as one, got a {} \
                 that it cannot read: {}",
                type_name(obj),
                e.value(obj.py())
            ))
        })?;
    Ok(converted.cast::<PyUntypedArray>()?.clone())
}

pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "object".into())
}

pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Reads a float array of shape `(N, 3)` (or `(N,)` with `columns = None`); `rows` fixes N.
/// C-contiguous float32 and float64 arrays are borrowed; strided ones are copied in their own
/// precision; integer arrays (and lists of them) and other floats (float16, byte-swapped, long
/// double) as float64.
pub fn float_array<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    columns: Option<usize>,
    rows: Option<(usize, &str)>,
) -> PyResult<(Floats<'py>, usize)> {
    let array = as_ndarray(name, obj)?;
    let shape = array.shape().to_vec();
    let want = match columns {
        Some(c) => format!("(N, {c})"),
        None => "(N,)".into(),
    };
    let shape_ok = match columns {
        Some(c) => shape.len() == 2 && shape[1] == c,
        None => shape.len() == 1,
    };
    if !shape_ok {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {want}, got {}",
            shape_text(&shape)
        )));
    }
    let n = shape[0];
    if let Some((rows, other)) = rows {
        if n != rows {
            return Err(PyValueError::new_err(format!(
                "{name}: expected {rows} rows, as {other} has, got shape {}",
                shape_text(&shape)
            )));
        }
    }
    let dtype = array.dtype();
    // Integers (as from a Python list of ints) are converted like float64, and so are the
    // floats read in neither native float32 nor float64: float16 and byte-swapped floats
    // (`np.fromfile(f, ">f8")`) exactly, long double rounded to float64.
    let native = array.cast::<PyArrayDyn<f32>>().is_ok() || array.cast::<PyArrayDyn<f64>>().is_ok();
    let array = if dtype.kind() == b'i' || dtype.kind() == b'u' || (dtype.kind() == b'f' && !native)
    {
        array
            .call_method1("astype", ("float64",))?
            .cast::<PyUntypedArray>()?
            .clone()
    } else {
        array
    };
    let floats = if let Ok(a) = array.cast::<PyArrayDyn<f32>>() {
        let a = a.readonly();
        if a.is_c_contiguous() {
            Floats::Borrowed(a)
        } else {
            Floats::Owned(a.as_array().iter().copied().collect())
        }
    } else if let Ok(a) = array.cast::<PyArrayDyn<f64>>() {
        let a = a.readonly();
        if a.is_c_contiguous() {
            Floats::BorrowedF64(a)
        } else {
            Floats::OwnedF64(a.as_array().iter().copied().collect())
        }
    } else {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected a float32 or float64 (or integer) array, got dtype {}",
            dtype.str()?
        )));
    };
    Ok((floats, n))
}

/// Reads an integer array of shape `(N, 3)` as u32 indices, each checked to be non-negative
/// and below 2³².
pub fn index_array(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<[u32; 3]>> {
    let array = as_ndarray(name, obj)?;
    let shape = array.shape().to_vec();
    if !(shape.len() == 2 && shape[1] == 3) {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 3), got {}",
            shape_text(&shape)
        )));
    }
    let flat = integer_values(name, &array)?;
    if let Some(k) = flat
        .iter()
        .position(|&i| !(0..=i128::from(u32::MAX)).contains(&i))
    {
        let why = if flat[k] < 0 {
            "is negative"
        } else {
            "does not fit 32 bits"
        };
        return Err(PyValueError::new_err(format!(
            "{name}: row {}: index {} {why}",
            k / 3,
            flat[k]
        )));
    }
    Ok(flat
        .chunks_exact(3)
        .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
        .collect())
}

/// The values of an integer array (of any integer dtype), in C order; a TypeError naming the
/// argument for any other dtype.
pub fn integer_values(name: &str, array: &Bound<'_, PyUntypedArray>) -> PyResult<Vec<i128>> {
    let dtype = array.dtype();
    if dtype.kind() != b'i' && dtype.kind() != b'u' {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected an integer dtype, got {}",
            dtype.str()?
        )));
    }
    // Unsigned arrays as uint64 (an index above 2^63 read as int64 was shown negative).
    Ok(if dtype.kind() == b'u' {
        let as_u64 = array.call_method1("astype", ("uint64",))?;
        let values = as_u64.cast::<PyArrayDyn<u64>>()?.readonly();
        values.as_array().iter().map(|&i| i128::from(i)).collect()
    } else {
        let as_i64 = array.call_method1("astype", ("int64",))?;
        let values = as_i64.cast::<PyArrayDyn<i64>>()?.readonly();
        values.as_array().iter().map(|&i| i128::from(i)).collect()
    })
}

/// A ray interval bound: one value for every ray, or one per ray.
pub enum IntervalBound<'py> {
    Scalar(f32),
    PerRay(Floats<'py>),
}

/// `tmin` / `tmax`: None (the default), a number, or an array of shape `(N,)`.
pub fn interval_bound<'py>(
    name: &str,
    obj: Option<&Bound<'py, PyAny>>,
    default: f32,
    rays: usize,
) -> PyResult<IntervalBound<'py>> {
    let Some(obj) = obj else {
        return Ok(IntervalBound::Scalar(default));
    };
    if obj.is_none() {
        return Ok(IntervalBound::Scalar(default));
    }
    if let Ok(x) = obj.extract::<f64>() {
        return Ok(IntervalBound::Scalar(x as f32));
    }
    if obj.is_instance_of::<pyo3::types::PyString>() || obj.is_instance_of::<pyo3::types::PyBytes>()
    {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected a number or an array of shape (N,), got {}",
            type_name(obj)
        )));
    }
    let (floats, _) = float_array(name, obj, None, Some((rays, "origins")))?;
    Ok(IntervalBound::PerRay(floats))
}

/// A bound as the query loops read it: a constant, or one value per ray.
#[derive(Clone, Copy)]
pub enum BoundSlice<'a> {
    Scalar(f32),
    PerRay(FloatSlice<'a>),
}

impl IntervalBound<'_> {
    pub fn as_slice(&self) -> BoundSlice<'_> {
        match self {
            IntervalBound::Scalar(x) => BoundSlice::Scalar(*x),
            IntervalBound::PerRay(f) => BoundSlice::PerRay(f.values()),
        }
    }
}

impl BoundSlice<'_> {
    /// The bound of every ray, if it is one value for all (else `otherwise`).
    #[inline]
    pub fn constant(&self, otherwise: f32) -> f32 {
        match self {
            BoundSlice::Scalar(x) => *x,
            BoundSlice::PerRay(_) => otherwise,
        }
    }

    #[inline]
    pub fn at(&self, i: usize) -> f32 {
        match self {
            BoundSlice::Scalar(x) => *x,
            BoundSlice::PerRay(v) => v.at(i),
        }
    }
}
