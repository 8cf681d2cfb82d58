//! A uniform grid over the space around a mesh whose cells know, ahead of any query, which few
//! triangles can be nearest to a point inside them: the nearest-point search's shortcut for
//! meshes of few, large triangles (modelled scenes: walls, boxes), where a tree search spends
//! its time bounding triangles it then rejects.
//!
//! **Candidates of a cell** (a conservative form of the Voronoi-cell lists of distance-field
//! methods, e.g. Mauch 2000, "A fast algorithm for computing the closest point and distance
//! transform"). Let `C` be a cell (a box with half-diagonal `r` and centre `c`), `t_c` the
//! triangle nearest to `c`, and `U = max_corner D(corner, t_c)`: the distance to a convex set is
//! a convex function, so its largest value over the box is at a corner, and every point `p` of
//! `C` has a triangle within `U`. The triangle `w` nearest to `p` then has
//! `D(c, w) ≤ D(p, w) + |p - c| ≤ U + r`, so the triangles within `U + r` of the centre hold the
//! answer for every point of the cell. With the f64 routine's rounding (computed distances within
//! `δ` of the real ones, `box_bound::rounding_margin`), the list is the triangles whose computed
//! distance from `c` is at most `Ũ + r + 4δ`: `D̃(c,w) ≤ D(c,w) + δ ≤ D(p,w) + r + δ ≤
//! D̃(p,w) + r + 2δ ≤ D̃(p,t_c) + r + 2δ ≤ D(p,t_c) + r + 3δ ≤ U + r + 3δ ≤ Ũ + r + 4δ`
//! (`D̃(p,w) ≤ D̃(p,t_c)`: `w` is the brute force's pick, the least computed distance). A query in
//! the cell decides those few triangles with the same f64 routine as the brute force, and so
//! gives its answer, ties included.
//!
//! A cell with more than [`CandidateGridConfig::max_candidates`] such triangles (cells of
//! scanned meshes, whose many small triangles crowd every shell) keeps only `t_c`, as the seed of
//! a tree search: the best-so-far it starts from, which stands in for the nearest triangle of the
//! previous point in a Morton-sorted batch, without the sort. Points outside the grid are seeded
//! from the nearest cell.
//!
//! Cells are enlarged by a millionth of their size (and a `10⁻¹²` of the grid's largest
//! coordinate) on every side before the lists are made, so that a point the index arithmetic
//! rounds into a neighbouring cell still lies in that cell's box.

use glam::DVec3;
use rayon::prelude::*;

use super::point_triangle::{closest_point_on_flagged_triangle, TrianglePoint};
use super::prefetch::prefetch;
use crate::geometry::directed_rounding::f32_below;

/// Settings of the candidate grid that `closest_point` queries use on meshes of a few large
/// triangles (cells listing every triangle that can be nearest inside them; see
/// [`ClosestPointTree::with_grid`](super::ClosestPointTree::with_grid)).
#[derive(Clone, Copy, Debug)]
pub struct CandidateGridConfig {
    /// About how many cells the grid has (cubic cells, over the mesh's box grown by
    /// [`CandidateGridConfig::margin`] of its largest extent on every side); 0: no grid, batches
    /// are sorted in Morton order and seeded from their neighbours instead.
    pub cells: usize,
    /// A cell lists its triangles only when there are at most this many; otherwise its queries
    /// search the tree.
    pub max_candidates: usize,
    /// The grid covers the mesh's box grown by this share of its largest extent on every side.
    pub margin: f64,
    /// The grid is made only if at least this share of a sample of its cells list their
    /// candidates (0: always).
    pub min_listing: f64,
    /// The grid is made once the tree has been asked for this many points per cell (the batch
    /// that reaches it included, and answered from the grid); 0: with the tree.
    ///
    /// Making a cell costs about as much as three or four nearest-point searches without a
    /// grid (the Cornell box: 34,848 cells in the time of 115,000 searches, on one thread and
    /// on two), and a grid saves its cost only over many queries: the Cornell box answers 1.6
    /// million points a second without one and 8 million with one, so the grid pays for itself
    /// after about 140,000 points. Made at once, it made a first call of 1,000 points take 27
    /// ms instead of 0.5 (BENCHMARKS.md). Made when the searches without it have cost about
    /// what it costs (4 points a cell), a user's queries take at most about twice as long as
    /// with the better choice in hindsight (the ski-rental argument); a batch that reaches the
    /// count on its own (131,072 points for the default cells) gets the grid at once.
    pub payback: f64,
}

impl Default for CandidateGridConfig {
    fn default() -> Self {
        Self {
            cells: 32_768,
            max_candidates: 16,
            margin: 0.25,
            min_listing: 0.5,
            payback: 4.0,
        }
    }
}

/// One cell: `count > 0` triangles listed from `first` in the grid's candidate array, or
/// (`count == 0`) the seed triangle `first` of a tree search. Triangles are the search tree's
/// local ids (`LANES × packet + lane`, module `enclosure_packet`).
#[derive(Clone, Copy, Debug)]
struct Cell {
    first: u32,
    count: u32,
}

/// One entry of a cell's list: the triangle (an index into the grid's `listed`) beside its
/// computed distance from the cell's centre, rounded down. Side by side, so that a query reads
/// one cache line of the list, not two (the grid is about 1 MB, beyond L2: the Cornell box's
/// queries missed L2 about twice each).
#[derive(Clone, Copy, Debug)]
struct Candidate {
    index: u32,
    centre_distance: f32,
}

/// A triangle some cell lists, in f64 (exact: the mesh's f32 vertices), with its face id.
#[derive(Clone, Copy, Debug)]
pub(super) struct ListedTriangle {
    pub vertices: [DVec3; 3],
    pub prim: u32,
    /// `point_triangle::is_sliver` of the vertices.
    pub sliver: bool,
}

/// A query point's cell ([`CandidateGrid::locate`]): its index in the grid's cells, its
/// position, and whether the point is inside it (else the cell is the nearest to the point).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Located {
    index: usize,
    at: [u32; 3],
    inside: bool,
}

/// What a query point's cell says.
pub(super) enum CellAnswer {
    /// The answer, from the cell's list: the nearest point, its computed squared distance and
    /// its triangle's face id.
    Nearest(TrianglePoint, f64, u32),
    /// Search the tree, starting from this triangle.
    Seed(u32),
}

/// The grid: `dims` cells of edge `size` from `origin`, x fastest.
#[derive(Clone, Debug)]
pub(super) struct CandidateGrid {
    origin: DVec3,
    size: f64,
    dims: [usize; 3],
    cells: Vec<Cell>,
    /// The cells' lists, one after another, each nearest to its cell's centre first.
    candidates: Vec<Candidate>,
    /// The rounding margin `δ` (`box_bound::rounding_margin`) of every point of the grid.
    delta: f64,
    /// How much each cell's box is grown on every side (module notes).
    grow: f64,
    /// The triangles listed by some cell.
    listed: Vec<ListedTriangle>,
    /// The search tree's local id of each of `listed` (cells that seed a search hold local ids).
    local: Vec<u32>,
}

/// The nearest-point queries the grid is made from (implemented by the search tree).
pub(super) trait NearestTriangles: Sync {
    /// The triangle nearest to each of `points` (local ids; `None` for an empty mesh), each
    /// search seeded with the previous point's answer: for points next to each other, such as
    /// the centres of a row of cells, most of each search is then cut short.
    fn nearest_in_turn(&self, points: &[DVec3]) -> Vec<Option<u32>>;
    /// The computed (f64 routine) squared distance from `p` to triangle `local`.
    fn distance_squared(&self, p: DVec3, local: u32) -> f64;
    /// Every triangle whose computed squared distance from `p` is at most `radius_squared`
    /// (local ids), or `None` when there are more than `limit`.
    fn within(&self, p: DVec3, radius_squared: f64, limit: usize) -> Option<Vec<u32>>;
    /// The largest coordinate magnitude of the triangles.
    fn mesh_scale(&self) -> f64;
    /// Triangle `local`'s vertices in f64 and its face id.
    fn triangle(&self, local: u32) -> ListedTriangle;
}

impl CandidateGrid {
    /// The grid over `bounds` (the mesh's box, `min`, `max`); `None` for a configuration without
    /// cells or an empty mesh.
    pub fn new(
        search: &impl NearestTriangles,
        (min, max): (DVec3, DVec3),
        config: CandidateGridConfig,
    ) -> Option<Self> {
        if config.cells == 0 || !(min.is_finite() && max.is_finite()) {
            return None;
        }
        let grow = (max - min).max_element() * config.margin;
        let (lo, hi) = (min - DVec3::splat(grow), max + DVec3::splat(grow));
        let extent = (hi - lo).max(DVec3::splat((hi - lo).max_element() * 1e-3));
        let volume = extent.x * extent.y * extent.z;
        let size = (volume / config.cells as f64).cbrt();
        if !(size > 0.0 && size.is_finite()) {
            return None;
        }
        let dims = extent
            .to_array()
            .map(|e| ((e / size).ceil() as usize).clamp(1, 1024));
        let count = dims[0] * dims[1] * dims[2];
        let origin = lo;
        // The largest coordinate of the grid (whose cells may reach a cell past `extent`) or
        // the mesh.
        let far = (origin.abs().max((origin + extent).abs() + size))
            .max_element()
            .max(search.mesh_scale());
        let grow = size * CELL_GROWTH + far * 1e-12;
        let layout = (origin, size, grow);
        let at_of = |index: usize| {
            [
                index % dims[0],
                index / dims[0] % dims[1],
                index / (dims[0] * dims[1]),
            ]
            .map(|k| k as u32)
        };
        let centre_of = |index: usize| {
            let (lo, hi) = cell_box(layout, at_of(index));
            (lo + hi) * 0.5
        };
        // The cells `first..first + n`, each from the triangle nearest to its centre, found in
        // turn along them.
        let lists_of = |first: usize, n: usize| -> Option<Vec<CellList>> {
            let centres: Vec<DVec3> = (first..first + n).map(centre_of).collect();
            let nearest = search.nearest_in_turn(&centres);
            (first..first + n)
                .zip(nearest)
                .map(|(index, seed)| {
                    Some(cell_list(
                        search,
                        layout,
                        at_of(index),
                        seed?,
                        config.max_candidates,
                    ))
                })
                .collect()
        };
        // A grid whose cells mostly seed searches is slower than none (batches are then sorted
        // in Morton order, which keeps the tree's nodes in cache from one query to the next):
        // a sample of cells decides first.
        let stride = (count / PROBE_CELLS).max(1);
        let probed: Vec<bool> = (0..count)
            .step_by(stride)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|index| lists_of(index, 1).map(|list| list[0].is_ok()))
            .collect::<Option<_>>()?;
        let listing = probed.iter().filter(|&&listing| listing).count();
        if (listing as f64) < config.min_listing * probed.len() as f64 {
            return None;
        }
        // Row by row (x fastest): neighbouring centres, so that each nearest-triangle search
        // starts from the last one's answer (on the Cornell box's 34,848 cells the grid took
        // 86 ms on one thread searching each centre from scratch).
        let rows: Vec<Vec<CellList>> = (0..count / dims[0])
            .into_par_iter()
            .map(|row| lists_of(row * dims[0], dims[0]))
            .collect::<Option<_>>()?;
        let lists = rows.into_iter().flatten();
        let mut grid = CandidateGrid {
            origin,
            size,
            dims,
            cells: Vec::with_capacity(count),
            candidates: Vec::new(),
            delta: far * 2.0 * f64::powi(2.0, -32),
            grow,
            listed: Vec::new(),
            local: Vec::new(),
        };
        let mut index_of = std::collections::HashMap::new();
        for list in lists {
            grid.cells.push(match list {
                Ok(list) => {
                    let first = grid.candidates.len() as u32;
                    for (local, centre_distance) in list {
                        let index = *index_of.entry(local).or_insert_with(|| {
                            grid.listed.push(search.triangle(local));
                            grid.local.push(local);
                            grid.listed.len() as u32 - 1
                        });
                        grid.candidates.push(Candidate {
                            index,
                            centre_distance,
                        });
                    }
                    Cell {
                        first,
                        count: grid.candidates.len() as u32 - first,
                    }
                }
                Err(seed) => Cell {
                    first: seed,
                    count: 0,
                },
            });
        }
        Some(grid)
    }

    /// The cell of a finite point `p` (the nearest cell for a point outside the grid) and what it
    /// says: an answer only for a point inside the grid.
    ///
    /// The cell's list is tried nearest to the centre `c` first, and ends at the first triangle
    /// `t` whose rounded-down distance from the centre `l_t` leaves
    /// `g = l_t - |p - c|(1 + 10⁻¹²) - 3δ > 0` with `g² > d̃²_best (1 + 10⁻¹²)` (no square root
    /// of the best on the way): then
    /// `D̃(p,t) ≥ D(p,t) - δ ≥ D(c,t) - |p - c| - δ ≥ l_t - |p - c| - 2δ > D̃_best`, so neither it
    /// nor any later one (their `l` are larger) is as near as the best. (The third `δ` and the
    /// relative `10⁻¹²` cover the rounding of `g`, `g²` and `|p - c|`, each below `10⁻¹⁵` of the
    /// grid's coordinates.)
    ///
    /// `cell` is `p`'s, from [`CandidateGrid::locate`] (done once per query, for its prefetches
    /// and its answer).
    #[inline(always)]
    pub fn answer(&self, p: DVec3, cell: Located) -> CellAnswer {
        let Located { index, at, inside } = cell;
        let cell = self.cells[index];
        if cell.count == 0 {
            return CellAnswer::Seed(cell.first);
        }
        let range = cell.first as usize..(cell.first + cell.count) as usize;
        if !inside {
            return CellAnswer::Seed(self.local[self.candidates[range.start].index as usize]);
        }
        let list = &self.candidates[range];
        let mut best: Option<(TrianglePoint, u32)> = None;
        let mut best_d2 = f64::INFINITY;
        // The first (nearest the centre) is always decided: no early-exit test for it, and
        // none of the test's set-up (`reach`, a square root) for a cell that lists one.
        decide(
            p,
            &self.listed[list[0].index as usize],
            &mut best,
            &mut best_d2,
        );
        if list.len() > 1 {
            let (lo, hi) = cell_box((self.origin, self.size, self.grow), at);
            let reach = (p - (lo + hi) * 0.5).length() * (1.0 + 1e-12) + 3.0 * self.delta;
            for candidate in &list[1..] {
                let gap = candidate.centre_distance as f64 - reach;
                if gap > 0.0 && gap * gap > best_d2 * (1.0 + 1e-12) {
                    break;
                }
                decide(
                    p,
                    &self.listed[candidate.index as usize],
                    &mut best,
                    &mut best_d2,
                );
            }
        }
        match best {
            Some((q, prim)) => CellAnswer::Nearest(q, best_d2, prim),
            // Not reached: lists are never empty.
            None => CellAnswer::Seed(self.local[0]),
        }
    }

    /// The cell of `p`: the nearest cell for a point outside the grid, some cell for any point
    /// (NaN included).
    #[inline(always)]
    pub fn locate(&self, p: DVec3) -> Located {
        let q = (p - self.origin) * (1.0 / self.size);
        let mut index = 0;
        let mut inside = true;
        let mut stride = 1;
        let mut at = [0u32; 3];
        for (axis, &dim) in self.dims.iter().enumerate() {
            let x = q[axis];
            // `as i32` truncates (the floor for x ≥ 0) and saturates; one instruction and a
            // fix-up, where `as usize` and `floor` (a library call without SSE4.1) cost more.
            let k = (x as i32).clamp(0, dim as i32 - 1);
            inside &= x >= 0.0 && x < dim as f64;
            at[axis] = k as u32;
            index += k as usize * stride;
            stride *= dim;
        }
        Located { index, at, inside }
    }

    /// Asks for the memory of `cell`: the first of the two dependent loads of
    /// [`CandidateGrid::answer`]. A batch calls it some queries ahead, then
    /// [`CandidateGrid::prefetch_list`] fewer ahead, so that each query finds its cell and list in
    /// the nearest cache (the grid, about 1 MB on the Cornell box, does not fit in L2, and
    /// queries in their callers' order visit its cells at random).
    #[inline(always)]
    pub fn prefetch_cell(&self, cell: &Located) {
        prefetch(self.cells.as_ptr().wrapping_add(cell.index));
    }

    /// Asks for the memory of the start of `cell`'s list (reading the cell, which
    /// [`CandidateGrid::prefetch_cell`] asked for earlier). A hint: for a cell that seeds a
    /// search, the address asked for is no list's, and the hint is wasted, never wrong.
    #[inline(always)]
    pub fn prefetch_list(&self, cell: &Located) {
        let first = self.cells[cell.index].first as usize;
        prefetch(self.candidates.as_ptr().wrapping_add(first));
    }

    /// The number of cells, of cells that list their candidates, and of candidates listed.
    pub fn summary(&self) -> (usize, usize, usize) {
        let listing = self.cells.iter().filter(|c| c.count > 0).count();
        (self.cells.len(), listing, self.candidates.len())
    }
}

/// Decides triangle `t` with the brute force's f64 routine and keeps it by the brute force's
/// rule: least computed `d²`, then least face id.
#[inline(always)]
fn decide(
    p: DVec3,
    t: &ListedTriangle,
    best: &mut Option<(TrianglePoint, u32)>,
    best_d2: &mut f64,
) {
    let [a, b, c] = t.vertices;
    let q = closest_point_on_flagged_triangle(p, a, b, c, t.sliver);
    let d2 = (p - q.point).length_squared();
    if d2 < *best_d2 || (d2 == *best_d2 && best.is_some_and(|(_, b)| t.prim < b)) {
        *best_d2 = d2;
        *best = Some((q, t.prim));
    }
}

/// Cells tried before the grid is made (evenly spread over its index order).
const PROBE_CELLS: usize = 512;

/// Relative growth of a cell on each side before its list is made (see the module's notes).
const CELL_GROWTH: f64 = 1e-6;

/// The grid's origin, cell size and growth of each cell on every side ([`CELL_GROWTH`] of the
/// size and `10⁻¹²` of the grid's largest coordinate).
type Layout = (DVec3, f64, f64);

/// The box of cell `at`, grown (the same floats wherever it is computed: the lists' centre is
/// the query's).
#[inline]
fn cell_box((origin, size, grow): Layout, at: [u32; 3]) -> (DVec3, DVec3) {
    let at = DVec3::new(at[0] as f64, at[1] as f64, at[2] as f64);
    let (lo, hi) = (origin + at * size, origin + (at + DVec3::ONE) * size);
    (lo - DVec3::splat(grow), hi + DVec3::splat(grow))
}

/// What a cell holds before the grid is packed: its candidates with their computed distances
/// from its centre rounded down (`Ok`, nearest first), or the seed of a tree search (`Err`).
type CellList = Result<Vec<(u32, f32)>, u32>;

/// The [`CellList`] of cell `at`, given `seed`, the triangle nearest to its centre: its
/// candidates, or `seed` when they are more than `limit`.
fn cell_list(
    search: &impl NearestTriangles,
    layout: Layout,
    at: [u32; 3],
    seed: u32,
    limit: usize,
) -> CellList {
    let (lo, hi) = cell_box(layout, at);
    let scale = lo
        .abs()
        .max(hi.abs())
        .max_element()
        .max(search.mesh_scale());
    let centre = (lo + hi) * 0.5;
    let corners = (0..8).map(|k| {
        DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    });
    let farthest = corners
        .map(|corner| search.distance_squared(corner, seed))
        .fold(0.0f64, f64::max)
        .sqrt();
    // δ of every point of the cell (`box_bound::rounding_margin`), and generous slack for the
    // rounding of this sum (a relative 10⁻¹², thousands of times f64's).
    let delta = scale * f64::powi(2.0, -32);
    let half_diagonal = (hi - lo).length() * 0.5;
    let radius = (farthest + half_diagonal + 4.0 * delta) * (1.0 + 1e-12);
    match search.within(centre, radius * radius, limit) {
        // (Never empty: the seed is within `farthest` of the centre.)
        Some(list) if !list.is_empty() => {
            let mut list: Vec<(u32, f32)> = list
                .into_iter()
                .map(|local| {
                    let d = search.distance_squared(centre, local).sqrt();
                    (local, f32_below(d))
                })
                .collect();
            list.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            Ok(list)
        }
        _ => Err(seed),
    }
}
