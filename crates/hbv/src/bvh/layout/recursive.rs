//! The build tree as it is, packed into arrays and traversed depth first.

use crate::bvh::tree::{BuildTree, NodeContent, NodeId};
use crate::geometry::{Aabb, PreparedRay, Ray, Triangle};
use crate::mesh::TriangleMesh;
use crate::query::{record_closer_hit, Hit, TraversalKernel};
use crate::stats::{Counter, TraversalStats};

/// A node of [`RecursiveLayout`]: its box, and a range of children (in `nodes`) or of
/// triangles (in `triangles`).
#[derive(Clone, Copy, Debug)]
struct PackedNode {
    bounds: Aabb,
    /// First child node, or first triangle for a leaf.
    first: u32,
    /// Number of child nodes, or of triangles for a leaf.
    count: u32,
    is_leaf: bool,
}

/// The n-ary build tree with each node's children side by side, and the triangles copied in leaf
/// order next to their face ids. Traversal is the plain depth-first recursion of the seed:
/// a node's children are tested only when the ray hits the node, in stored order. It is written
/// with an explicit stack, so no tree depth can overflow the call stack.
///
/// It is the baseline of the layouts: it keeps any arity the builder made, and counts exactly
/// the tests that the tree cost E\[X\] predicts.
#[derive(Clone, Debug)]
pub struct RecursiveLayout {
    nodes: Vec<PackedNode>,
    triangles: Vec<Triangle>,
    prim_ids: Vec<u32>,
}

impl RecursiveLayout {
    /// Packs `tree`, whose leaves hold face ids of `mesh`.
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        let mut layout = Self {
            nodes: Vec::with_capacity(tree.nodes().len()),
            triangles: Vec::new(),
            prim_ids: Vec::new(),
        };
        let Some(root) = tree.root() else {
            return layout;
        };
        // Breadth-first over the build tree: the children of each node are reserved together.
        layout.nodes.push(PackedNode::placeholder());
        let mut queue: std::collections::VecDeque<(NodeId, usize)> = [(root, 0)].into();
        while let Some((id, slot)) = queue.pop_front() {
            let node = tree.node(id);
            layout.nodes[slot] = match &node.content {
                NodeContent::Leaf(prims) => {
                    let first = layout.triangles.len() as u32;
                    layout
                        .triangles
                        .extend(prims.iter().map(|&p| mesh.triangle(p as usize)));
                    layout.prim_ids.extend_from_slice(prims);
                    PackedNode {
                        bounds: node.bounds,
                        first,
                        count: prims.len() as u32,
                        is_leaf: true,
                    }
                }
                NodeContent::Internal(children) => {
                    let first = layout.nodes.len();
                    for (k, &c) in children.iter().enumerate() {
                        layout.nodes.push(PackedNode::placeholder());
                        queue.push_back((c, first + k));
                    }
                    PackedNode {
                        bounds: node.bounds,
                        first: first as u32,
                        count: children.len() as u32,
                        is_leaf: false,
                    }
                }
            };
        }
        layout
    }

    /// Bytes of node and triangle data.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<PackedNode>()
            + self.triangles.len() * std::mem::size_of::<Triangle>()
            + self.prim_ids.len() * 4
    }

    /// Counts every test a traversal makes along `ray` without early exit: every box the ray
    /// meets within `[tmin, tmax]` is opened, every triangle in a reached leaf is tested, and
    /// nothing shrinks the interval. For an infinite line through the root, the mean of
    /// `tests() - 1` (the root's own box) over isotropic lines is the tree cost E\[X\].
    pub fn count_tests_without_early_exit(&self, ray: &Ray, stats: &mut TraversalStats) {
        stats.rays += 1;
        if ray.is_valid() {
            self.traverse::<_, false>(&mut PreparedRay::new(ray), stats, |_, _, _| false);
        }
    }

    /// Depth-first visit of the nodes whose boxes the ray hits. `visit_leaf` tests a leaf's
    /// triangles and returns `true` to stop the traversal; it may shrink `ray.tmax`. `WIDENED`
    /// selects the conservative box test of queries (true) or the plain one of measurement.
    #[inline]
    fn traverse<C: Counter, const WIDENED: bool>(
        &self,
        ray: &mut PreparedRay,
        counter: &mut C,
        mut visit_leaf: impl FnMut(&mut PreparedRay, std::ops::Range<usize>, &mut C) -> bool,
    ) {
        let Some(root) = self.nodes.first() else {
            return;
        };
        ray.bound_errors_within(&root.bounds);
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(index) = stack.pop() {
            // The box is tested when the node's turn comes, with the ray's current tmax: this is
            // exactly the recursion "for each child: if the ray hits it, descend".
            let node = &self.nodes[index as usize];
            counter.boxes_tested(1);
            let hit = if WIDENED {
                node.bounds.hit_by(ray)
            } else {
                node.bounds.hit_by_unwidened(ray)
            };
            if !hit {
                continue;
            }
            counter.node_visited();
            let range = node.first as usize..(node.first + node.count) as usize;
            if node.is_leaf {
                counter.triangles_tested(node.count);
                if visit_leaf(ray, range, counter) {
                    return;
                }
            } else {
                // Reversed, so that children are visited in stored order.
                stack.extend(range.rev().map(|c| c as u32));
            }
        }
    }
}

impl PackedNode {
    fn placeholder() -> Self {
        Self {
            bounds: Aabb::EMPTY,
            first: 0,
            count: 0,
            is_leaf: true,
        }
    }
}

impl TraversalKernel for RecursiveLayout {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        let mut prepared = PreparedRay::new(ray);
        let mut best: Option<Hit> = None;
        self.traverse::<_, true>(&mut prepared, counter, |ray, range, _| {
            for i in range {
                record_closer_hit(&self.triangles[i], self.prim_ids[i], ray, &mut best);
            }
            false
        });
        best
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        self.any_hit_prim(ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        let mut prepared = PreparedRay::new(ray);
        let mut found = None;
        self.traverse::<_, true>(&mut prepared, counter, |ray, range, _| {
            found = range
                .into_iter()
                .find(|&i| self.triangles[i].intersect(ray).is_some())
                .map(|i| self.prim_ids[i]);
            found.is_some()
        });
        found
    }
}
