//! What a nearest-point query answers ([`ClosestPoint`]), and where a batch's answers go
//! ([`AnswerRows`]): a list of answers, the same with each search's steps counted, or five
//! columns as array libraries (NumPy) hold them ([`ClosestPointColumns`]).

use glam::DVec3;

use super::search_tally::{SearchTally, Tally};

/// The nearest surface point to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The nearest point, `(1-u-v) p0 + u p1 + v p2` of triangle `prim`.
    pub point: DVec3,
    /// Euclidean distance from the query point to `point`.
    pub distance: f64,
    /// The triangle's index in the mesh's face order; among triangles at the same distance, the
    /// smallest.
    pub prim: u32,
    pub u: f64,
    pub v: f64,
}

/// Output columns for [`closest_points_into`](super::NearestPointSearch::closest_points_into),
/// one entry per query point: the nearest point, its distance, the triangle (-1 for none) and
/// the barycentrics `u`, `v`. A point without an answer gets NaN, +∞, -1, 0, 0.
pub struct ClosestPointColumns<'a> {
    pub point: &'a mut [[f64; 3]],
    pub distance: &'a mut [f64],
    pub prim: &'a mut [i64],
    pub u: &'a mut [f64],
    pub v: &'a mut [f64],
}

/// Where a batch's answers go, one row per query point, written by
/// [`closest_points_into_with`](super::NearestPointSearch::closest_points_into_with): a slice
/// of answers, a slice of answers with each search's steps ([`SearchTally`]), or
/// [`ClosestPointColumns`]. A batch cuts its rows into runs ([`AnswerRows::into_runs`]) that
/// threads fill apart, each row once; the writes are compiled into the search loop.
pub trait AnswerRows: Send + Sized {
    /// What a row keeps of its search's steps: `()` nothing (the searches count nothing, at no
    /// cost), [`SearchTally`] their counts.
    type Tally: Tally;

    /// Whether there is one row for each of `n` points.
    fn holds(&self, n: usize) -> bool;

    /// The rows in runs of `len` (the last one shorter), in order.
    fn into_runs(self, len: usize) -> Vec<Self>;

    /// Writes row `k`: `found`, and the steps its search took.
    fn write(&mut self, k: usize, found: Option<ClosestPoint>, tally: Self::Tally);
}

impl AnswerRows for &mut [Option<ClosestPoint>] {
    type Tally = ();

    fn holds(&self, n: usize) -> bool {
        self.len() == n
    }

    fn into_runs(self, len: usize) -> Vec<Self> {
        self.chunks_mut(len).collect()
    }

    #[inline(always)]
    fn write(&mut self, k: usize, found: Option<ClosestPoint>, (): ()) {
        self[k] = found;
    }
}

impl AnswerRows for &mut [(Option<ClosestPoint>, SearchTally)] {
    type Tally = SearchTally;

    fn holds(&self, n: usize) -> bool {
        self.len() == n
    }

    fn into_runs(self, len: usize) -> Vec<Self> {
        self.chunks_mut(len).collect()
    }

    #[inline(always)]
    fn write(&mut self, k: usize, found: Option<ClosestPoint>, tally: SearchTally) {
        self[k] = (found, tally);
    }
}

impl AnswerRows for ClosestPointColumns<'_> {
    type Tally = ();

    fn holds(&self, n: usize) -> bool {
        [
            self.point.len(),
            self.distance.len(),
            self.prim.len(),
            self.u.len(),
            self.v.len(),
        ] == [n; 5]
    }

    fn into_runs(self, len: usize) -> Vec<Self> {
        let Self {
            point,
            distance,
            prim,
            u,
            v,
        } = self;
        point
            .chunks_mut(len)
            .zip(distance.chunks_mut(len))
            .zip(prim.chunks_mut(len))
            .zip(u.chunks_mut(len))
            .zip(v.chunks_mut(len))
            .map(|((((point, distance), prim), u), v)| ClosestPointColumns {
                point,
                distance,
                prim,
                u,
                v,
            })
            .collect()
    }

    #[inline(always)]
    fn write(&mut self, k: usize, found: Option<ClosestPoint>, (): ()) {
        match found {
            Some(c) => {
                self.point[k] = c.point.to_array();
                self.distance[k] = c.distance;
                self.prim[k] = c.prim as i64;
                self.u[k] = c.u;
                self.v[k] = c.v;
            }
            None => {
                self.point[k] = [f64::NAN; 3];
                self.distance[k] = f64::INFINITY;
                self.prim[k] = -1;
                self.u[k] = 0.0;
                self.v[k] = 0.0;
            }
        }
    }
}
