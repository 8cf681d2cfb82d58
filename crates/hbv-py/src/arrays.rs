//! NumPy arguments: checked for shape and dtype with errors that name the argument, read in
//! place when they are C-contiguous float32, converted otherwise (float64, strided).

use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// float32 values of an argument: borrowed from the caller's array, or converted.
pub enum Floats<'py> {
    Borrowed(PyReadonlyArrayDyn<'py, f32>),
    Owned(Vec<f32>),
}

impl Floats<'_> {
    pub fn as_slice(&self) -> &[f32] {
        match self {
            Floats::Borrowed(a) => a.as_slice().expect("checked contiguous"),
            Floats::Owned(v) => v,
        }
    }
}

/// `obj` as a NumPy array (lists and other sequences through `numpy.asarray`).
fn as_ndarray<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        return Ok(a.clone());
    }
    let converted = obj
        .py()
        .import("numpy")?
        .call_method1("asarray", (obj,))
        .map_err(|_| {
            PyTypeError::new_err(format!(
                "{name}: expected a NumPy array, got {}",
                type_name(obj)
            ))
        })?;
    Ok(converted.cast::<PyUntypedArray>()?.clone())
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "object".into())
}

fn shape_text(shape: &[usize]) -> String {
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
/// float32 C-contiguous arrays are borrowed; float64 and strided arrays are converted.
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
    // Integers (as from a Python list of ints) are converted like float64.
    let array = if dtype.kind() == b'i' || dtype.kind() == b'u' {
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
        Floats::Owned(a.readonly().as_array().iter().map(|&x| x as f32).collect())
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
    let dtype = array.dtype();
    if dtype.kind() != b'i' && dtype.kind() != b'u' {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected an integer dtype, got {}",
            dtype.str()?
        )));
    }
    let as_i64 = array.call_method1("astype", ("int64",))?;
    let values = as_i64.cast::<PyArrayDyn<i64>>()?.readonly();
    let flat: Vec<i64> = values.as_array().iter().copied().collect();
    if let Some(k) = flat
        .iter()
        .position(|&i| !(0..=u32::MAX as i64).contains(&i))
    {
        return Err(PyValueError::new_err(format!(
            "{name}: row {}: index {} is negative or too large",
            k / 3,
            flat[k]
        )));
    }
    Ok(flat
        .chunks_exact(3)
        .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
        .collect())
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
    let (floats, _) = float_array(name, obj, None, Some((rays, "origins")))?;
    Ok(IntervalBound::PerRay(floats))
}

/// A bound as the slice form the query loops read: a constant, or one value per ray.
#[derive(Clone, Copy)]
pub enum BoundSlice<'a> {
    Scalar(f32),
    PerRay(&'a [f32]),
}

impl IntervalBound<'_> {
    pub fn as_slice(&self) -> BoundSlice<'_> {
        match self {
            IntervalBound::Scalar(x) => BoundSlice::Scalar(*x),
            IntervalBound::PerRay(f) => BoundSlice::PerRay(f.as_slice()),
        }
    }
}

impl BoundSlice<'_> {
    #[inline]
    pub fn at(&self, i: usize) -> f32 {
        match self {
            BoundSlice::Scalar(x) => *x,
            BoundSlice::PerRay(v) => v[i],
        }
    }
}
