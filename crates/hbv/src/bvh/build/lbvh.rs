//! Linear BVH: triangles sorted along a Morton curve, the hierarchy read off the bits of their
//! codes (Lauterbach, Garland, Sengupta, Luebke & Manocha 2009, "Fast BVH construction on GPUs",
//! Eurographics; the split rule as formulated by Karras 2012, "Maximizing parallelism in the
//! construction of BVHs, octrees, and k-d trees", HPG).

use rayon::prelude::*;

use super::leaf_policy::LARGEST_LEAF;
use super::{
    bounds_and_centroid_bounds, prim_refs, Builder, PrimRef, RangeTree, Subtree,
    PARALLEL_SUBTREE_MIN,
};
use crate::bvh::morton::morton_code;
use crate::bvh::tree::BuildTree;
use crate::mesh::TriangleMesh;

/// Options of [`LbvhBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LbvhConfig {
    /// Ranges of at most this many triangles become leaves; 1 to 255 (clamped). Default 4.
    pub max_leaf_size: usize,
}

impl Default for LbvhConfig {
    fn default() -> Self {
        Self { max_leaf_size: 4 }
    }
}

/// Builds a binary tree from the Morton order of the triangles' box centres.
///
/// Each triangle gets the 63-bit Morton code of its centre in the centroid bounds of the mesh
/// ([`morton_code`]); the triangles are sorted by code (ties by face id). A range of sorted
/// codes `[first, last]` is split where its highest differing bit flips,
///
/// ```text
///   bit   = 63 - clz(code[first] ^ code[last])
///   split = the first i with bit `bit` of code[i] set
/// ```
///
/// which is the cut of the implicit octree-like subdivision of space that the codes encode:
/// the two halves lie on either side of one grid plane. A range whose codes are all equal
/// (centres in one cell of the 2^21 grid) is split in the middle. Ranges of at most
/// `max_leaf_size` triangles become leaves.
///
/// O(n log n) for the (parallel) sort and O(n) for the hierarchy, which is built in parallel
/// (`rayon::join`): the fastest builder. Its trees cost more than SAH trees because it never
/// looks at the triangles' sizes, only at where their centres are.
#[derive(Clone, Debug, Default)]
pub struct LbvhBuilder {
    pub config: LbvhConfig,
}

impl Builder for LbvhBuilder {
    fn name(&self) -> &'static str {
        "lbvh"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        let prims = prim_refs(mesh);
        let keys = sorted_morton_keys(&prims);
        let codes: Vec<u64> = keys.par_iter().map(|&(code, _)| code).collect();
        let sorted: Vec<PrimRef> = keys.par_iter().map(|&(_, i)| prims[i as usize]).collect();

        let mut ranges = RangeTree::new(sorted.len());
        if let Some(root) = ranges.root() {
            self.build_subtree(&codes, root);
        }
        ranges.into_build_tree(&sorted)
    }
}

impl LbvhBuilder {
    pub fn new(config: LbvhConfig) -> Self {
        Self { config }
    }

    /// Builds the subtree over the sorted `codes` of its triangles.
    fn build_subtree(&self, codes: &[u64], subtree: Subtree<'_>) {
        let n = codes.len();
        if n <= self.config.max_leaf_size.clamp(1, LARGEST_LEAF) {
            return subtree.make_leaf();
        }
        let left_count = split_position(codes);
        let (left_subtree, right_subtree) = subtree.split(left_count);
        let (left_codes, right_codes) = codes.split_at(left_count);
        let build_left = || self.build_subtree(left_codes, left_subtree);
        let build_right = || self.build_subtree(right_codes, right_subtree);
        if n >= PARALLEL_SUBTREE_MIN {
            rayon::join(build_left, build_right);
        } else {
            build_left();
            build_right();
        }
    }
}

/// `(code, index into prims)` of every triangle, sorted: the Morton codes of the box centres in
/// the centroid bounds, ties broken by the order of `prims` (in parallel).
pub(super) fn sorted_morton_keys(prims: &[PrimRef]) -> Vec<(u64, u32)> {
    let (_, centroid_bounds) = bounds_and_centroid_bounds(prims);
    let mut keys: Vec<(u64, u32)> = prims
        .par_iter()
        .enumerate()
        .map(|(i, p)| (morton_code(p.centroid(), &centroid_bounds), i as u32))
        .collect();
    keys.par_sort_unstable();
    keys
}

/// Where a sorted range of at least 2 codes splits: the first code with the highest differing
/// bit of the range set, or the middle when all codes are equal. Always in `1..codes.len()`.
fn split_position(codes: &[u64]) -> usize {
    let (first, last) = (codes[0], codes[codes.len() - 1]);
    if first == last {
        return codes.len() / 2;
    }
    // All codes of the range share the bits above `bit`, so sorted they have this bit clear,
    // then set.
    let bit = 63 - (first ^ last).leading_zeros();
    codes.partition_point(|&c| c & (1 << bit) == 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::primitive_bounds;
    use crate::mesh::procedural::unit_triangles_at;
    use glam::Vec3;

    fn lbvh(max_leaf_size: usize) -> LbvhBuilder {
        LbvhBuilder::new(LbvhConfig { max_leaf_size })
    }

    #[test]
    fn split_at_highest_differing_bit_or_middle() {
        assert_eq!(split_position(&[0b000, 0b001, 0b100, 0b101, 0b111]), 2);
        assert_eq!(split_position(&[0b010, 0b011]), 1);
        assert_eq!(split_position(&[7, 7, 7, 7, 7]), 2);
        assert_eq!(split_position(&[0, u64::MAX >> 1]), 1);
    }

    #[test]
    fn two_clusters_are_separated_at_the_root() {
        let corners: Vec<Vec3> = (0..5)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.0, 0.0))
            .chain((0..7).map(|i| Vec3::new(100.0 + i as f32 * 0.1, 0.0, 0.0)))
            .collect();
        let mesh = unit_triangles_at(&corners);
        let tree = lbvh(2).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 2).unwrap();
        let root = tree.node(tree.root().unwrap());
        let sizes: Vec<f32> = root
            .children()
            .iter()
            .map(|&c| tree.node(c).bounds.extent().x)
            .collect();
        assert!(sizes.iter().all(|&x| x < 2.0), "{sizes:?}");
    }

    #[test]
    fn one_triangle_identical_triangles_and_leaf_sizes() {
        let one = unit_triangles_at(&[Vec3::ONE]);
        let tree = LbvhBuilder::default().build(&one);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[0]);

        let same = unit_triangles_at(&[Vec3::splat(3.0); 50]);
        for max_leaf_size in [0, 1, 4, 300] {
            let tree = lbvh(max_leaf_size).build(&same);
            tree.validate(&primitive_bounds(&same), max_leaf_size.clamp(1, 255))
                .unwrap();
            assert!(tree.shape().depth_max <= 6);
        }
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0];
        let mesh = TriangleMesh::new(positions, vec![[0, 1, 3], [0, 1, 2], [2, 2, 2]]).unwrap();
        let tree = LbvhBuilder::default().build(&mesh);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[1]);
    }
}
