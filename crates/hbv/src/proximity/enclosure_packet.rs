//! [`LANES`] triangles side by side (structure of arrays) with their enclosures, the leaf storage
//! of the nearest-point search (unrelated to the wide ray layout's four-triangle
//! `TrianglePacket`): one f32 pass bounds all their distances from below (the distance to each triangle's
//! enclosure, module `triangle_enclosure`: exact for points above the face, beside an edge,
//! and most points beside a vertex), and only the triangles the bound cannot reject go to the
//! exact f64 routine.

// The kernels loop over lanes by index, as the four-wide instructions they become do.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

use super::box_bound::{Box4, PointBracket};
use super::point_triangle::is_sliver;
use super::triangle_enclosure::TriangleEnclosure;

/// Triangles side by side in a packet: eight, one AVX register of f32 (two SSE registers
/// without AVX).
pub(super) const LANES: usize = 8;

/// Up to [`LANES`] triangles and their enclosures, the unit a search-tree leaf is made of:
/// `vertex[k][axis][lane]` is coordinate `axis` of vertex `k` of the
/// triangle in `lane`, `prim[lane]` its face id, and their [`TriangleEnclosure`]s lane by lane.
/// Unused lanes repeat lane 0 (the search never reads them: a leaf knows how many triangles it
/// has).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct EnclosurePacket {
    pub vertex: [[[f32; LANES]; 3]; 3],
    pub prim: [u32; LANES],
    /// Some triangle lies in a plane of constant x, y or z: its box is flat, and the box bound
    /// is then tighter than the enclosure's beside a vertex (walls and floors of modelled
    /// scenes).
    pub axis_aligned: bool,
    /// Lanes whose triangle is a sliver (`point_triangle::is_sliver`), one bit each: the lanes'
    /// region routine is not for them, and the search decides them with the scalar sliver
    /// routine instead.
    pub slivers: u8,
    /// The enclosures: `centre[axis][lane]`, `normal[axis][lane]`, `thickness[lane]`,
    /// `radius[lane]`, `edge_normal[edge][axis][lane]`, `edge_offset[edge][lane]`,
    /// `reach_slack[lane]`.
    pub centre: [[f32; LANES]; 3],
    pub normal: [[f32; LANES]; 3],
    pub thickness: [f32; LANES],
    pub radius: [f32; LANES],
    pub edge_normal: [[[f32; LANES]; 3]; 3],
    pub edge_offset: [[f32; LANES]; 3],
    pub reach_slack: [f32; LANES],
}

impl EnclosurePacket {
    /// Packs up to [`LANES`] `(face id, vertices)` triangles; `triangles` must not be empty.
    pub fn new(triangles: &[(u32, [glam::Vec3; 3])]) -> Self {
        let mut packet = EnclosurePacket {
            vertex: [[[0.0; LANES]; 3]; 3],
            prim: [0; LANES],
            axis_aligned: triangles
                .iter()
                .any(|(_, [a, b, c])| (0..3).any(|i| a[i] == b[i] && b[i] == c[i])),
            slivers: 0,
            centre: [[0.0; LANES]; 3],
            normal: [[0.0; LANES]; 3],
            thickness: [0.0; LANES],
            radius: [0.0; LANES],
            edge_normal: [[[0.0; LANES]; 3]; 3],
            edge_offset: [[0.0; LANES]; 3],
            reach_slack: [0.0; LANES],
        };
        for lane in 0..LANES {
            if lane >= triangles.len() {
                // Past the leaf's end: a copy of lane 0 (22 % of igea's lanes, whose
                // enclosures were made again).
                packet.copy_lane(0, lane);
                continue;
            }
            let (prim, v) = triangles[lane];
            packet.prim[lane] = prim;
            for (k, vertex) in v.iter().enumerate() {
                for axis in 0..3 {
                    packet.vertex[k][axis][lane] = vertex[axis];
                }
            }
            let [a, b, c] = v.map(|x| x.as_dvec3());
            if is_sliver(a, b, c) {
                packet.slivers |= 1 << lane;
            }
            let e = TriangleEnclosure::around(v);
            for axis in 0..3 {
                packet.centre[axis][lane] = e.centre[axis];
                packet.normal[axis][lane] = e.normal[axis];
                for edge in 0..3 {
                    packet.edge_normal[edge][axis][lane] = e.edge_normal[edge][axis];
                }
            }
            for edge in 0..3 {
                packet.edge_offset[edge][lane] = e.edge_offset[edge];
            }
            packet.thickness[lane] = e.thickness;
            packet.radius[lane] = e.radius;
            packet.reach_slack[lane] = e.reach_slack;
        }
        packet
    }

    /// Makes lane `to` a copy of lane `from`.
    fn copy_lane(&mut self, from: usize, to: usize) {
        self.prim[to] = self.prim[from];
        self.slivers |= (self.slivers >> from & 1) << to;
        for axis in 0..3 {
            for k in 0..3 {
                self.vertex[k][axis][to] = self.vertex[k][axis][from];
                self.edge_normal[k][axis][to] = self.edge_normal[k][axis][from];
            }
            self.centre[axis][to] = self.centre[axis][from];
            self.normal[axis][to] = self.normal[axis][from];
            self.edge_offset[axis][to] = self.edge_offset[axis][from];
        }
        self.thickness[to] = self.thickness[from];
        self.radius[to] = self.radius[from];
        self.reach_slack[to] = self.reach_slack[from];
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

    /// Conservative lower bounds of the squared distances from the bracketed point to the
    /// packet's triangles: [`EnclosurePacket::enclosure_lower_bounds`], and for a packet with an
    /// axis-aligned triangle the larger of that and the distance to each triangle's bounding box
    /// ([`Box4::distance_squared_lower_bounds`]).
    ///
    /// (Against the support-function bound `min_k u·(p - v_k)/|u|` with `u = p - centroid`,
    /// which the enclosures replaced: on spot 8.1 → 5.6 exact tests per query, 1.36 → 1.47 M
    /// queries/s on one thread; teapot 15.3 → 7.2 exact tests.)
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, p: &PointBracket) -> [f32; LANES] {
        let enclosure = self.enclosure_lower_bounds(p);
        if !self.axis_aligned {
            return enclosure;
        }
        let mut bound = enclosure;
        let v = &self.vertex;
        for half in 0..LANES / 4 {
            let mut boxes = Box4::NONE;
            for axis in 0..3 {
                for k in 0..4 {
                    let lane = half * 4 + k;
                    let (a, b, c) = (v[0][axis][lane], v[1][axis][lane], v[2][axis][lane]);
                    let lo = if a < b { a } else { b };
                    let hi = if a > b { a } else { b };
                    boxes.min[axis][k] = if lo < c { lo } else { c };
                    boxes.max[axis][k] = if hi > c { hi } else { c };
                }
            }
            let in_box = boxes.distance_squared_lower_bounds(p);
            for k in 0..4 {
                let lane = half * 4 + k;
                if in_box[k] > bound[lane] {
                    bound[lane] = in_box[k];
                }
            }
        }
        bound
    }

    /// The squared distances from the bracketed point to the triangles' enclosures
    /// (module `triangle_enclosure`), from below: with `w = p - centre`, `h = n·w`,
    /// `ρ = √(|w|² - h²)`,
    /// `max(|h| - thickness, 0)² + max(ρ - radius, max_e (m_e·w - k_e), 0)²`. One square root
    /// per lane.
    ///
    /// Conservative in f32 (`u = 2⁻²⁴`): `w̃ = fl(lo - centre)` is within `u|w|` of
    /// `w = lo - centre` (`lo` the bracket's low corner); each dot product `h̃`, `m_e·w̃` is within
    /// `5u Σ|w̃_i|` of the exact one (`|n_i|, |m_ei| ≤ 1`, `|n| = 1 ± 2⁻²⁰`), and the
    /// subtractions of `k_e` and of the margin round by `u` of `Σ|w̃_i| + |k_e|`, so both the
    /// height and the edge gaps are lowered by the margin `2⁻²⁰ Σ|w̃_i|` + `2⁻²⁰ max(|k_e|,
    /// thickness)`; `fl(|w̃|²) - fl(h̃²)` exceeds `ρ²` by at most `18u|w|²`, so `2⁻¹⁸ |w̃|²` is
    /// taken off, and the square root is lowered by `2⁻²⁰`. The bracket's spread
    /// `s = Σ (hi - lo) ≥ |p - lo|` is taken off every gap (all are 1-Lipschitz in `p`). The sum
    /// of squares is lowered by `2⁻¹⁷`: its own rounding, and `n`, `m_e` being unit and
    /// orthogonal only to `2⁻²⁰`. A bound that is not finite (coordinates near the f32 limit)
    /// is replaced by 0; a NaN gap counts as 0.
    #[inline(always)]
    pub fn enclosure_lower_bounds(&self, p: &PointBracket) -> [f32; LANES] {
        let spread =
            ((p.hi[0] - p.lo[0]) + (p.hi[1] - p.lo[1]) + (p.hi[2] - p.lo[2])) * (1.0 + SLACK);
        let mut w = [[0.0f32; LANES]; 3];
        let mut h = [0.0f32; LANES];
        let mut l1 = [0.0f32; LANES];
        let mut ww = [0.0f32; LANES];
        for axis in 0..3 {
            for lane in 0..LANES {
                let x = p.lo[axis] - self.centre[axis][lane];
                w[axis][lane] = x;
                h[lane] += self.normal[axis][lane] * x;
                l1[lane] += x.abs();
                ww[lane] += x * x;
            }
        }
        let mut side = [f32::NEG_INFINITY; LANES];
        for edge in 0..3 {
            let m = &self.edge_normal[edge];
            for lane in 0..LANES {
                let s = m[0][lane] * w[0][lane] + m[1][lane] * w[1][lane] + m[2][lane] * w[2][lane]
                    - self.edge_offset[edge][lane];
                side[lane] = if s > side[lane] { s } else { side[lane] };
            }
        }
        let mut bound = [0.0f32; LANES];
        for lane in 0..LANES {
            let margin = l1[lane] * SLACK + self.reach_slack[lane] + spread;
            let height = h[lane].abs() - (self.thickness[lane] + margin);
            let height = if height > 0.0 { height } else { 0.0 };
            let rho2 = ww[lane] - h[lane] * h[lane] - ww[lane] * LATERAL_SLACK;
            let rho2 = if rho2 > 0.0 { rho2 } else { 0.0 };
            let round = rho2.sqrt() * (1.0 - SLACK) - (self.radius[lane] + spread);
            let edges = side[lane] - margin;
            let lateral = if round > edges { round } else { edges };
            let lateral = if lateral > 0.0 { lateral } else { 0.0 };
            let b = (height * height + lateral * lateral) * (1.0 - SQUARES_SLACK);
            bound[lane] = if b < f32::INFINITY { b } else { 0.0 };
        }
        bound
    }
}

/// `2⁻²⁰`: the relative slack of the enclosure bound's dot products, of the bracket's spread
/// and of the square root.
const SLACK: f32 = 1.0 / 1_048_576.0;
/// `2⁻¹⁸`: the relative slack taken off `|w|² - h²` (its rounding is at most `18 · 2⁻²⁴` of
/// `|w|²`).
const LATERAL_SLACK: f32 = 1.0 / 262_144.0;
/// `2⁻¹⁷`: the relative slack of the final squares and sum.
const SQUARES_SLACK: f32 = 1.0 / 131_072.0;

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
            (vec3(c), Just(s), prop::collection::vec(triangle, LANES))
        })
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(256))]

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
            let packet = EnclosurePacket::new(&tris);
            let p = (tris[0].1[0].as_dvec3() + offset.as_dvec3() * (size as f64 * reach as f64))
                + DVec3::new(1e-9, -3e-10, 0.0) * size as f64;
            let bracket = PointBracket::new(p);
            let bounds = packet.distance_squared_lower_bounds(&bracket);
            let enclosure = packet.enclosure_lower_bounds(&bracket);
            for (lane, (_, [a, b, c])) in tris.iter().enumerate() {
                let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                let d2 = (p - q.point).length_squared();
                let t = prune_threshold(d2, 0.0);
                prop_assert!(bounds[lane] <= t, "lane {lane}: bound {} > threshold {t} (d² {d2})", bounds[lane]);
                prop_assert!(enclosure[lane] <= t, "lane {lane}: enclosure {} > threshold {t} (d² {d2})", enclosure[lane]);
            }
        }
    }

    /// Slivers and needles (a vertex a tiny way off the opposite edge, or two vertices nearly
    /// together), at any scale and distance from the origin, with points on the triangle's
    /// plane, just above it, on its edges and far away: the enclosure bound never exceeds the
    /// exact distance's threshold.
    #[test]
    fn enclosure_bound_holds_for_slivers_and_points_on_the_plane() {
        let mut runner = proptest::test_runner::TestRunner::new(proptest::test_runner::Config {
            cases: 2048,
            ..Default::default()
        });
        let centre = prop_oneof![Just(0.0f32), Just(1e3), Just(1e7), Just(1e18)];
        let size = prop_oneof![Just(1e-4f32), Just(1.0), Just(1e6)];
        let thin = prop_oneof![Just(1e-7f32), Just(1e-4), Just(1e-2)];
        let strategy = (centre, size, thin).prop_flat_map(|(c, s, thin)| {
            (
                vec3(c),
                vec3(s),
                vec3(s),
                0.0f32..1.0,
                vec3(s * thin),
                0.0f32..1.0,
                -2.0f32..2.0,
                prop_oneof![Just(0.0f32), Just(1e-6), Just(0.1), Just(3.0), Just(100.0)],
            )
        });
        runner
            .run(&strategy, |(centre, a, b, t, off, s, lift, height)| {
                let (a, b) = (centre + a, centre + b);
                let c = a + (b - a) * t + off;
                // Degenerate triangles (common at 10¹⁸ and 10⁻⁴) never reach a packet.
                if (b - a).cross(c - a).length_squared() == 0.0 {
                    return Ok(());
                }
                let packet = EnclosurePacket::new(&[(0, [a, b, c])]);
                let normal = (b - a).cross(c - a).normalize().as_dvec3();
                // On the line through the long edge (beyond it when `lift` is outside [0, 1]),
                // then lifted off the plane.
                let along =
                    a.as_dvec3() + (b - a).as_dvec3() * (s as f64 * 3.0 - 1.0) * lift as f64;
                let p = along + normal * height as f64 * (b - a).length() as f64;
                let bound = packet.enclosure_lower_bounds(&PointBracket::new(p))[0];
                let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                let d2 = (p - q.point).length_squared();
                let t = prune_threshold(d2, 0.0);
                prop_assert!(bound <= t, "bound {bound} > threshold {t} (d² {d2})");
                Ok(())
            })
            .unwrap();
    }

    /// For a point above the triangle, beside an edge, or beside a vertex in the direction from
    /// the circle's centre, the enclosure bound is nearly the distance.
    #[test]
    fn enclosure_bound_is_tight_above_and_beside_a_face() {
        let tri = (
            0,
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
        );
        let packet = EnclosurePacket::new(&[tri]);
        let bound = |p: DVec3| packet.enclosure_lower_bounds(&PointBracket::new(p))[0] as f64;
        let exact = |p: DVec3| {
            let q = closest_point_on_triangle(p, DVec3::ZERO, DVec3::X, DVec3::Y);
            (p - q.point).length_squared()
        };
        // Above the face: the height.
        let p = DVec3::new(0.25, 0.25, 10.0);
        assert!(
            bound(p) > 0.9999 * exact(p) && bound(p) <= exact(p),
            "{} vs {}",
            bound(p),
            exact(p)
        );
        // Beside the hypotenuse, 3 beyond its circle in the plane and 4 above: the edge's
        // half-space gives the distance (the cylinder only 3² + 4²).
        let side = DVec3::new(0.5, 0.5, 0.0)
            + DVec3::new(1.0, 1.0, 0.0).normalize() * (0.5f64.sqrt() + 3.0);
        let p = side + DVec3::new(0.0, 0.0, 4.0);
        assert!(
            bound(p) > 0.9999 * exact(p) && bound(p) <= exact(p),
            "{} vs {}",
            bound(p),
            exact(p)
        );
        // Beyond vertex (1, 0, 0) seen from the circle's centre (½, ½, 0), 2 away in the plane
        // and 1 above: the cylinder gives the distance, 2² + 1² (the edges only 2² / 2 + 1²).
        let p = DVec3::new(1.0, 0.0, 1.0) + DVec3::new(1.0, -1.0, 0.0).normalize() * 2.0;
        assert!(
            (bound(p) - 5.0).abs() < 1e-4 && bound(p) <= exact(p),
            "{} vs {}",
            bound(p),
            exact(p)
        );
        // On the face: nothing to bound.
        assert_eq!(bound(DVec3::new(0.2, 0.2, 0.0)), 0.0);
    }
}
