//! The wide layout made from a build tree: the tree binarized, each wide node collapsed from
//! binary nodes (the child of largest surface area opened first), each leaf's triangles packed
//! in fours.

use super::leaf_packets::push_leaf_packets;
use super::node::{WideNode, MAX_LEAF_TRIANGLES};
use super::{TrianglePacket, WideLayout};
use crate::bvh::layout::binarize::binary_form;
use crate::bvh::tree::{BuildTree, NodeId};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;
use rayon::prelude::*;

impl<const W: usize> WideLayout<W> {
    pub(super) const VALID_WIDTH: () =
        assert!(W == 4 || W == 8, "WideLayout supports widths 4 and 8");

    /// Lays out `tree` (binarized, then collapsed to `W`-wide nodes).
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_WIDTH;
        let binary = binary_form(tree);
        let counts = binary.triangle_counts();
        let mut layout = Self::from_parts(Vec::new(), Vec::new(), None);
        if let Some(root) = binary.root() {
            // About 3.3 triangles per packet and 4 packets per node in the shared scenes:
            // room for all of them at once, rather than copies as the arrays grow.
            let packets = counts[root as usize] as usize / 3 + 1;
            layout.packets.reserve(packets);
            layout.nodes.reserve(packets / 3 + 1);
            let reference = layout.emit(&binary, &counts, mesh, root);
            let bounds = binary.node(root).bounds;
            return Self::from_parts(layout.nodes, layout.packets, Some((reference, bounds)));
        }
        layout
    }

    /// Emits the subtree at binary node `id` as the collapse `plan` says, and returns its
    /// reference. Iterative over a work list, so that no depth overflows the call stack; no
    /// allocation per node (a leaf's triangles are gathered into one reused list).
    fn emit(&mut self, binary: &BuildTree, counts: &[u32], mesh: &TriangleMesh, id: NodeId) -> u32 {
        let is_leaf = |c: NodeId| binary.node(c).is_leaf() || counts[c as usize] as usize <= 4;
        let mut prims = Vec::new();
        if is_leaf(id) {
            binary.prims_below_into(id, &mut prims);
            return self.emit_leaf(mesh, &prims);
        }
        let root = self.nodes.len() as u32;
        self.nodes.push(WideNode::empty());
        let mut work: Vec<(NodeId, u32)> = vec![(id, root)];
        while let Some((id, slot)) = work.pop() {
            let mut node = WideNode::empty();
            let (children, count) = collapse::<W>(binary, counts, id);
            for (lane, &c) in children[..count].iter().enumerate() {
                node.set_box(lane, &binary.node(c).bounds);
                node.children[lane] = if is_leaf(c) {
                    binary.prims_below_into(c, &mut prims);
                    self.emit_leaf(mesh, &prims)
                } else {
                    let index = self.nodes.len() as u32;
                    self.nodes.push(WideNode::empty());
                    work.push((c, index));
                    index
                };
            }
            self.nodes[slot as usize] = node;
        }
        root
    }

    /// Packs `prims` into triangle packets and returns the leaf reference; more than a leaf holds
    /// (only from builders' leaves of up to 255 triangles) become a node over several leaves.
    fn emit_leaf(&mut self, mesh: &TriangleMesh, prims: &[u32]) -> u32 {
        if prims.len() > MAX_LEAF_TRIANGLES {
            let index = self.nodes.len() as u32;
            self.nodes.push(WideNode::empty());
            let mut node = WideNode::empty();
            for (lane, group) in prims.chunks(prims.len().div_ceil(W)).enumerate() {
                let bounds = group.iter().fold(Aabb::EMPTY, |b, &p| {
                    b.union(&mesh.triangle(p as usize).bounds())
                });
                node.set_box(lane, &bounds);
                node.children[lane] = self.emit_leaf(mesh, group);
            }
            self.nodes[index as usize] = node;
            return index;
        }
        push_leaf_packets(&mut self.packets, mesh, prims)
    }
}

/// The children of a wide node made from binary node `id`, and how many there are: start from
/// its two children and open the internal child of largest surface area until there are `W` or
/// none can be opened. A child whose subtree holds at most four triangles is not opened: it
/// becomes one leaf.
fn collapse<const W: usize>(
    binary: &BuildTree,
    counts: &[u32],
    id: NodeId,
) -> ([NodeId; W], usize) {
    let mut children = [0; W];
    let mut count = 0;
    for &c in binary.node(id).children() {
        children[count] = c;
        count += 1;
    }
    while count < W {
        let openable = children[..count]
            .iter()
            .enumerate()
            .filter(|(_, &c)| !binary.node(c).is_leaf() && counts[c as usize] > 4)
            .max_by(|(_, &a), (_, &b)| {
                binary
                    .node(a)
                    .bounds
                    .surface_area()
                    .total_cmp(&binary.node(b).bounds.surface_area())
            });
        let Some((k, _)) = openable else {
            break;
        };
        // `swap_remove` of slot `k`, then the opened node's two children at the end.
        let opened = children[k];
        count -= 1;
        children[k] = children[count];
        for &c in binary.node(opened).children() {
            children[count] = c;
            count += 1;
        }
    }
    (children, count)
}

/// The median over `packets` of the largest extent of each packet's box (0 for none).
pub(super) fn median_packet_extent(packets: &[TrianglePacket]) -> f32 {
    let mut extents: Vec<f32> = packets
        .par_iter()
        .with_min_len(4096)
        .map(|p| {
            let (mut lo, mut hi) = (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY);
            for lane in 0..4 {
                let t = p.triangle(lane);
                lo = lo.min(t.p0).min(t.p1).min(t.p2);
                hi = hi.max(t.p0).max(t.p1).max(t.p2);
            }
            (hi - lo).max_element()
        })
        .collect();
    if extents.is_empty() {
        return 0.0;
    }
    let middle = extents.len() / 2;
    *extents.select_nth_unstable_by(middle, f32::total_cmp).1
}
