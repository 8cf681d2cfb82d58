//! `TopLevel`: the BVH over the instances' world boxes, built by binned SAH as a binary tree and
//! traced in its collapse into wide nodes (`scene/wide_top_level.rs`), nearest child first.
//!
//! The mesh builders (`bvh/build/`) build over a mesh's triangles; the top level builds over
//! boxes, one per instance, so it has its own small builder here. Rays walk
//! [`TOP_LEVEL_WIDTH`]-wide nodes, several boxes tested at once: at least as fast as the binary
//! tree on every scene measured (BENCHMARKS.md, "Scenes: the top level").
//!
//! A live scene changes the tree in place between builds (`scene/live.rs` decides when):
//! [`TopLevel::refit`] recomputes every box bottom-up, keeping the topology, and
//! [`TopLevel::insert`] hangs a new leaf where its box grows the tree least. Both keep the one
//! rule the binary tree's sweeps need: a node's children come after it in `nodes`, so one
//! backwards sweep sees every child before its parent. The wide nodes are collapsed again at
//! every build and refit; an insertion is walked only after the refit that follows it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec3, Vec3};

use super::wide_top_level::WideTopLevel;
use crate::geometry::{Aabb, PreparedRay};

/// How many children a node of the walked tree has (4 or 8).
pub(super) const TOP_LEVEL_WIDTH: usize = 8;

/// A binary node: its box and, for a leaf, the one instance it holds; an interior node's
/// children are the nodes `first` and `first + 1`.
#[derive(Clone, Copy, Debug)]
pub(super) struct TopNode {
    pub bounds: Aabb,
    /// Leaf: the instance id. Interior: the index of the first child.
    pub first: u32,
    pub is_leaf: bool,
}

/// The top-level tree: one leaf per instance with a nonempty world box (when built; removed
/// instances keep an empty leaf until the next build).
#[derive(Clone, Debug, Default)]
pub(crate) struct TopLevel {
    nodes: Vec<TopNode>,
    /// `nodes` collapsed into wide nodes: what rays walk.
    wide: WideTopLevel<TOP_LEVEL_WIDTH>,
    /// Whether `wide` is behind `nodes`: from an insertion to the refit that follows it.
    stale: bool,
    /// [`TopLevel::cost`] when built: what refits are measured against.
    built_cost: f32,
    /// Instances `0..covered` have their leaf (those whose box was not empty): the ones the
    /// tree was built over, and those inserted since.
    covered: u32,
}

/// Centroid bins per axis of the binned SAH (Wald 2007, "On fast construction of SAH-based
/// bounding volume hierarchies").
const BINS: usize = 16;

/// An instance as the builder sees it.
#[derive(Clone, Copy)]
struct Item {
    id: u32,
    bounds: Aabb,
    centroid: Vec3,
}

impl TopLevel {
    /// Builds over `boxes[i]`, the world box of instance `i`; empty boxes are left out (nothing
    /// can hit them).
    pub fn build(boxes: impl ExactSizeIterator<Item = Aabb>) -> Self {
        let covered = boxes.len() as u32;
        let mut items: Vec<Item> = boxes
            .enumerate()
            .filter(|(_, b)| !b.is_empty())
            .map(|(id, bounds)| Item {
                id: id as u32,
                bounds,
                centroid: bounds.center(),
            })
            .collect();
        let mut top = TopLevel {
            nodes: Vec::with_capacity(2 * items.len()),
            wide: WideTopLevel::default(),
            stale: false,
            built_cost: 0.0,
            covered,
        };
        if !items.is_empty() {
            top.nodes.push(TopNode {
                bounds: Aabb::EMPTY,
                first: 0,
                is_leaf: true,
            });
            top.build_node(0, &mut items);
        }
        top.built_cost = top.cost();
        top.collapse();
        top
    }

    /// Makes the wide nodes anew from the binary ones.
    fn collapse(&mut self) {
        self.wide = WideTopLevel::collapse(&self.nodes);
        self.stale = false;
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Instances `0..instances_covered()` have their leaf if their box is not empty; later
    /// ones must be inserted.
    pub fn instances_covered(&self) -> u32 {
        self.covered
    }

    /// Records that instances `0..covered` now have their leaves (after inserting the new ones).
    pub fn cover_instances(&mut self, covered: u32) {
        self.covered = covered;
    }

    /// Recomputes every box bottom-up from `leaf_box(instance)`, keeping the topology (an empty
    /// box for a removed instance). Children follow their parent in `nodes`, so a backwards
    /// sweep finishes each child before its parent: `O(nodes)`, no stack. Returns the number of
    /// leaves left with an empty box (holes).
    pub fn refit(&mut self, leaf_box: impl Fn(u32) -> Aabb) -> usize {
        let mut holes = 0;
        for index in (0..self.nodes.len()).rev() {
            let node = self.nodes[index];
            self.nodes[index].bounds = if node.is_leaf {
                let bounds = leaf_box(node.first);
                holes += usize::from(bounds.is_empty());
                bounds
            } else {
                let first = node.first as usize;
                self.nodes[first]
                    .bounds
                    .union(&self.nodes[first + 1].bounds)
            };
        }
        self.collapse();
        holes
    }

    /// The number of leaves: a binary tree of `n` nodes has `(n + 1) / 2`.
    pub fn leaf_count(&self) -> usize {
        self.nodes.len().div_ceil(2)
    }

    /// Hangs a leaf for `instance` (world box `bounds`, not empty) into the tree: down from the
    /// root, into the child whose surface area the box grows least (Goldsmith & Salmon 1987's
    /// greedy descent), growing each box on the way; the leaf reached becomes an interior node
    /// over itself and the new leaf, both appended, so children still follow their parent.
    /// The wide nodes follow at the next [`TopLevel::refit`], which must come before a walk.
    pub fn insert(&mut self, instance: u32, bounds: Aabb) {
        self.stale = true;
        let leaf = TopNode {
            bounds,
            first: instance,
            is_leaf: true,
        };
        if self.nodes.is_empty() {
            self.nodes.push(leaf);
            return;
        }
        let mut index = 0;
        while !self.nodes[index].is_leaf {
            let node = &mut self.nodes[index];
            node.bounds = node.bounds.union(&bounds);
            let first = node.first as usize;
            let growth =
                |n: &TopNode| n.bounds.union(&bounds).surface_area() - n.bounds.surface_area();
            index = if growth(&self.nodes[first]) <= growth(&self.nodes[first + 1]) {
                first
            } else {
                first + 1
            };
        }
        let old = self.nodes[index];
        let first = self.nodes.len() as u32;
        self.nodes.extend([old, leaf]);
        self.nodes[index] = TopNode {
            bounds: old.bounds.union(&bounds),
            first,
            is_leaf: false,
        };
    }

    /// The SAH cost of the tree relative to its root, `Σ_n SA(n) / SA(root)` over every node:
    /// the expected number of boxes a random ray through the root meets (Goldsmith & Salmon
    /// 1987; MacDonald & Booth 1990). 0 for an empty or flat tree.
    pub fn cost(&self) -> f32 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = root.bounds.surface_area();
        if root_area <= 0.0 || root_area.is_nan() {
            return 0.0;
        }
        self.nodes
            .iter()
            .map(|n| n.bounds.surface_area())
            .sum::<f32>()
            / root_area
    }

    /// [`TopLevel::cost`] as it was when the tree was built.
    pub fn built_cost(&self) -> f32 {
        self.built_cost
    }

    /// Every leaf's box and each node's box inside its parent's, in the binary tree and in the
    /// wide one, and both with the same leaves: the leaves' `(instance, box)` pairs, in the
    /// wide tree's node order, for the caller to check against the scene.
    pub fn check_nesting(&self) -> Result<Vec<(u32, Aabb)>, String> {
        let binary = self.check_binary_nesting()?;
        if self.stale {
            return Err("the wide nodes were not collapsed after an insertion".into());
        }
        let wide = self.wide.check_nesting()?;
        let sorted = |mut leaves: Vec<(u32, Aabb)>| {
            leaves.sort_by_key(|(id, _)| *id);
            leaves
        };
        if sorted(binary) != sorted(wide.clone()) {
            return Err("the wide nodes do not hold the binary tree's leaves".into());
        }
        Ok(wide)
    }

    /// [`TopLevel::check_nesting`] of the binary tree: its leaves in node order.
    fn check_binary_nesting(&self) -> Result<Vec<(u32, Aabb)>, String> {
        let mut leaves = Vec::new();
        for (index, node) in self.nodes.iter().enumerate() {
            if node.is_leaf {
                leaves.push((node.first, node.bounds));
                continue;
            }
            let first = node.first as usize;
            if first <= index || first + 1 >= self.nodes.len() {
                return Err(format!(
                    "node {index}: children at {first} do not follow it"
                ));
            }
            for child in [first, first + 1] {
                if !node.bounds.contains(&self.nodes[child].bounds) {
                    return Err(format!(
                        "node {index}: box {:?} does not hold child {child}'s {:?}",
                        node.bounds, self.nodes[child].bounds
                    ));
                }
            }
        }
        Ok(leaves)
    }

    /// Fills node `index` with `items`: a leaf for one item, else two children split where the
    /// binned SAH cost `SA(L) · |L| + SA(R) · |R|` is least.
    fn build_node(&mut self, index: usize, items: &mut [Item]) {
        let bounds = items.iter().fold(Aabb::EMPTY, |b, i| b.union(&i.bounds));
        if let [item] = items {
            self.nodes[index] = TopNode {
                bounds,
                first: item.id,
                is_leaf: true,
            };
            return;
        }
        let split = binned_sah_split(items);
        let first = self.nodes.len();
        self.nodes[index] = TopNode {
            bounds,
            first: first as u32,
            is_leaf: false,
        };
        let placeholder = self.nodes[index];
        self.nodes.extend([placeholder, placeholder]);
        let (left, right) = items.split_at_mut(split);
        self.build_node(first, left);
        self.build_node(first + 1, right);
    }

    /// Walks the instances whose boxes, grown by `pad` on each side, the ray meets within its
    /// `[tmin, tmax]`, nearest first, calling `visit(instance, ray)`; `visit` may shrink
    /// `ray.tmax` (a closest-hit walk) and returns `true` to stop the walk (an any-hit walk).
    ///
    /// Every box is tested grown by `pad` (see `Scene::box_pad`): the rounding of a ray carried
    /// into an instance's space moves its points by up to that much in world space, and the
    /// grown boxes keep every point it could hit. The walk is the wide nodes'
    /// ([`WideTopLevel::walk`]).
    pub fn walk(
        &self,
        ray: &mut PreparedRay,
        pad: f32,
        visit: impl FnMut(u32, &mut PreparedRay) -> bool,
    ) {
        debug_assert!(!self.stale, "a walk between an insertion and its refit");
        self.wide.walk(ray, pad, visit);
    }
}

impl TopLevel {
    /// Calls `visit(instance, distance)` with the leaves in the order of their boxes' distance
    /// from `p` (0 inside a box), nearest first, skipping empty boxes, and stops before the
    /// first leaf farther than the bound `visit` returns (start: +∞). A best-first walk over
    /// the binary nodes with a priority queue (the branch and bound of nearest-neighbour
    /// search: a node's box distance bounds every leaf under it from below, so no leaf nearer
    /// than the bound is passed over). The binary nodes are current after an insertion too.
    pub fn nearest_first(&self, p: DVec3, mut visit: impl FnMut(u32, f64) -> f64) {
        let Some(root) = self.nodes.first() else {
            return;
        };
        let mut bound = f64::INFINITY;
        let mut queue = BinaryHeap::new();
        queue.push(Reverse(NodeDistance(box_distance(&root.bounds, p), 0)));
        while let Some(Reverse(NodeDistance(distance, index))) = queue.pop() {
            if distance > bound {
                break;
            }
            let node = self.nodes[index as usize];
            if node.is_leaf {
                bound = visit(node.first, distance);
                continue;
            }
            for child in [node.first, node.first + 1] {
                let bounds = &self.nodes[child as usize].bounds;
                if !bounds.is_empty() {
                    queue.push(Reverse(NodeDistance(box_distance(bounds, p), child)));
                }
            }
        }
    }
}

/// The distance from `p` to the nearest point of `bounds`, in f64: 0 inside, +∞ for an empty
/// box.
fn box_distance(bounds: &Aabb, p: DVec3) -> f64 {
    if bounds.is_empty() {
        return f64::INFINITY;
    }
    let below = bounds.min.as_dvec3() - p;
    let above = p - bounds.max.as_dvec3();
    below.max(above).max(DVec3::ZERO).length()
}

/// A node's box distance and index, ordered by distance (then index, for a total order).
#[derive(Clone, Copy, PartialEq)]
struct NodeDistance(f64, u32);

impl Eq for NodeDistance {}

impl PartialOrd for NodeDistance {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for NodeDistance {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

/// Sorts `items` around the cheapest binned-SAH plane and returns the size of the left part
/// (between 1 and `items.len() - 1`). Items whose centroids cannot be told apart by bins are
/// split in half, in their order.
fn binned_sah_split(items: &mut [Item]) -> usize {
    let centroids = items
        .iter()
        .fold(Aabb::EMPTY, |b, i| b.union_point(i.centroid));
    let extent = centroids.extent();
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, plane)
    for axis in 0..3 {
        if extent[axis] <= 0.0 || extent[axis].is_nan() {
            continue;
        }
        let lo = centroids.min[axis];
        let scale = BINS as f32 / extent[axis];
        let bin_of = |c: f32| (((c - lo) * scale) as usize).min(BINS - 1);
        let mut bin_boxes = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for item in items.iter() {
            let bin = bin_of(item.centroid[axis]);
            bin_boxes[bin] = bin_boxes[bin].union(&item.bounds);
            bin_counts[bin] += 1;
        }
        // Areas and counts right of each plane, swept from the right.
        let mut right_cost = [0.0f32; BINS];
        let (mut right_box, mut right_count) = (Aabb::EMPTY, 0usize);
        for plane in (1..BINS).rev() {
            right_box = right_box.union(&bin_boxes[plane]);
            right_count += bin_counts[plane];
            right_cost[plane] = right_box.surface_area() * right_count as f32;
        }
        let (mut left_box, mut left_count) = (Aabb::EMPTY, 0usize);
        for plane in 1..BINS {
            left_box = left_box.union(&bin_boxes[plane - 1]);
            left_count += bin_counts[plane - 1];
            if left_count == 0 || left_count == items.len() {
                continue;
            }
            let cost = left_box.surface_area() * left_count as f32 + right_cost[plane];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, plane));
            }
        }
    }
    let Some((_, axis, plane)) = best else {
        return items.len() / 2;
    };
    let lo = centroids.min[axis];
    let scale = BINS as f32 / extent[axis];
    let bin_of = |c: f32| (((c - lo) * scale) as usize).min(BINS - 1);
    let mut left = 0;
    for i in 0..items.len() {
        if bin_of(items[i].centroid[axis]) < plane {
            items.swap(i, left);
            left += 1;
        }
    }
    left
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    #[test]
    fn walk_finds_every_box_the_ray_meets_nearest_first() {
        let boxes: Vec<Aabb> = (0..40)
            .map(|i| {
                let x = (i * 7 % 40) as f32;
                Aabb::new(Vec3::new(x, -0.5, -0.5), Vec3::new(x + 0.5, 0.5, 0.5))
            })
            .chain([Aabb::EMPTY])
            .collect();
        let top = TopLevel::build(boxes.iter().copied());
        let mut ray = PreparedRay::new(&Ray::new(Vec3::new(-1.0, 0.0, 0.0), Vec3::X));
        let mut seen = Vec::new();
        top.walk(&mut ray, 0.0, |id, _| {
            seen.push(id);
            false
        });
        let xs: Vec<f32> = seen.iter().map(|&i| boxes[i as usize].min.x).collect();
        assert_eq!(seen.len(), 40);
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "{xs:?}");
        let mut miss = PreparedRay::new(&Ray::new(Vec3::new(-1.0, 2.0, 0.0), Vec3::X));
        top.walk(&mut miss, 0.0, |_, _| panic!("no box is met"));
    }

    #[test]
    fn inserted_and_refitted_leaves_stay_nested_and_found() {
        let unit =
            |x: f32, y: f32| Aabb::new(Vec3::new(x, y, -0.5), Vec3::new(x + 0.5, y + 0.5, 0.5));
        let mut boxes: Vec<Aabb> = (0..20).map(|i| unit(i as f32, 0.0)).collect();
        let mut top = TopLevel::build(boxes.iter().copied());
        let built = top.cost();
        assert_eq!(top.built_cost(), built);
        for i in 20..30 {
            boxes.push(unit(i as f32 - 25.0, 3.0));
            top.insert(i, boxes[i as usize]);
        }
        top.cover_instances(30);
        // Move a third of the boxes up by 3 and remove one: the refit follows.
        for b in boxes.iter_mut().step_by(3) {
            *b = Aabb::new(b.min + Vec3::Y * 3.0, b.max + Vec3::Y * 3.0);
        }
        boxes[7] = Aabb::EMPTY;
        assert_eq!(top.refit(|id| boxes[id as usize]), 1);
        assert_eq!(top.leaf_count(), 30);
        let leaves = top.check_nesting().unwrap();
        assert_eq!(leaves.len(), 30);
        for (id, bounds) in leaves {
            assert_eq!(bounds, boxes[id as usize]);
        }
        let mut ray = PreparedRay::new(&Ray::new(Vec3::new(-10.0, 3.25, 0.0), Vec3::X));
        let mut seen = Vec::new();
        top.walk(&mut ray, 0.0, |id, _| {
            seen.push(id);
            false
        });
        seen.sort();
        let expected: Vec<u32> = (0..30)
            .filter(|&i| !boxes[i as usize].is_empty() && boxes[i as usize].min.y == 3.0)
            .collect();
        assert_eq!(seen, expected);
        assert!(top.cost() > built);
    }
}
