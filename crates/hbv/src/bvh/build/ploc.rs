//! Parallel locally-ordered clustering (Meister & Bittner 2018, "Parallel Locally-Ordered
//! Clustering for Bounding Volume Hierarchy Construction", IEEE TVCG 24(3)).

use glam::{Vec3A, Vec4};
use rayon::prelude::*;

use super::lbvh::sorted_morton_keys;
use super::{prim_refs, Builder, LeafPolicy, PrimRef};
use crate::bvh::{BuildTree, NodeId, NodeList};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Largest [`PlocConfig::radius`]; larger ones are clamped to it.
const MAX_RADIUS: usize = 64;

/// Clusters per task in the parallel passes of a round; rounds of fewer clusters run on one
/// thread.
const CHUNK: usize = 1 << 12;

/// Options of [`PlocBuilder`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlocConfig {
    /// How many clusters on each side of a cluster, in Morton order, are searched for its
    /// nearest neighbour; 1 to 64 (clamped). Default 16, the radius Meister & Bittner found to
    /// give trees within a few per cent of the best for a fraction of the search.
    pub radius: usize,
    /// When a subtree becomes a leaf: the subtrees of the clustered tree are collapsed bottom up
    /// by the same weights and size bounds as the SAH builders' ([`LeafPolicy`]).
    pub leaf: LeafPolicy,
}

impl Default for PlocConfig {
    fn default() -> Self {
        Self {
            radius: 16,
            leaf: LeafPolicy::default(),
        }
    }
}

/// Builds a binary tree bottom up by merging, round after round, the clusters that are each
/// other's nearest neighbour.
///
/// The triangles are sorted by the Morton code of their box centres, as for
/// [`LbvhBuilder`](super::LbvhBuilder); each starts as a cluster. A round then
///
/// ```text
///   1. finds for every cluster i, among the clusters i-r..=i+r of the sorted list, the one j
///      whose union with it has the least surface area:  nn(i) = argmin_j SA(B_i ∪ B_j);
///   2. merges every mutual pair, nn(i) = j and nn(j) = i, into one cluster at i's place;
///   3. compacts the list, which stays in Morton order.
/// ```
///
/// until one cluster is left. Ties go to the lower index, so the pair least in (area, index)
/// order is always mutual and every round merges at least one pair. Each step is a parallel
/// map over the clusters; the result does not depend on the thread count.
///
/// The clustered tree has one triangle per leaf; it is then collapsed bottom up: a subtree of
/// `n <= max_leaf_size` triangles becomes one leaf when that is not dearer by the SAH than the
/// subtree (`C_i · n · SA(N) <= C_t · SA(N) + cost(L) + cost(R)`), which is the greedy rule of
/// the top-down builders applied to the whole subtree.
///
/// O(n log n) for the sort, O(r · n) per round; the rounds' sizes shrink geometrically (the
/// bunny's 69,451 clusters take 44 rounds, 3.7 n clusters searched in all). Its trees' E\[X\]
/// lies between LBVH's and binned SAH's (BENCHMARKS.md, "Tree quality per builder"); it builds
/// in 3–4× LBVH's time.
#[derive(Clone, Debug, Default)]
pub struct PlocBuilder {
    pub config: PlocConfig,
}

impl Builder for PlocBuilder {
    fn name(&self) -> &'static str {
        "ploc"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        let prims = morton_sorted(prim_refs(mesh));
        let merges = cluster(&prims, self.config.radius.clamp(1, MAX_RADIUS));
        collapse_into_tree(&prims, &merges, &self.config.leaf)
    }
}

impl PlocBuilder {
    pub fn new(config: PlocConfig) -> Self {
        Self { config }
    }
}

/// `prims` sorted by the Morton code of their box centres, ties by their order in `prims`.
fn morton_sorted(prims: Vec<PrimRef>) -> Vec<PrimRef> {
    sorted_morton_keys(&prims)
        .par_iter()
        .map(|&(_, i)| prims[i as usize])
        .collect()
}

/// A cluster's box in SIMD registers: the nearest-neighbour search takes the union of two
/// of them 2r times per cluster and round, the hottest loop of the build.
#[derive(Clone, Copy, Debug)]
struct ClusterBox {
    min: Vec3A,
    max: Vec3A,
}

impl ClusterBox {
    fn of(bounds: &Aabb) -> Self {
        Self {
            min: bounds.min.into(),
            max: bounds.max.into(),
        }
    }

    #[inline]
    fn union(&self, other: &ClusterBox) -> ClusterBox {
        ClusterBox {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Surface area in f64, where no finite box overflows.
    fn surface_area(&self) -> f64 {
        let d = (self.max - self.min).as_dvec3();
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

/// One merge of two clusters: the nodes of the clustered tree above the triangles.
#[derive(Clone, Copy, Debug)]
struct Merge {
    /// The two merged nodes: `i < n` is triangle `prims[i]`, `n + k` is the `k`-th merge.
    children: [u32; 2],
    bounds: ClusterBox,
}

/// Clusters the sorted `prims` into one tree: the merges in the order made, so that every
/// merge comes after its children. Empty for fewer than two triangles.
fn cluster(prims: &[PrimRef], radius: usize) -> Vec<Merge> {
    let n = prims.len();
    let mut merges: Vec<Merge> = Vec::with_capacity(n.saturating_sub(1));
    let mut boxes: Vec<ClusterBox> = prims
        .par_iter()
        .map(|p| ClusterBox::of(&p.bounds))
        .collect();
    let mut nodes: Vec<u32> = (0..n as u32).collect();
    while boxes.len() > 1 {
        let nearest = nearest_neighbours(&boxes, radius);
        let first_id = (n + merges.len()) as u32;
        (boxes, nodes) = merge_mutual_pairs(&boxes, &nodes, &nearest, first_id, &mut merges);
    }
    merges
}

/// For every cluster `i`, the `j != i` within `radius` of it whose union with it has the least
/// area (the lowest `j` of equals).
///
/// Each pair is priced once, for both its clusters (Meister & Bittner's halved search): the
/// clusters are cut into chunks, and a chunk `[s, e)` prices the pairs `(i, j)`, `i < j <= i + r`,
/// for every `i` of `[s - r, e)`, which are all the pairs of its own clusters. A neighbour is
/// chosen by the key `(area bits << 32) | index`: areas are never negative, so their bits sort
/// as they do, and the least key is the least area with ties to the lowest index (`+∞` included,
/// so that every cluster gets a neighbour).
fn nearest_neighbours(boxes: &[ClusterBox], radius: usize) -> Vec<u32> {
    let m = boxes.len();
    let mut nearest = vec![0u32; m];
    nearest.par_chunks_mut(CHUNK).enumerate().for_each_init(
        NeighbourWindow::default,
        |window, (chunk, out)| {
            let start = chunk * CHUNK;
            window.search(boxes, start, start + out.len(), radius);
            for (k, nn) in out.iter_mut().enumerate() {
                *nn = window.nearest_of(start + k);
            }
        },
    );
    nearest
}

/// The boxes of one chunk of clusters and of the `r` before and after it, in structure-of-arrays
/// form for four pairs at a time, and the least key found for each: a thread's scratch space,
/// reused from chunk to chunk.
#[derive(Default)]
struct NeighbourWindow {
    /// Index of the window's first cluster.
    first: usize,
    /// `min.x, min.y, min.z, max.x, max.y, max.z` of each cluster, with three more entries
    /// at the end so that four lanes can always be loaded.
    coords: [Vec<f32>; 6],
    /// The least key found for each cluster: `(area bits << 32) | index`, `u64::MAX` for none.
    best: Vec<u64>,
}

impl NeighbourWindow {
    /// Prices every pair of `boxes` within `radius` of each other that has a cluster in
    /// `start..end`.
    fn search(&mut self, boxes: &[ClusterBox], start: usize, end: usize, radius: usize) {
        let first = start.saturating_sub(radius);
        let last = (end + radius).min(boxes.len()); // exclusive
        self.first = first;
        for (axis, coords) in self.coords.iter_mut().enumerate() {
            coords.clear();
            coords.extend(boxes[first..last].iter().map(|b| {
                if axis < 3 {
                    b.min[axis]
                } else {
                    b.max[axis - 3]
                }
            }));
            coords.extend([0.0; 3]);
        }
        self.best.clear();
        self.best.resize(last - first, u64::MAX);
        let best = &mut self.best[..];
        let [lo_x, lo_y, lo_z, hi_x, hi_y, hi_z] = &self.coords;
        let lanes = |c: &Vec<f32>, k: usize| Vec4::from_slice(&c[k..k + 4]);
        for i in 0..end - first {
            let (ilo, ihi) = (
                [lo_x[i], lo_y[i], lo_z[i]].map(Vec4::splat),
                [hi_x[i], hi_y[i], hi_z[i]].map(Vec4::splat),
            );
            let mut best_i = best[i];
            let last_j = (i + radius).min(last - first - 1);
            let mut j = i + 1;
            while j <= last_j {
                let dx = lanes(hi_x, j).max(ihi[0]) - lanes(lo_x, j).min(ilo[0]);
                let dy = lanes(hi_y, j).max(ihi[1]) - lanes(lo_y, j).min(ilo[1]);
                let dz = lanes(hi_z, j).max(ihi[2]) - lanes(lo_z, j).min(ilo[2]);
                let area = dx * dy + dy * dz + dz * dx;
                // Not a number (extents beyond f32) counts as +∞: never less than a real area.
                let area = Vec4::select(area.cmpeq(area), area, Vec4::INFINITY).to_array();
                let lanes_in_range = (last_j + 1 - j).min(4);
                for (lane, area) in area[..lanes_in_range].iter().enumerate() {
                    let (bits, k) = (u64::from(area.to_bits()) << 32, j + lane);
                    best_i = best_i.min(bits | (first + k) as u64);
                    best[k] = best[k].min(bits | (first + i) as u64);
                }
                j += 4;
            }
            best[i] = best_i;
        }
    }

    /// The nearest neighbour of cluster `i` of the chunk searched.
    fn nearest_of(&self, i: usize) -> u32 {
        self.best[i - self.first] as u32
    }
}

/// What one chunk of a round keeps and makes: how many clusters survive it and how many
/// merges it leads.
#[derive(Clone, Copy, Default)]
struct ChunkCounts {
    survivors: usize,
    merges: usize,
}

/// Merges the mutual pairs of `nearest`: the pair `i < j` becomes one cluster at `i`'s place,
/// node `first_id + k` for the `k`-th such pair in list order (appended to `merges`); `j` is
/// dropped. Returns the new list of cluster boxes and nodes.
fn merge_mutual_pairs(
    boxes: &[ClusterBox],
    nodes: &[u32],
    nearest: &[u32],
    first_id: u32,
    merges: &mut Vec<Merge>,
) -> (Vec<ClusterBox>, Vec<u32>) {
    let is_mutual = |i: usize| nearest[nearest[i] as usize] as usize == i;
    // Pass 1: each chunk's counts, then where its survivors and merges go.
    let counts: Vec<ChunkCounts> = nearest
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(chunk, nearest_of_chunk)| {
            let mut c = ChunkCounts::default();
            for (k, &j) in nearest_of_chunk.iter().enumerate() {
                let i = chunk * CHUNK + k;
                let mutual = is_mutual(i);
                c.merges += usize::from(mutual && j as usize > i);
                c.survivors += usize::from(!(mutual && (j as usize) < i));
            }
            c
        })
        .collect();
    let survivors: usize = counts.iter().map(|c| c.survivors).sum();
    let new_merges: usize = counts.iter().map(|c| c.merges).sum();
    let mut new_boxes = vec![ClusterBox::of(&Aabb::EMPTY); survivors];
    let mut new_nodes = vec![0u32; survivors];
    let merges_before = merges.len();
    merges.resize(
        merges_before + new_merges,
        Merge {
            children: [0, 0],
            bounds: ClusterBox::of(&Aabb::EMPTY),
        },
    );
    // Pass 2: each chunk writes its own slices of the outputs.
    let box_slices = split_by(&mut new_boxes, counts.iter().map(|c| c.survivors));
    let node_slices = split_by(&mut new_nodes, counts.iter().map(|c| c.survivors));
    let merge_slices = split_by(
        &mut merges[merges_before..],
        counts.iter().map(|c| c.merges),
    );
    let first_merge_of_chunk = counts.iter().scan(0usize, |total, c| {
        let first = *total;
        *total += c.merges;
        Some(first)
    });
    let chunks: Vec<_> = box_slices
        .into_iter()
        .zip(node_slices)
        .zip(merge_slices)
        .zip(first_merge_of_chunk)
        .enumerate()
        .collect();
    chunks.into_par_iter().for_each(
        |(chunk, (((out_boxes, out_nodes), out_merges), first_merge))| {
            let start = chunk * CHUNK;
            let (mut kept, mut made) = (0, 0);
            for i in start..(start + CHUNK).min(boxes.len()) {
                let j = nearest[i] as usize;
                if !is_mutual(i) {
                    out_boxes[kept] = boxes[i];
                    out_nodes[kept] = nodes[i];
                    kept += 1;
                } else if i < j {
                    let bounds = boxes[i].union(&boxes[j]);
                    out_merges[made] = Merge {
                        children: [nodes[i], nodes[j]],
                        bounds,
                    };
                    out_boxes[kept] = bounds;
                    out_nodes[kept] = first_id + (first_merge + made) as u32;
                    kept += 1;
                    made += 1;
                }
            }
        },
    );
    (new_boxes, new_nodes)
}

/// `items` cut into consecutive slices of the given lengths (which sum to its length).
fn split_by<T>(mut items: &mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    lengths
        .map(|len| {
            let (head, tail) = std::mem::take(&mut items).split_at_mut(len);
            items = tail;
            head
        })
        .collect()
}

/// The clustered tree (`prims` and the `merges` over them) as a [`BuildTree`], each subtree
/// that `policy` prefers as one leaf collapsed into one.
fn collapse_into_tree(prims: &[PrimRef], merges: &[Merge], policy: &LeafPolicy) -> BuildTree {
    let n = prims.len();
    let mut tree = BuildTree::with_capacity(2 * n);
    if n == 0 {
        return tree;
    }
    let is_leaf = leaf_subtrees(prims, merges, policy);
    let root = (n + merges.len() - 1) as u32;
    // Post-order with an explicit stack: an internal node is pushed once both children are.
    let mut pending: Vec<(u32, bool)> = vec![(root, false)];
    let mut finished: Vec<NodeId> = Vec::new();
    let (mut below, mut stack) = (Vec::new(), Vec::new());
    while let Some((node, children_done)) = pending.pop() {
        let k = node as usize;
        if k < n || is_leaf[k - n] {
            below.clear();
            triangles_below(node, prims, merges, &mut stack, &mut below);
            let bounds = below
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(&prims[i as usize].bounds));
            let ids: NodeList = below.iter().map(|&i| prims[i as usize].id).collect();
            finished.push(tree.push_leaf(ids, bounds));
        } else if !children_done {
            let [left, right] = merges[k - n].children;
            pending.extend([(node, true), (right, false), (left, false)]);
        } else {
            let right = finished.pop().expect("right child built");
            let left = finished.pop().expect("left child built");
            finished.push(tree.push_internal([left, right].as_slice()));
        }
    }
    tree.set_root(finished.pop());
    tree
}

/// For each merge, whether its subtree is one leaf: bottom up (children come before parents),
/// with the SAH cost of each subtree in area-weighted units,
///
/// ```text
///   leaf(N)  = C_i · n · SA(N)
///   split(N) = C_t · SA(N) + cost(L) + cost(R)
///   cost(N)  = leaf(N) if N is a leaf, else split(N)
/// ```
///
/// N is a leaf when `n` is at most the policy's least leaf size, or at most its largest and
/// `split(N)` is not less than `leaf(N)`.
fn leaf_subtrees(prims: &[PrimRef], merges: &[Merge], policy: &LeafPolicy) -> Vec<bool> {
    let n = prims.len();
    let (c_t, c_i) = (policy.sah.traversal, policy.sah.intersection);
    let mut counts: Vec<usize> = Vec::with_capacity(merges.len());
    let mut costs: Vec<f64> = Vec::with_capacity(merges.len());
    let mut is_leaf: Vec<bool> = Vec::with_capacity(merges.len());
    let count_and_cost = |node: u32, counts: &[usize], costs: &[f64]| {
        let k = node as usize;
        if k < n {
            (1, c_i * ClusterBox::of(&prims[k].bounds).surface_area())
        } else {
            (counts[k - n], costs[k - n])
        }
    };
    for merge in merges {
        let (n_l, cost_l) = count_and_cost(merge.children[0], &counts, &costs);
        let (n_r, cost_r) = count_and_cost(merge.children[1], &counts, &costs);
        let count = n_l + n_r;
        let area = merge.bounds.surface_area();
        let leaf = c_i * count as f64 * area;
        let split = c_t * area + cost_l + cost_r;
        let leaf_here = policy.is_leaf_without_split(count)
            || (count <= policy.max_leaf()
                && split.partial_cmp(&leaf) != Some(std::cmp::Ordering::Less));
        counts.push(count);
        costs.push(if leaf_here { leaf } else { split });
        is_leaf.push(leaf_here);
    }
    is_leaf
}

/// Appends to `out` the positions in `prims` of the triangles under `node`; `stack` is scratch
/// space.
fn triangles_below(
    node: u32,
    prims: &[PrimRef],
    merges: &[Merge],
    stack: &mut Vec<u32>,
    out: &mut Vec<u32>,
) {
    let n = prims.len();
    stack.clear();
    stack.push(node);
    while let Some(node) = stack.pop() {
        let k = node as usize;
        if k < n {
            out.push(node);
        } else {
            let [left, right] = merges[k - n].children;
            stack.extend([right, left]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::primitive_bounds;
    use crate::mesh::procedural::unit_triangles_at;
    use glam::Vec3;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn ploc(radius: usize, max_leaf_size: usize) -> PlocBuilder {
        PlocBuilder::new(PlocConfig {
            radius,
            leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
        })
    }

    /// The nearest neighbours by definition: every candidate of every cluster priced.
    fn nearest_by_brute_force(boxes: &[ClusterBox], radius: usize) -> Vec<u32> {
        (0..boxes.len())
            .map(|i| {
                let candidates = i.saturating_sub(radius)..=(i + radius).min(boxes.len() - 1);
                let key = |j: usize| {
                    let u = boxes[i].union(&boxes[j]);
                    let d = u.max - u.min;
                    let area = d.x * d.y + d.y * d.z + d.z * d.x;
                    let area = if area.is_nan() { f32::INFINITY } else { area };
                    (area.to_bits(), j)
                };
                candidates
                    .filter(|&j| j != i)
                    .min_by_key(|&j| key(j))
                    .unwrap() as u32
            })
            .collect()
    }

    fn random_boxes(count: usize, distinct: usize, seed: u64) -> Vec<ClusterBox> {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let shapes: Vec<ClusterBox> = (0..distinct)
            .map(|_| {
                let lo = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
                let size = Vec3::new(rng.random(), rng.random(), rng.random());
                ClusterBox::of(&Aabb::new(lo, lo + size))
            })
            .collect();
        (0..count)
            .map(|_| shapes[rng.random_range(0..distinct)])
            .collect()
    }

    #[test]
    fn the_halved_search_finds_every_nearest_neighbour() {
        // Across chunk boundaries, at every radius, with many equal boxes (ties).
        for (count, distinct) in [(2, 2), (17, 3), (CHUNK + 37, 50), (2 * CHUNK + 5, 4000)] {
            let boxes = random_boxes(count, distinct, count as u64);
            for radius in [1, 2, 3, 4, 5, 16, MAX_RADIUS] {
                assert_eq!(
                    nearest_neighbours(&boxes, radius),
                    nearest_by_brute_force(&boxes, radius),
                    "{count} boxes, radius {radius}"
                );
            }
        }
    }

    #[test]
    fn areas_beyond_f32_are_farthest() {
        let big = crate::mesh::MAX_COORDINATE;
        let boxes: Vec<ClusterBox> = [
            Aabb::new(Vec3::new(-big, 0.0, 0.0), Vec3::new(-big, 0.0, 0.0)),
            Aabb::new(Vec3::new(big, 0.0, 0.0), Vec3::new(big, 1.0, 0.0)),
            Aabb::new(Vec3::new(big, 0.0, 1.0), Vec3::new(big, 1.0, 1.0)),
        ]
        .iter()
        .map(ClusterBox::of)
        .collect();
        assert_eq!(nearest_neighbours(&boxes, 2), [1, 2, 1]);
        assert_eq!(nearest_by_brute_force(&boxes, 2), [1, 2, 1]);
    }

    #[test]
    fn two_clusters_are_separated_at_the_root() {
        let corners: Vec<Vec3> = (0..5)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
            .chain((0..7).map(|i| Vec3::new(100.0 + i as f32 * 0.1, 0.0, 0.0)))
            .collect();
        let mesh = unit_triangles_at(&corners);
        for radius in [1, 16] {
            let tree = ploc(radius, 2).build(&mesh);
            tree.validate(&primitive_bounds(&mesh), 2).unwrap();
            let root = tree.node(tree.root().unwrap());
            let mut sides: Vec<Vec<u32>> = root
                .children()
                .iter()
                .map(|&c| {
                    let mut p = tree.prims_below(c);
                    p.sort_unstable();
                    p
                })
                .collect();
            sides.sort();
            assert_eq!(sides, [(0..5).collect::<Vec<u32>>(), (5..12).collect()]);
        }
    }

    #[test]
    fn coincident_triangles_collapse_into_one_leaf_up_to_the_leaf_size() {
        let same = unit_triangles_at(&[Vec3::splat(3.0); 8]);
        let tree = ploc(16, 8).build(&same);
        assert_eq!(tree.node(tree.root().unwrap()).prims().len(), 8);
        let many = unit_triangles_at(&[Vec3::splat(3.0); 50]);
        for max_leaf_size in [0, 1, 4, 300] {
            let tree = ploc(16, max_leaf_size).build(&many);
            tree.validate(&primitive_bounds(&many), max_leaf_size.clamp(1, 255))
                .unwrap();
        }
    }

    #[test]
    fn one_triangle_and_no_triangles() {
        let one = unit_triangles_at(&[Vec3::ONE]);
        let tree = PlocBuilder::default().build(&one);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[0]);
        let none = TriangleMesh::new(vec![], vec![]).unwrap();
        assert!(PlocBuilder::default().build(&none).is_empty());
    }

    #[test]
    fn far_apart_triangles_stay_apart_in_leaves() {
        // Two triangles 1000 apart: one leaf of both costs far more than two leaves.
        let mesh = unit_triangles_at(&[Vec3::ZERO, Vec3::splat(1000.0)]);
        let tree = PlocBuilder::default().build(&mesh);
        assert_eq!(tree.shape().leaves, 2);
    }
}
