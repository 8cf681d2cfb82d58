//! Counters of traversal work, filled by the same code that answers queries.
//!
//! Traversal kernels are generic over [`Counter`]. With [`NoCount`] every call is an empty inline
//! function and vanishes from the compiled kernel; with [`TraversalStats`] the same kernel counts.

use std::ops::AddAssign;

/// Receives the events of one traversal.
pub trait Counter {
    /// A node was visited (its children, or its triangles, are about to be tested).
    fn node_visited(&mut self) {}
    /// `n` boxes were tested against the ray.
    fn boxes_tested(&mut self, _n: u32) {}
    /// `n` triangles were tested against the ray.
    fn triangles_tested(&mut self, _n: u32) {}
    /// A triangle was skipped because the ray had already tested it in an earlier cell
    /// (a mailbox hit; see `grid::Mailbox`).
    fn mailbox_skipped(&mut self) {}
}

/// Counts nothing, costs nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCount;

impl Counter for NoCount {}

/// Work done by one or more traversals.
///
/// `boxes_tested + triangles_tested` is what the tree cost E\[X\] predicts per ray (for lines
/// traversed without early exit); the test of the root's own box is not included there, and is
/// counted here in `boxes_tested` like any other.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    pub rays: u64,
    pub nodes_visited: u64,
    pub boxes_tested: u64,
    pub triangles_tested: u64,
    /// Triangle tests saved by mailboxes (uniform grid): repeats of a triangle already tested.
    pub mailbox_skips: u64,
}

impl TraversalStats {
    /// Boxes plus triangles tested: the "intersection tests" of the tree cost.
    pub fn tests(&self) -> u64 {
        self.boxes_tested + self.triangles_tested
    }

    /// Mean tests per ray (0 when no ray was counted).
    pub fn tests_per_ray(&self) -> f64 {
        self.per_ray(self.tests())
    }

    /// Mean nodes visited per ray (0 when no ray was counted).
    pub fn nodes_per_ray(&self) -> f64 {
        self.per_ray(self.nodes_visited)
    }

    /// Mean boxes tested per ray (0 when no ray was counted).
    pub fn boxes_per_ray(&self) -> f64 {
        self.per_ray(self.boxes_tested)
    }

    /// Mean triangles tested per ray (0 when no ray was counted).
    pub fn triangles_per_ray(&self) -> f64 {
        self.per_ray(self.triangles_tested)
    }

    /// Mean mailbox skips per ray (0 when no ray was counted).
    pub fn mailbox_skips_per_ray(&self) -> f64 {
        self.per_ray(self.mailbox_skips)
    }

    /// `total` over the counted rays: 0 when none was counted, so that an empty ray set reports
    /// no work rather than NaN.
    fn per_ray(&self, total: u64) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            total as f64 / self.rays as f64
        }
    }
}

impl Counter for TraversalStats {
    #[inline]
    fn node_visited(&mut self) {
        self.nodes_visited += 1;
    }
    #[inline]
    fn boxes_tested(&mut self, n: u32) {
        self.boxes_tested += n as u64;
    }
    #[inline]
    fn triangles_tested(&mut self, n: u32) {
        self.triangles_tested += n as u64;
    }
    #[inline]
    fn mailbox_skipped(&mut self) {
        self.mailbox_skips += 1;
    }
}

impl AddAssign for TraversalStats {
    fn add_assign(&mut self, o: Self) {
        self.rays += o.rays;
        self.nodes_visited += o.nodes_visited;
        self.boxes_tested += o.boxes_tested;
        self.triangles_tested += o.triangles_tested;
        self.mailbox_skips += o.mailbox_skips;
    }
}
