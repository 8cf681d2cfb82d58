//! The point of a triangle nearest to a query point, in f64.

use glam::DVec3;

/// The point of a triangle nearest to a query point: `point = (1-u-v) a + u b + v c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePoint {
    pub point: DVec3,
    pub u: f64,
    pub v: f64,
}

/// The point of triangle `(a, b, c)` nearest to `p`, after Ericson, *Real-Time Collision
/// Detection* (2005), §5.1.5 "Closest point on triangle to point".
///
/// The plane of the triangle is cut into seven Voronoi regions: three vertices, three edges and
/// the face. With `ab = b - a`, `ac = c - a` and the dot products `d1 = ab·(p-a)`,
/// `d2 = ac·(p-a)`, `d3 = ab·(p-b)`, `d4 = ac·(p-b)`, `d5 = ab·(p-c)`, `d6 = ac·(p-c)`, the
/// region is found from signs alone (e.g. `d1 ≤ 0 ∧ d2 ≤ 0` is vertex `a`'s), and the edge and face
/// regions use the scaled barycentrics
/// `vc = d1 d4 - d3 d2`, `vb = d5 d2 - d1 d6`, `va = d3 d6 - d5 d4`; in the face region
/// `(u, v) = (vb, vc) / (va + vb + vc)`. No square root, no division outside the chosen region.
///
/// The triangle must not be degenerate (zero area): the face region divides by `va + vb + vc`.
#[inline(always)]
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> TrianglePoint {
    let at = |u: f64, v: f64, point: DVec3| TrianglePoint { point, u, v };
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return at(0.0, 0.0, a);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return at(1.0, 0.0, b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let s = d1 / (d1 - d3);
        return at(s, 0.0, a + s * ab);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return at(0.0, 1.0, c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let s = d2 / (d2 - d6);
        return at(0.0, s, a + s * ac);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let s = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at(1.0 - s, s, b + s * (c - b));
    }
    let denom = 1.0 / (va + vb + vc);
    let (u, v) = (vb * denom, vc * denom);
    at(u, v, a + u * ab + v * ac)
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: DVec3 = DVec3::new(0.0, 0.0, 0.0);
    const B: DVec3 = DVec3::new(1.0, 0.0, 0.0);
    const C: DVec3 = DVec3::new(0.0, 1.0, 0.0);

    #[test]
    fn each_region_gives_its_feature() {
        let q = |p: [f64; 3]| closest_point_on_triangle(DVec3::from(p), A, B, C);
        assert_eq!(q([-1.0, -1.0, 3.0]).point, A);
        assert_eq!(q([2.0, -0.5, 1.0]).point, B);
        assert_eq!(q([-0.5, 2.0, 0.0]).point, C);
        assert_eq!(q([0.5, -1.0, 0.0]).point, DVec3::new(0.5, 0.0, 0.0));
        assert_eq!(q([-1.0, 0.25, 0.0]).point, DVec3::new(0.0, 0.25, 0.0));
        let hyp = q([1.0, 1.0, 0.0]);
        assert!((hyp.point - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
        let face = q([0.25, 0.25, -2.0]);
        assert!((face.point - DVec3::new(0.25, 0.25, 0.0)).length() < 1e-15);
        assert!((face.u - 0.25).abs() < 1e-15 && (face.v - 0.25).abs() < 1e-15);
    }

    /// A known defect, found by a soak run of the property tests (session 16): for a sliver
    /// whose third vertex lies within 10⁻⁸ of the midpoint of its longest edge, the scaled
    /// barycentrics `va`, `vb`, `vc` are rounding noise, and the face region's division turns
    /// them into a point 1.32 away from a query that lies on the triangle (1.2·10⁻⁸ away). The
    /// answer depends on the vertices' order (1.32, 1.2·10⁻⁸, 0.085 for the three rotations).
    /// The brute force shares the routine, so the tree and grid agree with it except where the
    /// grid's list proof meets the wrong distances (the failing case). Fixing it needs a
    /// sliver path with exact or extended-precision arithmetic, in the scalar routine and the
    /// lanes alike; ignored until then.
    #[test]
    #[ignore = "known defect: slivers of relative height ~1e-8 (see the comment)"]
    fn a_query_on_a_sliver_is_at_distance_zero() {
        let v = |x: f32, y: f32, z: f32| DVec3::new(x as f64, y as f64, z as f64);
        let (a, b, c) = (
            v(0.49198264, -0.9902859, -0.973578),
            v(-0.19071285, 0.95109224, -0.17421271),
            v(0.15063488, -0.019596815, -0.57389534),
        );
        let p = v(-0.14524573, 0.8217976, -0.22744995);
        for (x, y, z) in [(a, b, c), (b, c, a), (c, a, b)] {
            let q = closest_point_on_triangle(p, x, y, z);
            assert!((q.point - p).length() < 1e-7, "{q:?}");
        }
    }

    #[test]
    fn barycentrics_reproduce_the_point() {
        for p in [
            [0.3, 0.9, 1.0],
            [2.0, 2.0, -1.0],
            [-3.0, 0.5, 0.2],
            [0.1, 0.1, 0.1],
        ] {
            let r = closest_point_on_triangle(DVec3::from(p), A, B, C);
            let back = (1.0 - r.u - r.v) * A + r.u * B + r.v * C;
            assert!((back - r.point).length() < 1e-14, "{p:?}");
        }
    }
}
