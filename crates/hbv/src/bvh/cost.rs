//! The cost of a tree: the seed's expected number of tests E\[X\], and the usual SAH cost.
//!
//! Both rest on one fact of integral geometry: for a uniformly distributed (isotropic) line that
//! meets a convex box `P`, the probability that it also meets a box `N` inside `P` is
//! `SA(N) / SA(P)` (Crofton; see Santaló 1976). A node's children are tested only when the ray
//! reaches the node, which happens with probability `SA(n) / SA(root)` for a line through the root.

use super::tree::BuildTree;

/// The expected number of intersection tests for a random line that meets the root box
/// (Goldsmith & Salmon 1987):
///
/// ```text
///   E[X] = Σ_n  a_n · SA(n) / SA(root)
/// ```
///
/// over every node `n`, where `a_n` is the number of tests made when a line reaches `n`: for an
/// internal node, one box test per child; for a leaf, one triangle test per triangle. A leaf of
/// one triangle therefore counts 1 (its triangle), and its box is counted once, as one of its
/// parent's children. The root's own box test is not counted (the line is given to meet it).
///
/// This is exactly what a traversal without early exit counts along such a line:
/// `boxes_tested + triangles_tested` minus the root box test. 0 for an empty tree.
pub fn expected_tests(tree: &BuildTree) -> f64 {
    weighted_area(tree, |node| node.arity() as f64)
}

/// Weights of the SAH cost: `traversal` (C_t) per node visited, `intersection` (C_i) per
/// triangle tested.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SahWeights {
    pub traversal: f64,
    pub intersection: f64,
}

impl Default for SahWeights {
    /// `C_t = 1`, `C_i = 1`: one unit per internal node visited and per triangle tested.
    fn default() -> Self {
        Self {
            traversal: 1.0,
            intersection: 1.0,
        }
    }
}

/// The surface area heuristic cost of the tree (MacDonald & Booth 1990):
///
/// ```text
///   SAH = Σ_internal C_t · SA(n) / SA(root)  +  Σ_leaf C_i · |n| · SA(n) / SA(root)
/// ```
///
/// with the root included (it contributes `C_t`, or `C_i · |root|` for a single leaf).
/// Unlike E\[X\], an internal node costs `C_t` once, however many children it has: it models a
/// node visit whose child tests are one step (as in a binary or SIMD-wide node).
pub fn sah_cost(tree: &BuildTree, weights: SahWeights) -> f64 {
    weighted_area(tree, |node| {
        if node.is_leaf() {
            weights.intersection * node.arity() as f64
        } else {
            weights.traversal
        }
    })
}

/// `Σ_n weight(n) · SA(n) / SA(root)` over the nodes reachable from the root, summed in f64.
fn weighted_area(tree: &BuildTree, weight: impl Fn(&super::tree::BuildNode) -> f64) -> f64 {
    let Some(root) = tree.root() else {
        return 0.0;
    };
    let root_area = tree.node(root).bounds.surface_area() as f64;
    if root_area <= 0.0 {
        // A tree of points or segments: every line that meets the root meets everything.
        let mut sum = 0.0;
        tree.walk(|id, _| sum += weight(tree.node(id)));
        return sum;
    }
    let mut sum = 0.0;
    tree.walk(|id, _| {
        let node = tree.node(id);
        sum += weight(node) * node.bounds.surface_area() as f64;
    });
    sum / root_area
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;
    use glam::Vec3;

    fn cube(lo: f32, hi: f32) -> Aabb {
        Aabb::new(Vec3::splat(lo), Vec3::splat(hi))
    }

    /// ```text
    ///            root [0,5]³  SA 150, a = 2
    ///            /        \
    ///     ab [0,3]³        c [4,5]³  (leaf, 1 triangle, SA 6)
    ///     SA 54, a = 2
    ///     /     \
    ///  a [0,1]³  b [2,3]³   (leaves, 1 triangle each, SA 6)
    /// ```
    fn three_leaf_tree() -> BuildTree {
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0, 1.0));
        let b = t.push_leaf(vec![1], cube(2.0, 3.0));
        let c = t.push_leaf(vec![2], cube(4.0, 5.0));
        let ab = t.push_internal(vec![a, b]);
        let root = t.push_internal(vec![ab, c]);
        t.set_root(Some(root));
        t
    }

    #[test]
    fn expected_tests_by_hand() {
        // (2·150 + 2·54 + 1·6 + 1·6 + 1·6) / 150 = 426 / 150
        let e = expected_tests(&three_leaf_tree());
        assert!((e - 426.0 / 150.0).abs() < 1e-12, "{e}");
    }

    #[test]
    fn sah_cost_by_hand() {
        // C_t (150 + 54) / 150 + C_i (6 + 6 + 6) / 150, with C_t = 2, C_i = 3.
        let w = SahWeights {
            traversal: 2.0,
            intersection: 3.0,
        };
        let c = sah_cost(&three_leaf_tree(), w);
        assert!(
            (c - (2.0 * 204.0 + 3.0 * 18.0) / 150.0).abs() < 1e-12,
            "{c}"
        );
    }

    #[test]
    fn flat_n_ary_root_and_fat_leaf() {
        // One root with three leaf children, one of them holding two triangles:
        //   E[X] = 3 (root) + (1·6 + 1·6 + 2·6)/150 ;  SAH(1,1) = 1 + (6 + 6 + 12)/150
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0, 1.0));
        let b = t.push_leaf(vec![1], cube(2.0, 3.0));
        let c = t.push_leaf(vec![2, 3], cube(4.0, 5.0));
        let root = t.push_internal(vec![a, b, c]);
        t.set_root(Some(root));
        assert!((expected_tests(&t) - (3.0 + 24.0 / 150.0)).abs() < 1e-12);
        assert!((sah_cost(&t, SahWeights::default()) - (1.0 + 24.0 / 150.0)).abs() < 1e-12);
    }

    #[test]
    fn empty_and_single_leaf() {
        assert_eq!(expected_tests(&BuildTree::new()), 0.0);
        let mut t = BuildTree::new();
        let a = t.push_leaf(vec![0], cube(0.0, 1.0));
        t.set_root(Some(a));
        assert_eq!(expected_tests(&t), 1.0);
        assert_eq!(sah_cost(&t, SahWeights::default()), 1.0);
    }
}
