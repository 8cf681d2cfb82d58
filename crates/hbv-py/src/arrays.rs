//! NumPy arguments: checked for shape and dtype with errors that name the argument, and read
//! through one door, [`ArrayValues`]: in place when the array is aligned, C-contiguous and of
//! the element type in native byte order, as NumPy's copy otherwise (misaligned, as a
//! deserialized Dask chunk can be; strided, Fortran-ordered, reversed; byte-swapped; integer).
//! The `(N, 3)` rays and points of the queries have a second door, `RowValues`
//! (`array_rows.rs`), that also reads rows a stride apart in place.

use hbv::glam::{DVec3, Vec3};
use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

/// The values of an argument array as one slice of `T`, in C order: the only way this module
/// reads the memory of an array it is handed.
///
/// Read in place (a view of the caller's data) when the array is aligned, C-contiguous and of
/// `T`'s dtype in native byte order; otherwise NumPy copies it (`astype(T, order="C")`, whose
/// result is aligned and C-contiguous). A slice of `T` must be aligned to `T`, so a misaligned
/// array (`np.frombuffer(buf, np.float32, offset=1)`) can only be read in place element by
/// element; a copy is a few ns a ray, against a query's tens to hundreds.
pub struct ArrayValues<'py, T: Element> {
    array: PyReadonlyArrayDyn<'py, T>,
}

impl<'py, T: Element> ArrayValues<'py, T> {
    /// Reads `array` as `T`. The caller chose `T` so that the conversion keeps the values it
    /// promises (float32 from any float32, integers and other floats as float64, indices as
    /// int64 or uint64); NumPy casts as `astype` does.
    pub fn read(name: &str, array: &Bound<'py, PyUntypedArray>) -> PyResult<Self> {
        let py = array.py();
        let in_place =
            array.is_aligned() && array.is_c_contiguous() && array.cast::<PyArrayDyn<T>>().is_ok();
        let readable = if in_place {
            // A view of its own, which no other code holds: its shape, strides and flags
            // cannot be changed between this check and the read.
            array.call_method0(pyo3::intern!(py, "view"))?
        } else {
            let order = PyDict::new(py);
            order.set_item("order", "C")?;
            array.call_method(
                pyo3::intern!(py, "astype"),
                (numpy::dtype::<T>(py),),
                Some(&order),
            )?
        };
        let refused = |why: String| PyValueError::new_err(format!("{name}: {why}"));
        let readable = readable.cast_into::<PyArrayDyn<T>>().map_err(|e| {
            refused(format!(
                "cannot be read as {}: {e}",
                std::any::type_name::<T>()
            ))
        })?;
        // The callers checked `array`'s shape; an ndarray subclass's own `view` or `astype`
        // could answer another.
        if readable.shape() != array.shape() {
            return Err(refused(format!(
                "its view or copy has shape {}, not its own {}",
                shape_text(readable.shape()),
                shape_text(array.shape())
            )));
        }
        let array = readable
            .try_readonly()
            .map_err(|e| refused(format!("cannot be read: {e}")))?;
        if let Err(e) = array.as_slice() {
            return Err(refused(format!("cannot be read as one slice: {e}")));
        }
        Ok(Self { array })
    }

    /// The array read: a view of the caller's, or NumPy's copy, aligned and C-contiguous.
    pub fn into_readonly(self) -> PyReadonlyArrayDyn<'py, T> {
        self.array
    }

    /// The values, in C order.
    pub fn as_slice(&self) -> &[T] {
        self.array
            .as_slice()
            .expect("ArrayValues::read checked a view that no other code can change")
    }
}

/// The values of a float argument, in the caller's precision: float32, or float64 (also for
/// integers and the other floats).
pub enum Floats<'py> {
    F32(ArrayValues<'py, f32>),
    F64(ArrayValues<'py, f64>),
}

impl Floats<'_> {
    /// The values as the query loops read them (no GIL needed).
    pub fn values(&self) -> FloatSlice<'_> {
        match self {
            Floats::F32(a) => FloatSlice::F32(a.as_slice()),
            Floats::F64(a) => FloatSlice::F64(a.as_slice()),
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
            FloatSlice::F32(v) => f32::dvec3(&v[3 * i..3 * i + 3]),
            FloatSlice::F64(v) => f64::dvec3(&v[3 * i..3 * i + 3]),
        }
    }

    /// Row `i` of an `(N, 3)` array as a vector, each value rounded to nearest float32.
    #[inline]
    pub fn row3(&self, i: usize) -> Vec3 {
        match self {
            FloatSlice::F32(v) => f32::vec3(&v[3 * i..3 * i + 3]),
            FloatSlice::F64(v) => f64::vec3(&v[3 * i..3 * i + 3]),
        }
    }
}

/// An element type of a float array read in place.
pub trait Coordinate: Element + Copy {
    /// The first three values of `row`, each rounded to nearest float32.
    fn vec3(row: &[Self]) -> Vec3;

    /// The first three values of `row` as float64, exactly.
    fn dvec3(row: &[Self]) -> DVec3;
}

impl Coordinate for f32 {
    #[inline(always)]
    fn vec3(row: &[f32]) -> Vec3 {
        Vec3::from_slice(row)
    }

    #[inline(always)]
    fn dvec3(row: &[f32]) -> DVec3 {
        Vec3::from_slice(row).as_dvec3()
    }
}

impl Coordinate for f64 {
    #[inline(always)]
    fn vec3(row: &[f64]) -> Vec3 {
        Vec3::new(row[0] as f32, row[1] as f32, row[2] as f32)
    }

    #[inline(always)]
    fn dvec3(row: &[f64]) -> DVec3 {
        DVec3::from_slice(row)
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
/// Float32 arrays are read as float32 and float64 ones as float64, in place where
/// [`ArrayValues`] can; integer arrays (and lists of them) and the other floats (float16, long
/// double) as float64.
pub fn float_array<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    columns: Option<usize>,
    rows: Option<(usize, &str)>,
) -> PyResult<(Floats<'py>, usize)> {
    let (array, n, precision) = float_argument(name, obj, columns, rows)?;
    let floats = match precision {
        Precision::F32 => Floats::F32(ArrayValues::read(name, &array)?),
        Precision::F64 => Floats::F64(ArrayValues::read(name, &array)?),
    };
    Ok((floats, n))
}

/// The precision a float argument is read in.
pub enum Precision {
    F32,
    F64,
}

/// `obj` as an array of shape `(N, columns)` (or `(N,)`), its N, and the precision it is read
/// in: float32 in either byte order as float32; integers (as from a Python list of ints) and
/// the other floats as float64 (float16 and float64 exactly, long double rounded).
pub fn float_argument<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    columns: Option<usize>,
    rows: Option<(usize, &str)>,
) -> PyResult<(Bound<'py, PyUntypedArray>, usize, Precision)> {
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
    let precision = match (dtype.kind(), dtype.itemsize()) {
        (b'f', 4) => Precision::F32,
        (b'f', _) | (b'i', _) | (b'u', _) => Precision::F64,
        _ => {
            return Err(PyTypeError::new_err(format!(
                "{name}: expected a float32 or float64 (or integer) array, got dtype {}",
                dtype.str()?
            )))
        }
    };
    Ok((array, n, precision))
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
    check_integer_dtype(name, &array)?;
    // Unsigned arrays as uint64, signed as int64 (in place where they are already that), each
    // index narrowed to u32 in one pass: no wider copy of the whole array.
    if array.dtype().kind() == b'u' {
        index_rows(name, ArrayValues::<u64>::read(name, &array)?.as_slice())
    } else {
        index_rows(name, ArrayValues::<i64>::read(name, &array)?.as_slice())
    }
}

/// Triangles of three u32 indices from a flat run of indices; a ValueError naming the row and
/// the first index that is negative or does not fit 32 bits.
fn index_rows<T>(name: &str, flat: &[T]) -> PyResult<Vec<[u32; 3]>>
where
    T: Copy + TryInto<u32> + Into<i128>,
{
    let mut rows = Vec::with_capacity(flat.len() / 3);
    for (r, c) in flat.chunks_exact(3).enumerate() {
        match (c[0].try_into(), c[1].try_into(), c[2].try_into()) {
            (Ok(a), Ok(b), Ok(d)) => rows.push([a, b, d]),
            _ => {
                let bad: i128 = c
                    .iter()
                    .map(|&i| i.into())
                    .find(|i| !(0..=i128::from(u32::MAX)).contains(i))
                    .expect("an index that did not narrow is out of range");
                let why = if bad < 0 {
                    "is negative"
                } else {
                    "does not fit 32 bits"
                };
                return Err(PyValueError::new_err(format!(
                    "{name}: row {r}: index {bad} {why}"
                )));
            }
        }
    }
    Ok(rows)
}

/// A TypeError naming the argument unless the array's dtype is an integer one.
fn check_integer_dtype(name: &str, array: &Bound<'_, PyUntypedArray>) -> PyResult<()> {
    let dtype = array.dtype();
    if dtype.kind() != b'i' && dtype.kind() != b'u' {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected an integer dtype, got {}",
            dtype.str()?
        )));
    }
    Ok(())
}

/// The values of an integer array (of any integer dtype), in C order; a TypeError naming the
/// argument for any other dtype.
pub fn integer_values(name: &str, array: &Bound<'_, PyUntypedArray>) -> PyResult<Vec<i128>> {
    check_integer_dtype(name, array)?;
    let dtype = array.dtype();
    // Unsigned arrays as uint64 (an index above 2^63 read as int64 was shown negative).
    Ok(if dtype.kind() == b'u' {
        let values = ArrayValues::<u64>::read(name, array)?;
        values.as_slice().iter().map(|&i| i128::from(i)).collect()
    } else {
        let values = ArrayValues::<i64>::read(name, array)?;
        values.as_slice().iter().map(|&i| i128::from(i)).collect()
    })
}

/// The bytes of a file handed over in memory: `bytes` (read in place) or anything NumPy reads as
/// a one-axis array of single bytes (a `bytearray`, a `memoryview`, `np.frombuffer(buf,
/// np.uint8, offset=1)`, a strided slice), through [`ArrayValues`].
pub enum Bytes<'py> {
    Python(Bound<'py, PyBytes>),
    Array(ArrayValues<'py, u8>),
}

impl Bytes<'_> {
    /// Reads `obj`, or a TypeError / ValueError naming the argument.
    pub fn read<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Bytes<'py>> {
        if let Ok(bytes) = obj.cast::<PyBytes>() {
            return Ok(Bytes::Python(bytes.clone()));
        }
        let array = as_ndarray(name, obj)?;
        let dtype = array.dtype();
        if !(matches!(dtype.kind(), b'u' | b'i') && dtype.itemsize() == 1) {
            return Err(PyTypeError::new_err(format!(
                "{name}: expected bytes or an array of uint8, got {} of dtype {}",
                type_name(obj),
                dtype.str()?
            )));
        }
        if array.ndim() != 1 {
            return Err(PyValueError::new_err(format!(
                "{name}: expected shape (N,), got {}",
                shape_text(array.shape())
            )));
        }
        Ok(Bytes::Array(ArrayValues::read(name, &array)?))
    }

    pub fn as_slice(&self) -> &[u8] {
        match self {
            Bytes::Python(bytes) => bytes.as_bytes(),
            Bytes::Array(array) => array.as_slice(),
        }
    }
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
    // An array of one value is an array, not a number (NumPy deprecated reading it as one).
    let is_array = obj.cast::<PyUntypedArray>().is_ok_and(|a| a.ndim() > 0);
    if !is_array {
        if let Ok(x) = obj.extract::<f64>() {
            return Ok(IntervalBound::Scalar(x as f32));
        }
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
