//! The convex set around one triangle whose distance the nearest-point search bounds in f32
//! before it decides a triangle in f64: a slab around the triangle's plane, cut by a cylinder
//! around its smallest enclosing circle and by its three edges' half-spaces.
//!
//! With `n` the unit normal, `c` the centre of the smallest enclosing circle, `w = p - c`, the
//! triangle lies in
//! - the slab `|n·w| ≤ thickness` (the vertices' largest height: 0 up to rounding),
//! - the cylinder `ρ(w) = √(|w|² - (n·w)²) ≤ radius` (the circle's radius), and
//! - the half-spaces `m_e·w ≤ k_e`, `m_e` the unit normal of edge `e` in the plane, pointing away
//!   from the opposite vertex, `k_e` the largest `m_e·(v - c)` over the vertices.
//!
//! Height and in-plane offset being orthogonal, every point `x` of the set has
//! `|p - x|² ≥ max(|n·w| - thickness, 0)² + max(ρ - radius, m_0·w - k_0, m_1·w - k_1,
//! m_2·w - k_2, 0)²`: the distance to the triangle itself where the nearest point is inside
//! the face or on an edge (the edges' gap) or at a vertex seen from the circle's centre (the
//! cylinder's gap: the circumcircle passes through the vertices), within a small factor
//! elsewhere. The two in-plane bounds are complementary: on spot, 8.1 exact tests per query with
//! the cylinder alone, 16.4 with the edges alone, 5.6 with both (2.4 triangles per query are as
//! near as the answer, and must be decided whatever the bound).
//!
//! **Made conservative in f64.** The rounded `n`, `c`, `m_e` are f32 (any values give a valid
//! set, provided `n`, `m_e` are unit and orthogonal to `2⁻²⁰`, checked; an edge that fails
//! gets `m_e = 0`, no bound); the thickness, radius and offsets are computed in f64 from the
//! exact f32 vertices with `n / |n|`, raised by `2⁻⁴⁰`–`2⁻²⁴` of the magnitudes involved (the
//! f64 rounding, and the cancellation in `|w|² - h²`), and rounded up to f32, so that the
//! triangle is inside. The query's f32 rounding is accounted for in
//! [`super::enclosure_packet::EnclosurePacket::distance_squared_lower_bounds`].

use glam::{DVec3, Vec3};

use crate::geometry::directed_rounding::f32_above;

/// The enclosure of one triangle (module notes), in f32.
#[derive(Clone, Copy, Debug)]
pub(super) struct TriangleEnclosure {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub thickness: f32,
    pub radius: f32,
    pub edge_normal: [[f32; 3]; 3],
    pub edge_offset: [f32; 3],
    /// `2⁻²⁰ max(|k_e|, thickness)`, rounded up: the query's allowance for rounding relative to
    /// the offsets.
    pub reach_slack: f32,
}

impl TriangleEnclosure {
    /// The enclosure of triangle `v` (a degenerate triangle gets a ball: no normal, no edges,
    /// thickness and radius its largest vertex distance from the centre).
    pub fn around(v: [Vec3; 3]) -> Self {
        let [a, b, c] = v.map(|x| x.as_dvec3());
        let (centre, normal) = (smallest_circle_centre(a, b, c), (b - a).cross(c - a));
        let centre = centre.as_vec3();
        let centre = if centre.is_finite() {
            centre
        } else {
            ((a + b + c) / 3.0).as_vec3()
        };
        let normal = normal.normalize_or_zero().as_vec3();
        let (cd, nd) = (centre.as_dvec3(), normal.as_dvec3());
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
        let mut enclosure = TriangleEnclosure {
            centre: centre.to_array(),
            normal: normal.to_array(),
            thickness: f32_above(thickness),
            radius: f32_above(radius),
            edge_normal: [[0.0; 3]; 3],
            edge_offset: [0.0; 3],
            reach_slack: 0.0,
        };
        let mut reach = enclosure.thickness as f64;
        let vd = [a, b, c];
        let tolerance = f64::powi(2.0, -20);
        for edge in 0..3 {
            let (p, q, opposite) = (vd[edge], vd[(edge + 1) % 3], vd[(edge + 2) % 3]);
            let mut m = nd.cross(q - p).normalize_or_zero();
            if m.dot(opposite - p) > 0.0 {
                m = -m;
            }
            let m = m.as_vec3().as_dvec3();
            let fits = (m.length() - 1.0).abs() <= tolerance
                && m.dot(nd).abs() <= tolerance
                && (unit - 1.0).abs() <= tolerance;
            let m = if fits { m } else { DVec3::ZERO };
            let mut k = f64::NEG_INFINITY;
            for x in vd {
                // Exact products of f32s; the sum rounds by at most 2⁻⁵³ of its terms twice.
                let terms = [0, 1, 2].map(|i| m[i] * (x[i] - cd[i]));
                let margin =
                    (terms[0].abs() + terms[1].abs() + terms[2].abs()) * f64::powi(2.0, -50);
                k = k.max(terms[0] + terms[1] + terms[2] + margin);
            }
            enclosure.edge_normal[edge] = m.as_vec3().to_array();
            enclosure.edge_offset[edge] = f32_above(k);
            reach = reach.max((enclosure.edge_offset[edge] as f64).abs());
        }
        enclosure.reach_slack = f32_above(reach * tolerance * (1.0 + tolerance));
        enclosure
    }
}

/// The centre of the smallest circle around triangle `(a, b, c)`: the middle of the longest
/// edge if the angle opposite it is at least 90°, else the circumcentre
/// `a + (|ac|² (ab × ac) × ab + |ab|² ac × (ab × ac)) / (2 |ab × ac|²)`.
fn smallest_circle_centre(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let edges = [(b - a, a, b, c), (c - b, b, c, a), (a - c, c, a, b)];
    let (_, p, q, r) = edges
        .into_iter()
        .max_by(|x, y| x.0.length_squared().total_cmp(&y.0.length_squared()))
        .unwrap();
    if (p - r).dot(q - r) <= 0.0 {
        return (p + q) * 0.5;
    }
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(ac);
    a + (n.cross(ab) * ac.length_squared() + ac.cross(n) * ab.length_squared())
        / (2.0 * n.length_squared())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vertices lie inside the enclosure as the f64 arithmetic sees it, for acute, right and
    /// obtuse triangles far from the origin.
    #[test]
    fn vertices_are_inside() {
        for offset in [Vec3::ZERO, Vec3::new(1e3, -2e4, 5.0), Vec3::splat(3e7)] {
            for v in [
                [Vec3::ZERO, Vec3::X, Vec3::Y],
                [
                    Vec3::ZERO,
                    Vec3::new(4.0, 0.0, 0.1),
                    Vec3::new(2.0, 0.1, 0.0),
                ],
                [
                    Vec3::ZERO,
                    Vec3::new(1.0, 0.2, 0.3),
                    Vec3::new(0.4, 1.0, -0.2),
                ],
            ] {
                // Scaled with the offset, so that the triangle stays one in f32.
                let scale = 1.0 + offset.abs().max_element() * 1e-3;
                let v = v.map(|x| x * scale + offset);
                assert!((v[1] - v[0]).cross(v[2] - v[0]).length_squared() > 0.0);
                let e = TriangleEnclosure::around(v);
                let (c, n) = (
                    Vec3::from(e.centre).as_dvec3(),
                    Vec3::from(e.normal).as_dvec3(),
                );
                for x in v.map(|x| x.as_dvec3()) {
                    let w = x - c;
                    let h = w.dot(n) / n.length();
                    assert!(h.abs() <= e.thickness as f64);
                    assert!((w.length_squared() - h * h).max(0.0).sqrt() <= e.radius as f64);
                    for edge in 0..3 {
                        let m = Vec3::from(e.edge_normal[edge]).as_dvec3();
                        assert!(m.dot(w) <= e.edge_offset[edge] as f64);
                    }
                }
            }
        }
    }
}
