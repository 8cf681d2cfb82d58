//! What the top-down builders share: triangle records and their bounds, and the compact binary
//! tree that threads write without locks before it becomes a [`BuildTree`].

use glam::Vec3;
use rayon::prelude::*;

use crate::bvh::{BuildTree, NodeId, NodeList};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Subtrees of at least this many triangles build their two children with `rayon::join`;
/// below it the fork costs more than it gains.
pub(super) const PARALLEL_SUBTREE_MIN: usize = 1024;

/// Top-down SAH builders split at the object median from this depth on. The SAH may prefer to
/// peel a few triangles off a node level after level (nested triangles of geometrically growing
/// size do that), making chains much deeper than `log2 n`; median splits halve, so no tree is
/// deeper than `SAH_DEPTH_LIMIT + log2 n` and the recursion's stack stays small. Real meshes never
/// come near it: the SAH trees of the shared scenes are at most 25 deep.
pub(super) const SAH_DEPTH_LIMIT: u32 = 96;

/// A triangle as the top-down builders move it: its box and its face id, together, so that
/// binning and partitioning read memory in order instead of chasing ids.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PrimRef {
    pub(crate) bounds: Aabb,
    pub(crate) id: u32,
}

impl PrimRef {
    /// The box centre, computed as `min/2 + max/2` so that it stays finite for any finite box.
    #[inline]
    pub(super) fn centroid(&self) -> Vec3 {
        self.bounds.min * 0.5 + self.bounds.max * 0.5
    }
}

/// The non-degenerate triangles of `mesh` in face order (degenerate ones are left out).
pub(crate) fn prim_refs(mesh: &TriangleMesh) -> Vec<PrimRef> {
    let prim = |i: usize| PrimRef {
        bounds: mesh.triangle(i).bounds(),
        id: i as u32,
    };
    if mesh.degenerate_count() == 0 {
        // The mesh counted its degenerate triangles when it was made: none to test (in f64)
        // and leave out, so each thread writes its share of the array in place.
        return (0..mesh.triangle_count())
            .into_par_iter()
            .with_min_len(4096)
            .map(prim)
            .collect();
    }
    (0..mesh.triangle_count())
        .into_par_iter()
        .with_min_len(4096)
        .filter(|&i| !mesh.triangle(i).is_degenerate())
        .map(prim)
        .collect()
}

/// The box of some triangles and the box of their centroids.
pub(crate) type SideBounds = (Aabb, Aabb);

/// The box of `prims` and the box of their centroids (in parallel for many triangles).
pub(crate) fn bounds_and_centroid_bounds(prims: &[PrimRef]) -> SideBounds {
    const PARALLEL_MIN: usize = 1 << 16;
    let add = |(b, c): (Aabb, Aabb), p: &PrimRef| (b.union(&p.bounds), c.union_point(p.centroid()));
    if prims.len() < PARALLEL_MIN {
        return prims.iter().fold((Aabb::EMPTY, Aabb::EMPTY), add);
    }
    prims
        .par_chunks(PARALLEL_MIN / 4)
        .map(|chunk| chunk.iter().fold((Aabb::EMPTY, Aabb::EMPTY), add))
        .reduce(
            || (Aabb::EMPTY, Aabb::EMPTY),
            |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
        )
}

/// One slot of a [`RangeTree`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) enum RangeNode {
    /// A slot left free because the subtree that owns it made a leaf of several triangles.
    #[default]
    Unused,
    /// Triangles `prims[first..first + count]` of the builder's final triangle order.
    Leaf { first: u32, count: u32 },
    /// Children at these slots.
    Internal { left: u32, right: u32 },
}

/// A binary tree whose leaves are ranges of one array of triangles, written by top-down builders
/// from any number of threads without locks.
///
/// A subtree over `m` triangles owns `2m - 1` consecutive slots, enough for any binary tree
/// with `m` non-empty leaves: its root first, then its left subtree's slots, then its right
/// subtree's. Splitting a subtree therefore splits its slots at a place known in advance, and
/// the halves go to two threads as disjoint `&mut` slices:
///
/// ```text
///   slots of [0, m):   root | left over [0, k): 2k - 1 slots | right over [k, m): 2(m-k) - 1
/// ```
pub(super) struct RangeTree {
    pub(super) slots: Vec<RangeNode>,
}

impl RangeTree {
    /// Room for a tree over `prims` triangles.
    pub(super) fn new(prims: usize) -> Self {
        Self {
            slots: vec![RangeNode::Unused; (2 * prims).saturating_sub(1)],
        }
    }

    /// The whole tree, as one subtree over all the triangles, for a builder to split; `None`
    /// when there are no triangles.
    pub(super) fn root(&mut self) -> Option<Subtree<'_>> {
        (!self.slots.is_empty()).then(|| Subtree {
            first_prim: 0,
            first_slot: 0,
            slots: &mut self.slots,
        })
    }

    /// Copies the tree into a [`BuildTree`], children before parents; `prims` is the triangle
    /// array in its final order, whose ranges the leaves name. A leaf's box is the union of its
    /// triangles' boxes and an internal node's the union of its children's: every box is tight.
    pub(super) fn into_build_tree(self, prims: &[PrimRef]) -> BuildTree {
        let nodes = self
            .slots
            .iter()
            .filter(|s| **s != RangeNode::Unused)
            .count();
        let mut tree = BuildTree::with_capacity(nodes);
        if nodes == 0 {
            return tree;
        }
        // Post-order with an explicit stack: a node is pushed once both children are.
        let mut pending: Vec<(u32, bool)> = vec![(0, false)];
        let mut finished: Vec<NodeId> = Vec::new();
        while let Some((slot, children_done)) = pending.pop() {
            match self.slots[slot as usize] {
                RangeNode::Leaf { first, count } => {
                    let leaf = &prims[first as usize..(first + count) as usize];
                    let bounds = leaf.iter().fold(Aabb::EMPTY, |b, p| b.union(&p.bounds));
                    finished.push(
                        tree.push_leaf(leaf.iter().map(|p| p.id).collect::<NodeList>(), bounds),
                    );
                }
                RangeNode::Internal { left, right } if !children_done => {
                    pending.extend([(slot, true), (right, false), (left, false)]);
                }
                RangeNode::Internal { .. } => {
                    let right = finished.pop().expect("right child built");
                    let left = finished.pop().expect("left child built");
                    finished.push(tree.push_internal([left, right].as_slice()));
                }
                RangeNode::Unused => unreachable!("slot {slot} is reachable but was never set"),
            }
        }
        tree.set_root(finished.pop());
        tree
    }
}

/// The slots of one subtree of a [`RangeTree`], over `slots.len() / 2 + 1` triangles starting
/// at `first_prim`. Consumed by making it a leaf or splitting it into two children.
pub(super) struct Subtree<'a> {
    pub(super) first_prim: u32,
    pub(super) first_slot: u32,
    pub(super) slots: &'a mut [RangeNode],
}

impl<'a> Subtree<'a> {
    /// Number of triangles under this subtree.
    pub(super) fn prim_count(&self) -> usize {
        self.slots.len() / 2 + 1
    }

    /// Makes the subtree one leaf holding all its triangles.
    pub(super) fn make_leaf(self) {
        self.slots[0] = RangeNode::Leaf {
            first: self.first_prim,
            count: self.prim_count() as u32,
        };
    }

    /// Makes the subtree's root internal, with the first `left_prims` triangles on the left;
    /// returns the two children's subtrees.
    pub(super) fn split(self, left_prims: usize) -> (Subtree<'a>, Subtree<'a>) {
        let m = self.prim_count();
        assert!(
            0 < left_prims && left_prims < m,
            "split {left_prims} of {m}"
        );
        let (root, rest) = self.slots.split_first_mut().expect("a subtree has a root");
        let (left_slots, right_slots) = rest.split_at_mut(2 * left_prims - 1);
        let left = Subtree {
            first_prim: self.first_prim,
            first_slot: self.first_slot + 1,
            slots: left_slots,
        };
        let right = Subtree {
            first_prim: self.first_prim + left_prims as u32,
            first_slot: self.first_slot + 2 * left_prims as u32,
            slots: right_slots,
        };
        *root = RangeNode::Internal {
            left: left.first_slot,
            right: right.first_slot,
        };
        (left, right)
    }
}

/// What [`SAH_DEPTH_LIMIT`] promises, checked for an SAH builder: 90 triangles in a row and 10
/// far away, which the SAH splits 90 | 10 at the root, are split at the object median (50 | 50)
/// when the root is built at the limit, and halved on down to leaves of 4. `build(mesh,
/// root_depth)` is the builder, with leaves of at most 4 triangles, putting its root at
/// `root_depth`.
#[cfg(test)]
pub(super) fn assert_median_splits_past_the_depth_limit(
    build: impl Fn(&TriangleMesh, u32) -> BuildTree,
) {
    use crate::bvh::build::primitive_bounds;
    use crate::mesh::procedural::unit_triangles_at;

    let corners: Vec<Vec3> = (0..90)
        .map(|i| Vec3::new(i as f32 * 0.01, 0.0, 0.0))
        .chain((0..10).map(|i| Vec3::new(1000.0 + i as f32 * 0.01, 0.0, 0.0)))
        .collect();
    let mesh = unit_triangles_at(&corners);
    let root_split = |root_depth| {
        let tree = build(&mesh, root_depth);
        tree.validate(&primitive_bounds(&mesh), 4).unwrap();
        let root = tree.node(tree.root().unwrap());
        let sizes: Vec<usize> = root
            .children()
            .iter()
            .map(|&c| tree.prims_below(c).len())
            .collect();
        (sizes, tree.shape().depth_max)
    };
    let (sah_sizes, _) = root_split(0);
    assert!(sah_sizes.contains(&10), "{sah_sizes:?}");
    let (median_sizes, depth) = root_split(SAH_DEPTH_LIMIT);
    assert_eq!(median_sizes, [50, 50]);
    assert_eq!(depth, 5, "balanced down to leaves of 4");
}

#[cfg(test)]
mod range_tree_tests {
    use super::*;

    fn prim(id: u32, x: f32) -> PrimRef {
        PrimRef {
            bounds: Aabb::new(Vec3::splat(x), Vec3::splat(x + 1.0)),
            id,
        }
    }

    #[test]
    fn split_subtrees_own_disjoint_slots_and_convert_to_a_tight_tree() {
        // Five triangles: ((0 1) (2 3 4)) with (2 3 4) one leaf.
        let prims: Vec<PrimRef> = (0..5).map(|i| prim(10 + i, i as f32)).collect();
        let mut ranges = RangeTree::new(prims.len());
        let (left, right) = ranges.root().unwrap().split(2);
        assert_eq!((left.prim_count(), right.prim_count()), (2, 3));
        let (a, b) = left.split(1);
        a.make_leaf();
        b.make_leaf();
        right.make_leaf();
        let tree = ranges.into_build_tree(&prims);
        let bounds: Vec<Aabb> = (0..15)
            .map(|i| {
                prims
                    .iter()
                    .find(|p| p.id == i)
                    .map_or(Aabb::EMPTY, |p| p.bounds)
            })
            .collect();
        tree.validate(&bounds, 3).unwrap();
        let shape = tree.shape();
        assert_eq!((shape.nodes, shape.leaves, shape.depth_max), (5, 3, 2));
        let root = tree.node(tree.root().unwrap());
        assert_eq!(root.bounds, Aabb::new(Vec3::ZERO, Vec3::splat(5.0)));
        assert_eq!(tree.node(root.children()[1]).prims(), &[12, 13, 14]);
    }

    #[test]
    fn no_triangles_no_tree() {
        let mut ranges = RangeTree::new(0);
        assert!(ranges.root().is_none());
        assert!(ranges.into_build_tree(&[]).is_empty());
    }
}
