//! The tree the nearest-point search walks: 8-child nodes with their children's boxes side by
//! side ([`SearchNode`]), and leaves of [`EnclosurePacket`]s, made from any builder's
//! [`BuildTree`].
//!
//! **Collapse** (as for wide ray-tracing BVHs, Wald et al. 2008, "Getting rid of packets"):
//! a node's children are its build node's children; while there are fewer than [`WIDTH`], the
//! internal child of largest surface area is replaced by its own children (when they fit). A
//! child with at most [`SearchTreeConfig::leaf_triangles`] triangles below it becomes one leaf
//! (its whole subtree, flattened), since testing a few triangles in packets of eight costs less
//! than visiting nodes. A build node with more than [`WIDTH`] children (n-ary builders) is split
//! into [`WIDTH`] groups along its longest axis, each group a node of its own. Near the leaves (at most
//! [`FRAME_MAX_TRIANGLES`] below), a node whose triangles face one way gets its boxes in a
//! [`NodeFrame`] facing their mean normal, when that makes the boxes smaller.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::box_bound::{Boxes, PointBracket};
use super::enclosure_packet::{EnclosurePacket, LANES};
use super::node_frame::{NodeFrame, FRAME_SHRINK};
use crate::bvh::{BuildTree, NodeContent, NodeId};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Knobs of the search tree built from a `BuildTree`.
#[derive(Clone, Copy, Debug)]
pub struct SearchTreeConfig {
    /// A subtree with at most this many triangles becomes one leaf. Default 16 (two packets;
    /// 8 and 24 measured within a few per cent of it, 1 and 4 slower).
    pub leaf_triangles: usize,
    /// Near the leaves, give a node's child boxes a frame facing their triangles' mean normal
    /// where that makes them smaller (module `node_frame`). Default true.
    pub rotated_frames: bool,
}

impl Default for SearchTreeConfig {
    fn default() -> Self {
        Self {
            leaf_triangles: 16,
            rotated_frames: true,
        }
    }
}

/// Children per node: eight, one AVX register of f32 bounds (two SSE registers without AVX).
/// Eight against four children, measured: on spot 10.4 → 6.6 nodes per query, 4,332 → 3,916
/// instructions, about 6 % faster (bunny, teapot alike).
pub(super) const WIDTH: usize = 8;

/// A node of the search tree: its [`WIDTH`] (eight) children's boxes side by side, and for each
/// child either a node (`triangles == 0`, `child` its index), a leaf (`triangles` of them in
/// packets from `child`), or nothing (NaN bounds, [`Boxes::NONE`]: the search never enters such
/// a slot). Named for the tree it belongs to rather than its width, which is [`WIDTH`]'s to say.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct SearchNode {
    pub bounds: Boxes<WIDTH>,
    pub child: [u32; WIDTH],
    pub triangles: [u32; WIDTH],
    /// The frame `bounds` are given in (their coordinates are `r_j · x`); world axes if `None`.
    pub frame: Option<NodeFrame>,
}

impl SearchNode {
    const EMPTY: SearchNode = SearchNode {
        bounds: Boxes::NONE,
        child: [0; WIDTH],
        triangles: [0; WIDTH],
        frame: None,
    };

    /// Lower bounds of the squared distances from the point in `bracket` to the children's
    /// boxes, in whichever frame they are given (see [`NodeFrame`] for the shrink that keeps a
    /// rotated bound conservative).
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, bracket: &PointBracket) -> [f32; WIDTH] {
        match &self.frame {
            None => self.bounds.distance_squared_lower_bounds(bracket),
            Some(frame) => self
                .bounds
                .distance_squared_lower_bounds(&frame.bracket(bracket))
                .map(|b| b * FRAME_SHRINK),
        }
    }

    fn set_bounds(&mut self, slot: usize, (lo, hi): SlotBox) {
        for axis in 0..3 {
            self.bounds.min[axis][slot] = lo[axis];
            self.bounds.max[axis][slot] = hi[axis];
        }
    }
}

/// Nodes (the root is `nodes[0]`; none for an empty mesh), triangle packets, and the largest
/// coordinate magnitude of the triangles kept (for the rounding margin of the search).
#[derive(Clone, Debug, Default)]
pub(super) struct SearchTree {
    pub nodes: Vec<SearchNode>,
    pub packets: Vec<EnclosurePacket>,
    pub mesh_scale: f64,
}

/// A slot's box, `(lo, hi)` per axis of its node's frame.
type SlotBox = ([f32; 3], [f32; 3]);

/// What one slot of a node will become.
#[derive(Clone)]
enum Slot {
    /// A build node that stays a node (more triangles than a leaf takes).
    Node(NodeId),
    /// A build node whose subtree becomes one leaf.
    Leaf(NodeId),
    /// Several build nodes (siblings of an n-ary node), made a node of their own.
    Group(Vec<NodeId>),
}

impl SearchTree {
    /// Collapses `tree` (over `mesh`) as the module describes; degenerate triangles are left
    /// out.
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh, config: SearchTreeConfig) -> Self {
        let mut search = SearchTree::default();
        let Some(root) = tree.root() else {
            return search;
        };
        let below = tree.triangle_counts();
        let leaf_max = config.leaf_triangles.max(1) as u32;
        // Sized for every triangle at once, not grown by doubling (copies, fresh pages).
        let n = mesh.triangle_count();
        let mut planned = PacketPlan {
            triangles: Vec::with_capacity(n),
            groups: Vec::with_capacity(n.div_ceil(LANES) * 2),
            leaf: Vec::new(),
        };
        // Nodes to try a rotated frame for: (node, its slots, their aligned boxes, the slots
        // given a child), decided in parallel once the shape is known.
        let mut frame_trials: Vec<(usize, Vec<Slot>, Vec<SlotBox>, u32)> = Vec::new();
        search.nodes.push(SearchNode::EMPTY);
        let mut pending: Vec<(Vec<NodeId>, usize)> = vec![(vec![root], 0)];
        while let Some((members, index)) = pending.pop() {
            let slots = search.slots_of(tree, &below, leaf_max, members);
            let boxes: Vec<SlotBox> = slots
                .iter()
                .map(|slot| {
                    let b = slot
                        .members()
                        .iter()
                        .fold(Aabb::EMPTY, |b, &id| b.union(&tree.node(id).bounds));
                    (b.min.to_array(), b.max.to_array())
                })
                .collect();
            let triangles: u32 = slots
                .iter()
                .flat_map(|slot| slot.members())
                .map(|&id| below[id as usize])
                .sum();
            let trial = (config.rotated_frames && triangles <= FRAME_MAX_TRIANGLES)
                .then(|| (slots.clone(), boxes.clone()));
            let mut given = 0u32;
            for (k, slot) in slots.into_iter().enumerate() {
                // The members of the child node the slot becomes, or a leaf planned here.
                let child_members = match slot {
                    Slot::Leaf(id) => {
                        let first = planned.groups.len() as u32;
                        let count = search.plan_leaf(tree, mesh, id, &mut planned);
                        if count > 0 {
                            let node = &mut search.nodes[index];
                            node.set_bounds(k, boxes[k]);
                            node.child[k] = first;
                            node.triangles[k] = count;
                            given |= 1 << k;
                        }
                        continue;
                    }
                    Slot::Node(id) => tree.node(id).children().to_vec(),
                    Slot::Group(ids) => ids,
                };
                let child = search.nodes.len();
                search.nodes.push(SearchNode::EMPTY);
                let node = &mut search.nodes[index];
                node.set_bounds(k, boxes[k]);
                node.child[k] = child as u32;
                given |= 1 << k;
                pending.push((child_members, child));
            }
            if let Some((slots, aligned)) = trial {
                frame_trials.push((index, slots, aligned, given));
            }
        }
        // Rotated frames, tried for every small node at once; a node that takes one has the
        // boxes of its given slots replaced by the rotated ones.
        let frames: Vec<_> = frame_trials
            .par_iter()
            .map(|(_, slots, aligned, _)| rotated_boxes(tree, mesh, slots, aligned))
            .collect();
        for ((index, _, _, given), frame) in frame_trials.iter().zip(frames) {
            if let Some((frame, rotated)) = frame {
                let node = &mut search.nodes[*index];
                node.frame = Some(frame);
                for (k, &slot_box) in rotated.iter().enumerate() {
                    if given >> k & 1 == 1 {
                        node.set_bounds(k, slot_box);
                    }
                }
            }
        }
        // The packets' enclosures are most of the build: made in parallel, in the planned order.
        search.packets = planned
            .groups
            .par_iter()
            .map(|group| EnclosurePacket::new(&planned.triangles[group.clone()]))
            .collect();
        search
    }

    /// The (at most [`WIDTH`]) slots of a node whose children are `members`: small subtrees become
    /// leaves, the largest internal child is opened while it fits, and more than [`WIDTH`] are
    /// grouped.
    fn slots_of(
        &self,
        tree: &BuildTree,
        below: &[u32],
        leaf_max: u32,
        mut members: Vec<NodeId>,
    ) -> Vec<Slot> {
        let opens = |id: NodeId| {
            matches!(tree.node(id).content, NodeContent::Internal(_))
                && below[id as usize] > leaf_max
        };
        while members.len() < WIDTH {
            let widest = members
                .iter()
                .enumerate()
                .filter(|&(_, &id)| opens(id))
                .max_by(|a, b| {
                    let area = |id: NodeId| tree.node(id).bounds.surface_area();
                    area(*a.1).total_cmp(&area(*b.1))
                });
            let Some((k, &id)) = widest else { break };
            let children = tree.node(id).children();
            if members.len() - 1 + children.len() > WIDTH {
                break;
            }
            members.swap_remove(k);
            members.extend_from_slice(children);
        }
        let classify = |id: NodeId| {
            if opens(id) {
                Slot::Node(id)
            } else {
                Slot::Leaf(id)
            }
        };
        if members.len() > WIDTH {
            return group_in_width(tree, members)
                .into_iter()
                .map(|group| match group.as_slice() {
                    [only] => classify(*only),
                    _ => Slot::Group(group),
                })
                .collect();
        }
        members.into_iter().map(classify).collect()
    }

    /// Plans the non-degenerate triangles below `id` as the next packets; returns how many
    /// triangles.
    fn plan_leaf(
        &mut self,
        tree: &BuildTree,
        mesh: &TriangleMesh,
        id: NodeId,
        planned: &mut PacketPlan,
    ) -> u32 {
        let start = planned.triangles.len();
        tree.prims_below_into(id, &mut planned.leaf);
        for &p in &planned.leaf {
            let t = mesh.triangle(p as usize);
            if t.is_degenerate() {
                continue;
            }
            for v in [t.p0, t.p1, t.p2] {
                self.mesh_scale = self.mesh_scale.max(v.abs().max_element() as f64);
            }
            planned.triangles.push((p, [t.p0, t.p1, t.p2]));
        }
        let end = planned.triangles.len();
        planned
            .groups
            .extend((start..end).step_by(LANES).map(|g| g..(g + LANES).min(end)));
        (end - start) as u32
    }
}

/// The packets a [`SearchTree`] will hold, in order: each a range of `triangles` (one leaf's
/// triangles in runs of [`LANES`]), made once the tree's shape is known.
#[derive(Default)]
struct PacketPlan {
    triangles: Vec<(u32, [Vec3; 3])>,
    groups: Vec<std::ops::Range<usize>>,
    /// One leaf's face ids at a time (reused: no list per leaf).
    leaf: Vec<u32>,
}

impl Slot {
    /// The build nodes the slot covers.
    fn members(&self) -> &[NodeId] {
        match self {
            Slot::Node(id) | Slot::Leaf(id) => std::slice::from_ref(id),
            Slot::Group(ids) => ids,
        }
    }
}

/// Nodes with at most this many triangles below are tried for a rotated frame: near the leaves,
/// where the surface is nearly flat (and the build enumerates each triangle a few times only).
/// 64, 256, 1024 and 4096 measured: 1024 is as fast as 4096 (igea 0.51 M queries/s against 0.38
/// with no frames, 0.47 at 256) and builds faster.
const FRAME_MAX_TRIANGLES: u32 = 1024;

/// A node's boxes are rotated only when that shrinks their summed area below this share of the
/// axis-aligned boxes' (0.8, 0.95 and 1 measured alike, 0.95 a hair ahead).
const ROTATED_AREA_GAIN: f32 = 0.95;

/// The slots' boxes in a frame facing the mean normal of their triangles, if that makes them
/// smaller (their summed area below [`ROTATED_AREA_GAIN`] of the axis-aligned `aligned`'s), for
/// patches that face one way (area-weighted normals summing to at least half their total).
fn rotated_boxes(
    tree: &BuildTree,
    mesh: &TriangleMesh,
    slots: &[Slot],
    aligned: &[SlotBox],
) -> Option<(NodeFrame, Vec<SlotBox>)> {
    let mut prims = Vec::new();
    let triangles: Vec<Vec<[Vec3; 3]>> = slots
        .iter()
        .map(|slot| {
            let mut triangles = Vec::new();
            for &id in slot.members() {
                tree.prims_below_into(id, &mut prims);
                triangles.extend(
                    (prims.iter().map(|&p| mesh.triangle(p as usize)))
                        .filter(|t| !t.is_degenerate())
                        .map(|t| [t.p0, t.p1, t.p2]),
                );
            }
            triangles
        })
        .collect();
    let (mut normal, mut area) = (DVec3::ZERO, 0.0);
    for [a, b, c] in triangles.iter().flatten() {
        let n = (b.as_dvec3() - a.as_dvec3()).cross(c.as_dvec3() - a.as_dvec3());
        normal += n;
        area += n.length();
    }
    if normal.length() < 0.5 * area {
        return None;
    }
    let frame = NodeFrame::facing(normal)?;
    let rotated: Vec<SlotBox> = triangles
        .iter()
        .zip(aligned)
        .map(|(tris, &empty)| {
            if tris.is_empty() {
                empty
            } else {
                frame.box_of(tris.iter().flatten().copied())
            }
        })
        .collect();
    let box_area = |(lo, hi): SlotBox| {
        let e = Vec3::from(hi) - Vec3::from(lo);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    };
    let rotated_area: f32 = rotated.iter().map(|&b| box_area(b)).sum();
    let aligned_area: f32 = aligned.iter().map(|&b| box_area(b)).sum();
    (rotated_area < ROTATED_AREA_GAIN * aligned_area).then_some((frame, rotated))
}

/// More than [`WIDTH`] siblings in [`WIDTH`] groups of nearly equal size, by their centres along the
/// longest axis of their union.
fn group_in_width(tree: &BuildTree, mut members: Vec<NodeId>) -> Vec<Vec<NodeId>> {
    let bounds = members
        .iter()
        .fold(Aabb::EMPTY, |b, &id| b.union(&tree.node(id).bounds));
    let axis = bounds.extent().max_position();
    members.sort_by(|&a, &b| {
        let c = |id: NodeId| tree.node(id).bounds.center()[axis];
        c(a).total_cmp(&c(b))
    });
    let n = members.len();
    (0..WIDTH)
        .map(|g| members[g * n / WIDTH..(g + 1) * n / WIDTH].to_vec())
        .collect()
}
