//! A rotated frame for the four child boxes of a search node near the leaves: boxes aligned with
//! a surface patch's normal instead of the world axes.
//!
//! A patch of surface tilted against the axes has an axis-aligned box as thick as it is wide, and
//! a distant point above the patch sees that box much nearer than the patch: the search visits
//! leaves it cannot use. In a frame whose third axis is the patch's mean normal, the box is as
//! thin as the patch is curved (oriented boxes, as fitted by Gottschalk, Lin & Manocha 1996; here
//! the four children of a node share one frame, so the point is rotated once per node).
//!
//! **Conservative.** The frame's rows `r_j` are f32 vectors, orthonormal only to `e ≤ 2⁻²⁰`
//! (checked when the frame is made). A child's box is the set `{x : lo_j ≤ r_j·x ≤ hi_j}`, with
//! `lo`, `hi` the extremes of `r_j·v` over its vertices, computed in f64 and rounded outward. The
//! query point's coordinates `r_j·p` are bracketed in f32 with their rounding error
//! ([`NodeFrame::bracket`]), and the box bound of [`super::box_bound`] then bounds `Σ_j gap_j²`
//! with `gap_j ≤ |r_j·(p - y)|` for every point `y` of the child. Since
//! `Σ_j (r_j·x)² = |R x|² ≤ σ_max² |x|²` with `σ_max² ≤ 1 + 3e` (Gershgorin), multiplying the bound
//! by [`FRAME_SHRINK`] keeps it below the real squared distance.

use glam::{DVec3, Vec3};

use super::box_bound::PointBracket;
use crate::geometry::directed_rounding::{f32_above, f32_below};

/// `1 - 2⁻¹⁶`: what a bound computed in a [`NodeFrame`] is multiplied by (it covers
/// `σ_max² ≤ 1 + 3·2⁻²⁰` and the f32 rounding of the bound).
pub(super) const FRAME_SHRINK: f32 = 1.0 - 1.0 / 65_536.0;

/// Three f32 rows, orthonormal to `2⁻²⁰`, the third along a patch's normal.
#[derive(Clone, Copy, Debug)]
pub(super) struct NodeFrame {
    rows: [[f32; 3]; 3],
    /// The rows side by side: `columns[i][j]` is `rows[j][i]` (lane 3 is 0), so that the three
    /// coordinates of a point are computed at once, four lanes wide.
    columns: [[f32; 4]; 3],
}

impl NodeFrame {
    /// The frame whose third axis is `normal` (any length but zero); `None` if its rows, rounded
    /// to f32, are not orthonormal to `2⁻²⁰`.
    pub fn facing(normal: DVec3) -> Option<NodeFrame> {
        let n = normal.try_normalize()?;
        let helper = if n.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
        let t1 = n.cross(helper).try_normalize()?;
        let t2 = n.cross(t1);
        let rows = [t1, t2, n].map(|r| r.as_vec3().to_array());
        let frame = NodeFrame {
            rows,
            columns: [0, 1, 2].map(|i| [rows[0][i], rows[1][i], rows[2][i], 0.0]),
        };
        let r = frame.rows.map(|row| Vec3::from(row).as_dvec3());
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                if (r[i].dot(r[j]) - want).abs() > f64::powi(2.0, -20) {
                    return None;
                }
            }
        }
        Some(frame)
    }

    /// The box of `vertices` in this frame, `(lo, hi)` per axis, rounded outward to f32: `r_j·v`
    /// in f64 (three exact products, two roundings of at most `2⁻⁵³` of `Σ |r_ji v_i|` each; a
    /// margin of `2⁻⁵⁰` of it is added).
    ///
    /// The extremes are taken in f64 and rounded once: directed rounding is monotone, so that is
    /// the box of the vertices' rounded bounds, bit for bit, at a sixth of the roundings per
    /// vertex.
    pub fn box_of(&self, vertices: impl IntoIterator<Item = Vec3>) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in vertices {
            for (j, row) in self.rows.iter().enumerate() {
                let terms = [0, 1, 2].map(|i| row[i] as f64 * v[i] as f64);
                let value = terms[0] + terms[1] + terms[2];
                let margin =
                    (terms[0].abs() + terms[1].abs() + terms[2].abs()) * f64::powi(2.0, -50);
                lo[j] = lo[j].min(value - margin);
                hi[j] = hi[j].max(value + margin);
            }
        }
        (lo.map(f32_below), hi.map(f32_above))
    }

    /// The point's coordinates in this frame, bracketed in f32, from its world bracket: with
    /// `l` the bracket's low side, `r_j·p` lies within `r_j·l ± Σ_i |r_ji| (hi_i - lo_i)`, and
    /// `fl(r_j·l)` within `2⁻²² Σ |r_ji l_i|` of `r_j·l`; the margin taken is
    /// `2⁻²⁰ (Σ |r_ji l_i| + |fl(r_j·l)|) + (1 + 2⁻²⁰) Σ |r_ji| (hi_i - lo_i)`, which also covers
    /// its own rounding and that of the final subtraction and addition. A coordinate whose bracket
    /// is not finite (points near the f32 limit) becomes `(-∞, +∞)`: no bound.
    ///
    /// On x86-64 in SSE intrinsics (the baseline: no detection), the portable form's operations
    /// in the same order, so the same bits; LLVM left the portable form mostly scalar (about
    /// 100 instructions a node, 800 of the bunny's 6,100 per query).
    #[inline(always)]
    pub fn bracket(&self, p: &PointBracket) -> PointBracket {
        #[cfg(target_arch = "x86_64")]
        return self.bracket_sse(p);
        #[cfg(not(target_arch = "x86_64"))]
        return self.bracket_portable(p);
    }

    /// [`NodeFrame::bracket`] in SSE, four lanes (the rows; lane 3 is 0) at once.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn bracket_sse(&self, p: &PointBracket) -> PointBracket {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86-64 baseline; the loads read the four f32 of a
        // column, the stores write four f32 arrays.
        unsafe {
            let sign = _mm_set1_ps(-0.0);
            let mut value = _mm_setzero_ps();
            let mut magnitude = _mm_setzero_ps();
            let mut spread = _mm_setzero_ps();
            for i in 0..3 {
                let column = _mm_loadu_ps(self.columns[i].as_ptr());
                let term = _mm_mul_ps(column, _mm_set1_ps(p.lo[i]));
                value = _mm_add_ps(value, term);
                magnitude = _mm_add_ps(magnitude, _mm_andnot_ps(sign, term));
                let width = _mm_set1_ps(p.hi[i] - p.lo[i]);
                spread = _mm_add_ps(spread, _mm_mul_ps(_mm_andnot_ps(sign, column), width));
            }
            let margin = _mm_add_ps(
                _mm_add_ps(
                    _mm_mul_ps(
                        _mm_add_ps(magnitude, _mm_andnot_ps(sign, value)),
                        _mm_set1_ps(1.0 / 1_048_576.0),
                    ),
                    _mm_mul_ps(spread, _mm_set1_ps(1.0 + 1.0 / 1_048_576.0)),
                ),
                _mm_set1_ps(f32::MIN_POSITIVE),
            );
            let (lo, hi) = (_mm_sub_ps(value, margin), _mm_add_ps(value, margin));
            let finite = _mm_and_ps(
                _mm_cmpgt_ps(lo, _mm_set1_ps(f32::NEG_INFINITY)),
                _mm_cmplt_ps(hi, _mm_set1_ps(f32::INFINITY)),
            );
            let lo = _mm_or_ps(
                _mm_and_ps(finite, lo),
                _mm_andnot_ps(finite, _mm_set1_ps(f32::NEG_INFINITY)),
            );
            let hi = _mm_or_ps(
                _mm_and_ps(finite, hi),
                _mm_andnot_ps(finite, _mm_set1_ps(f32::INFINITY)),
            );
            let (mut lo4, mut hi4) = ([0.0f32; 4], [0.0f32; 4]);
            _mm_storeu_ps(lo4.as_mut_ptr(), lo);
            _mm_storeu_ps(hi4.as_mut_ptr(), hi);
            PointBracket {
                lo: [lo4[0], lo4[1], lo4[2]],
                hi: [hi4[0], hi4[1], hi4[2]],
            }
        }
    }

    /// [`NodeFrame::bracket`] lane by lane in plain Rust (other CPUs; the SSE form's reference).
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    #[inline(always)]
    fn bracket_portable(&self, p: &PointBracket) -> PointBracket {
        // Lane `j` is row `j`: the same operations in the same order as row by row.
        let mut value = [0.0f32; 4];
        let mut magnitude = [0.0f32; 4];
        let mut spread = [0.0f32; 4];
        for (i, column) in self.columns.iter().enumerate() {
            let (lo, hi) = (p.lo[i], p.hi[i]);
            for j in 0..4 {
                let term = column[j] * lo;
                value[j] += term;
                magnitude[j] += term.abs();
                spread[j] += column[j].abs() * (hi - lo);
            }
        }
        let mut lo4 = [0.0f32; 4];
        let mut hi4 = [0.0f32; 4];
        for j in 0..4 {
            let margin = (magnitude[j] + value[j].abs()) * (1.0 / 1_048_576.0)
                + spread[j] * (1.0 + 1.0 / 1_048_576.0)
                + f32::MIN_POSITIVE;
            let (lo, hi) = (value[j] - margin, value[j] + margin);
            let finite = lo > f32::NEG_INFINITY && hi < f32::INFINITY;
            lo4[j] = if finite { lo } else { f32::NEG_INFINITY };
            hi4[j] = if finite { hi } else { f32::INFINITY };
        }
        PointBracket {
            lo: [lo4[0], lo4[1], lo4[2]],
            hi: [hi4[0], hi4[1], hi4[2]],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proximity::box_bound::{prune_threshold, Box4};

    /// A tilted square patch and points around it: the rotated bound never exceeds the squared
    /// distance to the nearest of the patch's sample points (at least the distance to their
    /// hull), and is nearly the distance for a point above the patch.
    #[test]
    fn rotated_bound_is_conservative_and_tight() {
        let normal = DVec3::new(1.0, 2.0, 2.0).normalize();
        let frame = NodeFrame::facing(normal).unwrap();
        let t1 = normal.cross(DVec3::X).normalize();
        let t2 = normal.cross(t1);
        for centre in [
            DVec3::new(1e3, -2e3, 5e2),
            DVec3::ZERO,
            DVec3::new(3e6, 1e6, -2e6),
        ] {
            let samples: Vec<Vec3> = (0..=10)
                .flat_map(|i| (0..=10).map(move |j| (i as f64 / 10.0 - 0.5, j as f64 / 10.0 - 0.5)))
                .map(|(a, b)| (centre + t1 * a + t2 * b).as_vec3())
                .collect();
            let (lo, hi) = frame.box_of(samples.iter().copied());
            let mut boxes = Box4::NONE;
            for j in 0..3 {
                boxes.min[j][0] = lo[j];
                boxes.max[j][0] = hi[j];
            }
            for (k, offset) in [
                normal * 3.0,
                normal * -0.01,
                t1 * 2.0 + normal * 0.5,
                DVec3::ZERO,
                t2 * 0.25 + normal * 1e-7,
            ]
            .into_iter()
            .enumerate()
            {
                let p = samples[60].as_dvec3() + offset;
                let bracket = frame.bracket(&PointBracket::new(p));
                let bound = boxes.distance_squared_lower_bounds(&bracket)[0] * FRAME_SHRINK;
                let nearest = samples
                    .iter()
                    .map(|s| (s.as_dvec3() - p).length_squared())
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    bound <= prune_threshold(nearest, 0.0),
                    "{centre:?} point {k}: {bound} > {nearest}"
                );
                if k == 0 && centre == DVec3::ZERO {
                    // 3 above the patch: the bound is nearly 9.
                    assert!(bound > 8.9, "{bound}");
                }
            }
        }
    }

    /// The SSE bracket is the portable one, bit for bit, at every scale (huge points included).
    #[test]
    fn sse_bracket_is_the_portable_bracket() {
        for n in [
            DVec3::new(0.3, -0.2, 0.9),
            DVec3::new(-1e-3, 1.0, 1e-4),
            DVec3::new(1.0, 2.0, 2.0),
        ] {
            let frame = NodeFrame::facing(n).unwrap();
            for p in [
                DVec3::new(0.1, -0.7, 3.3),
                DVec3::new(1e6 + 0.1, -2e6, 0.3),
                DVec3::new(-1e-30, 1e-20, 0.0),
                DVec3::splat(3e38),
                DVec3::new(-3.4e38, 1.0, 2e38),
            ] {
                let bracket = PointBracket::new(p);
                let (a, b) = (frame.bracket(&bracket), frame.bracket_portable(&bracket));
                let bits = |x: [f32; 3]| x.map(f32::to_bits);
                assert_eq!((bits(a.lo), bits(a.hi)), (bits(b.lo), bits(b.hi)), "{p:?}");
            }
        }
    }

    #[test]
    fn frames_are_orthonormal_and_huge_points_are_unbounded() {
        for n in [
            DVec3::X,
            DVec3::new(0.3, -0.2, 0.9),
            DVec3::new(-1e-3, 1.0, 1e-4),
        ] {
            assert!(NodeFrame::facing(n).is_some(), "{n:?}");
        }
        assert!(NodeFrame::facing(DVec3::ZERO).is_none());
        let frame = NodeFrame::facing(DVec3::new(1.0, 1.0, 1.0)).unwrap();
        let b = frame.bracket(&PointBracket::new(DVec3::splat(3e38)));
        assert!(b.lo.iter().zip(b.hi).all(|(lo, hi)| *lo <= hi));
    }
}
