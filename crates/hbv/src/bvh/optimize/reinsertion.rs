//! Insertion-based optimization (Bittner, Hapala & Havran 2013, "Fast insertion-based
//! optimization of bounding volume hierarchies", Computer Graphics Forum 32(1)): take nodes out
//! of a built tree and put each back where the tree cost grows least, found by the same
//! branch-and-bound search that builds trees by insertion ([`crate::bvh::placement`]).

use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

use crate::bvh::placement::{PlacedItem, PlacementRules, PlacementSearch};
use crate::bvh::tree::{BuildTree, NodeId};
use crate::bvh::TreeCost;

/// Fewest nodes a pass tries (see [`ReinsertionConfig::batch_fraction`]).
pub const MIN_BATCH: usize = 64;

/// Options of [`ReinsertionOptimizer`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReinsertionConfig {
    /// The cost lowered. Default: E\[X\] ([`TreeCost::ExpectedTests`]), under which a node may
    /// be put back as one more child of a node, as the insertion builder does. Under
    /// [`TreeCost::Sah`] a node is only put back paired with another (the moves of Bittner et
    /// al.), so no node gains children: the SAH charges `C_t` per node whatever its arity and
    /// would otherwise reward ever wider nodes.
    pub objective: TreeCost,
    /// Most passes. Default 100: with the default batch, every node is tried about once.
    pub max_passes: usize,
    /// Stop after the first pass that ends past this much time. Default: none.
    pub time_budget: Option<Duration>,
    /// Stop after a pass that lowers the cost by less than this fraction of it. Default 1e-4.
    pub min_gain: f64,
    /// Share of the tree's nodes taken out per pass, but at least [`MIN_BATCH`] nodes (all of
    /// a smaller tree), so that a pass of a small tree tries enough nodes for its gain to say
    /// whether the tree has converged. Default 0.01.
    pub batch_fraction: f64,
    /// Seed of the random choice of the nodes of each pass: the same seed, the same result.
    pub seed: u64,
}

impl Default for ReinsertionConfig {
    fn default() -> Self {
        Self {
            objective: TreeCost::ExpectedTests,
            max_passes: 100,
            time_budget: None,
            min_gain: 1e-4,
            batch_fraction: 0.01,
            seed: 0x5eed,
        }
    }
}

/// Why [`ReinsertionOptimizer::optimize`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// A pass gained less than [`ReinsertionConfig::min_gain`].
    Converged,
    /// [`ReinsertionConfig::max_passes`] passes were made.
    MaxPasses,
    /// [`ReinsertionConfig::time_budget`] ran out.
    TimeBudget,
    /// The tree has no node but the root.
    NothingToMove,
}

/// What [`ReinsertionOptimizer::optimize`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct ReinsertionReport {
    /// The objective before the first pass.
    pub cost_before: f64,
    /// The objective after each pass, as the exact change of each move adds up (equal to
    /// [`TreeCost::of`] up to the rounding of the sums); it never increases.
    pub pass_costs: Vec<f64>,
    /// The objective after the last pass, computed afresh.
    pub cost_after: f64,
    /// Nodes taken out and searched a place for.
    pub attempts: usize,
    /// Of those, the nodes put in a better place (the others went back where they were).
    pub moves: usize,
    pub elapsed: Duration,
    pub stop: StopReason,
}

/// Improves a built tree in place by moving subtrees, as Bittner, Hapala & Havran (2013) do;
/// works on any tree, of any arity and leaf size.
///
/// Each pass draws a batch of nodes and, one at a time, takes each out and puts it back where
/// the objective grows least:
///
/// ```text
///            G                        G                        G
///            |                        |                        |
///            P          take N        S         put N          S  ...  B'
///           / \          out         / \        back          / \     / \
///          N   S         ==>        .   .       ==>          .   .   B   N
///         / \                                                  (B' reuses P's node)
///        .   .        saving = removal_saving(N)      increase = placement_increase(B)
/// ```
///
/// - **Which nodes.** A node is drawn with probability proportional to its surface area (the
///   priority of Meister & Bittner 2018, and the simplest inefficiency measure of Bittner et
///   al.), without replacement, by the keys `ln(u) / SA` of Efraimidis & Spirakis (2006). Large
///   nodes carry the most cost and are tried most, but unlike taking the largest `k` each time
///   (the same nodes, already at their best, tried pass after pass) every node is tried now
///   and then. Measured on the shared scenes, sampling by area reached the same cost as
///   sampling by the exact saving of removal at half the time, and both beat the largest-`k`
///   rule, which stalls within a few passes.
/// - **Where to.** The node is detached (its subtree is then unreachable, so it is never put
///   inside itself) and [`PlacementSearch::find_with`] finds the cheapest place among all.
/// - **Whether.** The exact `f64` saving of the removal
///   ([`TreeCost::removal_saving`]) is weighed against the exact increase at the new place
///   ([`TreeCost::placement_increase`]); the node moves only when the cost falls by more than
///   a `1e-12` fraction of it, and otherwise goes back exactly where it was (same child
///   position, same boxes). So the cost falls with every move and never rises over a pass.
///
/// Boxes that are tight (as every builder makes them) stay tight: a removal refits, an insertion
/// grows to the union. So the root's box, the box of all the triangles, never changes, and the normalized costs E\[X\] and SAH fall
/// exactly as `Σ w SA` does. A pass costs O(n) to draw its batch plus about one root-to-leaf
/// search per node of the batch.
#[derive(Clone, Debug, Default)]
pub struct ReinsertionOptimizer {
    pub config: ReinsertionConfig,
}

/// Most triangles of a mesh whose tree [`ReinsertionOptimizer::pays_by_default`] optimizes: up to
/// here the optimizer costs about a millisecond (1.3 ms at 972 triangles, 3.5 ms at 1,932 on a
/// Zen 3 core, against 0.7 ms for the binned SAH build).
pub const OPTIMIZE_BY_DEFAULT_MAX_TRIANGLES: usize = 1024;

impl ReinsertionOptimizer {
    pub fn new(config: ReinsertionConfig) -> Self {
        Self { config }
    }

    /// Whether a tree over a mesh of `triangles` triangles is optimized when its user does not
    /// say (Python's `hbv.BVH(mesh)`): when the mesh has at most
    /// [`OPTIMIZE_BY_DEFAULT_MAX_TRIANGLES`], so that optimizing costs about a millisecond.
    ///
    /// Small meshes are where top-down builders go most wrong: modelled scenes of a few large
    /// triangles (a room's walls around its furniture), whose boxes span the scene. A
    /// centroid split puts each wall inside a subtree whose box it stretches over everything;
    /// reinsertion lifts it next to the root, where every ray tests it once. Measured on a
    /// Zen 3 core (BENCHMARKS.md, "Reinsertion by default on small meshes"): the Cornell box's random rays from 913 to 673
    /// instructions each and 1.0× to 1.4× embreex from Python; generated rooms of 8 to 300
    /// boxes 21–34 % fewer instructions; tessellated meshes (icospheres, a terrain, a triangle
    /// soup) within ±2 %. On larger scanned meshes the wide layouts gain nothing from it
    /// (spot, teapot, bunny within ±1 %) and it costs three to four times the build.
    pub fn pays_by_default(triangles: usize) -> bool {
        triangles <= OPTIMIZE_BY_DEFAULT_MAX_TRIANGLES
    }

    /// Optimizes `tree` in place, pass after pass until one of the stopping rules of
    /// [`ReinsertionConfig`] holds. The tree is [compacted](BuildTree::compact) first, so node
    /// ids from before do not name the same nodes after.
    pub fn optimize(&self, tree: &mut BuildTree) -> ReinsertionReport {
        let start = Instant::now();
        let config = &self.config;
        let objective = config.objective;
        let rules = PlacementRules {
            cost: objective,
            max_leaf_size: 1,
            may_add_child: matches!(objective, TreeCost::ExpectedTests),
        };
        let cost_before = objective.of(tree);
        let mut report = ReinsertionReport {
            cost_before,
            pass_costs: Vec::new(),
            cost_after: cost_before,
            attempts: 0,
            moves: 0,
            elapsed: Duration::ZERO,
            stop: StopReason::MaxPasses,
        };
        // Nodes in depth-first order make the walks of the passes read memory in order.
        tree.compact();
        let root_area = |tree: &BuildTree| {
            tree.root()
                .map_or(0.0, |r| tree.node(r).bounds.surface_area() as f64)
        };
        // The moves are weighed in `Σ w SA`, the normalized cost times SA(root).
        let mut weighted_area = cost_before * root_area(tree);
        let mut search = PlacementSearch::new();
        let mut rng = Pcg64Mcg::seed_from_u64(config.seed);
        let mut cost = cost_before;
        for _ in 0..config.max_passes {
            let batch = self.draw_batch(tree, &mut rng);
            if batch.is_empty() {
                report.stop = StopReason::NothingToMove;
                break;
            }
            let min_move_gain = 1e-12 * weighted_area;
            for node in batch {
                if let Some((moved, gain)) =
                    try_move(tree, node, &rules, &mut search, min_move_gain)
                {
                    report.attempts += 1;
                    report.moves += usize::from(moved);
                    weighted_area -= gain;
                }
            }
            let after = weighted_area / root_area(tree).max(f64::MIN_POSITIVE);
            report.pass_costs.push(after);
            let gain = (cost - after) / cost.max(f64::MIN_POSITIVE);
            cost = after;
            if gain < config.min_gain {
                report.stop = StopReason::Converged;
                break;
            }
            if config.time_budget.is_some_and(|t| start.elapsed() >= t) {
                report.stop = StopReason::TimeBudget;
                break;
            }
        }
        report.cost_after = objective.of(tree);
        report.elapsed = start.elapsed();
        report
    }

    /// The nodes of one pass: `batch_fraction` of the nodes below the root (at least
    /// [`MIN_BATCH`]),
    /// drawn without replacement with probability proportional to surface area, in the order
    /// drawn (largest key first).
    ///
    /// The tree must have been compacted before the first pass: the arena then holds only the
    /// tree and the nodes released since, and the nodes below the root are exactly those with a
    /// parent, read in arena order without walking the tree.
    fn draw_batch(&self, tree: &BuildTree, rng: &mut Pcg64Mcg) -> Vec<NodeId> {
        // Efraimidis–Spirakis: the k largest keys ln(u) / w are a weighted sample of k.
        let mut keyed: Vec<(f64, NodeId)> = Vec::with_capacity(tree.nodes().len());
        for (id, node) in tree.nodes().iter().enumerate() {
            if node.parent.is_none() {
                continue;
            }
            let area = node.bounds.surface_area() as f64;
            let u = rng.random::<f64>().max(f64::MIN_POSITIVE);
            let key = if area > 0.0 {
                u.ln() / area
            } else {
                f64::NEG_INFINITY
            };
            keyed.push((key, id as NodeId));
        }
        if keyed.is_empty() {
            return Vec::new();
        }
        let k = ((keyed.len() as f64 * self.config.batch_fraction).ceil() as usize)
            .max(MIN_BATCH)
            .min(keyed.len());
        let largest_first = |a: &(f64, NodeId), b: &(f64, NodeId)| b.0.total_cmp(&a.0);
        if k < keyed.len() {
            keyed.select_nth_unstable_by(k - 1, largest_first);
            keyed.truncate(k);
        }
        keyed.sort_unstable_by(largest_first);
        keyed.into_iter().map(|(_, id)| id).collect()
    }
}

/// Takes `node` out of `tree` and puts it where `rules.cost` grows least, when that lowers the
/// cost by more than `min_gain`, or else back where it was. Returns whether it moved and how
/// much `Σ w SA` fell, or `None` when the node has no parent (it is the root, or an earlier
/// move of the pass released it).
fn try_move(
    tree: &mut BuildTree,
    node: NodeId,
    rules: &PlacementRules,
    search: &mut PlacementSearch,
    min_gain: f64,
) -> Option<(bool, f64)> {
    let parent = tree.node(node).parent?;
    let only_child = tree.node(parent).arity() == 1;
    let saving = rules.cost.removal_saving(tree, node);
    let former = tree.detach(node);
    // The subtree's own cost does not depend on where it goes: `own_cost` is 0.
    let item = PlacedItem {
        bounds: tree.node(node).bounds,
        own_cost: 0.0,
        may_join_leaf: false,
    };
    let (placement, _) = search.find_with(tree, &item, rules);
    let increase = rules.cost.placement_increase(tree, placement, &item);
    if saving - increase > min_gain {
        tree.attach_node(placement, node);
        return Some((true, saving - increase));
    }
    // Back where it was: the tree is as before, but for a parent of which it was the only
    // child, which is gone.
    let gain = if only_child {
        saving
            - rules
                .cost
                .placement_increase(tree, former.placement(), &item)
    } else {
        0.0
    };
    tree.reattach(former, node);
    Some((false, gain))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{
        primitive_bounds, Builder, InsertionBuilder, InsertionConfig, InsertionOrder,
    };
    use crate::bvh::cost::SahWeights;
    use crate::mesh::procedural::{icosphere, torus};
    use crate::TriangleMesh;
    use glam::Vec3;

    fn input_order_tree(mesh: &TriangleMesh, max_leaf_size: usize) -> BuildTree {
        InsertionBuilder::new(InsertionConfig {
            order: InsertionOrder::Input,
            max_leaf_size,
        })
        .build(mesh)
    }

    #[test]
    fn lowers_the_cost_and_keeps_the_tree_valid() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.5, 32, 16);
        let bounds = primitive_bounds(&mesh);
        for max_leaf_size in [1, 3] {
            for objective in [
                TreeCost::ExpectedTests,
                TreeCost::Sah(SahWeights::default()),
            ] {
                let mut tree = input_order_tree(&mesh, max_leaf_size);
                let report = ReinsertionOptimizer::new(ReinsertionConfig {
                    objective,
                    ..Default::default()
                })
                .optimize(&mut tree);
                tree.validate(&bounds, max_leaf_size).unwrap();
                assert!(report.moves > 0 && report.attempts >= report.moves);
                // Pairing moves only, on an n-ary tree, leave the SAH objective less to gain.
                let target = match objective {
                    TreeCost::ExpectedTests => 0.9,
                    TreeCost::Sah(_) => 0.98,
                };
                assert!(
                    report.cost_after < target * report.cost_before,
                    "{objective:?}, leaf {max_leaf_size}: {report:?}"
                );
                assert_eq!(report.cost_after, objective.of(&tree));
            }
        }
    }

    #[test]
    fn sah_objective_keeps_nodes_as_wide_as_they_were() {
        // A binary tree stays binary: the SAH moves only pair nodes.
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let mut tree = input_order_tree(&mesh, 1);
        let widest = |t: &BuildTree| t.shape().arity_histogram.len() - 1;
        let before = widest(&tree);
        ReinsertionOptimizer::new(ReinsertionConfig {
            objective: TreeCost::Sah(SahWeights::default()),
            ..Default::default()
        })
        .optimize(&mut tree);
        assert!(widest(&tree) <= before);
    }

    #[test]
    fn same_seed_same_tree_and_budgets_stop_it() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let run = |config: ReinsertionConfig| {
            let mut tree = input_order_tree(&mesh, 1);
            let report = ReinsertionOptimizer::new(config).optimize(&mut tree);
            (tree, report)
        };
        let (a, ra) = run(ReinsertionConfig::default());
        let (b, rb) = run(ReinsertionConfig::default());
        assert_eq!(a, b);
        assert_eq!(ra.pass_costs, rb.pass_costs);

        let (_, r) = run(ReinsertionConfig {
            max_passes: 2,
            min_gain: 0.0,
            ..Default::default()
        });
        assert_eq!((r.pass_costs.len(), r.stop), (2, StopReason::MaxPasses));
        let (_, r) = run(ReinsertionConfig {
            time_budget: Some(Duration::ZERO),
            min_gain: 0.0,
            ..Default::default()
        });
        assert_eq!((r.pass_costs.len(), r.stop), (1, StopReason::TimeBudget));
    }

    #[test]
    fn tiny_trees() {
        let mut empty = BuildTree::new();
        let report = ReinsertionOptimizer::default().optimize(&mut empty);
        assert_eq!(report.stop, StopReason::NothingToMove);
        assert!(empty.is_empty());

        // Two triangles: the only nodes below the root are its two leaves, and no move helps.
        let mesh = TriangleMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            vec![[0, 1, 2], [0, 1, 3]],
        )
        .unwrap();
        let mut tree = input_order_tree(&mesh, 1);
        let mut before = tree.clone();
        let report = ReinsertionOptimizer::default().optimize(&mut tree);
        assert_eq!(report.moves, 0);
        // The same tree, renumbered in depth-first order.
        before.compact();
        assert_eq!(tree, before);
    }
}
