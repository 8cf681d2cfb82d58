//! The nearest point of a mesh's surface to a query point: a branch-and-bound search of a BVH.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::box_bound::{prune_threshold, rounding_margin, PointBracket};
use super::candidate_grid::{
    CandidateGrid, CandidateGridConfig, CellAnswer, ListedTriangle, Located, NearestTriangles,
};
use super::enclosure_packet::LANES;
use super::point_triangle::{
    closest_point_on_flagged_triangle, closest_point_on_sliver, closest_point_on_triangle,
    TrianglePoint,
};
use super::point_triangle_lanes::F64_LANES;
use super::prefetch::prefetch;
use super::query_order::morton_order;
use super::query_points::QueryPoints;
#[cfg(target_arch = "x86_64")]
use super::search_lanes::AvxLanes;
use super::search_lanes::{PortableLanes, SearchLanes};
use super::search_tree::{SearchTree, SearchTreeConfig, WIDTH};
use crate::batch_threads::{for_each_chunk, map_collect, share_out, Threads};
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// The nearest surface point to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The nearest point, `(1-u-v) p0 + u p1 + v p2` of triangle `prim`.
    pub point: DVec3,
    /// Euclidean distance from the query point to `point`.
    pub distance: f64,
    /// The triangle's index in the mesh's face order; among triangles at the same distance, the
    /// smallest.
    pub prim: u32,
    pub u: f64,
    pub v: f64,
}

/// A BVH laid out for nearest-point queries: any [`BuildTree`] collapsed to 8-child nodes with
/// leaves of eight-triangle packets (module `search_tree`), boxes and triangles in f32 as in the
/// mesh.
///
/// **Search** (branch and bound, as in Larsen et al. 1999 and Ericson §6.5): keep the best
/// squared distance `d²` so far; at a node bound the children's box distances
/// `Σ_axis max(min - p, 0, p - max)²` from below (near the leaves, boxes in a frame facing the
/// surface patch, module `node_frame`), and visit those not farther than `d²`, the nearest
/// first; in a leaf, bound each triangle from below by the distance to an enclosure (its plane's
/// slab cut by a cylinder around it and its edges' half-spaces, module `triangle_enclosure`),
/// and decide the survivors with
/// [`closest_point_on_triangle`] (Ericson §5.1.5) in f64 (four at a time, branch-free, where
/// two or more of a half packet survive: module `point_triangle_lanes`). The bounds are f32, eight at a
/// time, and conservative (`proximity/box_bound.rs`): nothing that the f64 brute force would pick is
/// ever pruned, so the answers are the brute force's, ties included (smallest face id).
/// Degenerate triangles are left out, as in every tree (they have no face to be nearest to, and
/// their edges are other triangles' edges on meshes that matter).
#[derive(Debug)]
pub struct ClosestPointTree {
    tree: SearchTree,
    /// Candidate lists and seeds per cell of the space around the mesh, made once enough points
    /// have been asked for ([`CandidateGridConfig::payback`]; unset until then). `None` inside:
    /// no grid, or one whose cells would mostly seed searches; batches are then sorted and
    /// seeded from their neighbours.
    grid: OnceLock<Option<CandidateGrid>>,
    grid_config: CandidateGridConfig,
    /// The mesh's box, which the grid covers (grown).
    bounds: (DVec3, DVec3),
    /// Points asked for so far, until the grid is made.
    queried: AtomicUsize,
}

impl Clone for ClosestPointTree {
    fn clone(&self) -> Self {
        Self {
            tree: self.tree.clone(),
            grid: self.grid.clone(),
            grid_config: self.grid_config,
            bounds: self.bounds,
            queried: AtomicUsize::new(self.queried.load(Ordering::Relaxed)),
        }
    }
}

/// Output columns for [`ClosestPointTree::closest_points_into`], one entry per query point:
/// the nearest point, its distance, the triangle (-1 for none) and the barycentrics `u`, `v`.
pub struct ClosestPointColumns<'a> {
    pub point: &'a mut [[f64; 3]],
    pub distance: &'a mut [f64],
    pub prim: &'a mut [i64],
    pub u: &'a mut [f64],
    pub v: &'a mut [f64],
}

impl<'a> ClosestPointColumns<'a> {
    /// The five columns, checked to hold `n` rows each (panics otherwise).
    pub(super) fn rows_for(self, n: usize) -> ColumnRun<'a> {
        let Self {
            point,
            distance,
            prim,
            u,
            v,
        } = self;
        assert!(
            [point.len(), distance.len(), prim.len(), u.len(), v.len()] == [n; 5],
            "closest_points_into: every column must have one entry per point"
        );
        (point, distance, prim, u, v)
    }
}

/// One run's slices of the five columns.
pub(super) type ColumnRun<'r> = (
    &'r mut [[f64; 3]],
    &'r mut [f64],
    &'r mut [i64],
    &'r mut [f64],
    &'r mut [f64],
);

/// Points `first..first + len` of `points` (`len` at most a run) in f64, on the stack: no
/// batch-sized copy.
#[inline]
pub(super) fn run_of<P: QueryPoints + ?Sized>(
    points: &P,
    first: usize,
    len: usize,
) -> [DVec3; ClosestPointTree::RUN] {
    let mut run = [DVec3::ZERO; ClosestPointTree::RUN];
    for (k, slot) in run[..len].iter_mut().enumerate() {
        *slot = points.point(first + k);
    }
    run
}

/// Writes answer `found` as row `k` of the columns.
#[inline]
pub(super) fn write_row(
    found: Option<ClosestPoint>,
    k: usize,
    (point, distance, prim, u, v): ColumnRun<'_>,
) {
    match found {
        Some(c) => {
            point[k] = c.point.to_array();
            distance[k] = c.distance;
            prim[k] = c.prim as i64;
            u[k] = c.u;
            v[k] = c.v;
        }
        None => {
            point[k] = [f64::NAN; 3];
            distance[k] = f64::INFINITY;
            prim[k] = -1;
            u[k] = 0.0;
            v[k] = 0.0;
        }
    }
}

/// Calls `f(r, rows of run r)` for every run of [`ClosestPointTree::RUN`] rows of `columns`
/// (the last one shorter), shared out as `threads` says (module `batch_threads`).
pub(super) fn for_each_column_run(
    threads: Threads,
    (point, distance, prim, u, v): ColumnRun<'_>,
    f: impl Fn(usize, ColumnRun<'_>) + Sync,
) {
    const RUN: usize = ClosestPointTree::RUN;
    let runs: Vec<(usize, ColumnRun<'_>)> = point
        .chunks_mut(RUN)
        .zip(distance.chunks_mut(RUN))
        .zip(prim.chunks_mut(RUN))
        .zip(u.chunks_mut(RUN))
        .zip(v.chunks_mut(RUN))
        .map(|((((point, distance), prim), u), v)| (point, distance, prim, u, v))
        .enumerate()
        .collect();
    share_out(threads, runs, |(r, columns)| f(r, columns));
}

/// One pending child of the search: its lower bound, and a node index (`triangles == 0`) or a
/// leaf's first packet and triangle count.
#[derive(Clone, Copy, Debug)]
struct Pending {
    bound: f32,
    child: u32,
    triangles: u32,
}

/// What one search did, counted: nodes whose child bounds were computed, triangle packets
/// bounded, and triangles decided by the exact f64 routine (the seed's included). For profiling
/// ([`ClosestPointTree::closest_point_tallied`]); the plain queries count nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SearchTally {
    pub nodes: u64,
    pub packets: u64,
    pub exact: u64,
}

/// Where a search reports its steps: [`SearchTally`] counts them, `()` (the plain queries)
/// ignores them at no cost.
trait Tally {
    fn node(&mut self);
    fn packet(&mut self);
    fn exact(&mut self);
}

impl Tally for () {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn packet(&mut self) {}
    #[inline(always)]
    fn exact(&mut self) {}
}

impl Tally for SearchTally {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn packet(&mut self) {
        self.packets += 1;
    }
    #[inline(always)]
    fn exact(&mut self) {
        self.exact += 1;
    }
}

/// The best triangle so far of one search.
struct Best {
    /// The nearest point so far, its triangle's face id and local id (`LANES × packet + lane`).
    found: Option<(TrianglePoint, u32, u32)>,
    d2: f64,
    /// [`prune_threshold`] of `d2`.
    threshold: f32,
    /// The rounding margin of [`prune_threshold`] for this query.
    delta: f64,
}

impl Best {
    /// Whether a triangle `prim` at computed squared distance `d2` replaces the best so far:
    /// nearer, or as near with a smaller face id (the brute force's tie rule).
    #[inline(always)]
    fn is_beaten_by(&self, d2: f64, prim: u32) -> bool {
        d2 < self.d2 || (d2 == self.d2 && self.found.is_some_and(|(_, b, _)| prim < b))
    }

    /// Makes `q` on triangle `prim` (local id `local`), at squared distance `d2`, the best.
    #[inline(always)]
    fn record(&mut self, q: TrianglePoint, d2: f64, prim: u32, local: u32) {
        self.d2 = d2;
        self.threshold = prune_threshold(d2, self.delta);
        self.found = Some((q, prim, local));
    }
}

impl ClosestPointTree {
    /// Lays out `tree` (built over `mesh` by any builder) for nearest-point search, with
    /// [`SearchTreeConfig::default`].
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        Self::with_config(tree, mesh, SearchTreeConfig::default())
    }

    /// [`ClosestPointTree::new`] with the leaf size of `config` (and the default grid).
    pub fn with_config(tree: &BuildTree, mesh: &TriangleMesh, config: SearchTreeConfig) -> Self {
        Self::with_grid(tree, mesh, config, CandidateGridConfig::default())
    }

    /// [`ClosestPointTree::with_config`] with the candidate grid of `grid` (module
    /// `candidate_grid`; `grid.cells == 0` for none), made with the tree if `grid.payback` is
    /// 0, otherwise once enough points have been asked for.
    pub fn with_grid(
        tree: &BuildTree,
        mesh: &TriangleMesh,
        config: SearchTreeConfig,
        grid: CandidateGridConfig,
    ) -> Self {
        let b = mesh.bounds();
        let search = Self {
            tree: SearchTree::new(tree, mesh, config),
            grid: OnceLock::new(),
            grid_config: grid,
            bounds: (b.min.as_dvec3(), b.max.as_dvec3()),
            queried: AtomicUsize::new(0),
        };
        if grid.cells == 0 {
            // No grid to wait for: queries need not count.
            let _ = search.grid.set(None);
        } else if search.grid_threshold() == 0 {
            search.grid_for(0);
        }
        search
    }

    /// The candidate grid's number of cells, of cells listing their candidates, and of
    /// candidates listed (zeros without a grid, or before it is made).
    pub fn grid_summary(&self) -> (usize, usize, usize) {
        self.grid().map_or((0, 0, 0), CandidateGrid::summary)
    }

    /// The grid, if it has been made and is used.
    fn grid(&self) -> Option<&CandidateGrid> {
        self.grid.get().and_then(Option::as_ref)
    }

    /// Points asked for after which the grid is made ([`CandidateGridConfig::payback`]).
    fn grid_threshold(&self) -> usize {
        let config = &self.grid_config;
        (config.payback.max(0.0) * config.cells as f64).min(usize::MAX as f64) as usize
    }

    /// The grid for a batch of `n` points: made now if the points asked for, these included,
    /// reach [`ClosestPointTree::grid_threshold`].
    fn grid_for(&self, n: usize) -> Option<&CandidateGrid> {
        if let Some(made) = self.grid.get() {
            return made.as_ref();
        }
        let asked = self
            .queried
            .fetch_add(n, Ordering::Relaxed)
            .saturating_add(n);
        if asked < self.grid_threshold() {
            return None;
        }
        self.grid
            .get_or_init(|| CandidateGrid::new(self, self.bounds, self.grid_config))
            .as_ref()
    }

    /// The nearest surface point to `point`; `None` for an empty tree or a point with a NaN or
    /// infinite coordinate.
    pub fn closest_point(&self, point: Vec3) -> Option<ClosestPoint> {
        self.closest_point_f64(point.as_dvec3())
    }

    /// [`ClosestPointTree::closest_point`] for an f64 query point.
    pub fn closest_point_f64(&self, p: DVec3) -> Option<ClosestPoint> {
        self.query::<PortableLanes>(p, &mut Vec::new())
    }

    /// [`ClosestPointTree::closest_point_f64`] by a tree search without seed (the grid is not
    /// used), counting its steps into `tally`.
    pub fn closest_point_tallied(&self, p: DVec3, tally: &mut SearchTally) -> Option<ClosestPoint> {
        self.search::<PortableLanes>(p, None, &mut Vec::new(), tally)
            .map(|(c, _)| c)
    }

    /// [`ClosestPointTree::closest_points`]'s Morton-ordered, seeded batch search (whatever the
    /// grid), counting the steps of each point's search: its answer and tally, in the input
    /// order.
    pub fn closest_points_tallied(
        &self,
        points: &[DVec3],
    ) -> Vec<(Option<ClosestPoint>, SearchTally)> {
        let order: Vec<(u64, usize)> = morton_order(points, Threads::Here)
            .into_iter()
            .map(|key| (key, key as u32 as usize))
            .collect();
        let mut out = vec![(None, SearchTally::default()); points.len()];
        let mut stack = Vec::with_capacity(64);
        for run in order.chunks(Self::RUN) {
            let mut seed = None;
            for &(_, i) in run {
                let mut tally = SearchTally::default();
                let found = self.search::<PortableLanes>(points[i], seed, &mut stack, &mut tally);
                seed = found.map(|(_, local)| local).or(seed);
                out[i] = (found.map(|(c, _)| c), tally);
            }
        }
        out
    }

    /// One query: from the grid's candidates, or a tree search from the grid's seed (or no seed
    /// without a grid).
    #[inline(always)]
    fn query<M: SearchLanes>(&self, p: DVec3, stack: &mut Vec<Pending>) -> Option<ClosestPoint> {
        let Some(grid) = self.grid_for(1) else {
            return self.search::<M>(p, None, stack, &mut ()).map(|(c, _)| c);
        };
        self.query_in_cell::<M>(grid, p, grid.locate(p), stack)
    }

    /// [`ClosestPointTree::query`] with a grid, `p`'s cell located already.
    #[inline(always)]
    fn query_in_cell<M: SearchLanes>(
        &self,
        grid: &CandidateGrid,
        p: DVec3,
        cell: Located,
        stack: &mut Vec<Pending>,
    ) -> Option<ClosestPoint> {
        if !p.is_finite() {
            return None;
        }
        match grid.answer(p, cell) {
            CellAnswer::Nearest(q, d2, prim) => Some(ClosestPoint {
                point: q.point,
                distance: d2.sqrt(),
                prim,
                u: q.u,
                v: q.v,
            }),
            CellAnswer::Seed(seed) => self
                .search::<M>(p, Some(seed), stack, &mut ())
                .map(|(c, _)| c),
        }
    }

    /// The nearest surface point to each of `points` (as [`ClosestPointTree::closest_point_f64`],
    /// the same answers), in parallel on the current rayon pool.
    ///
    /// With a candidate grid (meshes of few, large triangles; module `candidate_grid`) each
    /// point is answered from its cell: the brute force over the cell's list, or a search seeded
    /// with the cell's triangle. Otherwise the points are searched in Morton order (Morton
    /// 1966: bits of the quantized x, y, z
    /// interleaved, so that points near in the order are near in space), in runs of
    /// [`Self::RUN`]; each search but a run's first starts with the previous point's nearest
    /// triangle as its best so far. The distance to a neighbour's nearest triangle is a tight
    /// upper bound, so nodes are pruned from the first step instead of after a first descent.
    /// The answer does not depend on the seed: the search keeps the least `(d², face id)` over
    /// every triangle it does not prune, pruning stays conservative, and the seed triangle's
    /// `d²` is computed exactly as when its leaf is reached.
    pub fn closest_points(&self, points: &[DVec3]) -> Vec<Option<ClosestPoint>> {
        if let Some(grid) = self.grid_for(points.len()) {
            let mut out = vec![None; points.len()];
            out.par_chunks_mut(Self::RUN)
                .zip(points.par_chunks(Self::RUN))
                .for_each(|(out, run)| self.answer_run(grid, run, |k, found| out[k] = found));
            return out;
        }
        let (order, sorted) = self.search_in_morton_order(points, Threads::Pool);
        let mut out = vec![None; points.len()];
        for (found, &key) in sorted.into_iter().zip(&order) {
            out[key as u32 as usize] = found;
        }
        out
    }

    /// [`ClosestPointTree::closest_points`] written column by column into `out`, as array
    /// libraries (NumPy) hold answers, without a list of them in between; a point without an
    /// answer gets NaN, +∞, -1, 0, 0. Panics if a column's length is not the number of points.
    ///
    /// `points` may be a `[DVec3]` or the rows of an f32 or f64 array read in place
    /// ([`FlatPoints`](super::FlatPoints)). The calling thread works on the batch from the
    /// start, and the current rayon pool's other threads (the global pool's outside any pool)
    /// join as they wake; batches of up to two runs stay on the calling thread.
    pub fn closest_points_into<P: QueryPoints + ?Sized>(
        &self,
        points: &P,
        out: ClosestPointColumns<'_>,
    ) {
        self.closest_points_into_with(points, out, Threads::Pool);
    }

    /// [`ClosestPointTree::closest_points_into`] on the calling thread alone, with no rayon
    /// task: the same answers, for a caller that wants one thread and should not wait for a
    /// pool's thread to wake (`threads=1` from Python).
    pub fn closest_points_into_here<P: QueryPoints + ?Sized>(
        &self,
        points: &P,
        out: ClosestPointColumns<'_>,
    ) {
        self.closest_points_into_with(points, out, Threads::Here);
    }

    /// [`ClosestPointTree::closest_points_into`] with its threads as `threads` says.
    pub(super) fn closest_points_into_with<P: QueryPoints + ?Sized>(
        &self,
        points: &P,
        out: ClosestPointColumns<'_>,
        threads: Threads,
    ) {
        let n = points.count();
        let (point, distance, prim, u, v) = out.rows_for(n);
        let grid = self.grid_for(n);
        if n <= Self::RUN {
            // One run: answered on the calling thread, in the points' own order. No pool
            // thread to wake (from Python, 10 points took 76 µs through the pool against 21 µs
            // of work), and sorting a run this short saves less than it costs. The answers do
            // not depend on the order (module notes).
            let run = run_of(points, 0, n);
            let mut found = vec![None; n];
            if let Some(grid) = grid {
                self.answer_run(grid, &run[..n], |k, answer| found[k] = answer);
            } else {
                self.search_run(&run[..n], &mut found);
            }
            for (k, answer) in found.into_iter().enumerate() {
                write_row(
                    answer,
                    k,
                    (&mut *point, &mut *distance, &mut *prim, &mut *u, &mut *v),
                );
            }
            return;
        }
        // Two runs go to the calling thread alone too: a pool thread would join after the
        // caller had done most of the work, and the caller would then wait for it to start and
        // find nothing left (from Python, 512 points on two threads took as long as on one or
        // longer on every shared mesh; 1,024 were faster shared on spot and the bunny).
        let threads = if n <= 2 * Self::RUN {
            Threads::Here
        } else {
            threads
        };
        let columns = (point, distance, prim, u, v);
        if let Some(grid) = grid {
            for_each_column_run(threads, columns, |r, (point, distance, prim, u, v)| {
                let first = r * Self::RUN;
                let len = point.len();
                let run = run_of(points, first, len);
                self.answer_run(grid, &run[..len], |k, found| {
                    write_row(
                        found,
                        k,
                        (&mut *point, &mut *distance, &mut *prim, &mut *u, &mut *v),
                    )
                })
            });
            return;
        }
        let (order, sorted) = self.search_in_morton_order(points, threads);
        // Where each point's answer is in `sorted`; then each column is gathered run by run.
        let mut rank = vec![0u32; n];
        for (j, &key) in order.iter().enumerate() {
            rank[key as u32 as usize] = j as u32;
        }
        for_each_column_run(threads, columns, |r, (point, distance, prim, u, v)| {
            let ranks = &rank[r * Self::RUN..][..point.len()];
            for (k, &j) in ranks.iter().enumerate() {
                // The answers are read at random (4.7 MB of them for 65,536 points): each
                // is asked for 16 rows ahead (spot and teapot, 65,536 uniform points on a
                // Zen 3 VM: about 5 % of the batch, on one thread and on two).
                if let Some(&ahead) = ranks.get(k + 16) {
                    prefetch(sorted.as_ptr().wrapping_add(ahead as usize));
                }
                write_row(sorted[j as usize], k, (point, distance, prim, u, v));
            }
        });
    }

    /// The batch's searches in Morton order (module notes of
    /// [`ClosestPointTree::closest_points`]): the sort keys (`code << 32 | index`, ascending)
    /// and the answers in that order.
    fn search_in_morton_order<P: QueryPoints + ?Sized>(
        &self,
        points: &P,
        threads: Threads,
    ) -> (Vec<u64>, Vec<Option<ClosestPoint>>) {
        let order = morton_order(points, threads);
        // Gathered first: read inside the search loop, each point was a cache miss.
        let in_order: Vec<DVec3> = map_collect(threads, order.len(), |j| {
            points.point(order[j] as u32 as usize)
        });
        let mut sorted = vec![None; points.count()];
        for_each_chunk(threads, &mut sorted, Self::RUN, |k, out| {
            self.search_run(&in_order[k * Self::RUN..][..out.len()], out)
        });
        (order, sorted)
    }

    /// Answers one run of points from the grid (each query's cell), passing point `k`'s answer
    /// to `write(k, answer)`: compiled for AVX2 and FMA where the CPU has them, as
    /// [`ClosestPointTree::search_run`].
    fn answer_run(
        &self,
        grid: &CandidateGrid,
        run: &[DVec3],
        write: impl FnMut(usize, Option<ClosestPoint>),
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU has AVX2 and FMA, the features `answer_run_avx2` is compiled for.
            unsafe { self.answer_run_avx2(grid, run, write) };
            return;
        }
        self.answer_run_portable(grid, run, write);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn answer_run_avx2(
        &self,
        grid: &CandidateGrid,
        run: &[DVec3],
        write: impl FnMut(usize, Option<ClosestPoint>),
    ) {
        self.answer_run_with::<AvxLanes>(grid, run, write);
    }

    /// [`ClosestPointTree::answer_run`] for the x86-64 baseline.
    fn answer_run_portable(
        &self,
        grid: &CandidateGrid,
        run: &[DVec3],
        write: impl FnMut(usize, Option<ClosestPoint>),
    ) {
        self.answer_run_with::<PortableLanes>(grid, run, write);
    }

    /// [`ClosestPointTree::answer_run`] with the lane masks `M`, in whatever features its
    /// caller is compiled for.
    #[inline(always)]
    fn answer_run_with<M: SearchLanes>(
        &self,
        grid: &CandidateGrid,
        run: &[DVec3],
        mut write: impl FnMut(usize, Option<ClosestPoint>),
    ) {
        let mut stack = Vec::with_capacity(64);
        // Each query's cell is located and asked for `RING` queries before it is answered, and
        // its list (once the cell has arrived) `RING / 2` before: the grid's two dependent
        // loads overlap other queries' work instead of waiting on L3 in turn. Point `k`'s cell
        // is kept in `located[k % RING]` from then until its answer.
        const RING: usize = 8;
        let mut located = [Located::default(); RING];
        for (k, &p) in run.iter().enumerate().take(RING) {
            located[k] = grid.locate(p);
            grid.prefetch_cell(&located[k]);
        }
        for cell in located.iter().take(run.len().min(RING / 2)) {
            grid.prefetch_list(cell);
        }
        for (k, &p) in run.iter().enumerate() {
            let cell = located[k % RING];
            if let Some(&ahead) = run.get(k + RING) {
                located[k % RING] = grid.locate(ahead);
                grid.prefetch_cell(&located[k % RING]);
            }
            if k + RING / 2 < run.len() {
                grid.prefetch_list(&located[(k + RING / 2) % RING]);
            }
            write(k, self.query_in_cell::<M>(grid, p, cell, &mut stack));
        }
    }

    /// Searches one run of Morton-ordered points, each seeded with the previous one's answer:
    /// compiled for AVX2 and FMA where the CPU has them (three-operand instructions; +5–8 %
    /// queries/s on spot and bunny), else for the x86-64 baseline. The answers are the same
    /// bits either way: Rust never fuses a product and a sum into an FMA on its own.
    fn search_run(&self, run: &[DVec3], out: &mut [Option<ClosestPoint>]) {
        self.search_run_with_ids(run, |k, answer| out[k] = answer.map(|(c, _)| c));
    }

    /// [`ClosestPointTree::search_run`], passing point `k`'s answer with its triangle's
    /// `LANES × packet + lane` to `write(k, answer)`.
    fn search_run_with_ids(
        &self,
        run: &[DVec3],
        write: impl FnMut(usize, Option<(ClosestPoint, u32)>),
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU has AVX2 and FMA, the features `search_run_avx2` is compiled for.
            unsafe { self.search_run_avx2(run, write) };
            return;
        }
        self.search_run_with::<PortableLanes>(run, write);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn search_run_avx2(
        &self,
        run: &[DVec3],
        write: impl FnMut(usize, Option<(ClosestPoint, u32)>),
    ) {
        self.search_run_with::<AvxLanes>(run, write);
    }

    /// [`ClosestPointTree::search_run`] for the x86-64 baseline.
    #[cfg(test)]
    fn search_run_portable(&self, run: &[DVec3], out: &mut [Option<ClosestPoint>]) {
        self.search_run_with::<PortableLanes>(run, |k, answer| out[k] = answer.map(|(c, _)| c));
    }

    /// [`ClosestPointTree::search_run_with_ids`] with the lane masks `M`, in whatever features
    /// its caller is compiled for.
    #[inline(always)]
    fn search_run_with<M: SearchLanes>(
        &self,
        run: &[DVec3],
        mut write: impl FnMut(usize, Option<(ClosestPoint, u32)>),
    ) {
        let mut seed = None;
        let mut stack = Vec::with_capacity(64);
        for (k, &p) in run.iter().enumerate() {
            let found = self.search::<M>(p, seed, &mut stack, &mut ());
            seed = found.map(|(_, local)| local).or(seed);
            write(k, found);
        }
    }

    /// Points per run of [`ClosestPointTree::closest_points`]: one rayon task, seeded in turn.
    pub const RUN: usize = 256;

    /// The branch-and-bound search, starting from triangle `seed` (`LANES × packet + lane`) as the
    /// best so far when given; returns the answer and its triangle's `LANES × packet + lane`.
    /// `stack` is scratch space, reused between searches.
    #[inline(always)]
    fn search<M: SearchLanes>(
        &self,
        p: DVec3,
        seed: Option<u32>,
        stack: &mut Vec<Pending>,
        tally: &mut impl Tally,
    ) -> Option<(ClosestPoint, u32)> {
        let tree = &self.tree;
        if tree.nodes.is_empty() || !p.is_finite() {
            return None;
        }
        let bracket = PointBracket::new(p);
        let mut best = Best {
            found: None,
            d2: f64::INFINITY,
            threshold: f32::INFINITY,
            delta: rounding_margin(p, tree.mesh_scale),
        };
        if let Some(local) = seed {
            tally.exact();
            self.consider(p, local, &mut best);
        }
        stack.clear();
        // The child to search next: the nearest of the last node's, taken without a trip
        // through the stack.
        let mut next = Some(Pending {
            bound: 0.0,
            child: 0,
            triangles: 0,
        });
        while let Some(pending) = next.take().or_else(|| stack.pop()) {
            if pending.bound > best.threshold {
                continue;
            }
            if pending.triangles > 0 {
                self.search_leaf::<M>(p, &bracket, pending, seed, &mut best, tally);
                continue;
            }
            tally.node();
            let node = &tree.nodes[pending.child as usize];
            let bounds = node.distance_squared_lower_bounds(&bracket);
            let mut within = M::within(&bounds, best.threshold);
            // The children within the threshold: the nearest is searched next, the others
            // pushed in slot order. (Sorted farthest first before session 6: the same nodes
            // and packets visited on the bunny, 140 more instructions per query, 0–6 % slower
            // on bunny and spot.)
            let mut near = [Pending {
                bound: 0.0,
                child: 0,
                triangles: 0,
            }; WIDTH];
            let mut count = 0;
            let mut nearest = 0;
            while within != 0 {
                let k = within.trailing_zeros() as usize;
                within &= within - 1;
                let entry = Pending {
                    bound: bounds[k],
                    child: node.child[k],
                    triangles: node.triangles[k],
                };
                nearest = if entry.bound < near[nearest].bound {
                    count
                } else {
                    nearest
                };
                near[count] = entry;
                count += 1;
            }
            if count > 0 {
                near.swap(nearest, count - 1);
                // `extend` of a copied slice iterator: one capacity check, no `memmove` call
                // (`extend_from_slice` made one, a tenth of the time here).
                stack.extend(near[..count - 1].iter().copied());
                next = Some(near[count - 1]);
            }
        }
        // One square root per search, for the answer only.
        best.found.map(|(q, prim, local)| {
            let answer = ClosestPoint {
                point: q.point,
                distance: best.d2.sqrt(),
                prim,
                u: q.u,
                v: q.v,
            };
            (answer, local)
        })
    }

    /// Tests the triangles of one leaf: each packet's bounds first, the exact routine
    /// for those within the threshold, but the search's seed (decided first, and always within
    /// the threshold of its own distance: on spot 5.6 → 5.0 exact tests per query).
    #[inline(always)]
    fn search_leaf<M: SearchLanes>(
        &self,
        p: DVec3,
        bracket: &PointBracket,
        leaf: Pending,
        seed: Option<u32>,
        best: &mut Best,
        tally: &mut impl Tally,
    ) {
        let (seed_packet, seed_lane) = match seed {
            Some(local) => (local as usize / LANES, local as usize % LANES),
            None => (usize::MAX, 0),
        };
        let mut left = leaf.triangles as usize;
        let mut packet = leaf.child as usize;
        while left > 0 {
            tally.packet();
            let bounds = self.tree.packets[packet].distance_squared_lower_bounds(bracket);
            // Not `bound <= threshold`: a NaN bound must not prune.
            let mut within = M::not_beyond(&bounds, best.threshold);
            // Lanes past the leaf's last triangle repeat lane 0.
            within &= (1u32 << left.min(LANES)) - 1;
            if packet == seed_packet {
                within &= !(1u32 << seed_lane);
            }
            // A half of the packet with two or more triangles left is decided four lanes at
            // once (`consider_half`: branch-free, where the lane-by-lane routine mispredicts
            // its Voronoi-region branches); a single one by the scalar routine. Bunny +2–5 %
            // against one lane at a time, spot and teapot within 1 %; deciding every half
            // with a triangle left four at a time: bunny a further +1 %, spot and teapot −2 %.
            for half in 0..LANES / F64_LANES {
                let mut lanes = (within >> (half * F64_LANES)) & ((1 << F64_LANES) - 1);
                if lanes.count_ones() >= 2 {
                    for _ in 0..F64_LANES {
                        tally.exact();
                    }
                    self.consider_half::<M>(p, packet, half, best);
                    continue;
                }
                while lanes != 0 {
                    let lane = half * F64_LANES + lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    // The threshold may have dropped since the bounds were compared.
                    if bounds[lane] <= best.threshold || bounds[lane].is_nan() {
                        tally.exact();
                        self.consider(p, (packet * LANES + lane) as u32, best);
                    }
                }
            }
            left = left.saturating_sub(LANES);
            packet += 1;
        }
    }

    /// Decides the four triangles of half `half` of packet `packet` side by side
    /// ([`closest_points_on_lanes`]: the same bits as [`ClosestPointTree::consider`] lane by
    /// lane) and keeps each as `consider` would. Lanes the bounds pruned, past the leaf's end
    /// (repeats of lane 0) or the seed's are decided too: an exact answer for a triangle of the
    /// mesh never makes the result wrong.
    #[inline(always)]
    fn consider_half<M: SearchLanes>(&self, p: DVec3, packet: usize, half: usize, best: &mut Best) {
        let data = &self.tree.packets[packet];
        let mut found = M::closest_points_on_half(p, &data.vertex, half);
        // Slivers (rare) are decided again by the scalar routine, whose sliver path the lanes
        // do not have.
        let slivers = data.slivers >> (half * F64_LANES) & ((1 << F64_LANES) - 1);
        if slivers != 0 {
            for l in 0..F64_LANES {
                if slivers >> l & 1 == 1 {
                    let [a, b, c] = data.triangle(half * F64_LANES + l);
                    let q = closest_point_on_sliver(p, a, b, c);
                    for axis in 0..3 {
                        found.point[axis][l] = q.point[axis];
                    }
                    found.u[l] = q.u;
                    found.v[l] = q.v;
                    found.distance_squared[l] = (p - q.point).length_squared();
                }
            }
        }
        for l in 0..F64_LANES {
            let lane = half * F64_LANES + l;
            let (d2, prim) = (found.distance_squared[l], data.prim[lane]);
            if best.is_beaten_by(d2, prim) {
                let q = TrianglePoint {
                    point: DVec3::new(found.point[0][l], found.point[1][l], found.point[2][l]),
                    u: found.u[l],
                    v: found.v[l],
                };
                best.record(q, d2, prim, (packet * LANES + lane) as u32);
            }
        }
    }

    /// Decides triangle `local` (`LANES × packet + lane`) in f64 and keeps it if it is nearer than
    /// the best, or as near with a smaller face id.
    #[inline(always)]
    fn consider(&self, p: DVec3, local: u32, best: &mut Best) {
        let packet = &self.tree.packets[local as usize / LANES];
        let lane = local as usize % LANES;
        let [a, b, c] = packet.triangle(lane);
        let prim = packet.prim[lane];
        let q = closest_point_on_flagged_triangle(p, a, b, c, packet.slivers >> lane & 1 == 1);
        let d2 = (p - q.point).length_squared();
        if best.is_beaten_by(d2, prim) {
            best.record(q, d2, prim, local);
        }
    }
}

impl ClosestPointTree {
    /// Every triangle whose computed squared distance from `p` is at most `radius_squared`,
    /// `None` when more than `limit`: the search's walk with a fixed threshold
    /// (`prune_threshold(radius_squared, δ)`, under which no triangle of a pruned box can have a
    /// computed distance within the radius).
    fn triangles_within(&self, p: DVec3, radius_squared: f64, limit: usize) -> Option<Vec<u32>> {
        let tree = &self.tree;
        let mut found = Vec::new();
        if tree.nodes.is_empty() || !p.is_finite() {
            return Some(found);
        }
        let bracket = PointBracket::new(p);
        let threshold = prune_threshold(radius_squared, rounding_margin(p, tree.mesh_scale));
        let mut stack = vec![(0u32, 0u32)];
        while let Some((child, triangles)) = stack.pop() {
            if triangles > 0 {
                // Each packet's bounds first (as the search's leaves): the exact routine only
                // for triangles that may be within the radius.
                for k in 0..triangles.div_ceil(LANES as u32) {
                    let packet = child + k;
                    let bounds =
                        tree.packets[packet as usize].distance_squared_lower_bounds(&bracket);
                    let lanes = (triangles - k * LANES as u32).min(LANES as u32) as usize;
                    for (lane, &bound) in bounds.iter().enumerate().take(lanes) {
                        // Not `bound <= threshold`: a NaN bound must not prune.
                        if bound > threshold {
                            continue;
                        }
                        let local = packet * LANES as u32 + lane as u32;
                        if self.distance_squared(p, local) <= radius_squared {
                            found.push(local);
                            if found.len() > limit {
                                return None;
                            }
                        }
                    }
                }
                continue;
            }
            let node = &tree.nodes[child as usize];
            let bounds = node.distance_squared_lower_bounds(&bracket);
            for (k, &bound) in bounds.iter().enumerate() {
                // Empty slots have NaN bounds and fail the test.
                if bound <= threshold {
                    stack.push((node.child[k], node.triangles[k]));
                }
            }
        }
        Some(found)
    }
}

impl NearestTriangles for ClosestPointTree {
    fn nearest_in_turn(&self, points: &[DVec3]) -> Vec<Option<u32>> {
        let mut found = vec![None; points.len()];
        self.search_run_with_ids(points, |k, answer| {
            found[k] = answer.map(|(_, local)| local)
        });
        found
    }

    fn distance_squared(&self, p: DVec3, local: u32) -> f64 {
        let packet = &self.tree.packets[local as usize / LANES];
        let [a, b, c] = packet.triangle(local as usize % LANES);
        (p - closest_point_on_triangle(p, a, b, c).point).length_squared()
    }

    fn within(&self, p: DVec3, radius_squared: f64, limit: usize) -> Option<Vec<u32>> {
        self.triangles_within(p, radius_squared, limit)
    }

    fn mesh_scale(&self) -> f64 {
        self.tree.mesh_scale
    }

    fn triangle(&self, local: u32) -> ListedTriangle {
        let packet = &self.tree.packets[local as usize / LANES];
        let lane = local as usize % LANES;
        ListedTriangle {
            vertices: packet.triangle(lane),
            prim: packet.prim[lane],
            sliver: packet.slivers >> lane & 1 == 1,
        }
    }
}

/// The nearest surface point by testing every non-degenerate triangle in f64: the reference of
/// [`ClosestPointTree`] (same answer, same tie rule: smallest face id among equal distances).
pub fn closest_point_brute_force(mesh: &TriangleMesh, p: DVec3) -> Option<ClosestPoint> {
    if !p.is_finite() {
        return None;
    }
    let mut best: Option<ClosestPoint> = None;
    let mut best_d2 = f64::INFINITY;
    for (prim, t) in mesh.triangles().enumerate() {
        if t.is_degenerate() {
            continue;
        }
        let q = closest_point_on_triangle(p, t.p0.as_dvec3(), t.p1.as_dvec3(), t.p2.as_dvec3());
        let d2 = (p - q.point).length_squared();
        if d2 < best_d2 {
            best_d2 = d2;
            best = Some(ClosestPoint {
                point: q.point,
                distance: d2.sqrt(),
                prim: prim as u32,
                u: q.u,
                v: q.v,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
    use crate::mesh::procedural::{ground_plane, icosphere};

    /// Points around `mesh`'s box (a lattice, so that neighbours in Morton order seed each
    /// other), a few far away.
    fn points_around(mesh: &TriangleMesh) -> Vec<DVec3> {
        let b = mesh.bounds();
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        let mut points = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                for k in 0..12 {
                    let t = DVec3::new(i as f64, j as f64, k as f64) / 11.0 * 1.4 - 0.2;
                    points.push(lo + (hi - lo) * t);
                }
            }
        }
        points.extend([DVec3::splat(1e6), DVec3::new(-3e3, 2.0, 0.5)]);
        points
    }

    /// The batch runs give the same answers in the portable build as in the AVX2 one the CPU
    /// picks (on a CPU without AVX2 both are the portable one), with and without a grid.
    #[test]
    fn portable_and_detected_runs_agree() {
        let sphere = icosphere(Vec3::new(0.5, -1.0, 2.0), 1.5, 3);
        let floor = ground_plane(4.0, -2.0, 1);
        for (mesh, cells) in [(sphere, 0), (floor, CandidateGridConfig::default().cells)] {
            let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
            let grid = CandidateGridConfig {
                cells,
                min_listing: 0.0,
                payback: 0.0,
                ..CandidateGridConfig::default()
            };
            let search =
                ClosestPointTree::with_grid(&tree, &mesh, SearchTreeConfig::default(), grid);
            assert_eq!(search.grid().is_some(), cells > 0);
            let points = points_around(&mesh);
            let n = points.len();
            let (mut detected, mut portable) = (vec![None; n], vec![None; n]);
            search.search_run(&points, &mut detected);
            search.search_run_portable(&points, &mut portable);
            assert_eq!(detected, portable);
            if let Some(grid) = search.grid() {
                let (mut detected, mut from_grid) = (vec![None; n], vec![None; n]);
                search.answer_run(grid, &points, |k, found| detected[k] = found);
                search.answer_run_portable(grid, &points, |k, found| from_grid[k] = found);
                assert_eq!(detected, from_grid);
                assert_eq!(from_grid, portable);
            }
            for (i, p) in points.iter().enumerate() {
                assert_eq!(portable[i], closest_point_brute_force(&mesh, *p), "{p:?}");
            }
        }
    }
}
