//! Four triangles side by side (structure of arrays), the leaf storage of the nearest-point
//! search: one f32 pass bounds all four distances from below, and only the triangles the bound
//! cannot reject go to the exact f64 routine.

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
}

impl TrianglePacket {
    /// Packs up to four `(face id, vertices)` triangles; `triangles` must not be empty.
    pub fn new(triangles: &[(u32, [glam::Vec3; 3])]) -> Self {
        let mut packet = TrianglePacket {
            vertex: [[[0.0; 4]; 3]; 3],
            prim: [0; 4],
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
    /// triangles: the larger of the distance to the triangle's bounding box
    /// ([`Box4::distance_squared_lower_bounds`], boxes taken from the vertices here) and the
    /// support bound of [`TrianglePacket::support_lower_bounds`].
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, p: &PointBracket) -> [f32; 4] {
        let mut boxes = Box4::EMPTY;
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
        let support = self.support_lower_bounds(p);
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
