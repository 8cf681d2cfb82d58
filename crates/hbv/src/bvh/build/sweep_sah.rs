//! Top-down full-sweep SAH construction: every split position of every axis is priced
//! (MacDonald & Booth 1990, "Heuristics for ray tracing using space subdivision"; the sweep
//! over presorted orders as in Wald, Boulos & Shirley 2007, "Ray tracing deformable scenes
//! using dynamic bounding volume hierarchies", ACM TOG 26(1)).

use std::sync::atomic::{AtomicBool, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::{
    bounds_and_centroid_bounds, prim_refs, Builder, LeafPolicy, PrimRef, RangeTree, Subtree,
    PARALLEL_SUBTREE_MIN, SAH_DEPTH_LIMIT,
};
use crate::bvh::tree::BuildTree;
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Options of [`SweepSahBuilder`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SweepSahConfig {
    /// When to make a leaf; see [`LeafPolicy`].
    pub leaf: LeafPolicy,
}

/// Builds a binary tree top down, splitting each node at the lowest-SAH position among all
/// `3 (n - 1)` ways to cut its triangles, sorted by box centre on an axis, into a prefix and a
/// suffix:
///
/// ```text
///   SAH(axis, i) = C_t + C_i · (SA(first i) · i + SA(last n - i) · (n - i)) / SA(N)
/// ```
///
/// A sweep from the right stores the suffix areas, and a sweep from the left prices every `i`;
/// the node is then split, or made a leaf as [`LeafPolicy`] says. It is the exact greedy
/// optimum that [`BinnedSahBuilder`](super::BinnedSahBuilder) approximates with bins, so its
/// trees are a little better, at several times the build time.
///
/// The three orders are sorted once; a split keeps each of them sorted on both sides by a
/// stable partition, so a node costs O(n) and the build O(n log n) for balanced splits. The
/// children of large nodes are built in parallel (`rayon::join`).
#[derive(Clone, Debug, Default)]
pub struct SweepSahBuilder {
    pub config: SweepSahConfig,
}

impl Builder for SweepSahBuilder {
    fn name(&self) -> &'static str {
        "sweep-sah"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        self.build_with_root_depth(mesh, 0)
    }
}

impl SweepSahBuilder {
    pub fn new(config: SweepSahConfig) -> Self {
        Self { config }
    }

    /// [`Builder::build`] with the root at `root_depth` instead of 0: tests start near the
    /// depth limit to see the median fallback.
    fn build_with_root_depth(&self, mesh: &TriangleMesh, root_depth: u32) -> BuildTree {
        let prims = prim_refs(mesh);
        let n = prims.len();
        let shared = SweepInputs {
            centroids: prims.par_iter().map(PrimRef::centroid).collect(),
            goes_left: (0..n).map(|_| AtomicBool::new(false)).collect(),
            prims,
        };
        let mut orders = [0, 1, 2].map(|axis| shared.sorted_along(axis));
        let mut scratch = vec![0u32; n];
        let mut suffix_areas = vec![0f32; n];

        let mut ranges = RangeTree::new(n);
        if let Some(root) = ranges.root() {
            let [x, y, z] = &mut orders;
            let node = NodeOrders {
                orders: [x, y, z],
                scratch: &mut scratch,
                suffix_areas: &mut suffix_areas,
            };
            let (bounds, _) = bounds_and_centroid_bounds(&shared.prims);
            self.build_subtree(&shared, node, bounds, root, root_depth);
        }
        // Every leaf is a range of each order alike; take the x order's.
        let leaf_order: Vec<PrimRef> = orders[0]
            .iter()
            .map(|&i| shared.prims[i as usize])
            .collect();
        ranges.into_build_tree(&leaf_order)
    }

    /// Builds the subtree over the triangles of `node`, whose box is `bounds`.
    fn build_subtree(
        &self,
        shared: &SweepInputs,
        node: NodeOrders<'_>,
        bounds: Aabb,
        subtree: Subtree<'_>,
        depth: u32,
    ) {
        let n = node.len();
        let policy = &self.config.leaf;
        if policy.is_leaf_without_split(n) {
            return subtree.make_leaf();
        }
        let split = if depth < SAH_DEPTH_LIMIT {
            best_sweep_split(shared, &node.orders, node.suffix_areas)
        } else {
            None
        };
        if policy.is_leaf(n, bounds.surface_area(), split.map(|s| s.weighted_area)) {
            return subtree.make_leaf();
        }
        // Without a SAH split (too deep, or areas beyond f32), halve along the longest axis.
        let (axis, left_count) = match split {
            Some(s) => (s.axis, s.left_count),
            None => (node.longest_axis(&shared.centroids), n / 2),
        };
        let (left_node, right_node) = node.split(shared, axis, left_count);
        let left_bounds = left_node.bounds(shared);
        let right_bounds = right_node.bounds(shared);

        let (left_subtree, right_subtree) = subtree.split(left_count);
        let build_left =
            || self.build_subtree(shared, left_node, left_bounds, left_subtree, depth + 1);
        let build_right =
            || self.build_subtree(shared, right_node, right_bounds, right_subtree, depth + 1);
        if n >= PARALLEL_SUBTREE_MIN {
            rayon::join(build_left, build_right);
        } else {
            build_left();
            build_right();
        }
    }
}

/// What every node of one build reads: the triangles and their centres, by index, and one
/// flag per triangle that a split sets to say on which side the triangle goes. Each flag is
/// written only by the task that owns its triangle; `rayon::join` orders those writes before
/// the children read them, so relaxed atomics suffice.
struct SweepInputs {
    prims: Vec<PrimRef>,
    centroids: Vec<Vec3>,
    goes_left: Vec<AtomicBool>,
}

impl SweepInputs {
    /// Indices of all triangles sorted by centre coordinate on `axis`, ties by index.
    fn sorted_along(&self, axis: usize) -> Vec<u32> {
        let mut keys: Vec<u64> = self
            .centroids
            .par_iter()
            .enumerate()
            .map(|(i, c)| (u64::from(sortable_bits(c[axis])) << 32) | i as u64)
            .collect();
        keys.par_sort_unstable();
        keys.into_par_iter().map(|k| k as u32).collect()
    }

    #[inline]
    fn bounds(&self, i: u32) -> &Aabb {
        &self.prims[i as usize].bounds
    }
}

/// The bits of a finite `f32` as a `u32` that sorts in the same order (`-0.0` before `0.0`):
/// negative numbers have all bits flipped, positive ones the sign bit set.
fn sortable_bits(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | (1 << 31)
    }
}

/// One node's share of the build's arrays: its triangles in the three sorted orders, and
/// scratch space of the same length.
struct NodeOrders<'a> {
    orders: [&'a mut [u32]; 3],
    scratch: &'a mut [u32],
    suffix_areas: &'a mut [f32],
}

impl<'a> NodeOrders<'a> {
    fn len(&self) -> usize {
        self.scratch.len()
    }

    fn bounds(&self, shared: &SweepInputs) -> Aabb {
        self.orders[0]
            .iter()
            .fold(Aabb::EMPTY, |b, &i| b.union(shared.bounds(i)))
    }

    /// The axis along which the centres spread most.
    fn longest_axis(&self, centroids: &[Vec3]) -> usize {
        let spread = |axis: usize| {
            let order = &self.orders[axis];
            let first = centroids[order[0] as usize][axis];
            let last = centroids[order[order.len() - 1] as usize][axis];
            last - first
        };
        (0..3).fold(0, |best, axis| {
            if spread(axis) > spread(best) {
                axis
            } else {
                best
            }
        })
    }

    /// Splits the node in two: the first `left_count` triangles of the order along `axis` go
    /// left. The other two orders are stably partitioned by the same sides, so that all three
    /// stay sorted on both sides.
    fn split(
        self,
        shared: &SweepInputs,
        axis: usize,
        left_count: usize,
    ) -> (NodeOrders<'a>, NodeOrders<'a>) {
        let (left, right) = self.orders[axis].split_at(left_count);
        for &i in left {
            shared.goes_left[i as usize].store(true, Ordering::Relaxed);
        }
        for &i in right {
            shared.goes_left[i as usize].store(false, Ordering::Relaxed);
        }
        let NodeOrders {
            mut orders,
            scratch,
            suffix_areas,
        } = self;
        for (other, order) in orders.iter_mut().enumerate() {
            if other != axis {
                stable_partition(order, scratch, |i| {
                    shared.goes_left[i as usize].load(Ordering::Relaxed)
                });
            }
        }
        let [(x0, x1), (y0, y1), (z0, z1)] = orders.map(|order| order.split_at_mut(left_count));
        let (scratch_left, scratch_right) = scratch.split_at_mut(left_count);
        let (areas_left, areas_right) = suffix_areas.split_at_mut(left_count);
        (
            NodeOrders {
                orders: [x0, y0, z0],
                scratch: scratch_left,
                suffix_areas: areas_left,
            },
            NodeOrders {
                orders: [x1, y1, z1],
                scratch: scratch_right,
                suffix_areas: areas_right,
            },
        )
    }
}

/// A prefix/suffix cut of the order along `axis`.
#[derive(Clone, Copy, Debug)]
struct SweepSplit {
    axis: usize,
    left_count: usize,
    /// `SA(L) · n_L + SA(R) · n_R`.
    weighted_area: f32,
}

/// The cut of lowest SAH over all axes and positions (the first one on ties), or `None` when no
/// cut has a finite cost. `suffix_areas` is scratch space of the node's length.
fn best_sweep_split(
    shared: &SweepInputs,
    orders: &[&mut [u32]; 3],
    suffix_areas: &mut [f32],
) -> Option<SweepSplit> {
    let n = suffix_areas.len();
    let (mut best_cost, mut best_axis, mut best_left_count) = (f32::INFINITY, 0, 0);
    for (axis, order) in orders.iter().enumerate() {
        // Right to left: `suffix_areas[i]` = SA of the triangles from `i` on.
        let mut right = Aabb::EMPTY;
        for i in (1..n).rev() {
            right = right.union(shared.bounds(order[i]));
            suffix_areas[i] = right.surface_area();
        }
        // Left to right: price the cut before `i` with the first `i` triangles on the left.
        let mut left = Aabb::EMPTY;
        for i in 1..n {
            left = left.union(shared.bounds(order[i - 1]));
            let cost = left.surface_area() * i as f32 + suffix_areas[i] * (n - i) as f32;
            if cost < best_cost {
                (best_cost, best_axis, best_left_count) = (cost, axis, i);
            }
        }
    }
    (best_left_count > 0).then_some(SweepSplit {
        axis: best_axis,
        left_count: best_left_count,
        weighted_area: best_cost,
    })
}

/// Reorders `items` so that those for which `goes_left` holds come first, each side keeping its
/// order; `scratch` is at least as long as `items`.
fn stable_partition(items: &mut [u32], scratch: &mut [u32], goes_left: impl Fn(u32) -> bool) {
    let (mut left, mut right) = (0, 0);
    for k in 0..items.len() {
        let item = items[k];
        if goes_left(item) {
            items[left] = item;
            left += 1;
        } else {
            scratch[right] = item;
            right += 1;
        }
    }
    items[left..].copy_from_slice(&scratch[..right]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::range_tree::assert_median_splits_past_the_depth_limit;
    use crate::bvh::build::{primitive_bounds, BinnedSahBuilder};
    use crate::bvh::cost::{sah_cost, SahWeights};
    use crate::mesh::procedural::unit_triangles_at;
    use crate::mesh::procedural::{default_scene, torus};

    fn sweep(max_leaf_size: usize) -> SweepSahBuilder {
        SweepSahBuilder::new(SweepSahConfig {
            leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
        })
    }

    #[test]
    fn sortable_bits_keep_the_order_of_floats() {
        let xs = [f32::MIN, -1.0, -1e-30, -0.0, 0.0, 1e-30, 1.0, f32::MAX];
        for w in xs.windows(2) {
            assert!(sortable_bits(w[0]) < sortable_bits(w[1]), "{w:?}");
        }
    }

    #[test]
    fn stable_partition_keeps_both_sides_in_order() {
        let mut items = [5, 2, 8, 1, 9, 4];
        let mut scratch = [0; 6];
        stable_partition(&mut items, &mut scratch, |i| i % 2 == 0);
        assert_eq!(items, [2, 8, 4, 5, 1, 9]);
    }

    #[test]
    fn two_clusters_are_separated_at_the_root() {
        let corners: Vec<Vec3> = (0..6)
            .map(|i| Vec3::new(0.0, i as f32 * 0.1, 0.0))
            .chain((0..6).map(|i| Vec3::new(0.0, 50.0 + i as f32 * 0.1, 0.0)))
            .collect();
        let mesh = unit_triangles_at(&corners);
        let tree = sweep(4).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 4).unwrap();
        let root = tree.node(tree.root().unwrap());
        for &c in root.children() {
            assert!(tree.node(c).bounds.extent().y < 2.0);
        }
    }

    #[test]
    fn one_triangle_identical_triangles_and_coincident_centroids() {
        let one = unit_triangles_at(&[Vec3::ONE]);
        let tree = SweepSahBuilder::default().build(&one);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[0]);

        let same = unit_triangles_at(&[Vec3::ZERO; 40]);
        for max_leaf_size in [1, 4] {
            let tree = sweep(max_leaf_size).build(&same);
            tree.validate(&primitive_bounds(&same), max_leaf_size)
                .unwrap();
        }

        // Boxes of 30 sizes, all centred on the origin.
        let positions: Vec<Vec3> = (1..=30)
            .flat_map(|k| {
                let s = k as f32;
                [
                    Vec3::new(-s, -s, 0.0),
                    Vec3::new(s, -s, 0.0),
                    Vec3::new(s, s, 0.0),
                ]
            })
            .collect();
        let indices = (0..30u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let nested = TriangleMesh::new(positions, indices).unwrap();
        sweep(2)
            .build(&nested)
            .validate(&primitive_bounds(&nested), 2)
            .unwrap();
    }

    #[test]
    fn parallel_build_gives_the_same_tree_as_serial() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.6, 120, 40);
        let tree = SweepSahBuilder::default().build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 8).unwrap();
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| SweepSahBuilder::default().build(&mesh));
        assert_eq!(tree, one_thread);
    }

    #[test]
    fn at_least_as_good_as_binned() {
        let mesh = default_scene(2);
        let w = SahWeights::default();
        let swept = sah_cost(&SweepSahBuilder::default().build(&mesh), w);
        let binned = sah_cost(&BinnedSahBuilder::default().build(&mesh), w);
        assert!(swept <= binned * 1.02, "sweep {swept}, binned {binned}");
    }

    #[test]
    fn past_the_depth_limit_splits_are_object_medians() {
        assert_median_splits_past_the_depth_limit(|mesh, root_depth| {
            sweep(4).build_with_root_depth(mesh, root_depth)
        });
    }
}
