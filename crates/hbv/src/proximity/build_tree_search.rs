//! The nearest surface point found by walking a builder's tree as it is ([`BuildTree`]), with no
//! search tree made first: what a fresh BVH answers its first nearest-point queries with, until
//! the [`ClosestPointTree`](super::ClosestPointTree) (faster per query, but as dear to make as
//! thousands of these walks) has paid for itself (module `on_demand`).
//!
//! **Search** (branch and bound, as in [`ClosestPointTree`](super::ClosestPointTree), Larsen et
//! al. 1999): keep the best squared distance `d²` so far and its [`prune_threshold`]; at a node,
//! bound each child's box distance `Σ_axis max(min - p, 0, p - max)²` from below in f32
//! (`box_bound`: conservative for the f64 point), and visit those within the threshold, the
//! nearest first; in a leaf, decide every triangle with [`closest_point_on_triangle`] in f64.
//! A box is pruned only when no triangle in it can have a computed distance within the best's,
//! so the answer is [`closest_point_brute_force`](super::closest_point_brute_force)'s, ties
//! included (the smallest face id among equal distances).

use glam::DVec3;

use super::answers::{AnswerRows, ClosestPoint};
use super::batches::{assert_rows, for_each_run, run_of, BatchThreads};
use super::box_bound::{prune_threshold, rounding_margin, Boxes, PointBracket};
use super::nearest_point_search::NearestPointSearch;
use super::point_triangle::closest_point_on_triangle;
use super::prefetch::prefetch;
use super::query_points::QueryPoints;
use super::search_tally::Tally;
use crate::bvh::{BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// A builder's tree and its mesh, searched for nearest points in place.
#[derive(Clone, Copy, Debug)]
pub struct BuildTreeSearch<'a> {
    tree: &'a BuildTree,
    mesh: &'a TriangleMesh,
    /// The largest coordinate magnitude of the triangles in the tree (the rounding margin's
    /// scale): that of its root's box.
    mesh_scale: f64,
}

/// One pending node of a walk: its box's lower bound and its id.
type Pending = (f32, NodeId);

impl<'a> BuildTreeSearch<'a> {
    /// Searches `tree`, built over `mesh` by any builder.
    pub fn new(tree: &'a BuildTree, mesh: &'a TriangleMesh) -> Self {
        let mesh_scale = tree.root().map_or(0.0, |root| {
            let b = tree.node(root).bounds;
            b.min.abs().max(b.max.abs()).max_element() as f64
        });
        Self {
            tree,
            mesh,
            mesh_scale,
        }
    }

    /// The nearest surface point to `p` (module notes), `stack` scratch space reused between
    /// searches, the steps counted into `tally` (nodes opened and triangles decided: a walk has
    /// no packets).
    fn search(
        &self,
        p: DVec3,
        stack: &mut Vec<Pending>,
        tally: &mut impl Tally,
    ) -> Option<ClosestPoint> {
        let root = self.tree.root()?;
        if !p.is_finite() {
            return None;
        }
        let bracket = PointBracket::new(p);
        let delta = rounding_margin(p, self.mesh_scale);
        let mut best: Option<(ClosestPoint, f64)> = None;
        let mut threshold = f32::INFINITY;
        stack.clear();
        stack.push((0.0, root));
        while let Some((bound, id)) = stack.pop() {
            if bound > threshold {
                continue;
            }
            match &self.tree.node(id).content {
                NodeContent::Leaf(prims) => {
                    for &prim in prims.iter() {
                        let t = self.mesh.triangle(prim as usize);
                        if t.is_degenerate() {
                            continue;
                        }
                        tally.exact();
                        let q = closest_point_on_triangle(
                            p,
                            t.p0.as_dvec3(),
                            t.p1.as_dvec3(),
                            t.p2.as_dvec3(),
                        );
                        let d2 = (p - q.point).length_squared();
                        let beats = match &best {
                            None => true,
                            Some((b, best_d2)) => {
                                d2 < *best_d2 || (d2 == *best_d2 && prim < b.prim)
                            }
                        };
                        if beats {
                            let answer = ClosestPoint {
                                point: q.point,
                                distance: 0.0,
                                prim,
                                u: q.u,
                                v: q.v,
                            };
                            best = Some((answer, d2));
                            threshold = prune_threshold(d2, delta);
                        }
                    }
                }
                NodeContent::Internal(children) => {
                    tally.node();
                    // Pushed farthest first, so that the nearest is searched next.
                    let first = stack.len();
                    for &child in children.iter() {
                        let node = self.tree.node(child);
                        let bound = box_bound(&node.bounds, &bracket);
                        if bound <= threshold {
                            stack.push((bound, child));
                            // Its children's boxes are what the next step reads: asked for
                            // now, while this step's work goes on.
                            match &node.content {
                                NodeContent::Internal(grandchildren) => {
                                    for &g in grandchildren.iter() {
                                        prefetch(self.tree.node(g));
                                    }
                                }
                                NodeContent::Leaf(prims) => {
                                    for &prim in prims.iter() {
                                        prefetch(&self.mesh.indices()[prim as usize]);
                                    }
                                }
                            }
                        }
                    }
                    stack[first..].sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
                }
            }
        }
        best.map(|(answer, d2)| ClosestPoint {
            distance: d2.sqrt(),
            ..answer
        })
    }
}

impl NearestPointSearch for BuildTreeSearch<'_> {
    fn closest_point_tallied<T: Tally>(&self, p: DVec3, tally: &mut T) -> Option<ClosestPoint> {
        self.search(p, &mut Vec::new(), tally)
    }

    /// Runs of points shared out as `threads` says, each point walked on its own (the walk
    /// takes no seed).
    fn closest_points_into_with<P: QueryPoints + ?Sized, R: AnswerRows>(
        &self,
        points: &P,
        out: R,
        threads: BatchThreads,
    ) {
        let n = points.count();
        assert_rows(&out, n);
        for_each_run(threads.0, out, n, |points_of_run, mut rows| {
            let len = points_of_run.len();
            let run = run_of(points, points_of_run.start, len);
            let mut stack = Vec::new();
            for (k, &p) in run[..len].iter().enumerate() {
                let mut tally = R::Tally::default();
                let found = self.search(p, &mut stack, &mut tally);
                rows.write(k, found, tally);
            }
        });
    }
}

/// [`Boxes::distance_squared_lower_bounds`] of one box.
#[inline]
fn box_bound(b: &Aabb, bracket: &PointBracket) -> f32 {
    let boxes = Boxes::<1> {
        min: [[b.min.x], [b.min.y], [b.min.z]],
        max: [[b.max.x], [b.max.y], [b.max.z]],
    };
    boxes.distance_squared_lower_bounds(bracket)[0]
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
    use crate::mesh::procedural::icosphere;
    use crate::proximity::{closest_point_brute_force, ClosestPointsOnDemand, SearchTally};

    /// The walk's batch forms (a list, with tallies, on the calling thread or the pool's)
    /// answer as the brute force, and a counted walk counts the nodes it opens and at least
    /// the triangle it answers with.
    #[test]
    fn walked_batches_and_tallies_agree_with_brute_force() {
        let mesh = icosphere(Vec3::new(0.5, -1.0, 2.0), 1.5, 3);
        let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
        let walk = BuildTreeSearch::new(&tree, &mesh);
        let points: Vec<DVec3> = (0..700)
            .map(|i| {
                let t = i as f64;
                DVec3::new((t * 0.37).sin(), (t * 1.91).cos(), (t * 0.13).sin() + 2.0) * 2.5
            })
            .chain([DVec3::NAN])
            .collect();
        let want: Vec<_> = points
            .iter()
            .map(|&p| closest_point_brute_force(&mesh, p))
            .collect();
        assert_eq!(walk.closest_points(&points), want);
        let tallied = walk.closest_points_tallied(&points);
        for ((found, tally), want) in tallied.iter().zip(&want) {
            assert_eq!(found, want);
            if found.is_some() {
                assert!(tally.nodes >= 1 && tally.exact >= 1 && tally.packets == 0);
            }
        }
        let mut single = SearchTally::default();
        assert_eq!(walk.closest_point_tallied(points[3], &mut single), want[3]);
        assert_eq!(single, tallied[3].1);
        // On demand: one point walked, then the search tree once the walks are spent.
        let on_demand =
            ClosestPointsOnDemand::with_walk_limit(tree.clone().into(), mesh.clone().into(), 1);
        assert_eq!(on_demand.closest_point(points[5]), want[5]);
        assert!(on_demand.search_tree().is_none());
        assert_eq!(on_demand.closest_points(&points), want);
        assert!(on_demand.search_tree().is_some());
    }
}
