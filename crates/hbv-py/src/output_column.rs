//! Output arrays written once per row, without being zeroed first.

use std::mem::MaybeUninit;

/// An output column of `len` rows, allocated but not initialized: a query writes every row once
/// (through [`OutputColumn::rows`]) and then takes the values ([`OutputColumn::into_filled`]).
///
/// A zeroed `vec![0; n]` costs a `memset` of the whole column before the query overwrites it:
/// 5.5 MB for the five columns of 262,144 closest hits, 2% of a camera ray's time from Python.
pub struct OutputColumn<T> {
    values: Vec<T>,
    len: usize,
}

impl<T> OutputColumn<T> {
    pub fn new(len: usize) -> Self {
        Self {
            values: Vec::with_capacity(len),
            len,
        }
    }

    /// The rows, to be written.
    pub fn rows(&mut self) -> &mut [MaybeUninit<T>] {
        &mut self.values.spare_capacity_mut()[..self.len]
    }

    /// The values.
    ///
    /// # Safety
    /// Every row of [`OutputColumn::rows`] has been written.
    pub unsafe fn into_filled(mut self) -> Vec<T> {
        // SAFETY: the capacity is at least `len`, and the caller wrote rows `0..len`.
        unsafe { self.values.set_len(self.len) };
        self.values
    }
}
