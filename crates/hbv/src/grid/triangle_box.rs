//! Exact triangle–box overlap by the separating axis theorem.

use glam::DVec3;

/// Whether the triangle `v` overlaps the closed box `[lo, hi]` (touching counts), decided in f64.
///
/// Separating axis test of Akenine-Möller (2001, "Fast 3D triangle-box overlap testing", JGT
/// 6(1)): two convex bodies are disjoint iff some axis separates their projections. For a
/// triangle and a box it suffices to try 13 axes, with the box centred at the origin (half size
/// `h`) and the triangle's vertices `v_k` relative to that centre:
///
/// ```text
///   the box normals e_x, e_y, e_z:   [min_k v_k[i], max_k v_k[i]] misses [-h[i], h[i]]
///   the triangle normal n:           |n · v_0| > h · |n|
///   the 9 products a = e_i × f_j of box normals and triangle edges f_j:
///                                    [min_k a · v_k, max_k a · v_k] misses [-r, r], r = h · |a|
/// ```
///
/// f32 vertices are exact in f64 and every product rounds with a relative error near 1e-16, so
/// the answer is the exact one except for a triangle within about 1e-15 of the box's extent from
/// touching it. [`crate::grid::UniformGrid`] tests cells padded by far more than that, so that a
/// triangle is never missing from a cell it touches. A degenerate triangle (zero normal) is
/// decided by the edge axes alone.
pub fn triangle_overlaps_box(v: [DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    let center = 0.5 * (lo + hi);
    let h = 0.5 * (hi - lo);
    let [a, b, c] = v.map(|p| p - center);

    // The box's own axes: the triangle's bounding box against the box.
    let tmin = a.min(b).min(c);
    let tmax = a.max(b).max(c);
    if tmin.cmpgt(h).any() || tmax.cmplt(-h).any() {
        return false;
    }

    // The triangle's plane.
    let edges = [b - a, c - b, a - c];
    let normal = edges[0].cross(edges[1]);
    if normal.dot(a).abs() > h.dot(normal.abs()) {
        return false;
    }

    // The nine edge axes e_i × f.
    for f in edges {
        for axis in [
            DVec3::new(0.0, -f.z, f.y),
            DVec3::new(f.z, 0.0, -f.x),
            DVec3::new(-f.y, f.x, 0.0),
        ] {
            let (pa, pb, pc) = (axis.dot(a), axis.dot(b), axis.dot(c));
            let r = h.dot(axis.abs());
            if pa.min(pb).min(pc) > r || pa.max(pb).max(pc) < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Whether some point of the triangle lies in the box, by dense barycentric sampling
    /// (a lower bound of the truth: it can only miss overlaps, never invent them).
    fn sampled_overlap(v: [DVec3; 3], lo: DVec3, hi: DVec3, steps: u32) -> bool {
        (0..=steps).any(|i| {
            (0..=steps - i).any(|j| {
                let (s, t) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let p = v[0] + s * (v[1] - v[0]) + t * (v[2] - v[0]);
                p.cmpge(lo).all() && p.cmple(hi).all()
            })
        })
    }

    /// The distance from the box to the nearest of many sample points of the triangle: small
    /// when the triangle truly overlaps the box.
    fn box_distance(v: [DVec3; 3], lo: DVec3, hi: DVec3, steps: u32) -> f64 {
        let mut best = f64::INFINITY;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (s, t) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let p = v[0] + s * (v[1] - v[0]) + t * (v[2] - v[0]);
                let d = (lo - p).max(p - hi).max(DVec3::ZERO).length();
                best = best.min(d);
            }
        }
        best
    }

    #[test]
    fn agrees_with_sampling_on_random_triangles() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        let mut overlaps = 0;
        for _ in 0..4000 {
            let mut p = || DVec3::new(rng.random(), rng.random(), rng.random()) * 3.0 - 1.0;
            let v = [p(), p(), p()];
            let exact = triangle_overlaps_box(v, lo, hi);
            if sampled_overlap(v, lo, hi, 60) {
                // A sampled point inside the box: the test must say overlap.
                assert!(exact, "{v:?}");
            }
            if exact {
                overlaps += 1;
                // Claimed overlap: the triangle comes within sampling resolution of the box.
                let spacing = 4.0 * 3.0f64.sqrt() * 3.0 / 60.0;
                assert!(box_distance(v, lo, hi, 60) <= spacing, "{v:?}");
            }
        }
        assert!(overlaps > 500 && overlaps < 3900, "{overlaps}");
    }

    #[test]
    fn box_inside_a_big_triangle_and_touching_cases() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        // A huge triangle through the box's middle, none of its vertices near the box.
        let big = [
            DVec3::new(-100.0, -100.0, 0.5),
            DVec3::new(300.0, -100.0, 0.5),
            DVec3::new(-100.0, 300.0, 0.5),
        ];
        assert!(triangle_overlaps_box(big, lo, hi));
        // The same plane just above the box: separated by the triangle's normal.
        let above = big.map(|p| p + DVec3::Z * 0.5);
        assert!(
            triangle_overlaps_box(above, lo, hi),
            "touching the top face counts"
        );
        let far_above = big.map(|p| p + DVec3::Z * 0.501);
        assert!(!triangle_overlaps_box(far_above, lo, hi));
        // A diagonal plane x + y = 2.02 just beyond the edge of the box at x = y = 1, and one
        // at 1.98 that cuts that edge off.
        let diagonal = |k: f64| {
            [
                DVec3::new(k + 1.0, -1.0, -1.0),
                DVec3::new(-1.0, k + 1.0, -1.0),
                DVec3::new(k / 2.0, k / 2.0, 3.0),
            ]
        };
        assert!(!triangle_overlaps_box(diagonal(2.02), lo, hi));
        assert!(triangle_overlaps_box(diagonal(1.98), lo, hi));
        // A flat box (zero extent on z) cut by a tilted triangle.
        let flat_hi = DVec3::new(1.0, 1.0, 0.0);
        let tilted = [
            DVec3::new(0.5, 0.5, -1.0),
            DVec3::new(0.6, 0.5, 1.0),
            DVec3::new(0.5, 0.6, 1.0),
        ];
        assert!(triangle_overlaps_box(tilted, lo, flat_hi));
    }
}
