//! Top-down binned SAH construction (Wald 2007, "On fast construction of SAH-based bounding
//! volume hierarchies", IEEE Symposium on Interactive Ray Tracing).

use glam::Vec3A;
use rayon::prelude::*;

use super::median::split_at_object_median;
use super::{
    bounds_and_centroid_bounds, prim_refs, Builder, LeafPolicy, PrimRef, RangeTree, SideBounds,
    Subtree, PARALLEL_SUBTREE_MIN, SAH_DEPTH_LIMIT,
};
use crate::bvh::tree::BuildTree;
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Most bins per axis; [`BinnedSahConfig::bins`] is clamped to `2..=MAX_BINS`.
const MAX_BINS: usize = 64;

/// Nodes of at least this many triangles are binned by several threads (chunks binned apart,
/// then merged); smaller ones by one.
const PARALLEL_BINNING_MIN: usize = 1 << 16;

/// Triangles binned per task in parallel binning.
const BINNING_CHUNK: usize = 1 << 14;

/// Options of [`BinnedSahBuilder`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinnedSahConfig {
    /// Bins per axis over a node's centroid bounds, 2 to 64 (clamped); a node of `n < bins`
    /// triangles uses `max(n, 4)`, so extra bins cost time only in large nodes. Default 32: on
    /// the larger shared scenes it gives trees 0.2–0.7% cheaper (SAH) than 16 bins for 2–3%
    /// more build time; 8 bins make them up to 3% dearer.
    pub bins: usize,
    /// When to make a leaf; see [`LeafPolicy`].
    pub leaf: LeafPolicy,
}

impl Default for BinnedSahConfig {
    fn default() -> Self {
        Self {
            bins: 32,
            leaf: LeafPolicy::default(),
        }
    }
}

/// Builds a binary tree top down, splitting each node where the surface area heuristic is
/// lowest among the boundaries of `bins` equal slabs of its centroid bounds on each axis.
///
/// For a node `N`, every triangle is put in the bin of its box centre on each axis; one sweep
/// from the right and one from the left over the bins give, for every boundary `b`, the boxes
/// and counts of the two sides, hence
///
/// ```text
///   SAH(b) = C_t + C_i · (SA(L_b) · n_L + SA(R_b) · n_R) / SA(N)
/// ```
///
/// The node is split at the cheapest boundary of the three axes (triangles partitioned in
/// place), or made a leaf as [`LeafPolicy`] says. A node too large for a leaf and without a
/// boundary between its centres (all coincide) is split at the object median, as are all nodes
/// past a depth limit that only adversarial inputs reach.
///
/// O(n log n) for balanced splits: O(n) binning and partition per node, plus O(bins) to price
/// the boundaries. The two children of a large node are built in parallel (`rayon::join`), and
/// nodes of 65,536 triangles or more, near the root where there are fewer nodes than threads,
/// are binned in parallel (chunks binned apart, then merged).
#[derive(Clone, Debug, Default)]
pub struct BinnedSahBuilder {
    pub config: BinnedSahConfig,
}

impl Builder for BinnedSahBuilder {
    fn name(&self) -> &'static str {
        "binned-sah"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        self.build_with_root_depth(mesh, 0)
    }
}

impl BinnedSahBuilder {
    pub fn new(config: BinnedSahConfig) -> Self {
        Self { config }
    }

    /// [`Builder::build`] with the root at `root_depth` instead of 0: tests start near the
    /// depth limit to see the median fallback.
    fn build_with_root_depth(&self, mesh: &TriangleMesh, root_depth: u32) -> BuildTree {
        let mut prims = prim_refs(mesh);
        let mut ranges = RangeTree::new(prims.len());
        if let Some(root) = ranges.root() {
            let bounds = bounds_and_centroid_bounds(&prims);
            let bins = &mut BinCounts::new_boxed();
            self.build_subtree(&mut prims, bounds, root, bins, root_depth);
        }
        ranges.into_build_tree(&prims)
    }

    /// Builds the subtree over `prims`, whose box is `bounds` and whose centres' box is
    /// `centroid_bounds`, at `depth` below the root. `bins` is this thread's scratch space.
    fn build_subtree(
        &self,
        prims: &mut [PrimRef],
        bounds: SideBounds,
        subtree: Subtree<'_>,
        bins: &mut BinCounts,
        depth: u32,
    ) {
        let n = prims.len();
        let Some(split) = self.choose_split(prims, &bounds, depth, bins) else {
            return subtree.make_leaf();
        };
        let (left_count, [left, right]) = split.apply(prims);
        let (left_subtree, right_subtree) = subtree.split(left_count);
        let (left_prims, right_prims) = prims.split_at_mut(left_count);
        if n >= PARALLEL_SUBTREE_MIN {
            rayon::join(
                || self.build_subtree(left_prims, left, left_subtree, bins, depth + 1),
                || {
                    let bins = &mut BinCounts::new_boxed();
                    self.build_subtree(right_prims, right, right_subtree, bins, depth + 1)
                },
            );
        } else {
            self.build_subtree(left_prims, left, left_subtree, bins, depth + 1);
            self.build_subtree(right_prims, right, right_subtree, bins, depth + 1);
        }
    }

    /// How the node over `prims` (box and centres' box `bounds`, at `depth` below the root) is
    /// split, or `None` when it is a leaf: the cheapest bin boundary by the SAH, or the object
    /// median where no boundary separates the centres or past [`SAH_DEPTH_LIMIT`], or a leaf as
    /// [`LeafPolicy`] says. `bins` is this thread's scratch space.
    pub(crate) fn choose_split(
        &self,
        prims: &[PrimRef],
        (bounds, centroid_bounds): &SideBounds,
        depth: u32,
        bins: &mut BinCounts,
    ) -> Option<NodeSplit> {
        let n = prims.len();
        let policy = &self.config.leaf;
        if policy.is_leaf_without_split(n) {
            return None;
        }
        // A node of few triangles leaves most bins empty; fewer bins price the same splits
        // (the trees of the shared scenes change by under 0.01% in SAH) at less cost per node.
        let grid = BinGrid::new(centroid_bounds, self.config.bins.min(n.max(4)));
        let split = if depth < SAH_DEPTH_LIMIT {
            best_split(prims, &grid, bins)
        } else {
            None
        };
        if policy.is_leaf(n, bounds.surface_area(), split.map(|s| s.weighted_area)) {
            return None;
        }
        Some(match split {
            Some(split) => NodeSplit::Binned { grid, split },
            None => NodeSplit::Median {
                centroid_bounds: *centroid_bounds,
            },
        })
    }
}

/// Where [`BinnedSahBuilder::choose_split`] splits a node.
#[derive(Clone, Copy, Debug)]
pub(crate) enum NodeSplit {
    /// At a bin boundary of the node's grid.
    Binned { grid: BinGrid, split: BinSplit },
    /// At the object median of the node's centres.
    Median { centroid_bounds: Aabb },
}

impl NodeSplit {
    /// Partitions the node's `prims` in place, the left side first; returns how many went left
    /// and the box and centroid box of each side.
    pub(crate) fn apply(&self, prims: &mut [PrimRef]) -> (usize, [SideBounds; 2]) {
        match self {
            // One partition loop per axis, with the axis a constant in it.
            NodeSplit::Binned { grid, split: s } => match s.axis {
                0 => partition(prims, |c| grid.is_below::<0>(c, s.first_right_bin)),
                1 => partition(prims, |c| grid.is_below::<1>(c, s.first_right_bin)),
                _ => partition(prims, |c| grid.is_below::<2>(c, s.first_right_bin)),
            },
            NodeSplit::Median { centroid_bounds } => split_at_object_median(prims, centroid_bounds),
        }
    }
}

/// A box in SIMD registers (glam's `Vec3A`): the bins are updated once per triangle and axis,
/// the hottest loop of the build.
#[derive(Clone, Copy, Debug)]
struct BinBox {
    min: Vec3A,
    max: Vec3A,
}

impl BinBox {
    const EMPTY: BinBox = BinBox {
        min: Vec3A::INFINITY,
        max: Vec3A::NEG_INFINITY,
    };

    #[inline]
    fn grow(&mut self, other: &BinBox) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    /// Surface area; only meaningful for a box that holds something.
    #[inline]
    fn surface_area(&self) -> f32 {
        let d = self.max - self.min;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    #[inline]
    fn of(prim: &PrimRef) -> BinBox {
        BinBox {
            min: prim.bounds.min.into(),
            max: prim.bounds.max.into(),
        }
    }

    fn to_aabb(self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }
}

/// How centres map to bins: on each axis, `bins` equal slabs of the node's centroid bounds,
/// `bin = floor((c - lo) · bins / extent)`, clamped to the last bin.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BinGrid {
    lo: Vec3A,
    /// `bins / extent` per axis; 0 on an axis that cannot be binned (zero extent, or an extent
    /// so small or so large that the scale is not a finite positive f32).
    scale: Vec3A,
    bins: usize,
}

impl BinGrid {
    fn new(centroid_bounds: &Aabb, bins: usize) -> Self {
        let bins = bins.clamp(2, MAX_BINS);
        let extent = centroid_bounds.extent();
        let scale = Vec3A::from_array(extent.to_array().map(|e| {
            let s = bins as f32 / e;
            if e > 0.0 && s.is_finite() {
                s
            } else {
                0.0
            }
        }));
        Self {
            lo: centroid_bounds.min.into(),
            scale,
            bins,
        }
    }

    /// The bins of centre `c` on the three axes. Binning and partition both use it, so that
    /// they agree exactly.
    #[inline]
    fn bins_of(&self, c: Vec3A) -> [usize; 3] {
        let x = (c - self.lo) * self.scale;
        // Clamped to `[0, bins - 1]` before the conversion, NaN to 0 (`x > 0` is false):
        // rounding noise below `lo` goes to bin 0, the far end of the last bin stays in it.
        let last = Vec3A::splat((self.bins - 1) as f32);
        let x = Vec3A::select(x.cmpgt(Vec3A::ZERO), x, Vec3A::ZERO).min(last);
        truncate_lanes(x)
    }

    /// Whether centre `c` is in a bin below `bin` on `AXIS`: `bins_of(c)[AXIS] < bin`, without
    /// the conversion to an integer (`floor(x) < bin` exactly when `x < bin`).
    #[inline]
    fn is_below<const AXIS: usize>(&self, c: Vec3A, bin: usize) -> bool {
        (c[AXIS] - self.lo[AXIS]) * self.scale[AXIS] < bin as f32
    }

    fn can_split(&self, axis: usize) -> bool {
        self.scale[axis] > 0.0
    }
}

/// `[x, y, z]` of `x` truncated to integers, for lanes in `[0, 2^31)`: one SSE2 conversion of
/// all three on x86_64 (`as` per lane checks each for saturation).
#[inline]
fn truncate_lanes(x: Vec3A) -> [usize; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvttps_epi32, _mm_storeu_si128};
        let mut k = [0i32; 4];
        // SAFETY: SSE2 is part of the x86_64 baseline; the store writes the 16 bytes of `k`.
        unsafe {
            _mm_storeu_si128(k.as_mut_ptr().cast(), _mm_cvttps_epi32(__m128::from(x)));
        }
        [k[0] as usize, k[1] as usize, k[2] as usize]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x.to_array().map(|x| x as usize)
    }
}

/// The centre of a triangle's box, as `min/2 + max/2` (finite for any finite box).
#[inline]
fn centroid(b: &BinBox) -> Vec3A {
    b.min * 0.5 + b.max * 0.5
}

/// The bins of the three axes of one node, and room for the sweep over them. Allocated once per
/// thread of the build and reused by every node it bins (only the bins in use are reset).
pub(crate) struct BinCounts {
    boxes: [[BinBox; MAX_BINS]; 3],
    counts: [[u32; MAX_BINS]; 3],
    /// A second set of bins for every other triangle of a large node, merged into the first
    /// after binning and left empty.
    odd_boxes: [[BinBox; MAX_BINS]; 3],
    odd_counts: [[u32; MAX_BINS]; 3],
    /// `SA · n` of the bins right of each boundary, filled by the sweep.
    suffix_weighted_area: [[f32; MAX_BINS]; 3],
    suffix_count: [[u32; MAX_BINS]; 3],
}

impl BinCounts {
    /// Empty bins on the heap: at 8 KiB they would weigh on the stack of the recursion.
    pub(crate) fn new_boxed() -> Box<Self> {
        Box::new(Self::new())
    }

    fn new() -> Self {
        Self {
            boxes: [[BinBox::EMPTY; MAX_BINS]; 3],
            counts: [[0; MAX_BINS]; 3],
            odd_boxes: [[BinBox::EMPTY; MAX_BINS]; 3],
            odd_counts: [[0; MAX_BINS]; 3],
            suffix_weighted_area: [[0.0; MAX_BINS]; 3],
            suffix_count: [[0; MAX_BINS]; 3],
        }
    }

    fn reset(&mut self, bins: usize) {
        for axis in 0..3 {
            self.boxes[axis][..bins].fill(BinBox::EMPTY);
            self.counts[axis][..bins].fill(0);
        }
    }

    /// Bins `prims` into `self`, whose first `bins` bins are in use. In a node of many
    /// triangles, triangles alternate between two sets of bins, merged after: neighbours in a
    /// mesh often fall in the same bins, and with one set each update of a bin would wait for
    /// the previous one (a store and a load in a chain). With the partition's bounds kept in
    /// registers, the dragon's binary build went from 0.50 to 0.43 s on one thread
    /// (`build_time --builder binned-sah`, alternated, commit 667df70).
    fn add_prims(&mut self, prims: &[PrimRef], grid: &BinGrid, bins: usize) {
        if prims.len() < 4 * bins {
            return self.add_prims_to_one_set(prims, grid);
        }
        let mut pairs = prims.chunks_exact(2);
        for pair in &mut pairs {
            let (a, b) = (BinBox::of(&pair[0]), BinBox::of(&pair[1]));
            let (ka, kb) = (grid.bins_of(centroid(&a)), grid.bins_of(centroid(&b)));
            for axis in 0..3 {
                self.boxes[axis][ka[axis]].grow(&a);
                self.counts[axis][ka[axis]] += 1;
                self.odd_boxes[axis][kb[axis]].grow(&b);
                self.odd_counts[axis][kb[axis]] += 1;
            }
        }
        self.add_prims_to_one_set(pairs.remainder(), grid);
        for axis in 0..3 {
            for k in 0..bins {
                self.boxes[axis][k].grow(&self.odd_boxes[axis][k]);
                self.counts[axis][k] += self.odd_counts[axis][k];
            }
            self.odd_boxes[axis][..bins].fill(BinBox::EMPTY);
            self.odd_counts[axis][..bins].fill(0);
        }
    }

    fn add_prims_to_one_set(&mut self, prims: &[PrimRef], grid: &BinGrid) {
        for p in prims {
            let b = BinBox::of(p);
            let k = grid.bins_of(centroid(&b));
            for (axis, &k) in k.iter().enumerate() {
                self.boxes[axis][k].grow(&b);
                self.counts[axis][k] += 1;
            }
        }
    }

    fn merge(&mut self, other: &BinCounts, bins: usize) {
        for axis in 0..3 {
            for k in 0..bins {
                self.boxes[axis][k].grow(&other.boxes[axis][k]);
                self.counts[axis][k] += other.counts[axis][k];
            }
        }
    }
}

/// A split between bins: triangles whose centre is in a bin below `first_right_bin` on `axis`
/// go left.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BinSplit {
    axis: usize,
    first_right_bin: usize,
    /// `SA(L) · n_L + SA(R) · n_R`.
    weighted_area: f32,
}

/// The boundary of lowest SAH over the three axes, or `None` when no boundary has triangles on
/// both sides. Bins `prims` into `bins` first, in parallel for large nodes.
fn best_split(prims: &[PrimRef], grid: &BinGrid, bins: &mut BinCounts) -> Option<BinSplit> {
    if !(0..3).any(|axis| grid.can_split(axis)) {
        return None;
    }
    let n_bins = grid.bins;
    bins.reset(n_bins);
    if prims.len() >= PARALLEL_BINNING_MIN {
        let merged = prims
            .par_chunks(BINNING_CHUNK)
            .map(|chunk| {
                let mut counts = BinCounts::new_boxed();
                counts.add_prims(chunk, grid, n_bins);
                counts
            })
            .reduce_with(|mut a, b| {
                a.merge(&b, n_bins);
                a
            });
        bins.merge(&merged.expect("a large node has triangles"), n_bins);
    } else {
        bins.add_prims(prims, grid, n_bins);
    }

    // Sweep from the right: `SA · n` of the bins from `b` on, for every boundary `b`. The three
    // axes advance together, so that their dependency chains overlap.
    let mut right = [(BinBox::EMPTY, 0u32); 3];
    for b in (1..n_bins).rev() {
        for (axis, (boxes, count)) in right.iter_mut().enumerate() {
            boxes.grow(&bins.boxes[axis][b]);
            *count += bins.counts[axis][b];
            bins.suffix_weighted_area[axis][b] = boxes.surface_area() * *count as f32;
            bins.suffix_count[axis][b] = *count;
        }
    }
    // Sweep from the left, pricing each boundary with the right side found above.
    let (mut best_cost, mut best_axis, mut best_bin) = (f32::INFINITY, 0, 0);
    let mut left = [(BinBox::EMPTY, 0u32); 3];
    for b in 1..n_bins {
        for (axis, (boxes, count)) in left.iter_mut().enumerate() {
            boxes.grow(&bins.boxes[axis][b - 1]);
            *count += bins.counts[axis][b - 1];
            let cost = boxes.surface_area() * *count as f32 + bins.suffix_weighted_area[axis][b];
            // A side without triangles has no box: no split there.
            let has_both_sides = *count > 0 && bins.suffix_count[axis][b] > 0;
            if has_both_sides && cost < best_cost && grid.can_split(axis) {
                (best_cost, best_axis, best_bin) = (cost, axis, b);
            }
        }
    }
    (best_bin > 0).then_some(BinSplit {
        axis: best_axis,
        first_right_bin: best_bin,
        weighted_area: best_cost,
    })
}

/// Partitions `prims` in place, those whose centre satisfies `goes_left` first; returns how
/// many went left and the box and centroid box of each side, gathered on the way.
fn partition(prims: &mut [PrimRef], goes_left: impl Fn(Vec3A) -> bool) -> (usize, [SideBounds; 2]) {
    // The four boxes are locals grown on the branch that classified the triangle, so that
    // they stay in registers (grown through a reference picked per triangle, they were kept
    // in memory, each update waiting on the last).
    let (mut left, mut left_centres) = (BinBox::EMPTY, BinBox::EMPTY);
    let (mut right, mut right_centres) = (BinBox::EMPTY, BinBox::EMPTY);
    // Hoare's scheme, each triangle classified once: `prims[..i]` go left, `prims[j..]` right.
    let (mut i, mut j) = (0, prims.len());
    'scan: while i < j {
        let b = BinBox::of(&prims[i]);
        let c = centroid(&b);
        if goes_left(c) {
            left.grow(&b);
            left_centres.grow(&BinBox { min: c, max: c });
            i += 1;
            continue;
        }
        right.grow(&b);
        right_centres.grow(&BinBox { min: c, max: c });
        // `prims[i]` goes right: swap it with the last unclassified one that goes left.
        loop {
            j -= 1;
            if j == i {
                break 'scan;
            }
            let b = BinBox::of(&prims[j]);
            let c = centroid(&b);
            if goes_left(c) {
                left.grow(&b);
                left_centres.grow(&BinBox { min: c, max: c });
                prims.swap(i, j);
                i += 1;
                break;
            }
            right.grow(&b);
            right_centres.grow(&BinBox { min: c, max: c });
        }
    }
    (
        i,
        [
            (left.to_aabb(), left_centres.to_aabb()),
            (right.to_aabb(), right_centres.to_aabb()),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::primitive_bounds;
    use crate::bvh::build::range_tree::assert_median_splits_past_the_depth_limit;
    use crate::bvh::cost::{sah_cost, SahWeights};
    use crate::mesh::procedural::unit_triangles_at;
    use crate::mesh::procedural::{default_scene, torus};
    use glam::Vec3;

    fn leaf_sets(tree: &BuildTree, node: u32) -> Vec<u32> {
        let mut prims = tree.prims_below(node);
        prims.sort_unstable();
        prims
    }

    fn builder(bins: usize, max_leaf_size: usize) -> BinnedSahBuilder {
        BinnedSahBuilder::new(BinnedSahConfig {
            bins,
            leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
        })
    }

    #[test]
    fn two_clusters_are_separated_at_the_root() {
        let corners: Vec<Vec3> = (0..6)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
            .chain((0..6).map(|i| Vec3::new(100.0 + i as f32 * 0.1, 0.0, 5.0)))
            .collect();
        let mesh = unit_triangles_at(&corners);
        let tree = builder(16, 4).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 4).unwrap();
        let root = tree.node(tree.root().unwrap());
        assert_eq!(root.arity(), 2);
        let sides: Vec<Vec<u32>> = root
            .children()
            .iter()
            .map(|&c| leaf_sets(&tree, c))
            .collect();
        assert!(sides.contains(&(0..6).collect()), "{sides:?}");
        assert!(sides.contains(&(6..12).collect()), "{sides:?}");
    }

    #[test]
    fn one_triangle_is_one_leaf() {
        let mesh = unit_triangles_at(&[Vec3::ONE]);
        let tree = BinnedSahBuilder::default().build(&mesh);
        let root = tree.node(tree.root().unwrap());
        assert_eq!(root.prims(), &[0]);
        assert_eq!(root.bounds, mesh.bounds());
    }

    #[test]
    fn identical_triangles_split_by_count_only() {
        // 100 copies of one triangle: no bin boundary separates them, so nodes above the leaf
        // size are halved and the rest become leaves.
        let mesh = unit_triangles_at(&[Vec3::ZERO; 100]);
        for max_leaf_size in [1, 3, 8] {
            let tree = builder(16, max_leaf_size).build(&mesh);
            tree.validate(&primitive_bounds(&mesh), max_leaf_size)
                .unwrap();
            let shape = tree.shape();
            assert!(shape.depth_max <= 7, "{shape:?}");
            assert_eq!(
                shape.arity_histogram.iter().sum::<usize>(),
                shape.leaves - 1
            );
        }
    }

    #[test]
    fn coincident_centroids_of_different_triangles() {
        // Triangles of 40 sizes whose boxes are all centred on the origin: the centroid bounds
        // are one point, so every split is a median split.
        let positions: Vec<Vec3> = (1..=40)
            .flat_map(|k| {
                let s = k as f32;
                [
                    Vec3::new(-s, -s, 0.0),
                    Vec3::new(s, -s, 0.0),
                    Vec3::new(s, s, 0.0),
                ]
            })
            .collect();
        let indices = (0..40u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let mesh = TriangleMesh::new(positions, indices).unwrap();
        let tree = builder(16, 4).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 4).unwrap();
        assert!(tree.shape().depth_max <= 4);
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0];
        let mesh = TriangleMesh::new(positions, vec![[0, 1, 3], [0, 1, 2], [2, 2, 2]]).unwrap();
        let tree = BinnedSahBuilder::default().build(&mesh);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[1]);
        let none = TriangleMesh::new(vec![Vec3::ZERO, Vec3::X], vec![[0, 1, 1]]).unwrap();
        assert!(BinnedSahBuilder::default().build(&none).is_empty());
    }

    #[test]
    fn parallel_binning_gives_the_same_tree_as_serial() {
        // More triangles than PARALLEL_BINNING_MIN: the root is binned in chunks.
        let mesh = torus(Vec3::ZERO, 2.0, 0.6, 400, 100);
        assert!(mesh.triangle_count() >= PARALLEL_BINNING_MIN);
        let tree = BinnedSahBuilder::default().build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 8).unwrap();
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| BinnedSahBuilder::default().build(&mesh));
        assert_eq!(tree, one_thread);
    }

    #[test]
    fn more_bins_do_not_make_a_much_worse_tree() {
        let mesh = default_scene(2);
        let cost = |bins| sah_cost(&builder(bins, 8).build(&mesh), SahWeights::default());
        let (few, many) = (cost(4), cost(32));
        assert!(many <= few * 1.01, "4 bins: {few}, 32 bins: {many}");
    }

    #[test]
    fn past_the_depth_limit_splits_are_object_medians() {
        assert_median_splits_past_the_depth_limit(|mesh, root_depth| {
            builder(16, 4).build_with_root_depth(mesh, root_depth)
        });
    }

    #[test]
    fn partition_puts_each_side_together_and_bounds_it() {
        let prims: Vec<PrimRef> = [5.0f32, 1.0, 7.0, 2.0, 9.0, 0.0, 3.0]
            .iter()
            .enumerate()
            .map(|(id, &x)| PrimRef {
                bounds: Aabb::new(Vec3::splat(x), Vec3::splat(x + 1.0)),
                id: id as u32,
            })
            .collect();
        for threshold in [-1.0, 0.6, 3.6, 4.0, 20.0] {
            let mut p = prims.clone();
            let (k, [left, right]) = partition(&mut p, |c| c.x < threshold);
            let expected = prims.iter().filter(|q| q.centroid().x < threshold).count();
            assert_eq!(k, expected);
            assert!(p[..k].iter().all(|q| q.centroid().x < threshold));
            assert!(p[k..].iter().all(|q| q.centroid().x >= threshold));
            assert_eq!(left, bounds_and_centroid_bounds(&p[..k]));
            assert_eq!(right, bounds_and_centroid_bounds(&p[k..]));
        }
    }

    proptest::proptest! {
        #![proptest_config(crate::proptest_cases::cases(2000))]

        /// Binning and partition put every centre on the same side of every boundary, at any
        /// scale, for centres inside the node's centroid box, on its faces, and just outside it
        /// (rounding noise), with the clamp at both ends.
        #[test]
        fn binning_and_partition_agree(
            (lo, extent) in (-1e6f32..1e6, proptest::prop_oneof![
                proptest::prelude::Just(0.0f32), 1e-30f32..1e-20, 1e-3f32..1e3, 1e20f32..1e30
            ]),
            at in proptest::collection::vec(-0.01f32..1.01, 3),
            bins in 2usize..=MAX_BINS,
            face in 0usize..3,
        ) {
            let lo_v = Vec3::splat(lo);
            let hi_v = Vec3::new(lo + extent, lo + 2.0 * extent, lo + 0.5 * extent);
            let grid = BinGrid::new(&Aabb::new(lo_v, hi_v), bins);
            let mut c = lo_v + (hi_v - lo_v) * Vec3::from_slice(&at);
            // One coordinate exactly on the box's low or high face.
            c[face] = if at[face] < 0.5 { lo_v[face] } else { hi_v[face] };
            let k = grid.bins_of(c.into());
            for (axis, &k) in k.iter().enumerate() {
                proptest::prop_assert!(k < grid.bins);
                for bin in 1..grid.bins {
                    let below = match axis {
                        0 => grid.is_below::<0>(c.into(), bin),
                        1 => grid.is_below::<1>(c.into(), bin),
                        _ => grid.is_below::<2>(c.into(), bin),
                    };
                    proptest::prop_assert_eq!(k < bin, below, "axis {} bin {}", axis, bin);
                }
            }
        }
    }
}
