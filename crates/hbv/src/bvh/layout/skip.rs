//! The seed's layout: the tree in depth-first order with skip pointers, traversed without a stack.

use super::leaf_triangles::{
    any_hit_in_leaves, closest_hit_in_leaves, LeafTriangles, LeafVisitingLayout,
};
use crate::bvh::tree::BuildTree;
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::mesh::TriangleMesh;
use crate::query::{Hit, TraversalKernel};
use crate::stats::Counter;

/// `first_triangle` of an internal node.
const INTERNAL: u32 = u32::MAX;

/// A node of [`SkipLayout`]: 32 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct SkipNode {
    bounds: Aabb,
    /// The node to visit when the ray misses this one (or after this leaf): the next node in
    /// depth-first order that is not a descendant. `nodes.len()` ends the traversal.
    skip: u32,
    /// First triangle of a leaf in the leaf storage, or [`INTERNAL`].
    first_triangle: u32,
}

/// The tree in one array, in depth-first order (parents before children, children in order),
/// each node with a **skip pointer** to the node that follows its subtree (Smits 1998, "Efficiency
/// issues for ray tracing"; the seed's "skip pointers").
///
/// Traversal is one loop with no stack: at node `i`, if the ray hits its box, go to `i + 1` (the
/// first child) — after testing the triangles, for a leaf — else go to `skip`. The order is
/// fixed, so closest-hit queries cannot visit the nearer child first; they still shrink `tmax`
/// as hits are found, which culls boxes beyond the nearest hit so far. Works on any arity.
#[derive(Clone, Debug)]
pub struct SkipLayout {
    nodes: Vec<SkipNode>,
    leaves: LeafTriangles,
}

impl SkipLayout {
    /// Lays out `tree`, whose leaves hold face ids of `mesh`.
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        let mut nodes: Vec<SkipNode> = Vec::with_capacity(tree.nodes().len());
        let mut leaves = LeafTriangles::default();
        // Preorder, remembering where each subtree starts so its skip can be set once it ends.
        let mut open: Vec<(usize, usize)> = Vec::new(); // (node index, depth)
        tree.walk(|id, depth| {
            while let Some(&(start, d)) = open.last() {
                if d < depth {
                    break;
                }
                nodes[start].skip = nodes.len() as u32;
                open.pop();
            }
            let node = tree.node(id);
            let first_triangle = if node.is_leaf() {
                leaves.push_leaf(tree, id, mesh)
            } else {
                INTERNAL
            };
            open.push((nodes.len(), depth));
            nodes.push(SkipNode {
                bounds: node.bounds,
                skip: 0,
                first_triangle,
            });
        });
        for (start, _) in open {
            nodes[start].skip = nodes.len() as u32;
        }
        Self { nodes, leaves }
    }

    /// Bytes of node and triangle data.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<SkipNode>() + self.leaves.memory_bytes()
    }
}

impl LeafVisitingLayout for SkipLayout {
    fn leaves(&self) -> &LeafTriangles {
        &self.leaves
    }

    /// The stackless loop; `visit_leaf` returns `true` to stop.
    #[inline]
    fn traverse<C: Counter>(
        &self,
        ray: &mut PreparedRay,
        counter: &mut C,
        mut visit_leaf: impl FnMut(u32, &mut PreparedRay, &mut C) -> bool,
    ) {
        let Some(root) = self.nodes.first() else {
            return;
        };
        ray.bound_errors_within(&root.bounds);
        let mut i = 0usize;
        while let Some(node) = self.nodes.get(i) {
            counter.boxes_tested(1);
            if !node.bounds.hit_by(ray) {
                i = node.skip as usize;
                continue;
            }
            counter.node_visited();
            if node.first_triangle == INTERNAL {
                i += 1;
            } else {
                if visit_leaf(node.first_triangle, ray, counter) {
                    return;
                }
                i = node.skip as usize;
            }
        }
    }
}

impl TraversalKernel for SkipLayout {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        closest_hit_in_leaves(self, ray, counter)
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        any_hit_in_leaves(self, ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        any_hit_in_leaves(self, ray, counter)
    }
}
