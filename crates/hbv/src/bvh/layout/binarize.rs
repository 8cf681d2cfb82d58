//! A binary tree from an n-ary one: what the ordered and wide layouts start from.

use std::borrow::Cow;

use crate::bvh::tree::{BuildTree, NodeContent, NodeId};

/// `tree` itself when every node of its arena is a leaf or has exactly two children (the
/// top-down builders' trees), else [`binarize`]'s copy: the binary tree the layouts start from,
/// without copying one that is binary already (the copy of the dragon's 1.9 million nodes took
/// about a tenth of the wide layout's making).
pub(crate) fn binary_form(tree: &BuildTree) -> Cow<'_, BuildTree> {
    // Every node of the arena in memory order, where a walk from the root reads them in a
    // scattered order: released nodes too (unreachable, and empty), which can only make a
    // binary tree look n-ary, and then it is copied, as any n-ary tree is.
    let binary = tree
        .nodes()
        .iter()
        .all(|node| node.is_leaf() || node.children().len() == 2);
    if binary {
        Cow::Borrowed(tree)
    } else {
        Cow::Owned(binarize(tree))
    }
}

/// A copy of `tree` in which every internal node has exactly two children.
///
/// An internal node with `k > 2` children (the insertion builder makes them) becomes a small
/// binary subtree built by agglomerative clustering (Walter et al. 2008): repeatedly merge the
/// two entries whose union has the smallest surface area. Leaves are kept as they are; a node
/// with one child is replaced by the child. Binary trees come out unchanged (up to node ids).
pub fn binarize(tree: &BuildTree) -> BuildTree {
    let mut out = BuildTree::with_capacity(tree.nodes().len() * 2);
    let root = tree.root().map(|r| copy(tree, r, &mut out));
    out.set_root(root);
    out
}

/// Copies the subtree at `id` into `out`, binarized, and returns its new id. Iterative, so that
/// no tree depth can overflow the call stack.
fn copy(tree: &BuildTree, root: NodeId, out: &mut BuildTree) -> NodeId {
    // Post-order: a node is emitted once its children have been.
    enum Step {
        Enter(NodeId),
        Exit(NodeId),
    }
    let mut steps = vec![Step::Enter(root)];
    let mut done: Vec<NodeId> = Vec::new();
    while let Some(step) = steps.pop() {
        match step {
            Step::Enter(id) => {
                steps.push(Step::Exit(id));
                for &c in tree.node(id).children().iter().rev() {
                    steps.push(Step::Enter(c));
                }
            }
            Step::Exit(id) => {
                let node = tree.node(id);
                let new = match &node.content {
                    NodeContent::Leaf(prims) => out.push_leaf(prims.as_slice(), node.bounds),
                    NodeContent::Internal(children) => {
                        let k = children.len();
                        let copied = done.split_off(done.len() - k);
                        cluster(out, copied)
                    }
                };
                done.push(new);
            }
        }
    }
    done.pop().expect("the root was emitted")
}

/// Joins `nodes` (already in `out`) into one binary subtree by agglomerative clustering.
fn cluster(out: &mut BuildTree, mut nodes: Vec<NodeId>) -> NodeId {
    while nodes.len() > 1 {
        let mut best = (0, 1, f32::INFINITY);
        for i in 0..nodes.len() {
            for j in i + 1..nodes.len() {
                let area = out
                    .node(nodes[i])
                    .bounds
                    .union(&out.node(nodes[j]).bounds)
                    .surface_area();
                if area < best.2 {
                    best = (i, j, area);
                }
            }
        }
        let (i, j, _) = best;
        let b = nodes.swap_remove(j);
        let a = nodes[i];
        nodes[i] = out.push_internal([a, b].as_slice());
    }
    nodes[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{primitive_bounds, Builder, InsertionBuilder};
    use crate::bvh::expected_tests;
    use crate::mesh::procedural::torus;
    use glam::Vec3;

    #[test]
    fn binarized_tree_is_valid_and_binary() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.5, 32, 16);
        let tree = InsertionBuilder::default().build(&mesh);
        assert!(
            tree.shape().arity_histogram.len() > 3,
            "the insertion tree has n-ary nodes"
        );
        let binary = binarize(&tree);
        binary.validate(&primitive_bounds(&mesh), 1).unwrap();
        assert_eq!(
            binary.shape().arity_histogram,
            vec![0, 0, mesh.triangle_count() - 1]
        );
        assert!(expected_tests(&binary) > 0.0);
    }
}
