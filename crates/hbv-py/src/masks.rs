//! `mask=`: which instances of a scene a ray or point sees. Instance `i` is seen when
//! `mask & mask_i != 0` (hbv::scene::SceneRay); every bit set (the default) sees every instance
//! whose own mask is not zero.

use hbv::scene::SceneRay;
use numpy::{PyArrayDescrMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyInt};

use crate::arrays::{as_ndarray, integer_values, shape_text, type_name, ArrayValues};

/// One mask for every row, or one per row: an unsigned array of at most 32 bits read as uint32
/// (in place where it can be), or the checked values of another integer array.
pub enum Masks<'py> {
    Every(u32),
    Unsigned(ArrayValues<'py, u32>),
    Checked(Vec<u32>),
}

/// Masks as the query loops read them (no GIL needed).
#[derive(Clone, Copy)]
pub enum MaskSlice<'a> {
    Every(u32),
    PerRow(&'a [u32]),
}

impl Masks<'_> {
    pub fn as_slice(&self) -> MaskSlice<'_> {
        match self {
            Masks::Every(m) => MaskSlice::Every(*m),
            Masks::Unsigned(a) => MaskSlice::PerRow(a.as_slice()),
            Masks::Checked(v) => MaskSlice::PerRow(v),
        }
    }
}

impl MaskSlice<'_> {
    /// The mask of row `i`.
    #[inline]
    pub fn at(&self, i: usize) -> u32 {
        match self {
            MaskSlice::Every(m) => *m,
            MaskSlice::PerRow(v) => v[i],
        }
    }
}

/// A single mask: `None` for every bit, or a Python integer from 0 to 2³² - 1 (a `bool` is
/// refused: `mask=True` is surely a mistake).
pub fn one_mask(name: &str, obj: Option<&Bound<'_, PyAny>>) -> PyResult<u32> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(SceneRay::ALL);
    };
    if obj.is_instance_of::<PyBool>() || obj.extract::<i128>().is_err() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected an integer from 0 to 2**32 - 1, got {}",
            type_name(obj)
        )));
    }
    let value: i128 = obj.extract()?;
    u32::try_from(value).map_err(|_| {
        PyValueError::new_err(format!(
            "{name}: expected an integer from 0 to 2**32 - 1, got {value}"
        ))
    })
}

/// The `mask` of a query of `rows` rays or points (`rows_of` names the argument that fixed
/// the count): `None` (every bit), one integer (Python's or NumPy's) for all rows, or an array
/// of shape `(N,)` of uint8 to uint32 (read as [`ArrayValues`]: uint32 in place where it can
/// be) or another integer dtype (each value checked to fit 32 bits unsigned).
pub fn row_masks<'py>(
    obj: Option<&Bound<'py, PyAny>>,
    rows: usize,
    rows_of: &str,
) -> PyResult<Masks<'py>> {
    const NAME: &str = "mask";
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Masks::Every(SceneRay::ALL));
    };
    if obj.is_instance_of::<PyInt>() || obj.is_instance_of::<PyBool>() {
        return one_mask(NAME, Some(obj)).map(Masks::Every);
    }
    let array = as_ndarray(NAME, obj)?;
    if array.ndim() == 0 {
        // A NumPy integer (`np.uint32(3)`) is one mask, as a Python integer is.
        return one_mask(NAME, Some(obj)).map(Masks::Every);
    }
    let shape = array.shape().to_vec();
    if shape != [rows] {
        return Err(PyValueError::new_err(format!(
            "{NAME}: expected shape ({rows},), one mask per row of {rows_of}, got {}",
            shape_text(&shape)
        )));
    }
    let dtype = array.dtype();
    if dtype.kind() == b'u' && dtype.itemsize() <= 4 {
        return ArrayValues::read(NAME, &array).map(Masks::Unsigned);
    }
    let values = integer_values(NAME, &array)?;
    values
        .iter()
        .enumerate()
        .map(|(row, &m)| {
            u32::try_from(m).map_err(|_| {
                PyValueError::new_err(format!(
                    "{NAME}: row {row}: {m} does not fit 32 bits unsigned (0 to 2**32 - 1)"
                ))
            })
        })
        .collect::<PyResult<Vec<u32>>>()
        .map(Masks::Checked)
}
