//! Where a uniform grid's cells are: its box, its resolution and the box of each cell.

use glam::DVec3;

use crate::geometry::Aabb;

/// The geometry of a uniform grid, in f64: the box `[lo, lo + resolution · cell_size]` cut
/// into `resolution[0] × resolution[1] × resolution[2]` equal cells, numbered x fastest.
///
/// f64 keeps the cell boundaries and the ray's walk through them accurate to about 1e-16 of the
/// scene's size, far inside [`GridShape::pad`], the margin by which the triangle lists are made
/// conservative.
#[derive(Clone, Debug, PartialEq)]
pub struct GridShape {
    pub lo: DVec3,
    pub cell_size: DVec3,
    pub resolution: [u32; 3],
    /// How far every cell is enlarged when deciding which triangles it lists: a triangle within
    /// `pad` of a cell is in its list. Covers the rounding of the overlap test and of the walk.
    pub pad: f64,
}

impl GridShape {
    /// Most cells on one axis.
    pub const MAX_AXIS_CELLS: u32 = 1024;
    /// Most cells in all (64 Mi cells: 256 MiB of cell offsets).
    pub const MAX_CELLS: u64 = 1 << 26;

    /// The shape for `count` triangles in `bounds` (not empty): `λ · N^(1/3)` cells along the
    /// box's longest axis and proportionally fewer along the others, at least one each.
    ///
    /// This is the density heuristic of Cleary & Wyvill (1988) and Devillers (1989) in its
    /// per-axis form: for a cube it makes `λ³ N` cells, a constant number of triangles per
    /// cell, so a ray tests O(1) triangles per cell and crosses O(N^(1/3)) cells.
    ///
    /// The box is first enlarged by `2 · pad` on every side, so that a flat mesh (zero extent
    /// on one axis) still makes cells of non-zero size, and every triangle lies strictly inside.
    pub fn new(bounds: &Aabb, count: usize, lambda: f64) -> Self {
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        let longest = (max - min).max_element();
        let magnitude = min.abs().max(max.abs()).max_element();
        // Relative to the scene (2^-20) and to its distance from the origin (2^-40), both far
        // above f64 rounding (2^-52) and far below a cell.
        let pad = longest * (1.0 / 1_048_576.0) + magnitude * (1.0 / 1_099_511_627_776.0);
        let lo = min - DVec3::splat(2.0 * pad);
        let extent = (max + DVec3::splat(2.0 * pad)) - lo;

        let per_longest = lambda.max(1e-3) * (count.max(1) as f64).cbrt();
        let mut resolution = [0u32; 3];
        for axis in 0..3 {
            let cells = (per_longest * extent[axis] / extent.max_element()).round();
            resolution[axis] = cells.clamp(1.0, Self::MAX_AXIS_CELLS as f64) as u32;
        }
        while resolution.iter().map(|&r| r as u64).product::<u64>() > Self::MAX_CELLS {
            resolution = resolution.map(|r| (r - r / 8).max(1));
        }
        let cell_size = extent
            / DVec3::new(
                resolution[0] as f64,
                resolution[1] as f64,
                resolution[2] as f64,
            );
        Self {
            lo,
            cell_size,
            resolution,
            pad,
        }
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.resolution.iter().map(|&r| r as usize).product()
    }

    /// The far corner of the grid.
    pub fn hi(&self) -> DVec3 {
        self.lo
            + self.cell_size
                * DVec3::new(
                    self.resolution[0] as f64,
                    self.resolution[1] as f64,
                    self.resolution[2] as f64,
                )
    }

    /// The cell index along `axis` that holds coordinate `x`, clamped into the grid.
    #[inline]
    pub fn axis_cell(&self, axis: usize, x: f64) -> u32 {
        let k = ((x - self.lo[axis]) / self.cell_size[axis]).floor();
        k.clamp(0.0, (self.resolution[axis] - 1) as f64) as u32
    }

    /// The coordinate of the lower boundary of cell `k` along `axis` (`k` may be the resolution:
    /// the grid's upper face).
    #[inline]
    pub fn boundary(&self, axis: usize, k: u32) -> f64 {
        self.lo[axis] + k as f64 * self.cell_size[axis]
    }

    /// The flat index of cell `(x, y, z)`.
    #[inline]
    pub fn cell_index(&self, c: [u32; 3]) -> usize {
        let [rx, ry, _] = self.resolution;
        (c[2] as usize * ry as usize + c[1] as usize) * rx as usize + c[0] as usize
    }

    /// The box of cell `c`, enlarged by [`GridShape::pad`] on every side.
    pub fn padded_cell(&self, c: [u32; 3]) -> (DVec3, DVec3) {
        let lo = DVec3::new(
            self.boundary(0, c[0]),
            self.boundary(1, c[1]),
            self.boundary(2, c[2]),
        );
        let hi = DVec3::new(
            self.boundary(0, c[0] + 1),
            self.boundary(1, c[1] + 1),
            self.boundary(2, c[2] + 1),
        );
        (lo - DVec3::splat(self.pad), hi + DVec3::splat(self.pad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn resolution_follows_density_and_aspect() {
        let cube = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let s = GridShape::new(&cube, 8000, 2.0);
        assert_eq!(s.resolution, [40, 40, 40]);
        let long = Aabb::new(Vec3::ZERO, Vec3::new(4.0, 1.0, 2.0));
        let s = GridShape::new(&long, 1000, 1.0);
        assert_eq!(s.resolution, [10, 3, 5]);
        // A flat mesh gets one cell of non-zero size on its flat axis.
        let flat = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        let s = GridShape::new(&flat, 1000, 1.0);
        assert_eq!(s.resolution[2], 1);
        assert!(s.cell_size.z > 0.0);
    }

    #[test]
    fn cells_cover_the_box_and_clamp() {
        let b = Aabb::new(Vec3::splat(-3.0), Vec3::splat(5.0));
        let s = GridShape::new(&b, 1000, 1.0);
        assert!(s.lo.cmple(DVec3::splat(-3.0)).all() && s.hi().cmpge(DVec3::splat(5.0)).all());
        assert_eq!(s.axis_cell(0, -100.0), 0);
        assert_eq!(s.axis_cell(0, 100.0), s.resolution[0] - 1);
        assert_eq!(s.cell_index([1, 0, 0]), 1);
        assert_eq!(s.cell_index([0, 1, 0]), s.resolution[0] as usize);
    }
}
