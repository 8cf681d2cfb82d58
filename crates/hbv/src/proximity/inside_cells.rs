//! Inside tests answered by a lookup: a uniform grid over a closed surface whose cells that no
//! triangle touches are each known to lie inside or outside it.
//!
//! A closed cell that no triangle meets is connected and free of the surface, so every point
//! in it is on the same side as its centre (Jordan); so is every cell of a run of such cells
//! along x, since neighbours share a face that the surface does not meet. One exact inside test
//! per run (at its first cell's centre) therefore decides every point of every free cell, and
//! only the points in cells the surface may touch need a ray. Triangles mark the cells their
//! box, grown by a margin, overlaps: conservative, so a cell left free is free by at least the
//! margin, which covers the rounding of a point to its cell and of world coordinates to f32.
//!
//! ```text
//!   row of cells along x:   . . . S S . . . . S . .     S: a triangle's box overlaps it
//!   runs of free cells:     [ a ]     [  b  ]   [c]     one inside test each, at its first cell
//! ```
//!
//! On the shared scans, a grid of 128 cells along the longest axis leaves 3–6 % of the points
//! of the mesh's box in surface cells.

use glam::DVec3;

use crate::mesh::TriangleMesh;

/// The knobs of [`InsideCells`].
#[derive(Clone, Copy, Debug)]
pub struct InsideCellsConfig {
    /// Cells along the box's longest axis per cube root of the triangle count (default 16).
    pub cells_per_cube_root: f64,
    /// Fewest cells along the longest axis (default 16).
    pub min_cells: usize,
    /// Most cells along the longest axis (default 192: 7 million cells for a cube, 1.8 MB).
    pub max_cells: usize,
    /// The margin by which triangles' boxes grow, relative to the box's diagonal and to its
    /// largest coordinate (default 1e-5): far above the rounding of points to cells and of
    /// world coordinates to f32.
    pub relative_margin: f64,
}

impl Default for InsideCellsConfig {
    fn default() -> Self {
        Self {
            cells_per_cube_root: 16.0,
            min_cells: 16,
            max_cells: 192,
            relative_margin: 1e-5,
        }
    }
}

/// How many rings of cells around a surface cell [`InsideCells::known_point_near`] searches.
const NEAR_RINGS: i64 = 3;

/// What a cell knows about its points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Cell {
    Outside = 0,
    Inside = 1,
    /// A triangle's grown box overlaps the cell: its points need the exact test.
    Surface = 2,
}

/// Cells at two bits each, four to a byte, so that the grid of a large mesh stays in the
/// cache that random points' lookups hit (a byte a cell was twice as slow on spot's grid).
#[derive(Clone, Debug)]
struct PackedCells(Vec<u8>);

impl PackedCells {
    fn new(cells: &[Cell]) -> Self {
        let pack = |four: &[Cell]| {
            four.iter()
                .enumerate()
                .fold(0u8, |byte, (k, &c)| byte | (c as u8) << (2 * k))
        };
        Self(cells.chunks(4).map(pack).collect())
    }

    #[inline]
    fn get(&self, index: usize) -> Cell {
        match (self.0[index / 4] >> (2 * (index % 4))) & 3 {
            0 => Cell::Outside,
            1 => Cell::Inside,
            _ => Cell::Surface,
        }
    }
}

/// A grid over a closed surface's box answering inside tests for the points of the cells that
/// no triangle touches (see the module notes).
#[derive(Clone, Debug)]
pub struct InsideCells {
    /// The grid's lower corner.
    low: DVec3,
    /// The size of a cell (the same on every axis).
    cell: f64,
    /// 1 / the size of a cell, per axis.
    inverse_cell: DVec3,
    /// Cells per axis.
    dims: [usize; 3],
    /// Cell `(x, y, z)` at `(z · dims[1] + y) · dims[0] + x`.
    cells: PackedCells,
    /// How many cells the surface may touch.
    surface_cells: usize,
}

impl InsideCells {
    /// The grid over `mesh` (world-space triangles of closed surfaces), its free cells decided
    /// by `inside`, the exact test of a batch of points (called once, with one point per run
    /// of free cells). `None` for a mesh without triangles or with a coordinate not finite.
    pub fn new(
        mesh: &TriangleMesh,
        config: &InsideCellsConfig,
        inside: impl FnOnce(&[DVec3]) -> Vec<bool>,
    ) -> Option<Self> {
        let bounds = mesh.bounds();
        let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        if mesh.is_empty() || !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let margin = config.relative_margin
            * ((hi - lo).length() + lo.abs().max(hi.abs()).max_element())
            + f64::MIN_POSITIVE;
        let (low, high) = (lo - 2.0 * margin, hi + 2.0 * margin);
        let longest = (high - low).max_element();
        let along_longest = (config.cells_per_cube_root * (mesh.triangle_count() as f64).cbrt())
            .clamp(config.min_cells as f64, config.max_cells as f64);
        let cell = longest / along_longest.floor();
        let size = high - low;
        let dims = [0, 1, 2].map(|a| ((size[a] / cell).ceil() as usize).max(1));
        let mut grid = Self {
            low,
            cell,
            inverse_cell: DVec3::splat(1.0 / cell),
            dims,
            cells: PackedCells(Vec::new()),
            surface_cells: 0,
        };
        let mut cells = vec![Cell::Outside; dims[0] * dims[1] * dims[2]];
        grid.mark_surface(&mut cells, mesh, margin);
        grid.decide_free_runs(&mut cells, inside);
        grid.surface_cells = cells.iter().filter(|&&c| c == Cell::Surface).count();
        grid.cells = PackedCells::new(&cells);
        Some(grid)
    }

    /// Marks `Surface` every cell that a triangle's box, grown by `margin`, overlaps.
    fn mark_surface(&self, cells: &mut [Cell], mesh: &TriangleMesh, margin: f64) {
        for triangle in mesh.triangles() {
            let b = triangle.bounds();
            let first = self.clamped_cell(b.min.as_dvec3() - margin);
            let last = self.clamped_cell(b.max.as_dvec3() + margin);
            for z in first[2]..=last[2] {
                for y in first[1]..=last[1] {
                    let row = (z * self.dims[1] + y) * self.dims[0];
                    cells[row + first[0]..=row + last[0]].fill(Cell::Surface);
                }
            }
        }
    }

    /// Decides each run of free cells along x by the exact test at its first cell's centre.
    fn decide_free_runs(&self, cells: &mut [Cell], inside: impl FnOnce(&[DVec3]) -> Vec<bool>) {
        let [nx, ny, nz] = self.dims;
        // (first cell, one past the last) of each run, and its first cell's centre.
        let mut runs = Vec::new();
        let mut centres = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                let row = (z * ny + y) * nx;
                let mut x = 0;
                while x < nx {
                    if cells[row + x] == Cell::Surface {
                        x += 1;
                        continue;
                    }
                    let start = x;
                    while x < nx && cells[row + x] != Cell::Surface {
                        x += 1;
                    }
                    runs.push((row + start, row + x));
                    let index = DVec3::new(start as f64, y as f64, z as f64);
                    centres.push(self.low + (index + 0.5) * self.cell);
                }
            }
        }
        let answers = inside(&centres);
        assert_eq!(answers.len(), runs.len(), "one inside answer per run");
        for (&(start, end), &inside) in runs.iter().zip(&answers) {
            let value = if inside { Cell::Inside } else { Cell::Outside };
            cells[start..end].fill(value);
        }
    }

    /// The cell holding `p`, each coordinate clamped into the grid.
    fn clamped_cell(&self, p: DVec3) -> [usize; 3] {
        let at = (p - self.low) * self.inverse_cell;
        [0, 1, 2].map(|a| (at[a].floor().max(0.0) as usize).min(self.dims[a] - 1))
    }

    /// Whether `p` is inside, where its cell knows: `Some(false)` outside the grid (beyond
    /// every triangle's box) or for a point not finite, `Some(inside)` in a free cell, `None`
    /// in a surface cell, where the exact test must answer.
    #[inline]
    pub fn lookup(&self, p: DVec3) -> Option<bool> {
        let at = (p - self.low) * self.inverse_cell;
        // NaN fails every comparison: outside, as the exact test says of it.
        let within = |a: usize| at[a] >= 0.0 && at[a] < self.dims[a] as f64;
        if !(within(0) && within(1) && within(2)) {
            return Some(false);
        }
        let [x, y, z] = [0, 1, 2].map(|a| at[a] as usize);
        match self.cells.get((z * self.dims[1] + y) * self.dims[0] + x) {
            Cell::Outside => Some(false),
            Cell::Inside => Some(true),
            Cell::Surface => None,
        }
    }

    /// Whether `p` is inside, where the grid can tell: its cell's answer ([`lookup`]), else,
    /// when `segment_crossings` is given, the side of a known point nearby
    /// ([`known_point_near`]), the other side exactly when the segment from `p` to it crosses
    /// the surface an odd number of times (`segment_crossings(known)`). `None` where neither
    /// tells: the caller's exact test (a ray to infinity) answers.
    ///
    /// [`lookup`]: InsideCells::lookup
    /// [`known_point_near`]: InsideCells::known_point_near
    #[inline]
    pub fn decide(
        &self,
        p: DVec3,
        segment_crossings: Option<&mut dyn FnMut(DVec3) -> usize>,
    ) -> Option<bool> {
        if let Some(answer) = self.lookup(p) {
            return Some(answer);
        }
        let crossings = segment_crossings?;
        let (known, known_inside) = self.known_point_near(p)?;
        Some(known_inside != (crossings(known) % 2 == 1))
    }

    /// A point near `p` whose side is known: the centre of a free cell along an axis from `p`'s
    /// (the fewest steps, up to `NEAR_RINGS` (3); the nearest centre of those), else of the free
    /// cell nearest to `p` in the nearest ring of cells around `p`'s (up to `NEAR_RINGS` (3)
    /// rings out) that has one, and
    /// whether it is inside. A segment from `p` to it crosses the surface an odd number of
    /// times exactly when `p` is on the other side (Jordan, as a ray to infinity): a short
    /// segment, where the ray would cross the whole mesh. `None` outside the grid, or when no
    /// free cell is that near.
    pub fn known_point_near(&self, p: DVec3) -> Option<(DVec3, bool)> {
        let at = (p - self.low) * self.inverse_cell;
        if !(0..3).all(|a| at[a] >= 0.0 && at[a] < self.dims[a] as f64) {
            return None;
        }
        let home = [0, 1, 2].map(|a| at[a] as i64);
        // Along the six axis directions first, a step at a time: a few lookups, where a ring
        // of cells is 26 (then 98) of them.
        for distance in 1..=NEAR_RINGS {
            let mut best: Option<(f64, DVec3, bool)> = None;
            for (axis, sign) in [(0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1)] {
                let mut index = home;
                index[axis] += sign * distance;
                self.keep_nearer_free(index, p, &mut best);
            }
            if let Some((_, centre, inside)) = best {
                return Some((centre, inside));
            }
        }
        for ring in 1..=NEAR_RINGS {
            let mut best: Option<(f64, DVec3, bool)> = None;
            for dz in -ring..=ring {
                for dy in -ring..=ring {
                    for dx in -ring..=ring {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != ring {
                            continue;
                        }
                        let index = [home[0] + dx, home[1] + dy, home[2] + dz];
                        self.keep_nearer_free(index, p, &mut best);
                    }
                }
            }
            if let Some((_, centre, inside)) = best {
                return Some((centre, inside));
            }
        }
        None
    }

    /// Keeps in `best` (squared distance, centre, inside) the free cell `index` if it lies in
    /// the grid and its centre is nearer to `p`.
    #[inline]
    fn keep_nearer_free(&self, index: [i64; 3], p: DVec3, best: &mut Option<(f64, DVec3, bool)>) {
        if !(0..3).all(|a| (0..self.dims[a] as i64).contains(&index[a])) {
            return;
        }
        let [x, y, z] = index.map(|i| i as usize);
        let inside = match self.cells.get((z * self.dims[1] + y) * self.dims[0] + x) {
            Cell::Surface => return,
            Cell::Inside => true,
            Cell::Outside => false,
        };
        let corner = DVec3::new(x as f64, y as f64, z as f64);
        let centre = self.low + (corner + 0.5) * self.cell;
        let distance = centre.distance_squared(p);
        if best.is_none_or(|(d, _, _)| distance < d) {
            *best = Some((distance, centre, inside));
        }
    }

    /// Cells per axis.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The share of the cells that the surface may touch (0 to 1).
    pub fn surface_share(&self) -> f64 {
        self.surface_cells as f64 / (self.dims[0] * self.dims[1] * self.dims[2]) as f64
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::all_hits::AllHits;
    use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
    use crate::bvh::layout::Wide8Layout;
    use crate::geometry::Ray;
    use crate::mesh::procedural::torus;
    use crate::proximity::contains;

    #[test]
    fn lookups_agree_with_the_exact_test() {
        let mesh = torus(Vec3::ZERO, 1.0, 0.4, 40, 24);
        assert!(mesh.is_closed());
        let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
        let layout = Wide8Layout::new(&tree, &mesh);
        let exact = |p: DVec3| contains(&layout, p.as_vec3());
        let cells = InsideCells::new(&mesh, &InsideCellsConfig::default(), |centres| {
            centres.iter().map(|&c| exact(c)).collect()
        })
        .unwrap();
        assert!(cells.surface_share() < 0.6, "{}", cells.surface_share());
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 3.6 - 1.8
        };
        let (mut known, mut inside) = (0, 0);
        for _ in 0..20_000 {
            let p = DVec3::new(next(), next(), next() * 0.4);
            if let Some(answer) = cells.lookup(p) {
                assert_eq!(answer, exact(p), "at {p}");
                known += 1;
                inside += usize::from(answer);
            }
        }
        assert!(
            known > 10_000 && inside > 500,
            "{known} known, {inside} inside"
        );
        // Points in surface cells: the parity of a segment's crossings to a known point.
        let mut segments = 0;
        for _ in 0..20_000 {
            let p = DVec3::new(next(), next(), next() * 0.4);
            if cells.lookup(p).is_some() {
                continue;
            }
            // None: no free cell within reach (where the surface's cells are thick), a ray's
            // work.
            let Some((known, known_inside)) = cells.known_point_near(p) else {
                continue;
            };
            assert_eq!(cells.lookup(known), Some(known_inside));
            let from = p.as_vec3();
            let segment = Ray::new(from, known.as_vec3() - from).with_interval(0.0, 1.0);
            let odd = layout.count_hits(&segment) % 2 == 1;
            assert_eq!(known_inside != odd, exact(p), "at {p}");
            segments += 1;
        }
        assert!(segments > 1000, "{segments} points in surface cells");
        assert_eq!(cells.lookup(DVec3::splat(f64::NAN)), Some(false));
        assert_eq!(cells.lookup(DVec3::new(0.0, 0.0, 5.0)), Some(false));
        // The torus's hole is outside; the middle of its tube inside.
        assert_eq!(cells.lookup(DVec3::ZERO), Some(false));
        assert_eq!(cells.lookup(DVec3::new(1.0, 0.0, 0.0)), Some(true));
    }

    #[test]
    fn an_empty_mesh_has_no_grid() {
        let mesh = TriangleMesh::new(Vec::new(), Vec::new()).unwrap();
        assert!(InsideCells::new(&mesh, &InsideCellsConfig::default(), |_| Vec::new()).is_none());
    }
}
