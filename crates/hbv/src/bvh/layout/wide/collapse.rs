//! Which binary nodes become wide nodes and which become leaves: the collapse of a binary tree
//! into a `W`-wide one that is optimal for the surface area heuristic.
//!
//! Dynamic programming over the binary tree (Ylitie, Karras & Laine 2017, "Efficient incoherent
//! ray traversal on GPUs through compressed wide BVHs", §3). For a binary node `n` and a number of
//! slots `i` (1 to `W`), `C(n, i)` is the least SAH cost of covering `n`'s triangles with at most
//! `i` roots, each a wide node or a leaf:
//!
//! ```text
//!   C(n, 1)     = min( C_leaf(n), C_node(n) )
//!   C(n, i > 1) = min( C(n, i - 1), D(n, i) )
//!   D(n, j)     = min over k = 1 .. j-1 of  C(left, k) + C(right, j - k)      (n's children share j slots)
//!   C_node(n)   = SA(n) · COST_NODE   + D(n, W)                                (a wide node: its W slots)
//!   C_leaf(n)   = SA(n) · COST_PACKET · ⌈t(n) / 4⌉   if t(n) ≤ MAX_LEAF_TRIANGLES, else ∞
//! ```
//!
//! where `t(n)` is the number of triangles below `n`, tested four at a time in packets. A binary
//! leaf is always a leaf (`C(n, i) = C_leaf(n)` without the bound). The greedy collapse it
//! replaces (open the largest child until `W`) fixes the leaves before choosing the nodes; the
//! program chooses both together, and merges small sibling leaves into fuller packets.

use std::cmp::Ordering;

use crate::bvh::tree::{BuildTree, NodeContent, NodeId};

/// SAH cost of visiting a wide node (one SIMD test of its `W` boxes, ordering, stack).
const COST_NODE: f64 = 1.0;
/// SAH cost of testing one packet of four triangles.
const COST_PACKET: f64 = 1.0;
/// Most triangles a leaf made by merging binary nodes may hold (four packets).
const MAX_LEAF_TRIANGLES: u32 = 16;

/// The decisions of the dynamic program, per binary node.
pub(super) struct CollapsePlan<const W: usize> {
    /// Whether the node, as one root, is a leaf (else a wide node).
    leaf: Vec<bool>,
    /// `split[n][j - 1]`: the best `k` of `D(n, j)` (slots given to the left child), j = 2..W.
    split: Vec<[u8; W]>,
    /// `reduce[n][i - 1]`: whether `C(n, i)` is `C(n, i - 1)` rather than `D(n, i)`.
    reduce: Vec<[bool; W]>,
}

impl<const W: usize> CollapsePlan<W> {
    /// Solves the program for every node of the binary tree `tree`, bottom up.
    pub fn new(tree: &BuildTree, triangles_below: &[u32]) -> Self {
        let count = tree.nodes().len();
        let mut plan = Self {
            leaf: vec![true; count],
            split: vec![[0; W]; count],
            reduce: vec![[false; W]; count],
        };
        // `cost[n][i - 1]` = C(n, i).
        let mut cost = vec![[0.0f64; W]; count];
        let mut preorder = Vec::with_capacity(count);
        tree.walk(|id, _| preorder.push(id));
        for &n in preorder.iter().rev() {
            let node = tree.node(n);
            let area = f64::from(node.bounds.surface_area());
            let triangles = triangles_below[n as usize];
            let packets = f64::from(triangles.div_ceil(4));
            let leaf_cost = area * COST_PACKET * packets;
            let (left, right) = match &node.content {
                NodeContent::Internal(c) if c.len() == 2 => (c[0] as usize, c[1] as usize),
                _ => {
                    cost[n as usize] = [leaf_cost; W];
                    continue;
                }
            };
            // D(n, j) for j = 2..W.
            let mut distribute = [f64::INFINITY; W];
            for j in 2..=W {
                for k in 1..j {
                    let c = cost[left][k - 1] + cost[right][j - k - 1];
                    if c < distribute[j - 1] || plan.split[n as usize][j - 1] == 0 {
                        distribute[j - 1] = c;
                        plan.split[n as usize][j - 1] = k as u8;
                    }
                }
            }
            let node_cost = area * COST_NODE + distribute[W - 1];
            let leaf_cost = if triangles <= MAX_LEAF_TRIANGLES {
                leaf_cost
            } else {
                f64::INFINITY
            };
            // Ties (and costs that are not numbers) go to the wide node, always valid.
            let is_leaf = leaf_cost < node_cost;
            plan.leaf[n as usize] = is_leaf;
            let mut c = [0.0; W];
            c[0] = if is_leaf { leaf_cost } else { node_cost };
            for i in 2..=W {
                let reduce = distribute[i - 1].partial_cmp(&c[i - 2]) != Some(Ordering::Less);
                plan.reduce[n as usize][i - 1] = reduce;
                c[i - 1] = if reduce { c[i - 2] } else { distribute[i - 1] };
            }
            cost[n as usize] = c;
        }
        plan
    }

    /// Whether binary node `n`, as a root, becomes a leaf. Binary leaves always do.
    pub fn is_leaf(&self, n: NodeId) -> bool {
        self.leaf[n as usize]
    }

    /// The roots below the wide node made from the internal binary node `n`: 2 to `W` binary
    /// nodes whose subtrees together hold `n`'s triangles.
    pub fn children(&self, tree: &BuildTree, n: NodeId) -> Vec<NodeId> {
        let mut roots = Vec::with_capacity(W);
        self.distribute(tree, n, W, &mut roots);
        roots
    }

    /// The roots of `D(n, j)`: `n`'s two children sharing `j` slots as the plan says.
    fn distribute(&self, tree: &BuildTree, n: NodeId, j: usize, roots: &mut Vec<NodeId>) {
        let children = tree.node(n).children();
        let k = usize::from(self.split[n as usize][j - 1]);
        self.gather(tree, children[0], k, roots);
        self.gather(tree, children[1], j - k, roots);
    }

    /// The roots of `C(n, i)`.
    fn gather(&self, tree: &BuildTree, n: NodeId, i: usize, roots: &mut Vec<NodeId>) {
        let mut i = i;
        while i > 1 && self.reduce[n as usize][i - 1] {
            i -= 1;
        }
        if i == 1 || tree.node(n).is_leaf() {
            roots.push(n);
        } else {
            self.distribute(tree, n, i, roots);
        }
    }
}
