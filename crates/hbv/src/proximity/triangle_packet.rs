//! Four triangles side by side (structure of arrays), the leaf storage of the nearest-point
//! search: one f32 pass bounds all four distances from below (the distance to each triangle's
//! enclosing cylinder, exact for points above the triangle's disk), and only the triangles the
//! bound cannot reject go to the exact f64 routine.

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
    /// is then tighter than the cylinder bound beside the triangle (walls and floors of modelled
    /// scenes).
    pub axis_aligned: bool,
    /// Each triangle's enclosing cylinder ([`TriangleCylinder`]), structure of arrays: the
    /// centre `centre[axis][lane]`, the axis `normal[axis][lane]` (unit to f32 rounding), the
    /// half height `thickness[lane]` and the radius `radius[lane]`.
    pub centre: [[f32; 4]; 3],
    pub normal: [[f32; 4]; 3],
    pub thickness: [f32; 4],
    pub radius: [f32; 4],
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
            centre: [[0.0; 4]; 3],
            normal: [[0.0; 4]; 3],
            thickness: [0.0; 4],
            radius: [0.0; 4],
        };
        for lane in 0..4 {
            let (prim, v) = triangles[if lane < triangles.len() { lane } else { 0 }];
            packet.prim[lane] = prim;
            for (k, vertex) in v.iter().enumerate() {
                for axis in 0..3 {
                    packet.vertex[k][axis][lane] = vertex[axis];
                }
            }
            let cylinder = TriangleCylinder::around(v);
            for axis in 0..3 {
                packet.centre[axis][lane] = cylinder.centre[axis];
                packet.normal[axis][lane] = cylinder.normal[axis];
            }
            packet.thickness[lane] = cylinder.thickness;
            packet.radius[lane] = cylinder.radius;
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
    /// triangles: [`TrianglePacket::cylinder_lower_bounds`], and for a packet with an
    /// axis-aligned triangle the larger of that and the distance to each triangle's bounding box
    /// ([`Box4::distance_squared_lower_bounds`]).
    ///
    /// (Session 5 replaced the support-function bound of sessions 3–4, `min_k u·(p - v_k)/|u|`
    /// with `u = p - centroid`: the cylinder bound costs about half as many instructions and
    /// rejects as many triangles on spot (8.1 exact tests per query either way), spot 6,886 →
    /// 5,662 instructions per query, teapot 7,684 → 7,114, bunny 10,890 → 9,325; the larger of
    /// both bounds rejected more, 5.8 exact tests on spot, but cost more than it saved.)
    #[inline(always)]
    pub fn distance_squared_lower_bounds(&self, p: &PointBracket) -> [f32; 4] {
        let cylinder = self.cylinder_lower_bounds(p);
        if !self.axis_aligned {
            return cylinder;
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
            bound[lane] = if in_box[lane] > cylinder[lane] {
                in_box[lane]
            } else {
                cylinder[lane]
            };
        }
        bound
    }

    /// Conservative lower bounds of the squared distances from the bracketed point to the four
    /// triangles' enclosing cylinders ([`TriangleCylinder`]), hence to the triangles: with
    /// `w = p - centre`, height `h = n·w` and lateral distance `ρ = √(|w|² - h²)`,
    /// `dist(p, cylinder)² = max(|h| - thickness, 0)² + max(ρ - radius, 0)²` (the cylinder is a
    /// disk times an interval, in orthogonal coordinates). Exact for a point above the triangle's
    /// disk, nearly so beside it; one square root per lane.
    ///
    /// Conservative in f32 (`u = 2⁻²⁴`): `w̃ = fl(lo - centre)` is within `u|w|` of
    /// `w = lo - centre` (`lo` the bracket's low corner); `h̃` within `5u|w|` of the height
    /// `n̂·w` (three products and two sums, `|n| = 1 ± u`), so `|h̃|` is lowered by `2⁻²⁰ Σ|w̃_i|`;
    /// `fl(|w̃|²) - fl(h̃²)` exceeds `ρ²` by at most `18u|w|²`, so `2⁻¹⁸ |w̃|²` is taken off. The
    /// bracket's spread `s = Σ (hi - lo) ≥ |p - lo|` is taken off both gaps (height and lateral
    /// distance are 1-Lipschitz in `p`), and the sum of squares is lowered by `2⁻¹⁸` for the
    /// remaining roundings (each relative to its own result). A bound that is not finite
    /// (coordinates near the f32 limit) is replaced by 0.
    #[inline(always)]
    pub fn cylinder_lower_bounds(&self, p: &PointBracket) -> [f32; 4] {
        let spread =
            ((p.hi[0] - p.lo[0]) + (p.hi[1] - p.lo[1]) + (p.hi[2] - p.lo[2])) * (1.0 + SUM_SLACK);
        let mut ww = [0.0f32; 4];
        let mut h = [0.0f32; 4];
        let mut l1 = [0.0f32; 4];
        for axis in 0..3 {
            for lane in 0..4 {
                let w = p.lo[axis] - self.centre[axis][lane];
                ww[lane] += w * w;
                h[lane] += self.normal[axis][lane] * w;
                l1[lane] += w.abs();
            }
        }
        let mut bound = [0.0f32; 4];
        for lane in 0..4 {
            let below = self.thickness[lane] + spread + l1[lane] * SUM_SLACK;
            let height = h[lane].abs() - below;
            let height = if height > 0.0 { height } else { 0.0 };
            let rho2 = ww[lane] - h[lane] * h[lane] - ww[lane] * LATERAL_SLACK;
            let rho2 = if rho2 > 0.0 { rho2 } else { 0.0 };
            let lateral = rho2.sqrt() * (1.0 - SUM_SLACK) - (self.radius[lane] + spread);
            let lateral = if lateral > 0.0 { lateral } else { 0.0 };
            let b = (height * height + lateral * lateral) * (1.0 - RATIO_SLACK);
            bound[lane] = if b < f32::INFINITY { b } else { 0.0 };
        }
        bound
    }
}

/// `2⁻¹⁸`: the relative slack taken off the cylinder bound's `|w|² - h²` (its rounding is at
/// most `18 · 2⁻²⁴` of `|w|²`).
const LATERAL_SLACK: f32 = 1.0 / 262_144.0;

/// The cylinder around one triangle that [`TrianglePacket::cylinder_lower_bounds`] bounds the
/// distance to: axis the triangle's unit normal `n` (rounded to f32), centre the centre of its
/// smallest enclosing circle (the circumcentre of an acute triangle, else the middle of its
/// longest edge; rounded to f32), radius and half height the largest lateral distance and height
/// of its vertices from the centre. These are computed in f64 from the exact f32 vertices (with
/// `n̂ = n / |n|` for the rounded `n`), raised by `2⁻⁴⁰` of the magnitudes involved (the f64
/// rounding) and rounded up to f32, so that the triangle lies inside the cylinder.
#[derive(Clone, Copy, Debug)]
pub(super) struct TriangleCylinder {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub thickness: f32,
    pub radius: f32,
}

impl TriangleCylinder {
    /// The cylinder around a non-degenerate triangle (a degenerate one gets a sphere: thickness
    /// and radius both its largest vertex distance).
    pub fn around(v: [glam::Vec3; 3]) -> Self {
        let [a, b, c] = v.map(|x| x.as_dvec3());
        let edges = [(b - a, a, b, c), (c - b, b, c, a), (a - c, c, a, b)];
        // The longest edge and its opposite vertex: obtuse (or right) when the angle there is
        // at least 90°.
        let (_, p, q, r) = edges
            .iter()
            .copied()
            .max_by(|x, y| x.0.length_squared().total_cmp(&y.0.length_squared()))
            .unwrap();
        let centre = if (p - r).dot(q - r) <= 0.0 {
            (p + q) * 0.5
        } else {
            // Circumcentre: a + (|ac|² (ab × ac) × ab + |ab|² ac × (ab × ac)) / (2 |ab × ac|²).
            let (ab, ac) = (b - a, c - a);
            let n = ab.cross(ac);
            a + (n.cross(ab) * ac.length_squared() + ac.cross(n) * ab.length_squared())
                / (2.0 * n.length_squared())
        };
        let centre = centre.as_vec3();
        let centre = if centre.is_finite() {
            centre
        } else {
            ((a + b + c) / 3.0).as_vec3()
        };
        let normal = (b - a).cross(c - a).normalize_or_zero().as_vec3();
        let cd = centre.as_dvec3();
        let nd = normal.as_dvec3();
        let unit = nd.length();
        let mut thickness = 0.0f64;
        let mut radius = 0.0f64;
        for x in [a, b, c] {
            let w = x - cd;
            let magnitude = w.abs().element_sum() * (1.0 + f64::powi(2.0, -40));
            if unit > 0.5 {
                let height = w.dot(nd) / unit;
                let lateral2 = (w.length_squared() - height * height).max(0.0);
                thickness = thickness.max(height.abs() + magnitude * f64::powi(2.0, -40));
                radius = radius.max(lateral2.sqrt() + magnitude * f64::powi(2.0, -24));
            } else {
                thickness = thickness.max(magnitude);
                radius = radius.max(magnitude);
            }
        }
        TriangleCylinder {
            centre: centre.to_array(),
            normal: normal.to_array(),
            thickness: f32_above(thickness),
            radius: f32_above(radius),
        }
    }
}

/// The least f32 not below `x`.
fn f32_above(x: f64) -> f32 {
    let near = x as f32;
    if (near as f64) < x {
        near.next_up()
    } else {
        near
    }
}

/// `2⁻²⁰`: the relative slack of the cylinder bound's height (its rounding is at most `5 · 2⁻²⁴`
/// of `|w|`), of the bracket's spread and of the square root.
const SUM_SLACK: f32 = 1.0 / 1_048_576.0;
/// `2⁻¹⁸`: the relative slack of the cylinder bound's final squares and sum.
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
            let cylinder = packet.cylinder_lower_bounds(&bracket);
            for (lane, (_, [a, b, c])) in tris.iter().enumerate() {
                let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                let d2 = (p - q.point).length_squared();
                let t = prune_threshold(d2, 0.0);
                prop_assert!(bounds[lane] <= t, "lane {lane}: bound {} > threshold {t} (d² {d2})", bounds[lane]);
                prop_assert!(cylinder[lane] <= t, "lane {lane}: cylinder {} > threshold {t} (d² {d2})", cylinder[lane]);
            }
        }
    }

    /// Slivers and needles (a vertex a tiny way off the opposite edge, or two vertices nearly
    /// together), at any scale and distance from the origin, with points on the triangle's
    /// plane, just above it, on its edges and far away: the cylinder bound never exceeds the
    /// exact distance's threshold.
    #[test]
    fn cylinder_bound_holds_for_slivers_and_points_on_the_plane() {
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
                let packet = TrianglePacket::new(&[(0, [a, b, c])]);
                let normal = (b - a).cross(c - a).normalize().as_dvec3();
                // On the line through the long edge (beyond it when `lift` is outside [0, 1]),
                // then lifted off the plane.
                let along =
                    a.as_dvec3() + (b - a).as_dvec3() * (s as f64 * 3.0 - 1.0) * lift as f64;
                let p = along + normal * height as f64 * (b - a).length() as f64;
                let bound = packet.cylinder_lower_bounds(&PointBracket::new(p))[0];
                let q = closest_point_on_triangle(p, a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                let d2 = (p - q.point).length_squared();
                let t = prune_threshold(d2, 0.0);
                prop_assert!(bound <= t, "bound {bound} > threshold {t} (d² {d2})");
                Ok(())
            })
            .unwrap();
    }

    /// For a point above the triangle the cylinder bound is nearly the distance; beside it,
    /// nearly the distance to the enclosing disk.
    #[test]
    fn cylinder_bound_is_tight_above_and_beside_a_face() {
        let tri = (
            0,
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
        );
        let packet = TrianglePacket::new(&[tri]);
        let bound = |p: DVec3| packet.cylinder_lower_bounds(&PointBracket::new(p))[0] as f64;
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
        // Beside the hypotenuse, 3 away in the plane and 4 above: the disk (centre (½, ½),
        // radius √½) is 3 - 0 away laterally, so the bound is 3² + 4² = 25 = the distance².
        let side = DVec3::new(0.5, 0.5, 0.0)
            + DVec3::new(1.0, 1.0, 0.0).normalize() * (0.5f64.sqrt() + 3.0);
        let p = side + DVec3::new(0.0, 0.0, 4.0);
        assert!(
            (bound(p) - 25.0).abs() < 1e-3 && bound(p) <= exact(p),
            "{} vs {}",
            bound(p),
            exact(p)
        );
        // Inside the disk, on the plane: nothing to bound.
        assert_eq!(bound(DVec3::new(0.9, 0.9, 0.0)), 0.0);
    }
}
