//! Query points as callers hold them: a slice of `DVec3`, or the flat rows of an array
//! library's C-ordered (N, 3) float32 or float64 array, read in place.
//!
//! Why not always a `Vec<DVec3>`: from Python, converting 65,536 float32 points into a fresh
//! 1.5 MB vector cost more than the conversion itself. Memory the allocator has just handed
//! back to the kernel is faulted in again page by page on the next call (glibc trims its heap
//! once the answers' arrays are freed), and on this VM a fault costs about a microsecond:
//! the Cornell box's five answer columns and that vector took 20–30 ns per query of faults
//! in some processes, a third of the query's own time (measured with `perf`).

use glam::DVec3;

/// Points read one at a time, by index, from any thread.
pub trait QueryPoints: Sync {
    /// How many points there are.
    fn count(&self) -> usize;
    /// Point `i` in f64 (`i < count()`).
    fn point(&self, i: usize) -> DVec3;
}

impl QueryPoints for [DVec3] {
    #[inline]
    fn count(&self) -> usize {
        self.len()
    }

    #[inline]
    fn point(&self, i: usize) -> DVec3 {
        self[i]
    }
}

/// Rows of three coordinates laid end to end, `[x₀, y₀, z₀, x₁, …]`: a C-ordered (N, 3) array
/// of `f32` or `f64`, read in place.
#[derive(Clone, Copy, Debug)]
pub struct FlatPoints<'a, T>(&'a [T]);

impl<'a, T> FlatPoints<'a, T> {
    /// The rows of `flat`; `None` unless its length is a multiple of three.
    pub fn new(flat: &'a [T]) -> Option<Self> {
        flat.len().is_multiple_of(3).then_some(FlatPoints(flat))
    }
}

impl<T: Copy + Into<f64> + Sync> QueryPoints for FlatPoints<'_, T> {
    #[inline]
    fn count(&self) -> usize {
        self.0.len() / 3
    }

    #[inline]
    fn point(&self, i: usize) -> DVec3 {
        let row = &self.0[3 * i..3 * i + 3];
        DVec3::new(row[0].into(), row[1].into(), row[2].into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_rows_are_points() {
        let flat = [1.0f32, 2.0, 3.0, -4.0, 5.5, 6.0];
        let points = FlatPoints::new(&flat).unwrap();
        assert_eq!(points.count(), 2);
        assert_eq!(points.point(1), DVec3::new(-4.0, 5.5, 6.0));
        assert!(FlatPoints::new(&flat[..4]).is_none());
        let slice: &[DVec3] = &[DVec3::X];
        assert_eq!((slice.count(), slice.point(0)), (1, DVec3::X));
    }
}
