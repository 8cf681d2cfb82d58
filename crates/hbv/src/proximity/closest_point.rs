//! The nearest point of a mesh's surface to a query point: a branch-and-bound search of a BVH.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::point_triangle::closest_point_on_triangle;
use crate::bvh::morton::morton_code;
use crate::bvh::{BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;
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

/// A node of the search tree, 32 bytes (two to a cache line): its box in f32 (the tree's own
/// box, so converting it to f64 for the distance is exact), and its children (`first..first +
/// count` in `nodes`) or, when [`SearchNode::LEAF`] is set in `count`, its triangles.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct SearchNode {
    min: Vec3,
    max: Vec3,
    first: u32,
    count: u32,
}

impl SearchNode {
    /// Bit of `count` that marks a leaf.
    const LEAF: u32 = 1 << 31;

    #[inline]
    fn is_leaf(&self) -> bool {
        self.count & Self::LEAF != 0
    }

    /// Its children's or triangles' indices.
    #[inline]
    fn range(&self) -> std::ops::Range<u32> {
        self.first..self.first + (self.count & !Self::LEAF)
    }
}

/// A BVH laid out for nearest-point queries: any [`BuildTree`]'s nodes, children side by side,
/// boxes and triangles kept in f32 and converted to f64 where used (f32 to f64 is exact, so the
/// answers are those of the f64 brute force over the same f32 vertices).
///
/// **Search** (branch and bound, as in Larsen et al. 1999 and Ericson §6.5): keep the best
/// squared distance `d²` so far; at a node compute each child box's squared distance
/// `Σ_axis max(min - p, 0, p - max)²` and visit children nearest first; a box farther than `d²`
/// cannot hold a nearer triangle and is pruned. Each triangle is decided by
/// [`closest_point_on_triangle`] (Ericson §5.1.5). Degenerate triangles are left out, as in every
/// tree (they have no face to be nearest to, and their edges are other triangles' edges on
/// meshes that matter).
#[derive(Clone, Debug)]
pub struct ClosestPointTree {
    nodes: Vec<SearchNode>,
    /// `(face id, vertices)` in leaf order; f32 as in the mesh (half the memory of f64; the
    /// conversion to f64 for the search is exact).
    triangles: Vec<(u32, [Vec3; 3])>,
}

/// Relative slack of the box pruning test: a box is pruned only when its distance exceeds the
/// best by more than rounding (both are rounded f64 values of real distances that may be
/// equal), so that no triangle that the brute force would pick is ever skipped.
const PRUNE_SLACK: f64 = 1e-9;

impl ClosestPointTree {
    /// Lays out `tree` (built over `mesh` by any builder) for nearest-point search.
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        let mut search = Self {
            nodes: Vec::new(),
            triangles: Vec::new(),
        };
        let Some(root) = tree.root() else {
            return search;
        };
        // Breadth first: each node's children are pushed together, so they sit side by side.
        let root_node = search.node_for(tree, mesh, root);
        search.nodes.push(root_node);
        let mut queue: std::collections::VecDeque<(NodeId, usize)> = [(root, 0)].into();
        while let Some((id, slot)) = queue.pop_front() {
            if let NodeContent::Internal(children) = &tree.node(id).content {
                search.nodes[slot].first = search.nodes.len() as u32;
                search.nodes[slot].count = children.len() as u32;
                for &c in children {
                    let node = search.node_for(tree, mesh, c);
                    queue.push_back((c, search.nodes.len()));
                    search.nodes.push(node);
                }
            }
        }
        search
    }

    /// The search node for `id`; a leaf's triangles are appended here, an internal node's
    /// children are filled in by the caller.
    fn node_for(&mut self, tree: &BuildTree, mesh: &TriangleMesh, id: NodeId) -> SearchNode {
        let node = tree.node(id);
        let mut search = SearchNode {
            min: node.bounds.min,
            max: node.bounds.max,
            first: 0,
            count: 0,
        };
        if let NodeContent::Leaf(prims) = &node.content {
            search.first = self.triangles.len() as u32;
            for &p in prims {
                let t = mesh.triangle(p as usize);
                if t.is_degenerate() {
                    continue;
                }
                let v = [t.p0, t.p1, t.p2];
                self.triangles.push((p, v));
            }
            search.count = (self.triangles.len() as u32 - search.first) | SearchNode::LEAF;
        }
        search
    }

    /// The nearest surface point to `point`; `None` for an empty tree or a point with a NaN or
    /// infinite coordinate.
    pub fn closest_point(&self, point: Vec3) -> Option<ClosestPoint> {
        self.closest_point_f64(point.as_dvec3())
    }

    /// [`ClosestPointTree::closest_point`] for an f64 query point.
    pub fn closest_point_f64(&self, p: DVec3) -> Option<ClosestPoint> {
        self.search(p, None).map(|(c, _)| c)
    }

    /// The nearest surface point to each of `points` (as [`ClosestPointTree::closest_point_f64`],
    /// the same answers), in parallel on the current rayon pool.
    ///
    /// The points are searched in Morton order (Morton 1966: bits of the quantized x, y, z
    /// interleaved, so that points near in the order are near in space), in runs of
    /// [`Self::RUN`]; each search but a run's first starts with the previous point's nearest
    /// triangle as its best so far. The distance to a neighbour's nearest triangle is a tight
    /// upper bound, so nodes are pruned from the first step instead of after a first descent.
    /// The answer does not depend on the seed: the search keeps the least `(d², face id)` over
    /// every triangle it does not prune, pruning stays conservative, and the seed triangle's
    /// `d²` is computed exactly as when its leaf is reached.
    pub fn closest_points(&self, points: &[DVec3]) -> Vec<Option<ClosestPoint>> {
        let bounds = points
            .iter()
            .filter(|p| p.is_finite())
            .fold(Aabb::EMPTY, |b, p| b.union_point(p.as_vec3()));
        let mut order: Vec<(u64, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let code = if p.is_finite() {
                    morton_code(p.as_vec3(), &bounds)
                } else {
                    u64::MAX
                };
                (code, i as u32)
            })
            .collect();
        order.par_sort_unstable();
        let found: Vec<(u32, Option<ClosestPoint>)> = order
            .par_chunks(Self::RUN)
            .flat_map_iter(|run| {
                let mut seed = None;
                run.iter()
                    .map(|&(_, i)| {
                        let found = self.search(points[i as usize], seed);
                        seed = found.map(|(_, local)| local).or(seed);
                        (i, found.map(|(c, _)| c))
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut out = vec![None; points.len()];
        for (i, c) in found {
            out[i as usize] = c;
        }
        out
    }

    /// Points per run of [`ClosestPointTree::closest_points`]: one rayon task, seeded in turn.
    pub const RUN: usize = 256;

    /// The branch-and-bound search, starting from triangle `seed` (an index into
    /// `self.triangles`) as the best so far when given; returns the answer and its triangle's
    /// index into `self.triangles`.
    fn search(&self, p: DVec3, seed: Option<u32>) -> Option<(ClosestPoint, u32)> {
        if self.nodes.is_empty() || !p.is_finite() {
            return None;
        }
        let mut best: Option<(ClosestPoint, u32)> = None;
        let mut best_d2 = f64::INFINITY;
        let mut consider = |local: u32, best_d2: &mut f64| {
            let (prim, [a, b, c]) = &self.triangles[local as usize];
            let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            let d2 = (p - q.point).length_squared();
            let closer =
                d2 < *best_d2 || (d2 == *best_d2 && best.is_some_and(|(b, _)| *prim < b.prim));
            if closer {
                *best_d2 = d2;
                let found = ClosestPoint {
                    point: q.point,
                    distance: d2.sqrt(),
                    prim: *prim,
                    u: q.u,
                    v: q.v,
                };
                best = Some((found, local));
            }
        };
        if let Some(local) = seed {
            consider(local, &mut best_d2);
        }
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, box_distance_squared(&self.nodes[0], p)));
        while let Some((index, d2)) = stack.pop() {
            if d2 * (1.0 - PRUNE_SLACK) > best_d2 {
                continue;
            }
            let node = self.nodes[index as usize];
            let range = node.range();
            if node.is_leaf() {
                for local in range {
                    consider(local, &mut best_d2);
                }
                continue;
            }
            // Push the children farthest first, so that the nearest is searched next.
            let first = stack.len();
            for child in range {
                let d2 = box_distance_squared(&self.nodes[child as usize], p);
                if d2 * (1.0 - PRUNE_SLACK) <= best_d2 {
                    stack.push((child, d2));
                }
            }
            stack[first..].sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
        }
        best
    }
}

/// Squared distance from `p` to the node's box (0 inside): `Σ max(min - p, 0, p - max)²`.
#[inline]
fn box_distance_squared(node: &SearchNode, p: DVec3) -> f64 {
    let d = (node.min.as_dvec3() - p)
        .max(p - node.max.as_dvec3())
        .max(DVec3::ZERO);
    d.length_squared()
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
