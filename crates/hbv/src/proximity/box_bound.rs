//! Conservative f32 lower bounds of point–box squared distances, four boxes at a time, and the
//! f32 threshold they are compared with: the cheap, exact-safe pruning tests of the
//! nearest-point search.
//!
//! The search decides in f64 ([`super::point_triangle`]), but most of its work is rejecting
//! nodes by their boxes (and triangles by the enclosure bound of `enclosure_packet`, compared with
//! the same threshold). Those tests are done in f32, four lanes at once
//! (plain arrays that the compiler turns into SSE: no `unsafe`), and are made *conservative*:
//! a box is rejected only when its real distance exceeds the best f64 distance so far, so the
//! answer is the one the f64 brute force gives.
//!
//! **Why it is conservative.** The query point `p` (f64) is bracketed by f32 values
//! `lo ≤ p ≤ hi` per axis ([`PointBracket`]). For a box `[min, max]` the per-axis gap is
//! `g = max(min - hi, lo - max, 0) ≤ max(min - p, p - max, 0)`, and every f32 operation after
//! that (one subtraction, a square, two sums, all of non-negative values) rounds up by at most a
//! factor `1 + 2⁻²⁴`; so the computed bound `b̃ ≤ b (1 + 2⁻²⁴)⁵ + 3·2⁻¹⁴⁹` (the last term for
//! squares that fall among the subnormals), where `b` is the real squared distance from `p` to
//! the box. [`prune_threshold`] turns the best squared distance `d²` into
//! `t ≥ (d + δ)² (1 + 2⁻¹⁹) + 2⁻¹²⁶`, rounded up to f32; `b̃ > t` then implies `b > (d + δ)²`: the
//! box is farther than the best triangle by more than `δ`, the margin allowed for the rounding of
//! the f64 triangle routine (its computed distances may differ from the real ones by a few units
//! in the last place of the coordinates; `δ` is `2⁻³²` of the largest coordinate, millions of
//! such units). Overflow is safe too: a bound that rounds to `+∞` belongs to a box farther than
//! `f32::MAX`, and such a box is pruned only when `t` is finite, i.e. when the best distance is
//! far below it.

// The kernels loop over lanes by index, as the four-wide instructions they become do.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

/// `N` axis-aligned boxes, structure of arrays: `min[axis][lane]`, `max[axis][lane]`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(super) struct Boxes<const N: usize> {
    pub min: [[f32; N]; 3],
    pub max: [[f32; N]; 3],
}

/// Four boxes (a triangle packet's half, tests).
pub(super) type Box4 = Boxes<4>;

impl<const N: usize> Boxes<N> {
    /// Slots that hold nothing: NaN bounds, so that their distance bound is NaN and fails
    /// every `bound <= threshold` test, whatever the threshold.
    pub const NONE: Boxes<N> = Boxes {
        min: [[f32::NAN; N]; 3],
        max: [[f32::NAN; N]; 3],
    };

    /// Conservative lower bounds of the squared distances from the point bracketed by `p` to
    /// each box (0 inside): `Σ_axis max(min - hi, lo - max, 0)²` in f32; see the module's notes. Never
    /// NaN for a box of finite (or infinite) bounds.
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, p: &PointBracket) -> [f32; N] {
        let mut d2 = [0.0f32; N];
        for axis in 0..3 {
            let (lo, hi) = (p.lo[axis], p.hi[axis]);
            for lane in 0..N {
                let below = self.min[axis][lane] - hi;
                let above = lo - self.max[axis][lane];
                // `if` rather than `f32::max`: the same result for these operands (no NaN
                // for finite boxes) and one `maxps` instead of a NaN-aware sequence.
                let gap = if below > above { below } else { above };
                // Written so that a NaN gap stays NaN (the empty slots of [`Boxes::NONE`]).
                let gap = if gap < 0.0 { 0.0 } else { gap };
                d2[lane] += gap * gap;
            }
        }
        d2
    }
}

/// The query point bracketed by f32 values: `lo[axis] ≤ p[axis] ≤ hi[axis]`, each the nearest
/// f32 on its side (equal when the coordinate is an f32).
#[derive(Clone, Copy, Debug)]
pub(super) struct PointBracket {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

impl PointBracket {
    /// Brackets a finite point.
    pub fn new(p: DVec3) -> Self {
        let mut bracket = PointBracket {
            lo: [0.0; 3],
            hi: [0.0; 3],
        };
        for axis in 0..3 {
            let x = p[axis];
            let near = x as f32;
            let (lo, hi) = match (near as f64).partial_cmp(&x) {
                Some(std::cmp::Ordering::Less) => (near, near.next_up()),
                Some(std::cmp::Ordering::Greater) => (near.next_down(), near),
                _ => (near, near),
            };
            bracket.lo[axis] = lo;
            bracket.hi[axis] = hi;
        }
        bracket
    }
}

/// The f32 threshold for best squared distance `best_d2` and rounding margin `delta`:
/// `(√best_d2 + δ)² (1 + 2⁻¹⁹) + 2⁻¹²⁶`, rounded up to an f32 (`+∞` while there is no best, or
/// when it is beyond f32). A box whose [`Box4::distance_squared_lower_bounds`] exceeds it cannot
/// hold the answer.
pub(super) fn prune_threshold(best_d2: f64, delta: f64) -> f32 {
    let r = best_d2.sqrt() + delta;
    let t = r * r * (1.0 + f64::powi(2.0, -19)) + f64::powi(2.0, -126);
    let near = t as f32;
    if (near as f64) < t {
        near.next_up()
    } else {
        near
    }
}

/// The rounding margin `δ` of [`prune_threshold`] for a query point `p` and a mesh whose largest
/// coordinate magnitude is `mesh_scale`: `2⁻³² · max(mesh_scale, |p|∞)`.
#[inline]
pub(super) fn rounding_margin(p: DVec3, mesh_scale: f64) -> f64 {
    p.abs().max_element().max(mesh_scale) * f64::powi(2.0, -32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f64 squared distance from `p` to box `lane`.
    fn exact(b: &Box4, lane: usize, p: DVec3) -> f64 {
        (0..3)
            .map(|a| {
                let lo = b.min[a][lane] as f64;
                let hi = b.max[a][lane] as f64;
                let g = (lo - p[a]).max(p[a] - hi).max(0.0);
                g * g
            })
            .sum()
    }

    #[test]
    fn brackets_hold_the_point() {
        for x in [0.1f64, -0.1, 1e-40, 3.0, 1e39, -1e39, 16777217.0] {
            let b = PointBracket::new(DVec3::splat(x));
            assert!(b.lo[0] as f64 <= x && x <= b.hi[0] as f64, "{x}");
        }
    }

    #[test]
    fn bounds_never_exceed_the_threshold_of_the_exact_distance() {
        let mut boxes = Box4::NONE;
        let corners = [
            ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            ([-3.5, 2.25, 1e-30], [-3.0, 2.5, 1e-29]),
            ([1e6, -1e6, 7.0], [1e6 + 0.5, -1e6 + 0.5, 8.0]),
            ([0.1, 0.2, 0.3], [0.1, 0.2, 0.3]),
        ];
        for (lane, (lo, hi)) in corners.iter().enumerate() {
            for a in 0..3 {
                boxes.min[a][lane] = lo[a];
                boxes.max[a][lane] = hi[a];
            }
        }
        let points = [
            DVec3::new(0.5, 0.5, 0.5),
            DVec3::new(0.1, 0.2, 0.3),
            DVec3::new(0.1 + 1e-12, 0.2, 0.3 - 1e-13),
            DVec3::new(-3.25, 2.3, 0.0),
            DVec3::new(1e6 + 0.75, -1e6 - 0.1, 7.5),
            DVec3::new(-1e20, 1e19, 3.0),
        ];
        for p in points {
            let got = boxes.distance_squared_lower_bounds(&PointBracket::new(p));
            for lane in 0..4 {
                let d2 = exact(&boxes, lane, p);
                // Pruned against a best exactly at the box's distance: must not happen.
                assert!(got[lane] <= prune_threshold(d2, 0.0), "{p:?} lane {lane}");
            }
        }
    }

    #[test]
    fn threshold_is_infinite_without_a_best_and_beyond_f32() {
        assert_eq!(prune_threshold(f64::INFINITY, 0.0), f32::INFINITY);
        assert_eq!(prune_threshold(1e80, 0.0), f32::INFINITY);
        assert!(prune_threshold(0.0, 0.0) > 0.0);
        assert!(prune_threshold(2.0, 0.0) as f64 >= 2.0);
    }
}
