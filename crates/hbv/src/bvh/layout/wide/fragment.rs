//! A part of a wide layout built by one task of the direct build, with its own node and packet
//! arrays, and the parts joined into one layout's arrays.
//!
//! Tasks fill their parts at the same time without locks; a lane whose subtree another task
//! builds is left empty and recorded as a graft. Joining places the parts one after another,
//! each before the parts grafted under it:
//!
//! ```text
//!   nodes:   | part 0 (the root at 0) | part 1 | parts under 1 | part 2 | ...
//!   packets: | part 0                 | part 1 | parts under 1 | part 2 | ...
//! ```
//!
//! and adds each part's offsets to its references (a node's index, a leaf's first packet).

use super::node::{is_leaf, leaf_reference, leaf_span, WideNode};
use super::TrianglePacket;
use rayon::prelude::*;

/// Nodes and triangle packets of one subtree, its root node at index 0, and the parts built by
/// other tasks below it. References inside are local to the part.
pub(super) struct Fragment<const W: usize> {
    pub nodes: Vec<WideNode<W>>,
    pub packets: Vec<TrianglePacket>,
    /// `(node, lane, part)`: lane `lane` of node `node` holds the root of `parts[part]`.
    grafts: Vec<(u32, usize, usize)>,
    parts: Vec<Fragment<W>>,
}

/// A part and where its arrays start in the joined ones.
struct Placed<'a, const W: usize> {
    part: &'a Fragment<W>,
    first_node: u32,
    first_packet: u32,
}

impl<const W: usize> Placed<'_, W> {
    /// Child reference `reference` of this part made global.
    fn relocate(&self, reference: u32) -> u32 {
        if reference == 0 {
            // An empty lane, or a graft's (no part's root is a child within it).
            reference
        } else if is_leaf(reference) {
            let (first, count) = leaf_span(reference);
            leaf_reference(first as u32 + self.first_packet, count as u32)
        } else {
            reference + self.first_node
        }
    }
}

impl<const W: usize> Fragment<W> {
    pub fn new() -> Self {
        Self {
            nodes: Vec::new(),
            packets: Vec::new(),
            grafts: Vec::new(),
            parts: Vec::new(),
        }
    }

    /// Makes `part`'s root (a node) the child in lane `lane` of node `node`.
    pub fn graft(&mut self, node: u32, lane: usize, part: Fragment<W>) {
        self.grafts.push((node, lane, self.parts.len()));
        self.parts.push(part);
    }

    /// The nodes and packets of this part and all parts below it, joined (this part's root
    /// first), with every reference made global. Threads copy contiguous runs of the joined
    /// arrays, each element from the part that holds it.
    pub fn join(self) -> (Vec<WideNode<W>>, Vec<TrianglePacket>) {
        let mut placed = Vec::new();
        let (node_count, packet_count) = self.place(&mut placed, (0, 0));
        // Each graft's lane gets its part's root, a node at the part's first index.
        let grafted: Vec<Vec<(u32, usize, u32)>> = placed
            .iter()
            .map(|p| {
                let roots = p.part.parts.iter().map(|part| {
                    placed
                        .iter()
                        .find(|q| std::ptr::eq(q.part, part))
                        .expect("every part is placed")
                        .first_node
                });
                let roots: Vec<u32> = roots.collect();
                (p.part.grafts.iter())
                    .map(|&(node, lane, part)| (node, lane, roots[part]))
                    .collect()
            })
            .collect();
        // The part holding global index `i` of the nodes (packets): the last that starts at or
        // before it and holds some.
        let part_of = |i: u32, first: fn(&Placed<'_, W>) -> u32, len: fn(&Fragment<W>) -> usize| {
            let k = placed.partition_point(|p| first(p) <= i) - 1;
            let k = (0..=k)
                .rev()
                .find(|&k| len(placed[k].part) > 0)
                .expect("a part holds it");
            (k, (i - first(&placed[k])) as usize)
        };
        let nodes = (0..node_count)
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let (k, local) = part_of(i, |p| p.first_node, |f| f.nodes.len());
                let p = &placed[k];
                let node = &p.part.nodes[local];
                let mut children = node.children.map(|reference| p.relocate(reference));
                for &(_, lane, root) in grafted[k].iter().filter(|g| g.0 as usize == local) {
                    children[lane] = root;
                }
                WideNode {
                    boxes: node.boxes,
                    children,
                }
            })
            .collect();
        let packets = (0..packet_count)
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let (k, local) = part_of(i, |p| p.first_packet, |f| f.packets.len());
                placed[k].part.packets[local]
            })
            .collect();
        (nodes, packets)
    }

    /// Appends this part and the parts below it to `placed`, this one at `(first_node,
    /// first_packet)`; returns where the next part starts.
    fn place<'a>(&'a self, placed: &mut Vec<Placed<'a, W>>, at: (u32, u32)) -> (u32, u32) {
        placed.push(Placed {
            part: self,
            first_node: at.0,
            first_packet: at.1,
        });
        let mut next = (
            at.0 + self.nodes.len() as u32,
            at.1 + self.packets.len() as u32,
        );
        for part in &self.parts {
            next = part.place(placed, next);
        }
        next
    }
}
