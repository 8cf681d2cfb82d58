//! The search tree of nearest-point queries ([`ClosestPointTree`]): made from any builder's
//! tree, with a candidate grid for meshes of few large triangles (module `candidate_grid`) made
//! once it pays; one point's query, and what the grid is made from.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use glam::DVec3;

use super::answers::{AnswerRows, ClosestPoint};
use super::batches::BatchThreads;
use super::branch_and_bound::Pending;
use super::candidate_grid::{
    CandidateGrid, CandidateGridConfig, CellAnswer, ListedTriangle, Located, NearestTriangles,
};
use super::enclosure_packet::LANES;
use super::nearest_point_search::NearestPointSearch;
use super::point_triangle::closest_point_on_triangle;
use super::query_points::QueryPoints;
use super::search_lanes::{PortableLanes, SearchLanes};
use super::search_tally::Tally;
use super::search_tree::{SearchTree, SearchTreeConfig};
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// A BVH laid out for nearest-point queries: any [`BuildTree`] collapsed to 8-child nodes with
/// leaves of eight-triangle packets (module `search_tree`), boxes and triangles in f32 as in the
/// mesh.
///
/// **Search** (branch and bound, as in Larsen et al. 1999 and Ericson §6.5; module
/// `branch_and_bound`): keep the best squared distance `d²` so far; at a node bound the
/// children's box distances `Σ_axis max(min - p, 0, p - max)²` from below (near the leaves,
/// boxes in a frame facing the surface patch, module `node_frame`), and visit those not farther
/// than `d²`, the nearest first; in a leaf, bound each triangle from below by the distance to an
/// enclosure (its plane's slab cut by a cylinder around it and its edges' half-spaces, module
/// `triangle_enclosure`), and decide the survivors with [`closest_point_on_triangle`] (Ericson
/// §5.1.5) in f64 (four at a time, branch-free, where two or more of a half packet survive:
/// module `point_triangle_lanes`). The bounds are f32, eight at a time, and conservative
/// (`proximity/box_bound.rs`): nothing that the f64 brute force would pick is ever pruned, so
/// the answers are the brute force's, ties included (smallest face id). Batches (Morton order,
/// seeds, threads) are module `batches`'s. Degenerate triangles are left out, as in every tree
/// (they have no face to be nearest to, and their edges are other triangles' edges on meshes
/// that matter).
///
/// Queried through [`NearestPointSearch`].
#[derive(Debug)]
pub struct ClosestPointTree {
    pub(super) tree: SearchTree,
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
    pub(super) fn grid(&self) -> Option<&CandidateGrid> {
        self.grid.get().and_then(Option::as_ref)
    }

    /// Points asked for after which the grid is made ([`CandidateGridConfig::payback`]).
    fn grid_threshold(&self) -> usize {
        let config = &self.grid_config;
        (config.payback.max(0.0) * config.cells as f64).min(usize::MAX as f64) as usize
    }

    /// The grid for a batch of `n` points: made now if the points asked for, these included,
    /// reach [`ClosestPointTree::grid_threshold`].
    pub(super) fn grid_for(&self, n: usize) -> Option<&CandidateGrid> {
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
    pub(super) fn query_in_cell<M: SearchLanes>(
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
}

impl NearestPointSearch for ClosestPointTree {
    /// One point, with the portable lane steps: from the grid where it has been made, else by
    /// a tree search without seed (a counted search always, module `search_tally`).
    fn closest_point_tallied<T: Tally>(&self, p: DVec3, tally: &mut T) -> Option<ClosestPoint> {
        if T::COUNTS {
            return self
                .search::<PortableLanes>(p, None, &mut Vec::new(), tally)
                .map(|(c, _)| c);
        }
        self.query::<PortableLanes>(p, &mut Vec::new())
    }

    /// A batch as module `batches` describes: from the grid's cells, or searched in Morton
    /// order, each search seeded with its neighbour's triangle.
    fn closest_points_into_with<P: QueryPoints + ?Sized, R: AnswerRows>(
        &self,
        points: &P,
        out: R,
        threads: BatchThreads,
    ) {
        self.answer_batch(points, out, threads);
    }
}

impl NearestTriangles for ClosestPointTree {
    fn nearest_in_turn(&self, points: &[DVec3]) -> Vec<Option<u32>> {
        let mut found = vec![None; points.len()];
        self.search_run(points, |k, answer, ()| {
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
