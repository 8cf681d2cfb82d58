//! One interface for the nearest-point searches: the search tree ([`ClosestPointTree`]), the
//! walk of a builder's own tree ([`BuildTreeSearch`]) and the switch from the one to the other
//! ([`ClosestPointsOnDemand`]) answer one point, a batch into a list, a batch into columns,
//! counted or not, through the same methods.
//!
//! Each searcher writes two: one point with its steps counted into a [`Tally`], and a batch
//! written row by row into [`AnswerRows`] by the threads [`BatchThreads`] names. Every other
//! form is one of these with its arguments filled in. The methods are generic, so each form is
//! compiled for its searcher, tally and rows: the per-point loop has no dynamic dispatch, and
//! the plain queries (tally `()`) count nothing.
//!
//! [`ClosestPointTree`]: super::ClosestPointTree
//! [`BuildTreeSearch`]: super::BuildTreeSearch
//! [`ClosestPointsOnDemand`]: super::ClosestPointsOnDemand

use glam::DVec3;

use super::answers::{AnswerRows, ClosestPoint};
use super::batches::BatchThreads;
use super::query_points::QueryPoints;
use super::search_tally::{SearchTally, Tally};

/// Nearest surface points to query points. Every implementation answers exactly as
/// [`closest_point_brute_force`](super::closest_point_brute_force): the same point, distance and
/// barycentrics, and among triangles at the same distance the smallest face id; a point with a
/// NaN or infinite coordinate, or an empty mesh, has no answer.
pub trait NearestPointSearch: Sync {
    /// The nearest surface point to `p`, the search's steps counted into `tally` (`()`: not
    /// counted).
    fn closest_point_tallied<T: Tally>(&self, p: DVec3, tally: &mut T) -> Option<ClosestPoint>;

    /// The nearest surface point of each of `points`, written to row `i` of `out` for point `i`,
    /// by the threads `threads` names. `points` may be a `[DVec3]` or the rows of an f32 or f64
    /// array read in place ([`FlatPoints`](super::FlatPoints)). Panics unless `out` has one row
    /// per point.
    fn closest_points_into_with<P: QueryPoints + ?Sized, R: AnswerRows>(
        &self,
        points: &P,
        out: R,
        threads: BatchThreads,
    );

    /// The nearest surface point to `p` (an f32 or f64 point).
    fn closest_point(&self, p: impl Into<DVec3>) -> Option<ClosestPoint> {
        self.closest_point_tallied(p.into(), &mut ())
    }

    /// The nearest surface point of each of `points`, on the calling thread and the current
    /// rayon pool's.
    fn closest_points(&self, points: &[DVec3]) -> Vec<Option<ClosestPoint>> {
        let mut out = vec![None; points.len()];
        self.closest_points_into_with(points, out.as_mut_slice(), BatchThreads::POOL);
        out
    }

    /// [`NearestPointSearch::closest_points`] on the calling thread, each point's answer with
    /// the steps of its search.
    fn closest_points_tallied(&self, points: &[DVec3]) -> Vec<(Option<ClosestPoint>, SearchTally)> {
        let mut out = vec![(None, SearchTally::default()); points.len()];
        self.closest_points_into_with(points, out.as_mut_slice(), BatchThreads::CALLING_THREAD);
        out
    }

    /// The nearest surface point of each of `points` written into `out` (for instance
    /// [`ClosestPointColumns`](super::ClosestPointColumns), as array libraries hold answers,
    /// with no list of them in between). The calling thread works on the batch from the start,
    /// and the current rayon pool's other threads (the global pool's outside any pool) join as
    /// they wake.
    fn closest_points_into<P: QueryPoints + ?Sized, R: AnswerRows>(&self, points: &P, out: R) {
        self.closest_points_into_with(points, out, BatchThreads::POOL);
    }

    /// [`NearestPointSearch::closest_points_into`] on the calling thread alone, with no rayon
    /// task: the same answers, for a caller that wants one thread and should not wait for a
    /// pool's thread to wake (`threads=1` from Python).
    fn closest_points_into_here<P: QueryPoints + ?Sized, R: AnswerRows>(&self, points: &P, out: R) {
        self.closest_points_into_with(points, out, BatchThreads::CALLING_THREAD);
    }
}
