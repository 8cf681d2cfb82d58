//! Edits of a [`BuildTree`] that placement and optimization make: attaching a triangle or a
//! node at a [`Placement`], and taking a node out and putting it back.
//!
//! # Taking a node out
//!
//! `BuildTree::detach` is the inverse of placing: its parent loses a child, and a parent left
//! with one child is spliced out (the child takes its place). [`TreeCost::removal_saving`] and
//! [`TreeCost::placement_increase`] give the exact change of `Σ w SA` of both steps, which is
//! what insertion-based optimization weighs against each other.
//!
//! [`TreeCost::removal_saving`]: super::TreeCost::removal_saving
//! [`TreeCost::placement_increase`]: super::TreeCost::placement_increase

use super::placement::Placement;
use super::tree::{BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;

/// Where a node was before `BuildTree::detach` took it out, so that `BuildTree::reattach`
/// can put it back as it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FormerPlace {
    /// It was the root; the tree is now empty.
    Root,
    /// It was child `index` of `parent`, which kept two or more other children.
    ChildOf { parent: NodeId, index: usize },
    /// It was child `index` (0 or 1) of a parent whose one other child, `sibling`, has taken
    /// the parent's place.
    PairedWith { sibling: NodeId, index: usize },
}

impl FormerPlace {
    /// The placement that puts a node back at this place (in any child position).
    pub(crate) fn placement(&self) -> Placement {
        match *self {
            FormerPlace::Root => Placement::Root,
            FormerPlace::ChildOf { parent, .. } => Placement::AddChild(parent),
            FormerPlace::PairedWith { sibling, .. } => Placement::Pair(sibling),
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
        let leaf = self.push_leaf([prim].as_slice(), bounds);
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
                let pair = self.push_internal([sibling, item].as_slice());
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

    /// Takes `node` and its subtree out of the tree, and returns where it was. The node is
    /// kept in the arena, without a parent, to be put back by [`BuildTree::attach_node`] or
    /// [`BuildTree::reattach`]; a detached subtree is unreachable from the root, so no search
    /// can place a node inside itself.
    ///
    /// Its parent loses a child and is refitted with its ancestors; a parent left with one
    /// child is spliced out and released (the child takes its place), and one left with none
    /// is taken out in turn (see the drawing at [`TreeCost::removal_saving`], which is the
    /// cost this saves).
    pub(crate) fn detach(&mut self, node: NodeId) -> FormerPlace {
        let Some(parent) = self.node(node).parent else {
            self.set_root(None);
            return FormerPlace::Root;
        };
        self.node_mut(node).parent = None;
        let NodeContent::Internal(children) = &mut self.node_mut(parent).content else {
            unreachable!("a parent is an internal node");
        };
        let index = children
            .iter()
            .position(|&c| c == node)
            .expect("a node is among its parent's children");
        children.remove(index);
        match children[..] {
            [] => {
                let former = self.detach(parent);
                self.release(parent);
                former
            }
            [sibling] => {
                match self.node(parent).parent {
                    None => self.set_root(Some(sibling)),
                    Some(grandparent) => {
                        self.replace_child(grandparent, parent, sibling);
                        self.refit_from(grandparent);
                    }
                }
                self.release(parent);
                FormerPlace::PairedWith { sibling, index }
            }
            _ => {
                self.refit_from(parent);
                FormerPlace::ChildOf { parent, index }
            }
        }
    }

    /// Puts a node taken out by [`BuildTree::detach`] back where it was, in the same child
    /// position, growing its ancestors back: the tree is again what it was (but for a parent
    /// left empty by the detach, which is gone).
    pub(crate) fn reattach(&mut self, former: FormerPlace, node: NodeId) {
        let bounds = self.node(node).bounds;
        match former {
            FormerPlace::Root => self.set_root(Some(node)),
            FormerPlace::ChildOf { parent, index } => {
                if let NodeContent::Internal(children) = &mut self.node_mut(parent).content {
                    children.insert(index.min(children.len()), node);
                }
                self.node_mut(node).parent = Some(parent);
                self.grow_from(parent, &bounds);
            }
            FormerPlace::PairedWith { sibling, index } => {
                self.attach_node(Placement::Pair(sibling), node);
                let pair = self.node(node).parent.expect("a paired node has a parent");
                if let NodeContent::Internal(children) = &mut self.node_mut(pair).content {
                    // `attach_node` made the pair `[sibling, node]`.
                    if index == 0 {
                        children.swap(0, 1);
                    }
                }
            }
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
