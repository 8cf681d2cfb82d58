//! The build-time tree: an n-ary tree of boxes in an arena, the common output of every builder
//! and the common input of every layout.

use std::fmt;

use crate::geometry::Aabb;

/// Index of a node in [`BuildTree::nodes`].
pub type NodeId = u32;

/// A node's children or triangle ids: up to four held in the node itself, more on the heap.
/// Most nodes of a built tree have two children or a few triangles, so a tree is made, read
/// and dropped without a heap list per node (the dragon's tree has 1.9 million nodes).
pub type NodeList = smallvec::SmallVec<[u32; 4]>;

/// What a node holds: child nodes, or triangles.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeContent {
    /// Children are other nodes of the tree.
    Internal(NodeList),
    /// Triangle ids (the mesh's face indices).
    Leaf(NodeList),
}

/// One node of a [`BuildTree`].
#[derive(Clone, Debug, PartialEq)]
pub struct BuildNode {
    /// Bounds of everything below the node.
    pub bounds: Aabb,
    /// The parent, `None` for the root.
    pub parent: Option<NodeId>,
    pub content: NodeContent,
}

impl BuildNode {
    pub fn is_leaf(&self) -> bool {
        matches!(self.content, NodeContent::Leaf(_))
    }

    /// `a_n` of the tree cost: the number of tests done when a ray reaches this node — one box
    /// test per child node, or one triangle test per triangle of a leaf.
    pub fn arity(&self) -> usize {
        match &self.content {
            NodeContent::Internal(c) => c.len(),
            NodeContent::Leaf(p) => p.len(),
        }
    }

    pub fn children(&self) -> &[NodeId] {
        match &self.content {
            NodeContent::Internal(c) => c,
            NodeContent::Leaf(_) => &[],
        }
    }

    pub fn prims(&self) -> &[u32] {
        match &self.content {
            NodeContent::Internal(_) => &[],
            NodeContent::Leaf(p) => p,
        }
    }
}

/// An n-ary bounding volume hierarchy over triangle ids, stored in an arena.
///
/// Internal nodes hold child nodes, leaves hold triangle ids; a node's box bounds everything
/// below it. Nodes are referred to by [`NodeId`]; ids stay valid while the tree grows (but see
/// below for the optimizers and [`BuildTree::compact`]).
/// Degenerate triangles are normally left out by builders (they are never hit).
///
/// The tree is what is reachable from the root. Optimizers that restructure it
/// ([`crate::bvh::optimize`]) release the nodes they take out: released nodes stay in the arena,
/// unreachable, and are reused by the next node pushed; [`BuildTree::compact`] drops them and
/// renumbers the rest.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildTree {
    nodes: Vec<BuildNode>,
    root: Option<NodeId>,
    /// Released nodes, reused last released first by [`BuildTree::push_leaf`] and
    /// [`BuildTree::push_internal`].
    released: Vec<NodeId>,
}

/// Shape statistics of a tree, as `hbv info` reports them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeShape {
    pub nodes: usize,
    pub leaves: usize,
    pub prims: usize,
    pub depth_max: usize,
    /// Mean depth of leaves (the root has depth 0).
    pub depth_mean: f64,
    /// `arity_histogram[k]` = number of internal nodes with `k` children.
    pub arity_histogram: Vec<usize>,
}

/// A broken invariant found by [`BuildTree::validate`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InvariantError(pub String);

impl fmt::Display for InvariantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "tree invariant broken: {}", self.0)
    }
}

impl std::error::Error for InvariantError {}

impl BuildTree {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn with_capacity(nodes: usize) -> Self {
        Self {
            nodes: Vec::with_capacity(nodes),
            root: None,
            released: Vec::new(),
        }
    }

    pub fn root(&self) -> Option<NodeId> {
        self.root
    }

    pub fn is_empty(&self) -> bool {
        self.root.is_none()
    }

    /// All nodes of the arena, indexed by [`NodeId`]: the tree's, and any released node not yet
    /// reused (unreachable from the root; see [`BuildTree::compact`]).
    pub fn nodes(&self) -> &[BuildNode] {
        &self.nodes
    }

    #[inline]
    pub fn node(&self, id: NodeId) -> &BuildNode {
        &self.nodes[id as usize]
    }

    #[inline]
    pub(crate) fn node_mut(&mut self, id: NodeId) -> &mut BuildNode {
        &mut self.nodes[id as usize]
    }

    /// Adds a leaf holding `prims` with the given bounds; it has no parent until attached.
    pub fn push_leaf(&mut self, prims: impl Into<NodeList>, bounds: Aabb) -> NodeId {
        self.push(BuildNode {
            bounds,
            parent: None,
            content: NodeContent::Leaf(prims.into()),
        })
    }

    /// Adds an internal node over `children`, with their union as its bounds, and makes it
    /// their parent.
    pub fn push_internal(&mut self, children: impl Into<NodeList>) -> NodeId {
        let children = children.into();
        let bounds = children
            .iter()
            .fold(Aabb::EMPTY, |b, &c| b.union(&self.node(c).bounds));
        let id = self.push(BuildNode {
            bounds,
            parent: None,
            content: NodeContent::Internal(children),
        });
        for i in 0..self.node(id).children().len() {
            let c = self.node(id).children()[i];
            self.node_mut(c).parent = Some(id);
        }
        id
    }

    pub fn set_root(&mut self, root: Option<NodeId>) {
        self.root = root;
        if let Some(r) = root {
            self.node_mut(r).parent = None;
        }
    }

    fn push(&mut self, node: BuildNode) -> NodeId {
        if let Some(id) = self.released.pop() {
            self.nodes[id as usize] = node;
            return id;
        }
        let id = NodeId::try_from(self.nodes.len()).expect("more than 2^32 nodes");
        self.nodes.push(node);
        id
    }

    /// Number of released nodes waiting in the arena to be reused.
    pub fn released_count(&self) -> usize {
        self.released.len()
    }

    /// Gives node `id`, which nothing in the tree refers to any more, back to the arena: it is
    /// emptied and reused by the next push.
    pub(crate) fn release(&mut self, id: NodeId) {
        let node = self.node_mut(id);
        node.bounds = Aabb::EMPTY;
        node.parent = None;
        node.content = NodeContent::Internal(NodeList::new());
        self.released.push(id);
    }

    /// Recomputes the box of internal node `node` as the union of its children's, and of its
    /// ancestors in turn, stopping at the first box that does not change (the boxes above it
    /// are then right too). A leaf's box is left as it is: it depends on triangles the tree
    /// does not know the boxes of, so refitting starts at its parent.
    pub(crate) fn refit_from(&mut self, node: NodeId) {
        let mut at = Some(node);
        if self.node(node).is_leaf() {
            at = self.node(node).parent;
        }
        while let Some(id) = at {
            let n = self.node(id);
            let fitted = n
                .children()
                .iter()
                .fold(Aabb::EMPTY, |b, &c| b.union(&self.node(c).bounds));
            if fitted == n.bounds {
                break;
            }
            let n = self.node_mut(id);
            n.bounds = fitted;
            at = n.parent;
        }
    }

    /// Rebuilds the arena with only the nodes reachable from the root, in depth-first order
    /// (parents before children, children in order): drops released nodes and anything else
    /// unreachable. Node ids change; the tree (boxes, child order, triangles) does not.
    pub fn compact(&mut self) {
        let mut new_id = vec![NodeId::MAX; self.nodes.len()];
        let mut order = Vec::new();
        self.walk(|id, _| {
            new_id[id as usize] = order.len() as NodeId;
            order.push(id);
        });
        let mut nodes = Vec::with_capacity(order.len());
        for &old in &order {
            let node = std::mem::replace(
                &mut self.nodes[old as usize],
                BuildNode {
                    bounds: Aabb::EMPTY,
                    parent: None,
                    content: NodeContent::Internal(NodeList::new()),
                },
            );
            let content = match node.content {
                NodeContent::Internal(children) => {
                    NodeContent::Internal(children.iter().map(|&c| new_id[c as usize]).collect())
                }
                leaf => leaf,
            };
            nodes.push(BuildNode {
                bounds: node.bounds,
                parent: node.parent.map(|p| new_id[p as usize]),
                content,
            });
        }
        self.nodes = nodes;
        self.root = self.root.map(|r| new_id[r as usize]);
        self.released.clear();
    }

    /// Visits the nodes reachable from the root, parents before children, with their depth.
    pub fn walk(&self, mut visit: impl FnMut(NodeId, usize)) {
        let mut stack: Vec<(NodeId, usize)> = self.root.into_iter().map(|r| (r, 0)).collect();
        while let Some((id, depth)) = stack.pop() {
            visit(id, depth);
            for &c in self.node(id).children().iter().rev() {
                stack.push((c, depth + 1));
            }
        }
    }

    /// The triangles of every leaf below `node` (itself included), leaves left to right.
    pub fn prims_below(&self, node: NodeId) -> Vec<u32> {
        let mut prims = Vec::new();
        self.prims_below_into(node, &mut prims);
        prims
    }

    /// [`BuildTree::prims_below`] into `prims` (cleared first), a list the caller reuses: the
    /// layouts gather every leaf's triangles this way, without a new list each.
    pub fn prims_below_into(&self, node: NodeId, prims: &mut Vec<u32>) {
        prims.clear();
        let n = self.node(node);
        if n.is_leaf() {
            // Most calls, from the layouts: no list of nodes to visit.
            prims.extend_from_slice(n.prims());
            return;
        }
        let mut pending = vec![node];
        while let Some(id) = pending.pop() {
            let n = self.node(id);
            prims.extend_from_slice(n.prims());
            pending.extend(n.children().iter().rev());
        }
    }

    /// The number of triangles below each node, indexed by node id (0 for nodes not reachable
    /// from the root).
    ///
    /// The top-down builders store children before their parents: then one pass over the
    /// arena in memory order counts every node, where a walk from the root reads the nodes in
    /// a scattered order (on the dragon's 1.9 million nodes, most of a wide layout's making).
    /// The pass stops at the first child stored after its parent (optimized trees reuse the
    /// ids of nodes they took out), and a walk counts instead.
    pub fn triangle_counts(&self) -> Vec<u32> {
        let mut counts = vec![0u32; self.nodes.len()];
        let count = |counts: &[u32], node: &BuildNode| match &node.content {
            NodeContent::Leaf(p) => p.len() as u32,
            NodeContent::Internal(c) => c.iter().map(|&c| counts[c as usize]).sum(),
        };
        let children_first = self.nodes.iter().enumerate().all(|(id, node)| {
            let first = node.children().iter().all(|&c| (c as usize) < id);
            if first {
                counts[id] = count(&counts, node);
            }
            first
        });
        if children_first {
            return counts;
        }
        // Post-order: each node once on the way down (its children pushed after it) and
        // counted on the way up, once its children are.
        counts.fill(0);
        let mut pending: Vec<(NodeId, bool)> = self.root.into_iter().map(|r| (r, false)).collect();
        while let Some((id, children_done)) = pending.pop() {
            let node = self.node(id);
            if children_done || node.is_leaf() {
                counts[id as usize] = count(&counts, node);
            } else {
                pending.push((id, true));
                pending.extend(node.children().iter().map(|&c| (c, false)));
            }
        }
        counts
    }

    /// Nodes, leaves, depth and arity of the tree reachable from the root.
    pub fn shape(&self) -> TreeShape {
        let mut s = TreeShape::default();
        let mut depth_sum = 0usize;
        self.walk(|id, depth| {
            let node = self.node(id);
            s.nodes += 1;
            s.depth_max = s.depth_max.max(depth);
            if node.is_leaf() {
                s.leaves += 1;
                s.prims += node.arity();
                depth_sum += depth;
            } else {
                let a = node.arity();
                if s.arity_histogram.len() <= a {
                    s.arity_histogram.resize(a + 1, 0);
                }
                s.arity_histogram[a] += 1;
            }
        });
        if s.leaves > 0 {
            s.depth_mean = depth_sum as f64 / s.leaves as f64;
        }
        s
    }

    /// Checks the invariants every builder guarantees, given the bounds of each triangle
    /// (`prim_bounds[i]`, empty for triangles the tree must leave out):
    /// - every triangle with a non-empty box is in exactly one leaf, and no other triangle is;
    /// - every node's box contains its children's boxes (or its triangles' boxes);
    /// - parent links match child lists; internal nodes and leaves are not empty;
    /// - leaves hold at most `max_leaf_size` triangles;
    /// - no node is reached twice, and no released node is reached.
    pub fn validate(
        &self,
        prim_bounds: &[Aabb],
        max_leaf_size: usize,
    ) -> Result<(), InvariantError> {
        let err = |s: String| Err(InvariantError(s));
        let mut seen = vec![false; prim_bounds.len()];
        let mut problem: Option<String> = None;
        if let Some(r) = self.root {
            if self.node(r).parent.is_some() {
                return err(format!("root {r} has a parent"));
            }
        }
        // Released nodes are marked reached up front, so that reaching one is caught as a repeat.
        let mut reached = vec![false; self.nodes.len()];
        for &id in &self.released {
            reached[id as usize] = true;
        }
        self.walk(|id, _| {
            if problem.is_some() {
                return;
            }
            if std::mem::replace(&mut reached[id as usize], true) {
                problem = Some(format!("node {id} is reached twice, or was released"));
                return;
            }
            let node = self.node(id);
            match &node.content {
                NodeContent::Internal(children) => {
                    if children.is_empty() {
                        problem = Some(format!("internal node {id} has no children"));
                    }
                    for &c in children {
                        let child = self.node(c);
                        if child.parent != Some(id) {
                            problem = Some(format!("node {c} does not name {id} as its parent"));
                        } else if !node.bounds.contains(&child.bounds) {
                            problem = Some(format!("node {id} does not contain child {c}"));
                        }
                    }
                }
                NodeContent::Leaf(prims) => {
                    if prims.is_empty() || prims.len() > max_leaf_size {
                        problem = Some(format!("leaf {id} holds {} triangles", prims.len()));
                    }
                    for &p in prims {
                        let Some(b) = prim_bounds.get(p as usize) else {
                            problem = Some(format!("leaf {id} holds unknown triangle {p}"));
                            return;
                        };
                        if std::mem::replace(&mut seen[p as usize], true) {
                            problem = Some(format!("triangle {p} is in two leaves"));
                        } else if b.is_empty() {
                            problem = Some(format!("triangle {p} should have been left out"));
                        } else if !node.bounds.contains(b) {
                            problem = Some(format!("leaf {id} does not contain triangle {p}"));
                        }
                    }
                }
            }
        });
        if let Some(p) = problem {
            return err(p);
        }
        if let Some(p) = (0..prim_bounds.len()).find(|&p| !seen[p] && !prim_bounds[p].is_empty()) {
            return err(format!("triangle {p} is in no leaf"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder};
    use crate::bvh::optimize::{ReinsertionConfig, ReinsertionOptimizer};
    use crate::mesh::procedural::torus;
    use glam::Vec3;

    /// Triangle counts by the pass in memory order (children stored first: the top-down
    /// builders) and by the walk (children stored after a parent: an optimized tree, whose
    /// released ids are reused) are each node's triangles; `prims_below_into` empties its list
    /// first.
    #[test]
    fn triangle_counts_whatever_the_order_of_the_nodes() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.5, 24, 12);
        let sah = BinnedSahBuilder::default().build(&mesh);
        let insertion = InsertionBuilder::default().build(&mesh);
        let mut optimized = sah.clone();
        ReinsertionOptimizer::new(ReinsertionConfig::default()).optimize(&mut optimized);
        let child_after_parent = |tree: &BuildTree| {
            (tree.nodes().iter().enumerate())
                .any(|(id, node)| node.children().iter().any(|&c| c as usize > id))
        };
        assert!(!child_after_parent(&sah));
        assert!(child_after_parent(&optimized), "the optimizer reused ids");
        let mut prims = vec![u32::MAX];
        for tree in [&sah, &insertion, &optimized] {
            let counts = tree.triangle_counts();
            tree.walk(|id, _| {
                tree.prims_below_into(id, &mut prims);
                assert_eq!(prims, tree.prims_below(id));
                assert_eq!(counts[id as usize] as usize, prims.len());
            });
        }
    }

    fn cube(lo: f32, hi: f32) -> Aabb {
        Aabb::new(Vec3::splat(lo), Vec3::splat(hi))
    }

    #[test]
    fn shape_and_validate_on_small_tree() {
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0, 1.0));
        let b = t.push_leaf(vec![1], cube(2.0, 3.0));
        let c = t.push_leaf(vec![2], cube(4.0, 5.0));
        let ab = t.push_internal(vec![a, b]);
        let root = t.push_internal(vec![ab, c]);
        t.set_root(Some(root));
        let bounds = [cube(0.0, 1.0), cube(2.0, 3.0), cube(4.0, 5.0)];
        t.validate(&bounds, 1).unwrap();
        let s = t.shape();
        assert_eq!((s.nodes, s.leaves, s.prims, s.depth_max), (5, 3, 3, 2));
        assert!((s.depth_mean - 5.0 / 3.0).abs() < 1e-12);
        assert_eq!(s.arity_histogram, vec![0, 0, 2]);
    }

    #[test]
    fn validate_finds_missing_and_uncontained_triangles() {
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0, 1.0));
        t.set_root(Some(a));
        let err = t
            .validate(&[cube(0.0, 1.0), cube(0.0, 1.0)], 1)
            .unwrap_err();
        assert!(err.0.contains("triangle 1 is in no leaf"), "{err}");
        let err = t.validate(&[cube(0.0, 2.0)], 1).unwrap_err();
        assert!(err.0.contains("does not contain triangle 0"), "{err}");
    }

    /// ```text
    ///        root
    ///       /    \
    ///      ab     c
    ///     /  \
    ///    a    b
    /// ```
    fn three_leaves() -> (BuildTree, [Aabb; 3]) {
        let bounds = [cube(0.0, 1.0), cube(2.0, 3.0), cube(4.0, 5.0)];
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], bounds[0]);
        let b = t.push_leaf(vec![1], bounds[1]);
        let c = t.push_leaf(vec![2], bounds[2]);
        let ab = t.push_internal(vec![a, b]);
        let root = t.push_internal(vec![c, ab]);
        t.set_root(Some(root));
        (t, bounds)
    }

    #[test]
    fn released_nodes_are_reused_and_compact_drops_them() {
        let (mut t, bounds) = three_leaves();
        let (a, b, ab, root) = (0, 1, 3, 4);
        // Make `b` a child of the root and drop `ab` by hand: root [c, b, a].
        if let NodeContent::Internal(children) = &mut t.node_mut(root).content {
            children.retain(|c| *c != ab);
            children.extend([b, a]);
        }
        t.node_mut(a).parent = Some(root);
        t.node_mut(b).parent = Some(root);
        t.release(ab);
        t.validate(&bounds, 1).unwrap();
        assert_eq!((t.nodes().len(), t.released_count()), (5, 1));
        assert_eq!(
            t.push_leaf(vec![], Aabb::EMPTY),
            ab,
            "the released node is reused"
        );
        t.release(ab);

        let before = t.clone();
        t.compact();
        assert_eq!((t.nodes().len(), t.released_count()), (4, 0));
        t.validate(&bounds, 1).unwrap();
        assert_eq!(t.shape(), before.shape());
        assert_eq!(t.root(), Some(0));
        let prims = |t: &BuildTree| {
            let mut p = Vec::new();
            t.walk(|id, _| p.extend_from_slice(t.node(id).prims()));
            p
        };
        assert_eq!(prims(&t), prims(&before));
    }

    #[test]
    fn validate_finds_a_released_node_in_the_tree() {
        let (mut t, bounds) = three_leaves();
        t.release(0);
        t.node_mut(0).content = NodeContent::Leaf([0].as_slice().into());
        t.node_mut(0).parent = Some(3);
        let err = t.validate(&bounds, 1).unwrap_err();
        assert!(err.0.contains("released"), "{err}");
    }

    #[test]
    fn refit_shrinks_ancestors_to_their_children() {
        let (mut t, bounds) = three_leaves();
        let (b, ab, root) = (1, 3, 4);
        t.node_mut(b).bounds = cube(0.5, 1.0);
        t.refit_from(b);
        assert_eq!(t.node(ab).bounds, cube(0.0, 1.0));
        assert_eq!(t.node(root).bounds, cube(0.0, 5.0));
        t.node_mut(b).bounds = bounds[1];
        t.refit_from(ab);
        assert_eq!(t.node(ab).bounds, cube(0.0, 3.0));
    }
}
