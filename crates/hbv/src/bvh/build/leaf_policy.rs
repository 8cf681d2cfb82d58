//! When a top-down SAH builder stops splitting: the termination rule of the surface area
//! heuristic (MacDonald & Booth 1990), with hard bounds on the leaf size.

use std::cmp::Ordering;

use crate::bvh::cost::SahWeights;

/// Largest leaf any builder makes: leaf sizes are stored in a byte by compact layouts.
pub(crate) const LARGEST_LEAF: usize = 255;

/// When [`BinnedSahBuilder`](super::BinnedSahBuilder) and
/// [`SweepSahBuilder`](super::SweepSahBuilder) make a leaf of a node of `n` triangles.
///
/// Splitting node `N` into `L` and `R` costs, by the SAH (in units of a ray reaching `N`),
///
/// ```text
///   split = C_t + C_i · (SA(L) · n_L + SA(R) · n_R) / SA(N)        leaf = C_i · n
/// ```
///
/// The node becomes a leaf when `n <= min_leaf_size`, or when `n <= max_leaf_size` and the best
/// split is not cheaper than the leaf. Nodes of more than `max_leaf_size` triangles are always
/// split. This is the greedy, local form of [`sah_cost`](crate::bvh::sah_cost) with the same
/// weights, so a tree built with weights `w` is (locally) minimal for `sah_cost(tree, w)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafPolicy {
    /// Most triangles a leaf may hold, 1 to 255 (values outside are clamped). Default 8.
    pub max_leaf_size: usize,
    /// Nodes of at most this many triangles become leaves without trying a split. Default 1.
    /// Values above `max_leaf_size` act as `max_leaf_size`.
    pub min_leaf_size: usize,
    /// `C_t` and `C_i` of the rule above. Default 1 and 1, as [`SahWeights::default`].
    pub sah: SahWeights,
}

impl Default for LeafPolicy {
    fn default() -> Self {
        Self {
            max_leaf_size: 8,
            min_leaf_size: 1,
            sah: SahWeights::default(),
        }
    }
}

impl LeafPolicy {
    /// The default policy with leaves of at most `max_leaf_size` triangles.
    pub fn with_max_leaf_size(max_leaf_size: usize) -> Self {
        Self {
            max_leaf_size,
            ..Self::default()
        }
    }

    /// `max_leaf_size` clamped to `1..=255`.
    pub(crate) fn max_leaf(&self) -> usize {
        self.max_leaf_size.clamp(1, LARGEST_LEAF)
    }

    /// Whether a node of `n` triangles is a leaf without looking for a split.
    pub(crate) fn is_leaf_without_split(&self, n: usize) -> bool {
        n <= self.min_leaf_size.min(self.max_leaf())
    }

    /// Whether a node of `n` triangles and surface area `node_area` is a leaf, given the
    /// best split's `SA(L) · n_L + SA(R) · n_R` (`None` when no split was found). A split whose
    /// cost is not a number (boxes too large for f32 areas) counts as no split.
    pub(crate) fn is_leaf(&self, n: usize, node_area: f32, best_split: Option<f32>) -> bool {
        if n > self.max_leaf() {
            return false;
        }
        let Some(weighted_area) = best_split else {
            return true;
        };
        let split = self.sah.traversal
            + self.sah.intersection * f64::from(weighted_area) / f64::from(node_area);
        let leaf = self.sah.intersection * n as f64;
        // A split cost that is not a number (areas beyond f32) makes a leaf too.
        split.partial_cmp(&leaf) != Some(Ordering::Less)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_nodes_always_split_and_small_ones_always_stop() {
        let policy = LeafPolicy {
            max_leaf_size: 4,
            min_leaf_size: 2,
            ..LeafPolicy::default()
        };
        assert!(!policy.is_leaf(5, 1.0, None));
        assert!(!policy.is_leaf(5, 1.0, Some(1e9)));
        assert!(policy.is_leaf_without_split(2));
        assert!(!policy.is_leaf_without_split(3));
    }

    #[test]
    fn leaf_when_split_is_not_cheaper() {
        let policy = LeafPolicy::default();
        // Two triangles in disjoint halves: split = 1 + (0.5·1 + 0.5·1) = 2 = leaf: a leaf.
        assert!(policy.is_leaf(2, 1.0, Some(1.0)));
        // Two small far-apart triangles: split = 1 + 0.2 < 2.
        assert!(!policy.is_leaf(2, 1.0, Some(0.2)));
        // Areas that overflowed f32.
        assert!(policy.is_leaf(2, f32::INFINITY, Some(f32::INFINITY)));
    }

    #[test]
    fn leaf_size_is_clamped() {
        assert_eq!(LeafPolicy::with_max_leaf_size(0).max_leaf(), 1);
        assert_eq!(LeafPolicy::with_max_leaf_size(1000).max_leaf(), 255);
    }
}
