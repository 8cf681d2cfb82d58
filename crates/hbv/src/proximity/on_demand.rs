//! Nearest-point queries on a fresh BVH that make the [`ClosestPointTree`] only once it has
//! paid for itself: until then each point is answered by walking the builder's tree as it is
//! ([`BuildTreeSearch`]).
//!
//! **When to make the tree** (the ski-rental argument, as for the candidate grid,
//! [`CandidateGridConfig::payback`](super::CandidateGridConfig::payback)): the search tree
//! costs as much to make as `make / (walk - search)` points cost more by walks than by it, the
//! break-even count. Measured on two cores for points uniform around the shared meshes
//! (`examples/on_demand_payback.rs`, BENCHMARKS.md "Nearest points on a fresh BVH"), it grows
//! about as the square root of the triangle count (the making is linear in it, a walk's cost
//! per point grows about as its square root): 2,600–3,400 points on spot and the teapot (about
//! 6,000 triangles), 6,500–10,000 on the bunny (69,451), 10,500–17,800 on igea (268,686),
//! 31,000–49,000 on the dragon (871,414), in four runs. [`ClosestPointsOnDemand::payback`] is
//! `32 √triangles`, within 0.6–1.6× of each. The first `payback` points (all batches together) are walked, and the batch that would
//! pass that count makes the tree and is answered with it: a caller asking for few points never
//! pays for the tree, and one asking for many pays about twice the better choice in hindsight at
//! most. Both answer exactly as
//! [`closest_point_brute_force`](super::closest_point_brute_force), so the answers do not
//! depend on which one gave them.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use glam::DVec3;

use super::answers::{AnswerRows, ClosestPoint};
use super::batches::BatchThreads;
use super::build_tree_search::BuildTreeSearch;
use super::closest_point_tree::ClosestPointTree;
use super::nearest_point_search::NearestPointSearch;
use super::query_points::QueryPoints;
use super::search_tally::Tally;
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// The nearest-point search of one [`BuildTree`] over its mesh, with the [`ClosestPointTree`]
/// made on demand (module notes).
#[derive(Debug)]
pub struct ClosestPointsOnDemand {
    tree: Arc<BuildTree>,
    mesh: Arc<TriangleMesh>,
    search: OnceLock<ClosestPointTree>,
    /// Points answered by walks so far.
    walked: AtomicUsize,
    /// How many points may be walked, all batches together.
    walk_limit: usize,
}

impl ClosestPointsOnDemand {
    /// Nearest points on `mesh` by `tree` (built over it by any builder); the search tree is
    /// made once [`ClosestPointsOnDemand::payback`] points have been asked for.
    pub fn new(tree: Arc<BuildTree>, mesh: Arc<TriangleMesh>) -> Self {
        let limit = Self::payback(mesh.triangle_count());
        Self::with_walk_limit(tree, mesh, limit)
    }

    /// [`ClosestPointsOnDemand::new`] with the search tree made once `points` points have been
    /// asked for (0: by the first batch that is not empty).
    pub fn with_walk_limit(tree: Arc<BuildTree>, mesh: Arc<TriangleMesh>, points: usize) -> Self {
        Self {
            tree,
            mesh,
            search: OnceLock::new(),
            walked: AtomicUsize::new(0),
            walk_limit: points,
        }
    }

    /// How many points, all batches together, are answered by walking a tree of `triangles`
    /// before the search tree is made (by default): `32 √triangles` (module notes).
    pub fn payback(triangles: usize) -> usize {
        (32.0 * (triangles as f64).sqrt()) as usize
    }

    /// The search tree, if it has been made.
    pub fn search_tree(&self) -> Option<&ClosestPointTree> {
        self.search.get()
    }

    fn walker(&self) -> BuildTreeSearch<'_> {
        BuildTreeSearch::new(&self.tree, &self.mesh)
    }

    /// The search tree, made now if it has not been.
    fn search_tree_made(&self) -> &ClosestPointTree {
        self.search
            .get_or_init(|| ClosestPointTree::new(&self.tree, &self.mesh))
    }

    /// Whether `n` more points are walked: the search tree has not been made, and walks of
    /// them stay within the limit (they are then counted as walked).
    fn walks(&self, n: usize) -> bool {
        self.search.get().is_none()
            && self
                .walked
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |walked| {
                    (walked + n <= self.walk_limit).then_some(walked + n)
                })
                .is_ok()
    }
}

impl NearestPointSearch for ClosestPointsOnDemand {
    /// By a walk of the builder's tree while walks have not cost as much as making the search
    /// tree, by the search tree (made now if need be) after.
    fn closest_point_tallied<T: Tally>(&self, p: DVec3, tally: &mut T) -> Option<ClosestPoint> {
        if self.walks(1) {
            return self.walker().closest_point_tallied(p, tally);
        }
        self.search_tree_made().closest_point_tallied(p, tally)
    }

    /// By walks of the builder's tree while they have not cost as much as making the search
    /// tree, by the search tree (made now if need be) after: a batch is answered by one or the
    /// other, never both.
    fn closest_points_into_with<P: QueryPoints + ?Sized, R: AnswerRows>(
        &self,
        points: &P,
        out: R,
        threads: BatchThreads,
    ) {
        if self.walks(points.count()) {
            self.walker().closest_points_into_with(points, out, threads);
            return;
        }
        self.search_tree_made()
            .closest_points_into_with(points, out, threads);
    }
}
