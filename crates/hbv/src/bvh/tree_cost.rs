//! The bookkeeping of a tree cost `Σ_n w(n) · SA(n)`: the weight of each node under E\[X\] or
//! the SAH, and the exact change of the sum when a node is taken out of a tree
//! ([`TreeCost::removal_saving`]) or a box is placed in it ([`TreeCost::placement_increase`]):
//! the two figures that incremental construction and insertion-based optimization weigh
//! (the derivation is in [`crate::bvh::placement`]).

use super::cost::{expected_tests, sah_cost, SahWeights};
use super::placement::{PlacedItem, Placement};
use super::tree::{BuildNode, BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;

/// A tree cost of the form `Σ_n w(n) · SA(n)` (divided by `SA(root)`), named by its weights.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum TreeCost {
    /// The seed's E\[X\] ([`expected_tests`]): `w(n) = a_n`, the children of an internal node or
    /// the triangles of a leaf.
    #[default]
    ExpectedTests,
    /// The SAH cost ([`sah_cost`]): `w(n) = C_t` for an internal node whatever its arity,
    /// `C_i · |n|` for a leaf.
    Sah(SahWeights),
}

impl TreeCost {
    /// The cost of `tree`: [`expected_tests`] or [`sah_cost`].
    pub fn of(&self, tree: &BuildTree) -> f64 {
        match *self {
            TreeCost::ExpectedTests => expected_tests(tree),
            TreeCost::Sah(weights) => sah_cost(tree, weights),
        }
    }

    /// `w` of an internal node with `children` children.
    pub fn internal_weight(&self, children: usize) -> f64 {
        match self {
            TreeCost::ExpectedTests => children as f64,
            TreeCost::Sah(w) => w.traversal,
        }
    }

    /// `w` of a leaf holding `prims` triangles.
    pub fn leaf_weight(&self, prims: usize) -> f64 {
        match self {
            TreeCost::ExpectedTests => prims as f64,
            TreeCost::Sah(w) => w.intersection * prims as f64,
        }
    }

    /// `w(node)`.
    pub fn weight(&self, node: &BuildNode) -> f64 {
        match &node.content {
            NodeContent::Internal(children) => self.internal_weight(children.len()),
            NodeContent::Leaf(prims) => self.leaf_weight(prims.len()),
        }
    }

    /// How much `Σ w(n) SA(n)` falls when `node` is taken out of `tree`, not
    /// counting the subtree of `node` itself (it does not change). Exact, in `f64` from the
    /// `f32` areas, as [`TreeCost::of`] sums them.
    ///
    /// The parent `P` either keeps its other children (a), losing a child's weight and shrinking
    /// to them, or is left with one child `S`, which takes its place (b), and `P`'s whole term
    /// goes; (a parent left with no child goes too, and the same is asked of it). Then every
    /// ancestor shrinks to its children, up to the first whose box does not change:
    ///
    /// ```text
    ///  (a)     G               G'           (b)      G               G'
    ///          |               |                     |               |
    ///          P      ==>      P'    N               P      ==>      S     N     (P released)
    ///        / | \            / \                   / \
    ///       N  A  B          A   B                 N   S
    ///
    ///  (a)  saving = w(P) SA(P) − w(P') SA(P') + Σ_{A above} w(A) (SA(A) − SA(A'))
    ///  (b)  saving = w(P) SA(P)                + Σ_{A above} w(A) (SA(A) − SA(A'))
    /// ```
    pub fn removal_saving(&self, tree: &BuildTree, node: NodeId) -> f64 {
        let area = |b: &Aabb| b.surface_area() as f64;
        let mut saving = 0.0;
        let mut leaving = node;
        while let Some(p) = tree.node(leaving).parent {
            let parent = tree.node(p);
            let children = parent.children();
            saving += self.weight(parent) * area(&parent.bounds);
            match children.len() {
                // P goes too: it leaves its own parent in turn.
                1 => leaving = p,
                2 => {
                    let sibling = children[usize::from(children[0] == leaving)];
                    let sibling_box = tree.node(sibling).bounds;
                    return saving + self.refit_saving(tree, p, sibling_box);
                }
                k => {
                    let fitted = children
                        .iter()
                        .filter(|&&c| c != leaving)
                        .fold(Aabb::EMPTY, |b, &c| b.union(&tree.node(c).bounds));
                    saving -= self.internal_weight(k - 1) * area(&fitted);
                    return saving + self.refit_saving(tree, p, fitted);
                }
            }
        }
        saving
    }

    /// The saving of refitting the ancestors of `changed`, whose box becomes `new_box`: each
    /// shrinks to the union of its children, up to the first that does not change (as
    /// `BuildTree::refit_from` does).
    fn refit_saving(&self, tree: &BuildTree, mut changed: NodeId, mut new_box: Aabb) -> f64 {
        let mut saving = 0.0;
        while let Some(a) = tree.node(changed).parent {
            let ancestor = tree.node(a);
            let fitted = ancestor.children().iter().fold(new_box, |b, &c| {
                if c == changed {
                    b
                } else {
                    b.union(&tree.node(c).bounds)
                }
            });
            if fitted == ancestor.bounds {
                break;
            }
            saving += self.weight(ancestor)
                * (ancestor.bounds.surface_area() as f64 - fitted.surface_area() as f64);
            (changed, new_box) = (a, fitted);
        }
        saving
    }

    /// How much `Σ w(n) SA(n)` grows when `item` is put at `placement` (as a node, or a
    /// triangle joining a leaf): the exact, `f64` form of
    /// the cost [`PlacementSearch::find_with`](super::placement::PlacementSearch::find_with)
    /// minimizes in `f32`.
    pub fn placement_increase(
        &self,
        tree: &BuildTree,
        placement: Placement,
        item: &PlacedItem,
    ) -> f64 {
        let area = |b: &Aabb| b.surface_area() as f64;
        let x = &item.bounds;
        let own_cost = item.own_cost as f64;
        let (direct, above) = match placement {
            Placement::Root => return own_cost,
            Placement::Pair(sibling) => {
                let n = tree.node(sibling);
                let pair = self.internal_weight(2) * area(&n.bounds.union(x));
                (pair + own_cost, n.parent)
            }
            Placement::AddChild(parent) => {
                let n = tree.node(parent);
                let grown = self.internal_weight(n.arity() + 1) * area(&n.bounds.union(x));
                (
                    grown - self.weight(n) * area(&n.bounds) + own_cost,
                    n.parent,
                )
            }
            Placement::AddToLeaf(leaf) => {
                let n = tree.node(leaf);
                let grown = self.leaf_weight(n.arity() + 1) * area(&n.bounds.union(x));
                (grown - self.weight(n) * area(&n.bounds), n.parent)
            }
        };
        // Every ancestor grows to include X, up to the first that already does.
        let mut increase = direct;
        let mut at = above;
        while let Some(a) = at {
            let n = tree.node(a);
            if n.bounds.contains(x) {
                break;
            }
            increase += self.weight(n) * (area(&n.bounds.union(x)) - area(&n.bounds));
            at = n.parent;
        }
        increase
    }
}
