//! `WideTopLevel`: the top level's binary tree collapsed into `W`-wide nodes, the form rays
//! walk (`W` = 4 or 8).
//!
//! The binary tree (`top_level.rs`) is what is built, refitted and inserted into; after each
//! of those it is collapsed again here (linear in its nodes: a fraction of a refit's cost).

use glam::Vec3;

use super::grown_box_lanes::{grown_boxes, GrownBoxRay};
use super::top_level::TopNode;
use crate::bvh::layout::LaneBoxes;
use crate::bvh::layout::TraversalStack;
use crate::geometry::{Aabb, PreparedRay};

/// A node: up to `W` children, each a node or a leaf (one instance), their boxes as lanes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct WideTopNode<const W: usize> {
    boxes: LaneBoxes<W>,
    /// Per lane: the child node's index, or for a leaf lane the instance id.
    children: [u32; W],
    /// Bit `i`: lane `i` is a leaf.
    leaves: u32,
    /// Bit `i`: lane `i` holds a child (the others hold the empty box).
    occupied: u32,
}

impl<const W: usize> WideTopNode<W> {
    const EMPTY: Self = Self {
        boxes: [[[f32::INFINITY; W]; 3], [[f32::NEG_INFINITY; W]; 3]],
        children: [0; W],
        leaves: 0,
        occupied: 0,
    };

    fn set_lane(&mut self, lane: usize, bounds: &Aabb, child: u32, leaf: bool) {
        for axis in 0..3 {
            self.boxes[0][axis][lane] = bounds.min[axis];
            self.boxes[1][axis][lane] = bounds.max[axis];
        }
        self.children[lane] = child;
        self.occupied |= 1 << lane;
        self.leaves |= u32::from(leaf) << lane;
    }

    fn lane_box(&self, lane: usize) -> Aabb {
        Aabb::new(
            Vec3::from_array(self.boxes[0].map(|axis| axis[lane])),
            Vec3::from_array(self.boxes[1].map(|axis| axis[lane])),
        )
    }
}

/// A child waiting on the walk's stack: its node index or instance id, whether it is a leaf,
/// and where the ray enters its grown box.
type Postponed = (u32, bool, f32);

/// The collapsed tree; node 0 is the root, and every node's children come after it.
#[derive(Clone, Debug)]
pub(super) struct WideTopLevel<const W: usize> {
    nodes: Vec<WideTopNode<W>>,
    /// The binary root's box: the scene the rays' error margins are set for.
    bounds: Aabb,
}

impl<const W: usize> Default for WideTopLevel<W> {
    fn default() -> Self {
        Self {
            nodes: Vec::new(),
            bounds: Aabb::EMPTY,
        }
    }
}

impl<const W: usize> WideTopLevel<W> {
    const VALID_WIDTH: () = assert!(W == 4 || W == 8, "the top level is 4 or 8 wide");

    /// Collapses the binary tree `binary` (root at 0, an interior node's children at `first`
    /// and `first + 1`): each wide node starts from a binary node's two children and opens the
    /// child of largest surface area — the one most rays reach — until it has `W` children or
    /// only leaves (the collapse of Wald et al. 2008, "Getting rid of packets", as the meshes'
    /// wide layouts do). A binary tree of one leaf becomes a root with one leaf lane.
    pub fn collapse(binary: &[TopNode]) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_WIDTH;
        let Some(root) = binary.first() else {
            return Self::default();
        };
        let mut wide = Self {
            nodes: Vec::with_capacity(binary.len() / (W - 1) + 1),
            bounds: root.bounds,
        };
        wide.nodes.push(WideTopNode::EMPTY);
        // (wide node to fill, binary node it stands for)
        let mut work = vec![(0usize, 0usize)];
        let mut lanes: Vec<usize> = Vec::with_capacity(W);
        while let Some((at, from)) = work.pop() {
            lanes.clear();
            let node = &binary[from];
            if node.is_leaf {
                lanes.push(from);
            } else {
                lanes.extend([node.first as usize, node.first as usize + 1]);
            }
            while lanes.len() < W {
                let widest = lanes
                    .iter()
                    .enumerate()
                    .filter(|(_, &b)| !binary[b].is_leaf)
                    .max_by(|(_, &a), (_, &b)| {
                        let area = |n: usize| binary[n].bounds.surface_area();
                        area(a).total_cmp(&area(b))
                    })
                    .map(|(k, &b)| (k, binary[b].first as usize));
                let Some((k, first)) = widest else {
                    break;
                };
                lanes[k] = first;
                lanes.push(first + 1);
            }
            let mut filled = WideTopNode::EMPTY;
            for (lane, &b) in lanes.iter().enumerate() {
                let child = &binary[b];
                if child.is_leaf {
                    filled.set_lane(lane, &child.bounds, child.first, true);
                } else {
                    let index = wide.nodes.len();
                    wide.nodes.push(WideTopNode::EMPTY);
                    filled.set_lane(lane, &child.bounds, index as u32, false);
                    work.push((index, b));
                }
            }
            wide.nodes[at] = filled;
        }
        wide
    }

    /// Walks the instances whose boxes, grown by `pad` on each side, the ray meets within its
    /// `[tmin, tmax]`, nearest first, calling `visit(instance, ray)`; `visit` may shrink
    /// `ray.tmax` (a closest-hit walk), which culls the children entered beyond it, and returns
    /// `true` to stop the walk (an any-hit walk).
    ///
    /// The ray's margins are set for the grown root box ([`PreparedRay::bound_errors_within`]);
    /// each node's `W` grown boxes are tested at once ([`grown_boxes`]) against
    /// `[tmin - m, tmax + m]`, `m` the box margin. The children met are ordered by entry
    /// distance and pushed farthest first, so the nearest is popped next; a popped child whose
    /// entry lies beyond `tmax + m` is dropped (Wald et al. 2008 order wide-node children so).
    pub fn walk(
        &self,
        ray: &mut PreparedRay,
        pad: f32,
        mut visit: impl FnMut(u32, &mut PreparedRay) -> bool,
    ) {
        if self.nodes.is_empty() || self.bounds.is_empty() {
            // No nodes, or only removed instances' empty leaves.
            return;
        }
        let pad3 = Vec3::splat(pad);
        ray.bound_errors_within(&Aabb::new(self.bounds.min - pad3, self.bounds.max + pad3));
        let lanes_ray = GrownBoxRay::new(ray, pad);
        // On the machine stack, not allocated per ray; deeper trees spill to the heap.
        let mut stack: TraversalStack<Postponed, 64> = TraversalStack::new();
        let mut node = 0usize;
        loop {
            let wide = &self.nodes[node];
            let (met, entry) = grown_boxes(&wide.boxes, &lanes_ray, ray.box_tmin(), ray.box_tmax());
            push_nearest_last(
                met & wide.occupied,
                wide.leaves,
                &wide.children,
                &entry,
                &mut stack,
            );
            loop {
                let Some((reference, leaf, near)) = stack.pop() else {
                    return;
                };
                // A nearer hit found since the push culls the child.
                if near > ray.box_tmax() {
                    continue;
                }
                if !leaf {
                    node = reference as usize;
                    break;
                }
                if visit(reference, ray) {
                    return;
                }
            }
        }
    }

    /// Checks that every lane box of an interior lane holds its node's boxes, that children
    /// follow their parent, and that the root's lanes lie in `bounds`; returns the leaves'
    /// `(instance, box)` pairs.
    pub fn check_nesting(&self) -> Result<Vec<(u32, Aabb)>, String> {
        let mut leaves = Vec::new();
        for (index, node) in self.nodes.iter().enumerate() {
            for lane in 0..W {
                if node.occupied & (1 << lane) == 0 {
                    if !node.lane_box(lane).is_empty() {
                        return Err(format!("wide node {index}: unused lane {lane} not empty"));
                    }
                    continue;
                }
                let bounds = node.lane_box(lane);
                if index == 0 && !self.bounds.contains(&bounds) {
                    return Err(format!("wide root: lane {lane} outside the root box"));
                }
                let child = node.children[lane];
                if node.leaves & (1 << lane) != 0 {
                    leaves.push((child, bounds));
                    continue;
                }
                let Some(below) = self.nodes.get(child as usize) else {
                    return Err(format!("wide node {index}: child {child} does not exist"));
                };
                if child as usize <= index {
                    return Err(format!(
                        "wide node {index}: child {child} does not follow it"
                    ));
                }
                for k in 0..W {
                    if below.occupied & (1 << k) != 0 && !bounds.contains(&below.lane_box(k)) {
                        return Err(format!(
                            "wide node {index}: lane {lane}'s box {bounds:?} does not hold \
                             lane {k} of node {child}"
                        ));
                    }
                }
            }
        }
        Ok(leaves)
    }
}

/// Pushes the children of lanes `met` onto `stack`, farthest entry first, so that the nearest
/// is popped next: one child as is, more by insertion sort (at most `W` entries).
#[inline(always)]
fn push_nearest_last<const W: usize>(
    met: u32,
    leaves: u32,
    children: &[u32; W],
    entry: &[f32; W],
    stack: &mut TraversalStack<Postponed, 64>,
) {
    let item = |lane: usize| (children[lane], leaves & (1 << lane) != 0, entry[lane]);
    if met & met.wrapping_sub(1) == 0 {
        if met != 0 {
            stack.push(item(met.trailing_zeros() as usize));
        }
        return;
    }
    let mut order = [(0u32, false, 0.0f32); W];
    let mut n = 0;
    let mut rest = met;
    while rest != 0 {
        let next = item(rest.trailing_zeros() as usize);
        rest &= rest - 1;
        let mut k = n;
        while k > 0 && order[k - 1].2 < next.2 {
            order[k] = order[k - 1];
            k -= 1;
        }
        order[k] = next;
        n += 1;
    }
    for &postponed in &order[..n] {
        stack.push(postponed);
    }
}
