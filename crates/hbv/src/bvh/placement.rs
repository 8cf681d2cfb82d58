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
//!
//! # Other costs of the same form
//!
//! Nothing above depends on `a_n` being a count: any tree cost `Σ_n w(n) · SA(n)` with a weight
//! `w` per node works, with `w` in place of `a` on the path, `w(pair of two)` in place of 2 in
//! (1), the growth of `w` by one more child in place of the `SA(N')` of (2) and by one more
//! triangle in place of that of (3). [`TreeCost`] names the two weights of this crate: E\[X\]'s
//! `a_n`, and the SAH's `C_t` per internal node and `C_i` per triangle. [`PlacementRules`]
//! chooses the cost and which candidates are offered.
//!
use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::tree::{BuildTree, NodeContent, NodeId};
use super::tree_cost::TreeCost;
use crate::geometry::Aabb;

/// The rules of a placement search: the cost it minimizes and the candidates it may choose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacementRules {
    /// The cost whose increase is minimized. Default: E\[X\].
    pub cost: TreeCost,
    /// Most triangles a leaf may hold, bounding [`Placement::AddToLeaf`]. Default 1.
    pub max_leaf_size: usize,
    /// Whether [`Placement::AddChild`] is a candidate. Default true. Under the SAH cost a node
    /// pays `C_t` whatever its arity, so a new child costs only the growth of the box: leave it
    /// out to keep the tree's arity (a node then never gains children).
    pub may_add_child: bool,
}

impl Default for PlacementRules {
    fn default() -> Self {
        Self {
            cost: TreeCost::ExpectedTests,
            max_leaf_size: 1,
            may_add_child: true,
        }
    }
}

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

/// What one search looks for: the item and the rules.
struct Query<'a> {
    item: &'a PlacedItem,
    rules: &'a PlacementRules,
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

    /// The placement of `item` that increases `Σ a_n SA(n)` least, and that increase: the
    /// search of the insertion builder, [`PlacementSearch::find_with`] under the default rules.
    ///
    /// `max_leaf_size` bounds [`Placement::AddToLeaf`]. Ties go to the first candidate found.
    pub fn find(
        &mut self,
        tree: &BuildTree,
        item: &PlacedItem,
        max_leaf_size: usize,
    ) -> (Placement, f32) {
        let rules = PlacementRules {
            max_leaf_size,
            ..PlacementRules::default()
        };
        self.find_with(tree, item, &rules)
    }

    /// The placement of `item` that increases `rules.cost` (as `Σ w(n) SA(n)`) least among the
    /// candidates `rules` offers, and that increase, computed in `f32`. Ties go to the first
    /// candidate found.
    pub fn find_with(
        &mut self,
        tree: &BuildTree,
        item: &PlacedItem,
        rules: &PlacementRules,
    ) -> (Placement, f32) {
        let Some(root) = tree.root() else {
            return (Placement::Root, item.own_cost);
        };
        let x = &item.bounds;
        let cost = &rules.cost;
        let query = Query { item, rules };
        // The weight a placement adds: of a new pair node, of one more child, of one more
        // triangle (2, 1 and 1 for E[X]).
        let pair_weight = cost.internal_weight(2) as f32;
        let child_weight = (cost.internal_weight(3) - cost.internal_weight(2)) as f32;
        let prim_weight = cost.leaf_weight(1) as f32;
        // Lower bound of any placement inside a node, above its descent cost: the cheapest
        // candidate's own terms with SA(D') >= SA(X).
        let x_area = x.surface_area();
        let mut tail_bound = pair_weight * x_area + item.own_cost;
        if rules.may_add_child {
            tail_bound = tail_bound.min(child_weight * x_area + item.own_cost);
        }
        if item.may_join_leaf && rules.max_leaf_size > 1 {
            tail_bound = tail_bound.min(prim_weight * x_area);
        }

        let mut best = (
            Placement::Pair(root),
            pair_weight * tree.node(root).bounds.union(x).surface_area() + item.own_cost,
        );
        self.queue.clear();
        self.push_if_open(tree, &query, root, 0.0, best.1 - tail_bound);

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
                    let cost = descent_cost + prim_weight * grown_area;
                    if cost < best.1 {
                        best = (Placement::AddToLeaf(node), cost);
                    }
                }
                NodeContent::Internal(children) => {
                    if rules.may_add_child {
                        let cost = descent_cost + child_weight * grown_area + item.own_cost;
                        if cost < best.1 {
                            best = (Placement::AddChild(node), cost);
                        }
                    }
                    for &c in children {
                        let child_grown = tree.node(c).bounds.union(x).surface_area();
                        let pair = descent_cost + pair_weight * child_grown + item.own_cost;
                        if pair < best.1 {
                            best = (Placement::Pair(c), pair);
                        }
                        self.push_if_open(tree, &query, c, descent_cost, best.1 - tail_bound);
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
        query: &Query,
        node: NodeId,
        inherited: f32,
        limit: f32,
    ) {
        let n = tree.node(node);
        let open = match &n.content {
            NodeContent::Internal(_) => true,
            NodeContent::Leaf(prims) => {
                query.item.may_join_leaf && prims.len() < query.rules.max_leaf_size
            }
        };
        if !open {
            return;
        }
        let x = &query.item.bounds;
        let enlargement = n.bounds.union(x).surface_area() - n.bounds.surface_area();
        let descent_cost = inherited + query.rules.cost.weight(n) as f32 * enlargement;
        if descent_cost < limit {
            self.queue.push(Pending { node, descent_cost });
        }
    }
}

#[cfg(test)]
mod tests {
    //! The placement machinery as a whole: the search, the cost changes it relies on
    //! (`tree_cost`) and the edits that carry placements out (`tree_edits`).
    use super::*;
    use crate::bvh::build::{
        primitive_bounds, Builder, InsertionBuilder, InsertionConfig, InsertionOrder,
    };
    use crate::bvh::cost::SahWeights;
    use crate::bvh::tree_edits::FormerPlace;
    use crate::mesh::procedural::{default_scene, torus};
    use glam::Vec3;

    fn sah() -> TreeCost {
        TreeCost::Sah(SahWeights {
            traversal: 1.5,
            intersection: 0.7,
        })
    }

    /// `Σ w(n) SA(n)` over the nodes reachable from `from` (the root when `None`).
    fn raw_cost(tree: &BuildTree, cost: &TreeCost, from: Option<NodeId>) -> f64 {
        let mut sum = 0.0;
        let mut stack: Vec<NodeId> = from.or(tree.root()).into_iter().collect();
        while let Some(id) = stack.pop() {
            let n = tree.node(id);
            sum += cost.weight(n) * n.bounds.surface_area() as f64;
            stack.extend_from_slice(n.children());
        }
        sum
    }

    fn trees() -> Vec<(BuildTree, usize)> {
        let meshes = [torus(Vec3::ZERO, 2.0, 0.5, 16, 8), default_scene(1)];
        let mut trees = Vec::new();
        for mesh in &meshes {
            for (order, leaf) in [
                (InsertionOrder::Input, 1),
                (InsertionOrder::Shuffle { seed: 5 }, 3),
            ] {
                let tree = InsertionBuilder::new(InsertionConfig {
                    order,
                    max_leaf_size: leaf,
                })
                .build(mesh);
                trees.push((tree, leaf));
            }
        }
        trees
    }

    fn close(a: f64, b: f64, scale: f64) -> bool {
        (a - b).abs() <= 1e-9 * scale
    }

    #[test]
    fn default_rules_are_the_builders() {
        let (tree, _) = &trees()[0];
        let item = PlacedItem {
            bounds: Aabb::new(Vec3::splat(0.1), Vec3::splat(0.2)),
            own_cost: 0.06,
            may_join_leaf: true,
        };
        let rules = PlacementRules {
            max_leaf_size: 4,
            ..PlacementRules::default()
        };
        let mut search = PlacementSearch::new();
        assert_eq!(
            search.find(tree, &item, 4),
            search.find_with(tree, &item, &rules)
        );
    }

    #[test]
    fn removal_saving_and_placement_increase_are_exact() {
        for (tree, _) in trees() {
            for cost in [TreeCost::ExpectedTests, sah()] {
                let rules = PlacementRules {
                    cost,
                    max_leaf_size: 1,
                    may_add_child: cost == TreeCost::ExpectedTests,
                };
                let mut tree = tree.clone();
                let mut search = PlacementSearch::new();
                let total = raw_cost(&tree, &cost, None);
                for node in (1..tree.nodes().len() as NodeId).step_by(7) {
                    if tree.node(node).parent.is_none() {
                        continue;
                    }
                    let before = raw_cost(&tree, &cost, None);
                    let own = raw_cost(&tree, &cost, Some(node));
                    let saving = cost.removal_saving(&tree, node);
                    tree.detach(node);
                    let detached = raw_cost(&tree, &cost, None) + own;
                    assert!(close(before - detached, saving, total), "node {node}");

                    let item = PlacedItem {
                        bounds: tree.node(node).bounds,
                        own_cost: 0.0,
                        may_join_leaf: false,
                    };
                    let (placement, approx) = search.find_with(&tree, &item, &rules);
                    let increase = cost.placement_increase(&tree, placement, &item);
                    assert!((approx as f64 - increase).abs() <= 1e-4 * total);
                    tree.attach_node(placement, node);
                    let attached = raw_cost(&tree, &cost, None);
                    assert!(close(attached - detached, increase, total), "node {node}");
                }
            }
        }
    }

    #[test]
    fn the_search_finds_the_cheapest_of_all_candidates() {
        for (tree, leaf) in trees() {
            for cost in [TreeCost::ExpectedTests, sah()] {
                for may_add_child in [true, false] {
                    let rules = PlacementRules {
                        cost,
                        max_leaf_size: leaf,
                        may_add_child,
                    };
                    let total = raw_cost(&tree, &cost, None);
                    let mut search = PlacementSearch::new();
                    for k in 0..20 {
                        let c = Vec3::new(k as f32 * 0.37 - 3.0, (k % 5) as f32 * 0.6 - 1.0, 0.2);
                        let b = Aabb::new(c, c + Vec3::splat(0.05 + 0.03 * k as f32));
                        let item = PlacedItem {
                            bounds: b,
                            own_cost: cost.leaf_weight(1) as f32 * b.surface_area(),
                            may_join_leaf: k % 2 == 0,
                        };
                        let (found, _) = search.find_with(&tree, &item, &rules);
                        let found = cost.placement_increase(&tree, found, &item);
                        let mut cheapest = f64::INFINITY;
                        tree.walk(|id, _| {
                            let n = tree.node(id);
                            let mut candidates = vec![Placement::Pair(id)];
                            if !n.is_leaf() && may_add_child {
                                candidates.push(Placement::AddChild(id));
                            }
                            if n.is_leaf() && item.may_join_leaf && n.arity() < leaf {
                                candidates.push(Placement::AddToLeaf(id));
                            }
                            for p in candidates {
                                cheapest = cheapest.min(cost.placement_increase(&tree, p, &item));
                            }
                        });
                        assert!(
                            found <= cheapest + 1e-6 * total,
                            "{cost:?}: found {found}, cheapest {cheapest}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn detach_then_reattach_restores_the_tree_exactly() {
        for (tree, leaf) in trees() {
            let mut work = tree.clone();
            for node in 0..tree.nodes().len() as NodeId {
                let former = work.detach(node);
                work.reattach(former, node);
                assert_eq!(work, tree, "node {node}, leaf {leaf}");
            }
        }
    }

    #[test]
    fn detach_splices_out_parents_left_with_one_child_or_none() {
        // root [P, b], P [a]: taking `a` out empties P, which goes, and then root is left with
        // `b` alone, which takes its place.
        let cube = |lo: f32| Aabb::new(Vec3::splat(lo), Vec3::splat(lo + 1.0));
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0));
        let b = t.push_leaf(vec![1], cube(3.0));
        let p = t.push_internal(vec![a]);
        let root = t.push_internal(vec![p, b]);
        t.set_root(Some(root));
        let cost = TreeCost::ExpectedTests;
        let before = raw_cost(&t, &cost, None);
        let saving = cost.removal_saving(&t, a);
        assert_eq!(
            t.detach(a),
            FormerPlace::PairedWith {
                sibling: b,
                index: 0
            }
        );
        assert_eq!(t.root(), Some(b));
        assert_eq!(t.released_count(), 2);
        assert!(close(
            before - raw_cost(&t, &cost, None) - 6.0,
            saving,
            before
        ));
        t.reattach(
            FormerPlace::PairedWith {
                sibling: b,
                index: 0,
            },
            a,
        );
        t.validate(&[cube(0.0), cube(3.0)], 1).unwrap();
        let r = t.node(t.root().unwrap());
        assert_eq!(r.children(), &[a, b]);
        assert!(raw_cost(&t, &cost, None) < before);
    }

    #[test]
    fn detached_and_moved_trees_stay_valid() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.5, 16, 8);
        let prim_bounds = primitive_bounds(&mesh);
        for (order, leaf) in [(InsertionOrder::Morton, 1), (InsertionOrder::Input, 4)] {
            let mut tree = InsertionBuilder::new(InsertionConfig {
                order,
                max_leaf_size: leaf,
            })
            .build(&mesh);
            let mut search = PlacementSearch::new();
            for node in (0..tree.nodes().len() as NodeId).rev().step_by(3) {
                if tree.node(node).parent.is_none() {
                    continue;
                }
                tree.detach(node);
                let item = PlacedItem {
                    bounds: tree.node(node).bounds,
                    own_cost: 0.0,
                    may_join_leaf: false,
                };
                let (placement, _) = search.find(&tree, &item, leaf);
                tree.attach_node(placement, node);
                tree.validate(&prim_bounds, leaf).unwrap();
            }
        }
    }
}
