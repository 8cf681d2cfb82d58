//! A binary tree with sibling nodes side by side, traversed nearest child first with a stack.

use super::binarize::binary_form;
use super::leaf_triangles::{
    any_hit_in_leaves, closest_hit_in_leaves, LeafTriangles, LeafVisitingLayout,
};
use super::stack::TraversalStack;
use crate::bvh::tree::{BuildTree, NodeContent, NodeId};
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::mesh::TriangleMesh;
use crate::query::{Hit, TraversalKernel};
use crate::stats::Counter;

/// A node of [`OrderedLayout`]: 32 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct OrderedNode {
    bounds: Aabb,
    /// Internal: index of the first child (the second follows it). Leaf: first triangle.
    offset: u32,
    is_leaf: u32,
}

/// The binary tree (n-ary nodes binarized, see `binarize`) with the two children of each node
/// stored next to each other, so that one cache line holds both boxes.
///
/// Traversal keeps a stack of postponed subtrees with their entry distances (Wald et al. 2001):
/// at an internal node both child boxes are tested, the nearer hit child is visited next and the
/// farther is pushed; a popped subtree whose entry lies beyond the closest hit found so far is
/// dropped. This is what the skip layout cannot do: visit the nearer side first, so that the
/// first hit found is usually the closest and most of the far side is culled.
#[derive(Clone, Debug)]
pub struct OrderedLayout {
    nodes: Vec<OrderedNode>,
    leaves: LeafTriangles,
}

impl OrderedLayout {
    /// Lays out `tree` (binarized first if it has n-ary nodes).
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        let binary = binary_form(tree);
        let mut layout = Self {
            nodes: Vec::with_capacity(binary.nodes().len()),
            leaves: LeafTriangles::default(),
        };
        let Some(root) = binary.root() else {
            return layout;
        };
        layout.nodes.push(OrderedNode {
            bounds: Aabb::EMPTY,
            offset: 0,
            is_leaf: 1,
        });
        // Depth first, so that a subtree's nodes are close together in memory.
        let mut pending: Vec<(NodeId, usize)> = vec![(root, 0)];
        while let Some((id, slot)) = pending.pop() {
            let node = binary.node(id);
            layout.nodes[slot] = match &node.content {
                NodeContent::Leaf(_) => OrderedNode {
                    bounds: node.bounds,
                    offset: layout.leaves.push_leaf(&binary, id, mesh),
                    is_leaf: 1,
                },
                NodeContent::Internal(children) => {
                    let first = layout.nodes.len();
                    for (k, &c) in children.iter().enumerate() {
                        layout.nodes.push(OrderedNode {
                            bounds: Aabb::EMPTY,
                            offset: 0,
                            is_leaf: 1,
                        });
                        pending.push((c, first + k));
                    }
                    OrderedNode {
                        bounds: node.bounds,
                        offset: first as u32,
                        is_leaf: 0,
                    }
                }
            };
        }
        layout
    }

    /// Bytes of node and triangle data.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<OrderedNode>() + self.leaves.memory_bytes()
    }
}

impl LeafVisitingLayout for OrderedLayout {
    fn leaves(&self) -> &LeafTriangles {
        &self.leaves
    }

    /// Nearest-first traversal; `visit_leaf` returns `true` to stop.
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
        counter.boxes_tested(1);
        if !root.bounds.hit_by(ray) {
            return;
        }
        let mut stack: TraversalStack<(u32, f32), 64> = TraversalStack::new();
        let mut current = 0u32;
        loop {
            let node = &self.nodes[current as usize];
            counter.node_visited();
            let next = if node.is_leaf != 0 {
                if visit_leaf(node.offset, ray, counter) {
                    return;
                }
                None
            } else {
                let (a, b) = (node.offset, node.offset + 1);
                counter.boxes_tested(2);
                let hit_a = self.nodes[a as usize].bounds.intersect_interval(ray);
                let hit_b = self.nodes[b as usize].bounds.intersect_interval(ray);
                match (hit_a, hit_b) {
                    (Some((near_a, _)), Some((near_b, _))) => {
                        let (first, second, second_near) = if near_a <= near_b {
                            (a, b, near_b)
                        } else {
                            (b, a, near_a)
                        };
                        stack.push((second, second_near));
                        Some(first)
                    }
                    (Some(_), None) => Some(a),
                    (None, Some(_)) => Some(b),
                    (None, None) => None,
                }
            };
            current = match next {
                Some(n) => n,
                None => loop {
                    match stack.pop() {
                        // Entered beyond the closest hit so far: nothing nearer can be there.
                        Some((n, near)) if near <= ray.box_tmax() => break n,
                        Some(_) => continue,
                        None => return,
                    }
                },
            };
        }
    }
}

impl TraversalKernel for OrderedLayout {
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
