//! Where to put a new box in a tree so that the tree cost E\[X\] grows least: the search at the
//! heart of incremental construction (Goldsmith & Salmon 1987), and of insertion-based
//! optimization (Bittner, Hapala & Havran 2013), which takes subtrees out and puts them back.
//!
//! # The cost of a placement
//!
//! A box `X` (area `x = SA(X)`) is to be added. For a node `N` write `N' = N ∪ X` and
//! `enl(N) = SA(N') − SA(N)`. Every ancestor of the place where `X` lands grows to include `X`,
//! and each of its `a` children is then tested by more lines: along the path
//! `root = A₀, A₁, …, A_k = N`, the cost **inherited** by `N` is
//!
//! ```text
//!   inh(N) = Σ_{i<k} a(A_i) · enl(A_i)
//! ```
//!
//! The candidates at a node `N`, each with its increase of `Σ a_n SA(n)` (E\[X\] times SA(root)):
//!
//! ```text
//!  (1) pair: a new node K = {N, X} in N's place      (2) add child: X joins internal N
//!
//!        P                 P'                             N                N'
//!       / \               /  \                          / | \    ==>    / | \ \
//!      N   .     ==>     K    .                        .  .  .         .  .  . X
//!                       / \
//!                      N   X                          Δ = inh(N) + a(N)·enl(N) + SA(N') + c_X
//!
//!      Δ = inh(N) + 2·SA(N') + c_X
//!
//!  (3) add to leaf: X's triangle joins leaf N (when the leaf has room)
//!
//!      Δ = inh(N) + a(N)·enl(N) + SA(N')
//! ```
//!
//! `c_X` is the cost of `X`'s own node: `SA(X)` for a new leaf of one triangle (tested when its
//! parent is reached... its one triangle is tested when it is), and 0 when `X` is a subtree being
//! reinserted (its internal cost does not depend on where it goes).
//!
//! # Branch and bound
//!
//! Costs only grow on the way down: for any place at or below a child `D` of `N`, the cost is at
//! least `inh(D) + x` (+ `c_X` when no leaf has room), since `SA(D') ≥ x` and `inh(D) =
//! inh(N) + a(N)·enl(N)`. The search keeps the nodes still to descend into in a priority queue
//! ordered by that bound and stops when the smallest bound is no better than the best candidate
//! found: it follows the cheapest path down, and opens a second path only where one could still
//! win. On typical scenes it visits a few nodes per level: about one root-to-leaf path, so
//! building by insertion is O(n log n). Unlike a greedy descent, the result is the exact
//! minimum over every candidate in the tree.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::tree::{BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;

/// Where a new box goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Into the empty tree, as its root.
    Root,
    /// Paired with this node under a new internal node that takes its place.
    Pair(NodeId),
    /// As a new child of this internal node.
    AddChild(NodeId),
    /// Into this leaf, which has room for another triangle.
    AddToLeaf(NodeId),
}

/// What is being placed.
#[derive(Clone, Copy, Debug)]
pub struct PlacedItem {
    /// Its box.
    pub bounds: Aabb,
    /// `c_X`: the cost of its own node, paid by every placement except [`Placement::AddToLeaf`].
    pub own_cost: f32,
    /// Whether it may join a leaf (a single triangle may; a subtree may not).
    pub may_join_leaf: bool,
}

/// The branch-and-bound placement search, with its queue kept between calls to avoid allocation.
#[derive(Default)]
pub struct PlacementSearch {
    queue: BinaryHeap<Pending>,
    /// Candidate nodes whose cost was evaluated, over all searches: the work of the search,
    /// reported to show that it grows like log n per insertion.
    evaluated: u64,
}

/// A node still to descend into, and the cost inherited by its children.
struct Pending {
    node: NodeId,
    /// `inh(node) + a(node) · enl(node)`: what any placement strictly inside `node` pays above it.
    descent_cost: f32,
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        self.descent_cost.total_cmp(&other.descent_cost) == Ordering::Equal
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    /// Reversed, so that `BinaryHeap` pops the smallest cost first.
    fn cmp(&self, other: &Self) -> Ordering {
        other.descent_cost.total_cmp(&self.descent_cost)
    }
}

impl PlacementSearch {
    pub fn new() -> Self {
        Self::default()
    }

    /// Nodes evaluated by all searches so far.
    pub fn evaluated(&self) -> u64 {
        self.evaluated
    }

    /// The placement of `item` that increases `Σ a_n SA(n)` least, and that increase.
    ///
    /// `max_leaf_size` bounds [`Placement::AddToLeaf`]. Ties go to the first candidate found.
    pub fn find(
        &mut self,
        tree: &BuildTree,
        item: &PlacedItem,
        max_leaf_size: usize,
    ) -> (Placement, f32) {
        let Some(root) = tree.root() else {
            return (Placement::Root, item.own_cost);
        };
        let x = &item.bounds;
        let leaf_has_room = |prims: &Vec<u32>| item.may_join_leaf && prims.len() < max_leaf_size;
        // Lower bound of any placement inside a node, above its descent cost: SA(D') >= SA(X),
        // plus the new node's cost unless it may join a leaf.
        let tail_bound = x.surface_area()
            + if item.may_join_leaf && max_leaf_size > 1 {
                0.0
            } else {
                item.own_cost
            };

        let mut best = (
            Placement::Pair(root),
            2.0 * tree.node(root).bounds.union(x).surface_area() + item.own_cost,
        );
        self.queue.clear();
        self.push_if_open(tree, root, 0.0, x, &leaf_has_room, best.1 - tail_bound);

        while let Some(Pending { node, descent_cost }) = self.queue.pop() {
            if descent_cost + tail_bound >= best.1 {
                break;
            }
            let n = tree.node(node);
            self.evaluated += 1 + n.children().len() as u64;
            let grown_area = n.bounds.union(x).surface_area();
            match &n.content {
                NodeContent::Leaf(_) => {
                    // Queued only when it has room.
                    let cost = descent_cost + grown_area;
                    if cost < best.1 {
                        best = (Placement::AddToLeaf(node), cost);
                    }
                }
                NodeContent::Internal(children) => {
                    let cost = descent_cost + grown_area + item.own_cost;
                    if cost < best.1 {
                        best = (Placement::AddChild(node), cost);
                    }
                    for &c in children {
                        let child_grown = tree.node(c).bounds.union(x).surface_area();
                        let pair = descent_cost + 2.0 * child_grown + item.own_cost;
                        if pair < best.1 {
                            best = (Placement::Pair(c), pair);
                        }
                        self.push_if_open(
                            tree,
                            c,
                            descent_cost,
                            x,
                            &leaf_has_room,
                            best.1 - tail_bound,
                        );
                    }
                }
            }
        }
        best
    }

    /// Queues `node` for descent when something inside it could still cost less than `limit`
    /// (the best cost so far minus the tail bound).
    fn push_if_open(
        &mut self,
        tree: &BuildTree,
        node: NodeId,
        inherited: f32,
        x: &Aabb,
        leaf_has_room: &impl Fn(&Vec<u32>) -> bool,
        limit: f32,
    ) {
        let n = tree.node(node);
        let open = match &n.content {
            NodeContent::Internal(_) => true,
            NodeContent::Leaf(prims) => leaf_has_room(prims),
        };
        if !open {
            return;
        }
        let enlargement = n.bounds.union(x).surface_area() - n.bounds.surface_area();
        let descent_cost = inherited + n.arity() as f32 * enlargement;
        if descent_cost < limit {
            self.queue.push(Pending { node, descent_cost });
        }
    }
}

impl BuildTree {
    /// Adds triangle `prim` with box `bounds` at `placement`: into the leaf it names, or in a
    /// new leaf of its own. Returns the leaf that holds it.
    pub(crate) fn attach_prim(&mut self, placement: Placement, prim: u32, bounds: Aabb) -> NodeId {
        if let Placement::AddToLeaf(leaf) = placement {
            if let NodeContent::Leaf(prims) = &mut self.node_mut(leaf).content {
                prims.push(prim);
            }
            self.grow_from(leaf, &bounds);
            return leaf;
        }
        let leaf = self.push_leaf(vec![prim], bounds);
        self.attach_node(placement, leaf);
        leaf
    }

    /// Puts node `item` (in the arena, detached) at `placement`, growing the boxes of its new
    /// ancestors. `placement` is never [`Placement::AddToLeaf`] (a node does not join a leaf).
    pub(crate) fn attach_node(&mut self, placement: Placement, item: NodeId) {
        let bounds = self.node(item).bounds;
        match placement {
            Placement::Root => self.set_root(Some(item)),
            Placement::Pair(sibling) => {
                let parent = self.node(sibling).parent;
                let pair = self.push_internal(vec![sibling, item]);
                match parent {
                    None => self.set_root(Some(pair)),
                    Some(p) => {
                        self.replace_child(p, sibling, pair);
                        self.grow_from(p, &bounds);
                    }
                }
            }
            Placement::AddChild(parent) => {
                if let NodeContent::Internal(children) = &mut self.node_mut(parent).content {
                    children.push(item);
                }
                self.node_mut(item).parent = Some(parent);
                self.grow_from(parent, &bounds);
            }
            Placement::AddToLeaf(_) => unreachable!("a node never joins a leaf"),
        }
    }

    /// Replaces `old` by `new` in `parent`'s children and makes `parent` the parent of `new`.
    fn replace_child(&mut self, parent: NodeId, old: NodeId, new: NodeId) {
        if let NodeContent::Internal(children) = &mut self.node_mut(parent).content {
            if let Some(slot) = children.iter_mut().find(|c| **c == old) {
                *slot = new;
            }
        }
        self.node_mut(new).parent = Some(parent);
    }

    /// Grows `node` and its ancestors to contain `bounds`, stopping at the first that does.
    fn grow_from(&mut self, node: NodeId, bounds: &Aabb) {
        let mut at = Some(node);
        while let Some(id) = at {
            let n = self.node_mut(id);
            if n.bounds.contains(bounds) {
                break;
            }
            n.bounds = n.bounds.union(bounds);
            at = n.parent;
        }
    }
}
