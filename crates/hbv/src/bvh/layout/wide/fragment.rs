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
    /// first), with every reference made global.
    pub fn join(self) -> (Vec<WideNode<W>>, Vec<TrianglePacket>) {
        let mut placed = Vec::new();
        let (nodes, packets) = self.place(&mut placed, (0, 0));
        let mut all_nodes = Vec::with_capacity(nodes as usize);
        let mut all_packets = Vec::with_capacity(packets as usize);
        for p in &placed {
            let relocate = |reference: u32| {
                if reference == 0 {
                    // An empty lane (no part's root is a child).
                    reference
                } else if is_leaf(reference) {
                    let (first, count) = leaf_span(reference);
                    leaf_reference(first as u32 + p.first_packet, count as u32)
                } else {
                    reference + p.first_node
                }
            };
            let start = all_nodes.len();
            all_nodes.extend(p.part.nodes.iter().map(|node| WideNode {
                boxes: node.boxes,
                children: node.children.map(relocate),
            }));
            for &(node, lane, part) in &p.part.grafts {
                let root = placed
                    .iter()
                    .find(|q| std::ptr::eq(q.part, &p.part.parts[part]))
                    .expect("every part is placed")
                    .first_node;
                all_nodes[start + node as usize].children[lane] = root;
            }
            all_packets.extend_from_slice(&p.part.packets);
        }
        (all_nodes, all_packets)
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
