//! The cells a ray crosses, in order along the ray.

use glam::DVec3;

use super::GridShape;
use crate::geometry::Ray;

/// A walk through the cells of a [`GridShape`] along a ray: the 3D digital differential
/// analyzer of Amanatides & Woo (1987, "A fast voxel traversal algorithm for ray tracing").
///
/// From the cell that holds the entry point, each step crosses the nearest of the three next
/// cell boundaries: the one with the smallest
///
/// ```text
///   t_next[i] = (boundary_i − o_i) / d_i,     boundary_i = lo_i + (cell_i + [d_i > 0]) · size_i
/// ```
///
/// The boundary is recomputed from the cell index at each step (instead of adding
/// `size_i / |d_i|` to a running `t`), so that error does not accumulate; everything is f64.
/// An axis with `d_i = ±0` never steps (`t_next = +inf`).
#[derive(Clone, Debug)]
pub struct CellWalk<'a> {
    shape: &'a GridShape,
    origin: DVec3,
    direction: DVec3,
    cell: [u32; 3],
    t_next: [f64; 3],
    /// Where the walk ends: the grid's exit, or the end of the ray's interval.
    t_end: f64,
}

impl<'a> CellWalk<'a> {
    /// The walk over the part of the ray inside the grid with `t` in `[t_from, t_to]`; `None`
    /// when that part is empty. The ray must be valid.
    pub fn new(shape: &'a GridShape, ray: &Ray, t_from: f64, t_to: f64) -> Option<Self> {
        let origin = ray.origin.as_dvec3();
        let direction = ray.direction.as_dvec3();
        let (lo, hi) = (shape.lo, shape.hi());
        let (mut near, mut far) = (t_from, t_to);
        for axis in 0..3 {
            let (o, d) = (origin[axis], direction[axis]);
            if d == 0.0 {
                // Parallel to this slab: inside it everywhere or nowhere.
                if o < lo[axis] || o > hi[axis] {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo[axis] - o) / d, (hi[axis] - o) / d);
            near = near.max(a.min(b));
            far = far.min(a.max(b));
        }
        if near > far || near.is_nan() || far.is_nan() {
            return None;
        }
        let start = origin + near * direction;
        let mut cell = [0u32; 3];
        let mut t_next = [f64::INFINITY; 3];
        for axis in 0..3 {
            let x = if direction[axis] == 0.0 {
                origin[axis]
            } else {
                start[axis]
            };
            cell[axis] = shape.axis_cell(axis, x);
        }
        let mut walk = Self {
            shape,
            origin,
            direction,
            cell,
            t_next,
            t_end: far,
        };
        for (axis, t) in t_next.iter_mut().enumerate() {
            *t = walk.boundary_t(axis);
        }
        walk.t_next = t_next;
        Some(walk)
    }

    /// The `t` at which the ray crosses the next boundary of the current cell along `axis`.
    #[inline]
    fn boundary_t(&self, axis: usize) -> f64 {
        let d = self.direction[axis];
        if d == 0.0 {
            return f64::INFINITY;
        }
        let k = self.cell[axis] + (d > 0.0) as u32;
        (self.shape.boundary(axis, k) - self.origin[axis]) / d
    }

    /// The flat index of the current cell.
    #[inline]
    pub fn cell(&self) -> usize {
        self.shape.cell_index(self.cell)
    }

    /// The `t` at which the ray leaves the current cell (at most the end of the walk).
    #[inline]
    pub fn exit_t(&self) -> f64 {
        self.t_next[0]
            .min(self.t_next[1])
            .min(self.t_next[2])
            .min(self.t_end)
    }

    /// Steps into the next cell; `false` when the walk has ended (out of the grid, or past
    /// `t_to`).
    #[inline]
    pub fn advance(&mut self) -> bool {
        let t = &self.t_next;
        let axis = if t[0] <= t[1] && t[0] <= t[2] {
            0
        } else if t[1] <= t[2] {
            1
        } else {
            2
        };
        if self.t_next[axis] > self.t_end {
            return false;
        }
        if self.direction[axis] > 0.0 {
            if self.cell[axis] + 1 >= self.shape.resolution[axis] {
                return false;
            }
            self.cell[axis] += 1;
        } else {
            if self.cell[axis] == 0 {
                return false;
            }
            self.cell[axis] -= 1;
        }
        self.t_next[axis] = self.boundary_t(axis);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;
    use glam::Vec3;

    fn shape() -> GridShape {
        // 10 cells per axis over about [0, 1]^3.
        GridShape::new(&Aabb::new(Vec3::ZERO, Vec3::ONE), 1000, 1.0)
    }

    fn cells(shape: &GridShape, ray: &Ray) -> Vec<[u32; 3]> {
        let Some(mut walk) = CellWalk::new(shape, ray, 0.0, f64::INFINITY) else {
            return vec![];
        };
        let mut out = vec![walk.cell];
        while walk.advance() {
            out.push(walk.cell);
        }
        out
    }

    #[test]
    fn axis_ray_crosses_one_row() {
        let s = shape();
        let c = cells(&s, &Ray::new(Vec3::new(-1.0, 0.55, 0.05), Vec3::X));
        assert_eq!(c.len(), 10);
        assert!(c.iter().enumerate().all(|(i, c)| *c == [i as u32, 5, 0]));
        let back = cells(&s, &Ray::new(Vec3::new(2.0, 0.55, 0.05), -Vec3::X));
        assert_eq!(back.first(), Some(&[9, 5, 0]));
        assert_eq!(back.last(), Some(&[0, 5, 0]));
    }

    #[test]
    fn diagonal_ray_steps_one_axis_at_a_time_and_misses_outside() {
        let s = shape();
        let c = cells(
            &s,
            &Ray::new(Vec3::new(0.05, 0.02, 0.51), Vec3::new(1.0, 0.5, -0.0)),
        );
        for w in c.windows(2) {
            let moved: u32 = (0..3).map(|k| w[0][k].abs_diff(w[1][k])).sum();
            assert_eq!(moved, 1, "{w:?}");
        }
        assert_eq!(c[0], [0, 0, 5]);
        assert!(cells(&s, &Ray::new(Vec3::new(-1.0, 2.0, 0.5), Vec3::X)).is_empty());
        assert!(cells(&s, &Ray::new(Vec3::new(-1.0, 0.5, 0.5), -Vec3::X)).is_empty());
    }
}
