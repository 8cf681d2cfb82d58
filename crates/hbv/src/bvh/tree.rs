//! The build-time tree: an n-ary tree of boxes in an arena, the common output of every builder
//! and the common input of every layout.

use std::fmt;

use crate::geometry::Aabb;

/// Index of a node in [`BuildTree::nodes`].
pub type NodeId = u32;

/// What a node holds: child nodes, or triangles.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeContent {
    /// Children are other nodes of the tree.
    Internal(Vec<NodeId>),
    /// Triangle ids (the mesh's face indices).
    Leaf(Vec<u32>),
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
/// below it. Nodes are referred to by [`NodeId`]; ids stay valid while the tree grows.
/// Degenerate triangles are normally left out by builders (they are never hit).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildTree {
    nodes: Vec<BuildNode>,
    root: Option<NodeId>,
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
        }
    }

    pub fn root(&self) -> Option<NodeId> {
        self.root
    }

    pub fn is_empty(&self) -> bool {
        self.root.is_none()
    }

    /// All nodes of the arena, indexed by [`NodeId`].
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
    pub fn push_leaf(&mut self, prims: Vec<u32>, bounds: Aabb) -> NodeId {
        self.push(BuildNode {
            bounds,
            parent: None,
            content: NodeContent::Leaf(prims),
        })
    }

    /// Adds an internal node over `children`, with their union as its bounds, and makes it
    /// their parent.
    pub fn push_internal(&mut self, children: Vec<NodeId>) -> NodeId {
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
        let id = NodeId::try_from(self.nodes.len()).expect("more than 2^32 nodes");
        self.nodes.push(node);
        id
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
    /// - leaves hold at most `max_leaf_size` triangles.
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
        self.walk(|id, _| {
            if problem.is_some() {
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
    use glam::Vec3;

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
}
