//! Leaf collapse: replace each subtree by one leaf of its triangles wherever that lowers the SAH
//! cost, the bottom-up pass that turns a tree of one-triangle leaves into a tree of SAH-sized
//! leaves. The rule is the leaf-or-node choice of Karras & Aila 2013 ("Fast parallel
//! construction of high-quality bounding volume hierarchies", HPG), which takes for each node
//! `min(C_i · n · SA, C_t · SA + cost of the children)`.

use crate::bvh::cost::SahWeights;
use crate::bvh::tree::{BuildTree, NodeContent, NodeId};

/// Options of [`collapse_leaves`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollapseConfig {
    /// Most triangles a collapsed leaf may hold. Default 8, as the top-down SAH builders.
    /// Leaves that already hold more are left as they are (a leaf is never split).
    pub max_leaf_size: usize,
    /// `C_t` and `C_i` of the SAH cost the collapse lowers. Default 1 and 1.
    pub sah: SahWeights,
}

impl Default for CollapseConfig {
    fn default() -> Self {
        Self {
            max_leaf_size: 8,
            sah: SahWeights::default(),
        }
    }
}

/// What a node of the tree would cost at best, as the bottom-up pass finds it.
#[derive(Clone, Copy, Default)]
struct Best {
    /// Triangles below the node, counted up to `max_leaf_size + 1` (more is "too many").
    prims: usize,
    /// `Σ w(n) SA(n)` of the cheapest subtree: as it is, with its children at their best, or
    /// one leaf.
    cost: f64,
    /// Whether the cheapest subtree is one leaf.
    collapse: bool,
}

/// Replaces subtrees of `tree` by single leaves where that lowers the SAH cost
/// ([`sah_cost`](crate::bvh::sah_cost) with `config.sah`), and returns how many subtrees were
/// replaced.
///
/// Bottom up, each internal node `N` over `n ≤ max_leaf_size` triangles is made a leaf when
///
/// ```text
///   C_i · n · SA(N)  ≤  C_t · SA(N) + Σ_children best(c)
/// ```
///
/// where `best(c)` is the cost (`Σ w SA` over the subtree) of child `c` after the same choice
/// below it; ties collapse, for the smaller tree. Because every node compares its leaf cost with
/// its children at their best, the result is the cheapest tree among all that collapsing
/// subtrees of `tree` can make. O(nodes).
///
/// The removed nodes are released to the arena (see [`BuildTree::compact`]); the tree keeps
/// every invariant of [`BuildTree::validate`] with leaves of at most
/// `max(max_leaf_size, largest leaf of the input)` triangles.
pub fn collapse_leaves(tree: &mut BuildTree, config: &CollapseConfig) -> usize {
    let Some(root) = tree.root() else {
        return 0;
    };
    let best = best_subtrees(tree, config);
    // Top down: collapse the highest node of each collapsing subtree.
    let mut collapsed = 0;
    let mut stack = vec![root];
    while let Some(id) = stack.pop() {
        if tree.node(id).is_leaf() {
            continue;
        }
        if best[id as usize].collapse {
            collapse_into_leaf(tree, id);
            collapsed += 1;
        } else {
            stack.extend_from_slice(tree.node(id).children());
        }
    }
    collapsed
}

/// [`Best`] of every node reachable from the root, indexed by node id: children before parents.
fn best_subtrees(tree: &BuildTree, config: &CollapseConfig) -> Vec<Best> {
    let too_many = config.max_leaf_size + 1;
    let SahWeights {
        traversal,
        intersection,
    } = config.sah;
    let mut parents_first = Vec::new();
    tree.walk(|id, _| parents_first.push(id));
    let mut best = vec![Best::default(); tree.nodes().len()];
    for &id in parents_first.iter().rev() {
        let node = tree.node(id);
        let area = node.bounds.surface_area() as f64;
        best[id as usize] = match &node.content {
            NodeContent::Leaf(prims) => Best {
                prims: prims.len().min(too_many),
                cost: intersection * prims.len() as f64 * area,
                collapse: false,
            },
            NodeContent::Internal(children) => {
                let prims = children
                    .iter()
                    .map(|&c| best[c as usize].prims)
                    .sum::<usize>()
                    .min(too_many);
                let as_is =
                    traversal * area + children.iter().map(|&c| best[c as usize].cost).sum::<f64>();
                let as_leaf = intersection * prims as f64 * area;
                let collapse = prims < too_many && as_leaf <= as_is;
                Best {
                    prims,
                    cost: if collapse { as_leaf } else { as_is },
                    collapse,
                }
            }
        };
    }
    best
}

/// Makes internal node `id` a leaf holding every triangle below it (in depth-first order),
/// keeping its box, and releases the nodes below it.
fn collapse_into_leaf(tree: &mut BuildTree, id: NodeId) {
    let mut prims = Vec::new();
    let mut stack: Vec<NodeId> = tree.node(id).children().iter().rev().copied().collect();
    while let Some(n) = stack.pop() {
        match &tree.node(n).content {
            NodeContent::Leaf(p) => prims.extend_from_slice(p),
            NodeContent::Internal(children) => stack.extend(children.iter().rev()),
        }
        tree.release(n);
    }
    tree.node_mut(id).content = NodeContent::Leaf(prims.into());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{
        primitive_bounds, Builder, InsertionBuilder, InsertionConfig, InsertionOrder,
    };
    use crate::bvh::cost::sah_cost;
    use crate::geometry::Aabb;
    use crate::mesh::procedural::{default_scene, torus};
    use glam::Vec3;

    fn cube(lo: f32, hi: f32) -> Aabb {
        Aabb::new(Vec3::splat(lo), Vec3::splat(hi))
    }

    /// ```text
    ///          root [0,10]³
    ///        /            \
    ///   near [0,1.1]³      far [9,10]³
    ///    /    \             /    \
    ///  [0,1]³ [0.1,1.1]³  [9,9.1]³ [9.9,10]³
    /// ```
    /// `near`'s two boxes almost coincide: one leaf of two costs less. `far`'s are small and
    /// apart: two leaves cost less.
    fn two_pairs() -> BuildTree {
        let mut t = BuildTree::new();
        let l: Vec<NodeId> = [
            cube(0.0, 1.0),
            cube(0.1, 1.1),
            cube(9.0, 9.1),
            cube(9.9, 10.0),
        ]
        .iter()
        .enumerate()
        .map(|(i, b)| t.push_leaf(vec![i as u32], *b))
        .collect();
        let near = t.push_internal(vec![l[0], l[1]]);
        let far = t.push_internal(vec![l[2], l[3]]);
        let root = t.push_internal(vec![near, far]);
        t.set_root(Some(root));
        t
    }

    #[test]
    fn collapses_only_where_a_leaf_is_cheaper() {
        let mut t = two_pairs();
        let before = sah_cost(&t, SahWeights::default());
        assert_eq!(collapse_leaves(&mut t, &CollapseConfig::default()), 1);
        let root = t.node(t.root().unwrap());
        let (near, far) = (t.node(root.children()[0]), t.node(root.children()[1]));
        assert_eq!(near.prims(), &[0, 1]);
        assert_eq!(far.children().len(), 2);
        assert!(sah_cost(&t, SahWeights::default()) < before);
        assert_eq!(t.released_count(), 2);

        // A leaf size of 1 forbids it; cheap enough triangle tests collapse everything.
        let mut t = two_pairs();
        let one = CollapseConfig {
            max_leaf_size: 1,
            ..Default::default()
        };
        assert_eq!(collapse_leaves(&mut t, &one), 0);
        let cheap = CollapseConfig {
            max_leaf_size: 4,
            sah: SahWeights {
                traversal: 1.0,
                intersection: 0.01,
            },
        };
        let mut t = two_pairs();
        assert_eq!(collapse_leaves(&mut t, &cheap), 1);
        assert_eq!(t.node(t.root().unwrap()).prims(), &[0, 1, 2, 3]);
    }

    #[test]
    fn lowers_the_sah_cost_keeps_invariants_and_is_optimal_locally() {
        let meshes = [torus(Vec3::ZERO, 2.0, 0.5, 24, 12), default_scene(1)];
        for mesh in &meshes {
            let prim_bounds = primitive_bounds(mesh);
            for (order, built_leaf) in [(InsertionOrder::Input, 1), (InsertionOrder::Morton, 2)] {
                for max_leaf_size in [1, 4, 8] {
                    let config = CollapseConfig {
                        max_leaf_size,
                        ..Default::default()
                    };
                    let mut tree = InsertionBuilder::new(InsertionConfig {
                        order,
                        max_leaf_size: built_leaf,
                    })
                    .build(mesh);
                    let before = sah_cost(&tree, config.sah);
                    collapse_leaves(&mut tree, &config);
                    tree.validate(&prim_bounds, max_leaf_size.max(built_leaf))
                        .unwrap();
                    assert!(sah_cost(&tree, config.sah) <= before);
                    // Nothing is left to collapse.
                    assert_eq!(collapse_leaves(&mut tree, &config), 0);
                    let best = best_subtrees(&tree, &config);
                    assert!(best.iter().all(|b| !b.collapse));
                    tree.compact();
                    tree.validate(&prim_bounds, max_leaf_size.max(built_leaf))
                        .unwrap();
                }
            }
        }
    }

    #[test]
    fn empty_tree_and_single_leaf() {
        let mut t = BuildTree::new();
        assert_eq!(collapse_leaves(&mut t, &CollapseConfig::default()), 0);
        let leaf = t.push_leaf(vec![0], cube(0.0, 1.0));
        t.set_root(Some(leaf));
        assert_eq!(collapse_leaves(&mut t, &CollapseConfig::default()), 0);
        assert_eq!(t.node(leaf).prims(), &[0]);
    }
}
