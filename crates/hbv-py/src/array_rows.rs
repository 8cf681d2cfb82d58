//! `(N, 3)` float arguments read as rows a stride apart: in place where each row's three values
//! are contiguous and aligned and the rows a whole number of items apart, as `rays[:, :3]` and
//! `rays[:, 3:]` of a C-ordered `(N, 6)` array of rays are; every other array as
//! [`ArrayValues`] reads it.

use hbv::glam::{DVec3, Vec3};
use numpy::{
    Element, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::{float_argument, ArrayValues, Coordinate, Precision};

/// The rows of an `(N, 3)` array read in place: row `i` is `values[stride·i .. stride·i + 3]`.
#[derive(Clone, Copy)]
pub struct RowSlice<'a, T> {
    /// From row 0's first value to row N-1's last: `(N - 1)·stride + 3` values (none when N
    /// is 0), the values between rows included (they belong to no row and are never read).
    values: &'a [T],
    /// Items from one row's first value to the next one's: 3 for a C-ordered array, 6 for
    /// either half of a C-ordered `(N, 6)` array.
    stride: usize,
}

impl<T: Coordinate> RowSlice<'_, T> {
    /// Row `i`, each value rounded to nearest float32: one multiply-add to find it
    /// (`stride·i`), the same for a copy (stride 3) as for a view.
    #[inline(always)]
    pub fn row3(&self, i: usize) -> Vec3 {
        let start = self.stride * i;
        T::vec3(&self.values[start..start + 3])
    }

    /// Row `i` as float64, exactly.
    #[inline(always)]
    pub fn row3_f64(&self, i: usize) -> DVec3 {
        let start = self.stride * i;
        T::dvec3(&self.values[start..start + 3])
    }
}

/// The rows of an `(N, 3)` float argument, read in place where [`ArrayValues`] would read the
/// array in place and also where the rows lie a stride apart: each row's three values
/// contiguous (column stride one item), aligned, in native byte order, and the row stride a
/// whole number of items, at least three (rows that do not overlap). So `rays[:, :3]` and
/// `rays[:, 3:]` of a C-ordered `(N, 6)` array are read where they lie: NumPy's copy of them
/// cost `hbv.open3d`'s `cast_rays` 7–13 % over `BVH.intersect` on 1 M rays (docs/PYTHON.md,
/// the Open3D drop-in's speed, as of 5b25b92). Every other array is NumPy's copy, as
/// [`ArrayValues`] reads it.
pub struct RowValues<'py, T: Element> {
    array: PyReadonlyArrayDyn<'py, T>,
    stride: usize,
}

impl<'py, T: Coordinate> RowValues<'py, T> {
    /// Reads `array`, of shape `(N, 3)` (the caller checked it), as rows of `T`.
    pub fn read(name: &str, array: &Bound<'py, PyUntypedArray>) -> PyResult<Self> {
        if row_stride::<T>(array).is_some() {
            // A view of its own, which no other code holds: its shape, strides and flags
            // cannot be changed between the check below and the reads.
            let view = array.call_method0(pyo3::intern!(array.py(), "view"))?;
            if let Ok(view) = view.cast_into::<PyArrayDyn<T>>() {
                // An ndarray subclass's own `view` could answer another shape or layout.
                let stride = (view.shape() == array.shape())
                    .then(|| row_stride::<T>(view.as_untyped()))
                    .flatten();
                if let Some(stride) = stride {
                    let array = view.try_readonly().map_err(|e| {
                        PyValueError::new_err(format!("{name}: cannot be read: {e}"))
                    })?;
                    return Ok(Self { array, stride });
                }
            }
        }
        let copy = ArrayValues::<T>::read(name, array)?;
        Ok(Self {
            array: copy.into_readonly(),
            stride: 3,
        })
    }

    /// The rows, for the query loops (no GIL needed).
    pub fn rows(&self) -> RowSlice<'_, T> {
        let rows = self.array.shape()[0];
        if rows == 0 {
            return RowSlice {
                values: &[],
                stride: self.stride,
            };
        }
        let len = (rows - 1) * self.stride + 3;
        // SAFETY: `read` checked that the array (a view no other code holds, kept alive and
        // borrowed read-only by `self.array`) is aligned for `T`, of `T`'s dtype, and that its
        // row i's values lie at items stride·i, stride·i + 1, stride·i + 2 from its data
        // pointer, with stride ≥ 3: the `len` items from the data pointer run from its first
        // value to its last, one span of the one buffer the array views. For a C-ordered copy
        // (stride 3) they are exactly its values, as `as_slice` would give them. Writes to the
        // buffer from Python while the query runs are as for any array read in place.
        let values = unsafe { std::slice::from_raw_parts(self.array.data().cast_const(), len) };
        RowSlice {
            values,
            stride: self.stride,
        }
    }
}

/// The row stride, in items, with which [`RowValues`] reads `array` in place, if it can: an
/// aligned `(N, 3)` array of `T`'s dtype in native byte order whose rows' values are one item apart
/// and whose rows are a whole number of items, at least three, apart (any stride when there
/// are fewer than two rows: only row 0 is read).
fn row_stride<T: Element>(array: &Bound<'_, PyUntypedArray>) -> Option<usize> {
    let item = std::mem::size_of::<T>() as isize;
    let (shape, strides) = (array.shape(), array.strides());
    let readable = shape.len() == 2
        && shape[1] == 3
        && array.is_aligned()
        && array.cast::<PyArrayDyn<T>>().is_ok()
        && strides[1] == item;
    if !readable {
        return None;
    }
    if shape[0] < 2 {
        return Some(3);
    }
    let stride = strides[0];
    (stride >= 3 * item && stride % item == 0).then_some((stride / item) as usize)
}

/// The rows of an `(N, 3)` float argument in the caller's precision (as [`Floats`]).
pub enum FloatRowValues<'py> {
    F32(RowValues<'py, f32>),
    F64(RowValues<'py, f64>),
}

impl FloatRowValues<'_> {
    /// The rows as the query loops read them (no GIL needed).
    pub fn rows(&self) -> FloatRows<'_> {
        match self {
            FloatRowValues::F32(a) => FloatRows::F32(a.rows()),
            FloatRowValues::F64(a) => FloatRows::F64(a.rows()),
        }
    }
}

/// Rows of three floats in place, float32 or float64 (see [`RowSlice`]).
#[derive(Clone, Copy)]
pub enum FloatRows<'a> {
    F32(RowSlice<'a, f32>),
    F64(RowSlice<'a, f64>),
}

impl FloatRows<'_> {
    /// Row `i` as a vector, each value rounded to nearest float32 (in loops, match the rows
    /// once outside and use [`RowSlice::row3`]).
    #[inline]
    pub fn row3(&self, i: usize) -> Vec3 {
        match self {
            FloatRows::F32(r) => r.row3(i),
            FloatRows::F64(r) => r.row3(i),
        }
    }

    /// Row `i` as a float64 vector, exactly.
    #[inline]
    pub fn row3_f64(&self, i: usize) -> DVec3 {
        match self {
            FloatRows::F32(r) => r.row3_f64(i),
            FloatRows::F64(r) => r.row3_f64(i),
        }
    }
}

/// Reads a float array of shape `(N, 3)` as [`float_array`] does, in place also where its rows
/// lie a stride apart ([`RowValues`]); `rows` fixes N.
pub fn float_rows<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    rows: Option<(usize, &str)>,
) -> PyResult<(FloatRowValues<'py>, usize)> {
    let (array, n, precision) = float_argument(name, obj, Some(3), rows)?;
    let floats = match precision {
        Precision::F32 => FloatRowValues::F32(RowValues::read(name, &array)?),
        Precision::F64 => FloatRowValues::F64(RowValues::read(name, &array)?),
    };
    Ok((floats, n))
}
