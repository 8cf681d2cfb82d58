//! Counting what a nearest-point search does, for profiling: [`SearchTally`] counts the steps,
//! `()` ignores them, and the plain queries, which pass `()`, compile the counting away.

/// What one search did, counted: nodes whose child bounds were computed, triangle packets
/// bounded (none in a walk of the build tree, whose leaves hold triangles one by one), and
/// triangles decided by the exact f64 routine (a seed's included). For profiling
/// ([`closest_points_tallied`](super::NearestPointSearch::closest_points_tallied)); the plain
/// queries count nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SearchTally {
    pub nodes: u64,
    pub packets: u64,
    pub exact: u64,
}

/// Where a search reports its steps: [`SearchTally`] counts them, `()` (the plain queries)
/// ignores them at no cost.
pub trait Tally: Copy + Default + Send + Sync {
    /// Whether the steps are counted. A counted search is the tree search alone: answers that a
    /// candidate grid would give from its lists (module `candidate_grid`) are searched for
    /// instead, so that every step is seen.
    const COUNTS: bool;
    /// A node's child bounds computed.
    fn node(&mut self);
    /// A packet of triangles bounded.
    fn packet(&mut self);
    /// A triangle decided exactly.
    fn exact(&mut self);
}

impl Tally for () {
    const COUNTS: bool = false;
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn packet(&mut self) {}
    #[inline(always)]
    fn exact(&mut self) {}
}

impl Tally for SearchTally {
    const COUNTS: bool = true;
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn packet(&mut self) {
        self.packets += 1;
    }
    #[inline(always)]
    fn exact(&mut self) {
        self.exact += 1;
    }
}
