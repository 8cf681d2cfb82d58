//! Batches of nearest-point queries: cut into runs of [`ClosestPointTree::RUN`] points that
//! threads take in turn ([`BatchThreads`], module `batch_threads`), and, for the search tree,
//! the order the points are searched in.
//!
//! **The search tree's batches.** With a candidate grid (meshes of few, large triangles; module
//! `candidate_grid`) each point is answered from its cell: the brute force over the cell's
//! list, or a search seeded with the cell's triangle. Otherwise the points are searched in
//! Morton order (Morton 1966: bits of the quantized x, y, z interleaved, so that points near in
//! the order are near in space; module `query_order`), in runs of [`ClosestPointTree::RUN`];
//! each search but a run's first starts with the previous point's nearest triangle as its best
//! so far. The distance to a neighbour's nearest triangle is a tight upper bound, so nodes are
//! pruned from the first step instead of after a first descent. The answer does not depend on
//! the seed: the search keeps the least `(d², face id)` over every triangle it does not prune,
//! pruning stays conservative, and the seed triangle's `d²` is computed exactly as when its
//! leaf is reached. The answers are then written back in the points' order.

use std::ops::Range;

use glam::DVec3;

use super::answers::{AnswerRows, ClosestPoint};
use super::candidate_grid::{CandidateGrid, Located};
use super::closest_point_tree::ClosestPointTree;
use super::prefetch::prefetch;
use super::query_order::morton_order;
use super::query_points::QueryPoints;
#[cfg(target_arch = "x86_64")]
use super::search_lanes::AvxLanes;
use super::search_lanes::{PortableLanes, SearchLanes};
use super::search_tally::Tally;
use crate::batch_threads::{for_each_chunk, map_collect, share_out, Threads};

/// Which threads answer a batch: [`BatchThreads::POOL`], the calling thread with the current
/// rayon pool's other threads (the global pool's outside any pool) joining as they wake, or
/// [`BatchThreads::CALLING_THREAD`], the calling thread alone with no rayon task. The same
/// answers either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchThreads(pub(super) Threads);

impl BatchThreads {
    /// The calling thread and the current rayon pool's.
    pub const POOL: Self = Self(Threads::Pool);
    /// The calling thread alone: for a caller that wants one thread and should not wait for a
    /// pool's thread to wake (`threads=1` from Python).
    pub const CALLING_THREAD: Self = Self(Threads::Here);
}

/// Panics unless `out` has one row per point of a batch of `n`.
pub(super) fn assert_rows<R: AnswerRows>(out: &R, n: usize) {
    assert!(
        out.holds(n),
        "closest_points_into: every column must have one entry per point"
    );
}

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

/// Calls `f(points of the run, its rows)` for every run of [`ClosestPointTree::RUN`] rows of
/// `out`, which holds `n` (the last run shorter), shared out as `threads` says (module
/// `batch_threads`).
pub(super) fn for_each_run<R: AnswerRows>(
    threads: Threads,
    out: R,
    n: usize,
    f: impl Fn(Range<usize>, R) + Sync,
) {
    const RUN: usize = ClosestPointTree::RUN;
    let runs: Vec<(usize, R)> = out.into_runs(RUN).into_iter().enumerate().collect();
    share_out(threads, runs, |(r, rows)| {
        f(r * RUN..((r + 1) * RUN).min(n), rows)
    });
}

impl ClosestPointTree {
    /// Points per run of a batch: one rayon task, seeded in turn.
    pub const RUN: usize = 256;

    /// The nearest surface point of each of `points` into `out` (module notes): a point's
    /// answer is the same whichever way it is found. Counted searches (module `search_tally`)
    /// never use the grid.
    pub(super) fn answer_batch<P: QueryPoints + ?Sized, R: AnswerRows>(
        &self,
        points: &P,
        mut out: R,
        threads: BatchThreads,
    ) {
        let n = points.count();
        assert_rows(&out, n);
        let grid = if R::Tally::COUNTS {
            None
        } else {
            self.grid_for(n)
        };
        if n <= Self::RUN {
            // One run: answered on the calling thread, in the points' own order. No pool
            // thread to wake (from Python, 10 points took 76 µs through the pool against 21 µs
            // of work), and sorting a run this short saves less than it costs. The answers do
            // not depend on the order (module notes).
            let run = run_of(points, 0, n);
            if let Some(grid) = grid {
                self.answer_run(grid, &run[..n], |k, found| {
                    out.write(k, found, R::Tally::default())
                });
            } else {
                self.search_run(&run[..n], |k, found, tally| {
                    out.write(k, found.map(|(c, _)| c), tally)
                });
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
            threads.0
        };
        if let Some(grid) = grid {
            for_each_run(threads, out, n, |points_of_run, mut rows| {
                let len = points_of_run.len();
                let run = run_of(points, points_of_run.start, len);
                self.answer_run(grid, &run[..len], |k, found| {
                    rows.write(k, found, R::Tally::default())
                })
            });
            return;
        }
        let (order, sorted) = self.search_in_morton_order::<P, R::Tally>(points, threads);
        // Where each point's answer is in `sorted`; then the rows are gathered run by run.
        let mut rank = vec![0u32; n];
        for (j, &key) in order.iter().enumerate() {
            rank[key as u32 as usize] = j as u32;
        }
        for_each_run(threads, out, n, |points_of_run, mut rows| {
            let ranks = &rank[points_of_run];
            for (k, &j) in ranks.iter().enumerate() {
                // The answers are read at random (4.7 MB of them for 65,536 points): each
                // is asked for 16 rows ahead (spot and teapot, 65,536 uniform points on a
                // Zen 3 VM: about 5 % of the batch, on one thread and on two).
                if let Some(&ahead) = ranks.get(k + 16) {
                    prefetch(sorted.as_ptr().wrapping_add(ahead as usize));
                }
                let (found, tally) = sorted[j as usize];
                rows.write(k, found, tally);
            }
        });
    }

    /// The batch's searches in Morton order (module notes): the sort keys
    /// (`code << 32 | index`, ascending) and the answers in that order, with their searches'
    /// steps.
    fn search_in_morton_order<P: QueryPoints + ?Sized, T: Tally>(
        &self,
        points: &P,
        threads: Threads,
    ) -> (Vec<u64>, Vec<(Option<ClosestPoint>, T)>) {
        let order = morton_order(points, threads);
        // Gathered first: read inside the search loop, each point was a cache miss.
        let in_order: Vec<DVec3> = map_collect(threads, order.len(), |j| {
            points.point(order[j] as u32 as usize)
        });
        let mut sorted = vec![(None, T::default()); points.count()];
        for_each_chunk(threads, &mut sorted, Self::RUN, |k, out| {
            self.search_run(
                &in_order[k * Self::RUN..][..out.len()],
                |i, found, tally| out[i] = (found.map(|(c, _)| c), tally),
            )
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

    /// Searches one run of Morton-ordered points, each seeded with the previous one's answer,
    /// passing point `k`'s answer, with its triangle's `LANES × packet + lane`, and its search's
    /// steps to `write(k, answer, tally)`: compiled for AVX2 and FMA where the CPU has them
    /// (three-operand instructions; +5–8 % queries/s on spot and bunny), else for the x86-64
    /// baseline. The answers are the same bits either way: Rust never fuses a product and a
    /// sum into an FMA on its own.
    pub(super) fn search_run<T: Tally>(
        &self,
        run: &[DVec3],
        write: impl FnMut(usize, Option<(ClosestPoint, u32)>, T),
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU has AVX2 and FMA, the features `search_run_avx2` is compiled for.
            unsafe { self.search_run_avx2(run, write) };
            return;
        }
        self.search_run_portable(run, write);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn search_run_avx2<T: Tally>(
        &self,
        run: &[DVec3],
        write: impl FnMut(usize, Option<(ClosestPoint, u32)>, T),
    ) {
        self.search_run_with::<AvxLanes, T>(run, write);
    }

    /// [`ClosestPointTree::search_run`] for the x86-64 baseline.
    fn search_run_portable<T: Tally>(
        &self,
        run: &[DVec3],
        write: impl FnMut(usize, Option<(ClosestPoint, u32)>, T),
    ) {
        self.search_run_with::<PortableLanes, T>(run, write);
    }

    /// [`ClosestPointTree::search_run`] with the lane masks `M`, in whatever features its
    /// caller is compiled for.
    #[inline(always)]
    fn search_run_with<M: SearchLanes, T: Tally>(
        &self,
        run: &[DVec3],
        mut write: impl FnMut(usize, Option<(ClosestPoint, u32)>, T),
    ) {
        let mut seed = None;
        let mut stack = Vec::with_capacity(64);
        for (k, &p) in run.iter().enumerate() {
            let mut tally = T::default();
            let found = self.search::<M>(p, seed, &mut stack, &mut tally);
            seed = found.map(|(_, local)| local).or(seed);
            write(k, found, tally);
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
    use crate::mesh::procedural::{ground_plane, icosphere};
    use crate::mesh::TriangleMesh;
    use crate::proximity::{closest_point_brute_force, CandidateGridConfig, SearchTreeConfig};

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
            search.search_run(&points, |k, found, ()| detected[k] = found.map(|(c, _)| c));
            search.search_run_portable(&points, |k, found, ()| portable[k] = found.map(|(c, _)| c));
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
