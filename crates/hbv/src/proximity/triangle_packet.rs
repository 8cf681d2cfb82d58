//! Four triangles side by side (structure of arrays), the leaf storage of the nearest-point
//! search: one f32 pass bounds all four distances from below (a support-function bound, tight for
//! the distant points that visit the most triangles), and only the triangles the bound cannot
//! reject go to the exact f64 routine.

// The kernels loop over lanes by index, as the four-wide instructions they become do.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

use super::box_bound::{Box4, PointBracket};

/// Up to four triangles: `vertex[k][axis][lane]` is coordinate `axis` of vertex `k` of the
/// triangle in `lane`, `prim[lane]` its face id. Unused lanes repeat lane 0 (the search never
/// reads them: a leaf knows how many triangles it has).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct TrianglePacket {
    pub vertex: [[[f32; 4]; 3]; 3],
    pub prim: [u32; 4],
    /// Some triangle lies in a plane of constant x, y or z: its box is flat, and the box bound
    /// is then tighter than the support bound (walls and floors of modelled scenes).
    pub axis_aligned: bool,
}

impl TrianglePacket {
    /// Packs up to four `(face id, vertices)` triangles; `triangles` must not be empty.
    pub fn new(triangles: &[(u32, [glam::Vec3; 3])]) -> Self {
        let mut packet = TrianglePacket {
            vertex: [[[0.0; 4]; 3]; 3],
            prim: [0; 4],
            axis_aligned: triangles
                .iter()
                .any(|(_, [a, b, c])| (0..3).any(|i| a[i] == b[i] && b[i] == c[i])),
        };
        for lane in 0..4 {
            let (prim, v) = triangles[if lane < triangles.len() { lane } else { 0 }];
            packet.prim[lane] = prim;
            for (k, vertex) in v.iter().enumerate() {
                for axis in 0..3 {
                    packet.vertex[k][axis][lane] = vertex[axis];
                }
            }
        }
        packet
    }

    /// The triangle in `lane`, in f64 (exact: the vertices are f32).
    #[inline]
    pub fn triangle(&self, lane: usize) -> [DVec3; 3] {
        let v = &self.vertex;
        let at = |k: usize| {
            DVec3::new(
                v[k][0][lane] as f64,
                v[k][1][lane] as f64,
                v[k][2][lane] as f64,
            )
        };
        [at(0), at(1), at(2)]
    }

    /// Conservative lower bounds of the squared distances from the bracketed point to the four
    /// triangles: [`TrianglePacket::support_lower_bounds`], and for a packet with an
    /// axis-aligned triangle the larger of that and the distance to each triangle's bounding box
    /// ([`Box4::distance_squared_lower_bounds`]). (The box bound on every packet rejected no more
    /// on scanned meshes and cost 3–4 %; on the Cornell box's walls it gains 12–17 %.)
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, p: &PointBracket) -> [f32; 4] {
        let support = self.support_lower_bounds(p);
        if !self.axis_aligned {
            return support;
        }
        let mut boxes = Box4::NONE;
        let v = &self.vertex;
        for axis in 0..3 {
            for lane in 0..4 {
                let (a, b, c) = (v[0][axis][lane], v[1][axis][lane], v[2][axis][lane]);
                let lo = if a < b { a } else { b };
                let hi = if a > b { a } else { b };
                boxes.min[axis][lane] = if lo < c { lo } else { c };
                boxes.max[axis][lane] = if hi > c { hi } else { c };
            }
        }
        let in_box = boxes.distance_squared_lower_bounds(p);
        let mut bound = [0.0f32; 4];
        for lane in 0..4 {
            bound[lane] = if in_box[lane] > support[lane] {
                in_box[lane]
            } else {
                support[lane]
            };
        }
        bound
    }

    /// The support-function bound: for any direction `u ≠ 0`, the triangle `T = conv(a, b, c)`
    /// lies in the half-space `u·x ≤ max_k u·v_k`, so
    /// `dist(p, T) ≥ min_k u·(p - v_k) / |u|` (equality when `u` points from the nearest point
    /// of `T` to `p`). Here `u = p - centroid`: for a point far from a patch of small triangles
    /// (the common case of the search) this is nearly the true distance, where the box bound is
    /// loose by the triangle's size. Squared, clamped at 0.
    ///
    /// Conservative in f32: `u` is whatever f32 vector was computed (any direction is valid);
    /// each `p - v_k` uses the side of `p`'s bracket that makes `u·(p - v_k)` smaller; the sum
    /// `S_k = Σ u_i w_i` (one subtraction, one product and two sums, each rounding by at most
    /// `2⁻²⁴` of `Σ |u_i| |w_i|`) is lowered by `2⁻²⁰ Σ |u_i| |w_i|`; the square over
    /// `|u|²` (raised by `2⁻²⁰`, plus the least normal f32 against underflow) is lowered by
    /// `2⁻¹⁸`. A result that is not finite (coordinates near the f32 limit) is replaced by 0.
    #[inline(always)]
    pub fn support_lower_bounds(&self, p: &PointBracket) -> [f32; 4] {
        let v = &self.vertex;
        let mut u = [[0.0f32; 4]; 3];
        let mut uu = [0.0f32; 4];
        for axis in 0..3 {
            for lane in 0..4 {
                let centroid =
                    (v[0][axis][lane] + v[1][axis][lane] + v[2][axis][lane]) * (1.0 / 3.0);
                let x = p.lo[axis] - centroid;
                u[axis][lane] = x;
                uu[lane] += x * x;
            }
        }
        let mut least = [f32::INFINITY; 4];
        for vertex in v {
            let mut sum = [0.0f32; 4];
            let mut magnitude = [0.0f32; 4];
            for axis in 0..3 {
                for lane in 0..4 {
                    let ui = u[axis][lane];
                    let pi = if ui >= 0.0 { p.lo[axis] } else { p.hi[axis] };
                    let w = pi - vertex[axis][lane];
                    sum[lane] += ui * w;
                    magnitude[lane] += ui.abs() * w.abs();
                }
            }
            for lane in 0..4 {
                let s = sum[lane] - magnitude[lane] * SUM_SLACK;
                least[lane] = if s < least[lane] { s } else { least[lane] };
            }
        }
        let mut bound = [0.0f32; 4];
        for lane in 0..4 {
            let n = if least[lane] > 0.0 { least[lane] } else { 0.0 };
            let b =
                n * n / (uu[lane] * (1.0 + SUM_SLACK) + f32::MIN_POSITIVE) * (1.0 - RATIO_SLACK);
            bound[lane] = if b < f32::INFINITY { b } else { 0.0 };
        }
        bound
    }
}

/// `2⁻²⁰`: the relative slack of the support bound's sums (their rounding is at most `2⁻²²`).
const SUM_SLACK: f32 = 1.0 / 1_048_576.0;
/// `2⁻¹⁸`: the relative slack of the support bound's square and division.
const RATIO_SLACK: f32 = 1.0 / 262_144.0;

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use proptest::prelude::*;

    use super::*;
    use crate::proximity::box_bound::prune_threshold;
    use crate::proximity::point_triangle::closest_point_on_triangle;

    fn vec3(s: f32) -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(move |(x, y, z)| Vec3::new(x, y, z) * s)
    }

    /// Four triangles of one size around one centre: tiny to huge, near and far from the origin;
    /// some lying in a plane of constant x, y or z (the packets that use the box bound too).
    fn packet() -> impl Strategy<Value = (Vec3, f32, Vec<[Vec3; 3]>)> {
        let centre = prop_oneof![Just(0.0f32), Just(1e3), Just(1e7), Just(1e18)];
        let size = prop_oneof![Just(1e-4f32), Just(1.0), Just(1e3), Just(1e6)];
        (centre, size).prop_flat_map(|(c, s)| {
            let flat = prop_oneof![Just(None), (0usize..3).prop_map(Some)];
            let triangle = (vec3(s), vec3(s), vec3(s), flat).prop_map(|(a, mut b, mut c, flat)| {
                if let Some(axis) = flat {
                    b[axis] = a[axis];
                    c[axis] = a[axis];
                }
                [a, b, c]
            });
            (vec3(c), Just(s), prop::collection::vec(triangle, 4))
        })
    }

    proptest! {
        /// Both bounds stay at or below the threshold of the exact f64 squared distance: a
        /// triangle is never pruned against a best equal to its own distance.
        #[test]
        fn bounds_never_exceed_the_exact_distance((centre, size, tris) in packet(), offset in vec3(1.0), reach in prop_oneof![Just(0.0f32), Just(1e-6), Just(1e-3), Just(1.0), Just(30.0)]) {
            let tris: Vec<(u32, [Vec3; 3])> = tris
                .into_iter()
                .enumerate()
                .map(|(i, [a, b, c])| (i as u32, [centre + a, centre + b, centre + c]))
                .collect();
            // Degenerate triangles never reach a packet.
            prop_assume!(tris.iter().all(|(_, [a, b, c])| (*b - *a).cross(*c - *a).length_squared() > 0.0));
            let packet = TrianglePacket::new(&tris);
            let p = (tris[0].1[0].as_dvec3() + offset.as_dvec3() * (size as f64 * reach as f64))
                + DVec3::new(1e-9, -3e-10, 0.0) * size as f64;
            let bracket = PointBracket::new(p);
            let bounds = packet.distance_squared_lower_bounds(&bracket);
            let support = packet.support_lower_bounds(&bracket);
            for (lane, (_, [a, b, c])) in tris.iter().enumerate() {
                let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                let d2 = (p - q.point).length_squared();
                let t = prune_threshold(d2, 0.0);
                prop_assert!(bounds[lane] <= t, "lane {lane}: bound {} > threshold {t} (d² {d2})", bounds[lane]);
                prop_assert!(support[lane] <= t, "lane {lane}: support {} > threshold {t} (d² {d2})", support[lane]);
            }
        }
    }

    /// For a point far above a flat patch the support bound is nearly the distance, where the
    /// box bound is loose by the triangle's size.
    #[test]
    fn support_bound_is_tight_far_above_a_face() {
        let tri = (
            0,
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
        );
        let packet = TrianglePacket::new(&[tri]);
        let p = DVec3::new(1.5, 1.5, 10.0);
        let exact = closest_point_on_triangle(p, DVec3::ZERO, DVec3::X, DVec3::Y);
        let d2 = (p - exact.point).length_squared();
        let support = packet.support_lower_bounds(&PointBracket::new(p))[0] as f64;
        assert!(
            support > 0.97 * d2 && support <= d2 * (1.0 + 1e-6),
            "{support} vs {d2}"
        );
    }
}
