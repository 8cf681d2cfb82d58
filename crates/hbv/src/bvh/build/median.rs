//! Top-down construction by object median splits: the simplest balanced tree, the baseline that
//! the SAH builders must beat.

use super::leaf_policy::LARGEST_LEAF;
use super::{
    bounds_and_centroid_bounds, prim_refs, Builder, PrimRef, RangeTree, SideBounds, Subtree,
    PARALLEL_SUBTREE_MIN,
};
use crate::bvh::tree::BuildTree;
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// Options of [`MedianBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MedianConfig {
    /// Nodes of at most this many triangles become leaves; 1 to 255 (clamped). Default 4.
    pub max_leaf_size: usize,
}

impl Default for MedianConfig {
    fn default() -> Self {
        Self { max_leaf_size: 4 }
    }
}

/// Builds a binary tree top down, halving each node of more than `max_leaf_size` triangles at
/// the object median: the median of the box centres along the longest axis of the node's
/// centroid bounds (found by selection, O(n) per node).
///
/// The tree is balanced (depth `ceil(log2(n / max_leaf_size))`), O(n log n) to build, and
/// ignores surface areas: a cheap tree to make, a costly one to trace where triangles vary in
/// size or density. Subtrees are built in parallel (`rayon::join`).
#[derive(Clone, Debug, Default)]
pub struct MedianBuilder {
    pub config: MedianConfig,
}

impl Builder for MedianBuilder {
    fn name(&self) -> &'static str {
        "median"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        let mut prims = prim_refs(mesh);
        let mut ranges = RangeTree::new(prims.len());
        if let Some(root) = ranges.root() {
            let (_, centroid_bounds) = bounds_and_centroid_bounds(&prims);
            self.build_subtree(&mut prims, centroid_bounds, root);
        }
        ranges.into_build_tree(&prims)
    }
}

impl MedianBuilder {
    pub fn new(config: MedianConfig) -> Self {
        Self { config }
    }

    fn build_subtree(&self, prims: &mut [PrimRef], centroid_bounds: Aabb, subtree: Subtree<'_>) {
        let n = prims.len();
        if n <= self.config.max_leaf_size.clamp(1, LARGEST_LEAF) {
            return subtree.make_leaf();
        }
        let (left_count, [left, right]) = split_at_object_median(prims, &centroid_bounds);
        let (left_subtree, right_subtree) = subtree.split(left_count);
        let (left_prims, right_prims) = prims.split_at_mut(left_count);
        let build_left = || self.build_subtree(left_prims, left.1, left_subtree);
        let build_right = || self.build_subtree(right_prims, right.1, right_subtree);
        if n >= PARALLEL_SUBTREE_MIN {
            rayon::join(build_left, build_right);
        } else {
            build_left();
            build_right();
        }
    }
}

/// Splits `prims` (at least 2) into halves by the centre coordinate on the longest axis of
/// their `centroid_bounds` (the lower half gets `n / 2`); returns the size of the lower half and
/// the box and centroid box of each half. When all centres coincide the halves are arbitrary.
pub(super) fn split_at_object_median(
    prims: &mut [PrimRef],
    centroid_bounds: &Aabb,
) -> (usize, [SideBounds; 2]) {
    let axis = centroid_bounds.extent().max_position();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| {
        a.centroid()[axis].total_cmp(&b.centroid()[axis])
    });
    let (left, right) = prims.split_at(mid);
    (
        mid,
        [
            bounds_and_centroid_bounds(left),
            bounds_and_centroid_bounds(right),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::primitive_bounds;
    use crate::mesh::procedural::unit_triangles_at;
    use glam::Vec3;

    fn median(max_leaf_size: usize) -> MedianBuilder {
        MedianBuilder::new(MedianConfig { max_leaf_size })
    }

    #[test]
    fn splits_along_the_longest_axis_at_the_median() {
        // Eight triangles along z, spread 10 apart; slightly jittered in x.
        let corners: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i % 3) as f32 * 0.1, 0.0, 10.0 * i as f32))
            .collect();
        let mesh = unit_triangles_at(&corners);
        let tree = median(2).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 2).unwrap();
        let root = tree.node(tree.root().unwrap());
        let left = tree.node(root.children()[0]);
        assert!(
            left.bounds.max.z < 40.0 && left.bounds.min.z == 0.0,
            "{left:?}"
        );
        let shape = tree.shape();
        assert_eq!((shape.leaves, shape.depth_max), (4, 2));
    }

    #[test]
    fn one_triangle_and_identical_triangles() {
        let one = unit_triangles_at(&[Vec3::ONE]);
        let tree = MedianBuilder::default().build(&one);
        assert_eq!(tree.node(tree.root().unwrap()).prims(), &[0]);

        let same = unit_triangles_at(&[Vec3::ZERO; 37]);
        let tree = median(1).build(&same);
        tree.validate(&primitive_bounds(&same), 1).unwrap();
        assert_eq!(tree.shape().depth_max, 6);
    }

    #[test]
    fn leaf_size_is_clamped_to_one_and_255() {
        let mesh = unit_triangles_at(&[Vec3::ZERO; 300]);
        median(0)
            .build(&mesh)
            .validate(&primitive_bounds(&mesh), 1)
            .unwrap();
        let tree = median(1000).build(&mesh);
        tree.validate(&primitive_bounds(&mesh), 255).unwrap();
        assert_eq!(tree.shape().leaves, 2);
    }
}
