//! The point of a triangle nearest to a query point, in f64.

use glam::DVec3;

use crate::geometry::exact_sign::two_product;

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
///
/// A sliver (`is_sliver`) takes `closest_point_on_sliver` instead: there `va`, `vb`, `vc`
/// are differences of nearly equal products, and can be rounding noise whose signs pick a wrong
/// region and whose quotient a point far from the answer (1.32 away from a query lying on a
/// triangle whose third vertex was within 10⁻⁸ of the midpoint of its longest edge).
#[inline(always)]
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> TrianglePoint {
    closest_point_on_flagged_triangle(p, a, b, c, is_sliver(a, b, c))
}

/// [`closest_point_on_triangle`] with [`is_sliver`] known (computed once per triangle by the
/// search tree's packets and the candidate grid's lists).
#[inline(always)]
pub(super) fn closest_point_on_flagged_triangle(
    p: DVec3,
    a: DVec3,
    b: DVec3,
    c: DVec3,
    sliver: bool,
) -> TrianglePoint {
    if sliver {
        closest_point_on_sliver(p, a, b, c)
    } else {
        closest_point_by_regions(p, a, b, c)
    }
}

/// Whether triangle `(a, b, c)` is a sliver for [`closest_point_on_triangle`]: twice its area
/// below `2^-10` of its longest edge squared (`|ab × ac|² ≤ 2^-20 L⁴`: an aspect ratio beyond
/// about a thousand). The edge vectors of f32 vertices are exact in f64, and so is this test's
/// input: every caller decides a triangle alike.
#[inline]
pub(super) fn is_sliver(a: DVec3, b: DVec3, c: DVec3) -> bool {
    let (ab, ac, bc) = (b - a, c - a, c - b);
    let longest = ab
        .length_squared()
        .max(ac.length_squared())
        .max(bc.length_squared());
    ab.cross(ac).length_squared() <= SLIVER_AREA * longest * longest
}

/// `2^-20`: see [`is_sliver`].
const SLIVER_AREA: f64 = 1.0 / (1u64 << 20) as f64;

/// The point of a sliver `(a, b, c)` nearest to `p`, from quantities that stay accurate
/// however thin it is: the nearest point of each edge (a clamped projection), and the
/// projection onto the plane when it falls inside the triangle, whichever is nearest (ties to
/// the first of face, `ab`, `ac`, `bc`). The plane's normal `n = ab × ac` is computed with
/// each product's rounding error kept (`two_product`), so that each component is right to an
/// ulp or two of itself even where it is a tiny difference of large products (a triangle a
/// hair wide): a plain f64 cross product of the edge vectors (exact f32 differences of up to
/// 33 significant bits, whose products round) tilted the plane of a sliver 4·10⁻⁹ wide by
/// 2.5·10⁻⁸, and a point 0.5 above it came out 0.4999999964 away. The inside test takes signs
/// of `n · (edge × (q − vertex))`.
#[cold]
#[inline(never)]
pub(super) fn closest_point_on_sliver(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> TrianglePoint {
    let (ab, ac) = (b - a, c - a);
    let difference_of_products = |w: f64, x: f64, y: f64, z: f64| {
        let ((wx, wx_error), (yz, yz_error)) = (two_product(w, x), two_product(y, z));
        (wx - yz) + (wx_error - yz_error)
    };
    let n = DVec3::new(
        difference_of_products(ab.y, ac.z, ab.z, ac.y),
        difference_of_products(ab.z, ac.x, ab.x, ac.z),
        difference_of_products(ab.x, ac.y, ab.y, ac.x),
    );
    let mut best: Option<(f64, TrianglePoint)> = None;
    let mut keep = |q: TrianglePoint| {
        let d2 = (p - q.point).length_squared();
        if best.is_none_or(|(b2, _)| d2 < b2) {
            best = Some((d2, q));
        }
    };
    let n2 = n.length_squared();
    if n2 > 0.0 {
        let q = p - n * ((p - a).dot(n) / n2);
        let aq = q - a;
        let u = aq.cross(ac).dot(n) / n2;
        let v = ab.cross(aq).dot(n) / n2;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
            keep(TrianglePoint { point: q, u, v });
        }
    }
    let segment = |from: DVec3, to: DVec3| -> (DVec3, f64) {
        let e = to - from;
        let e2 = e.length_squared();
        let s = if e2 > 0.0 {
            ((p - from).dot(e) / e2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (from + s * e, s)
    };
    let (q, s) = segment(a, b);
    keep(TrianglePoint {
        point: q,
        u: s,
        v: 0.0,
    });
    let (q, s) = segment(a, c);
    keep(TrianglePoint {
        point: q,
        u: 0.0,
        v: s,
    });
    let (q, s) = segment(b, c);
    keep(TrianglePoint {
        point: q,
        u: 1.0 - s,
        v: s,
    });
    best.expect("an edge is always kept").1
}

/// Ericson's routine proper (the notes of [`closest_point_on_triangle`]), for triangles that
/// are not slivers; the lanes of `point_triangle_lanes` compute it bit for bit.
#[inline(always)]
pub(super) fn closest_point_by_regions(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> TrianglePoint {
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

    /// A sliver whose third vertex lies within 10⁻⁸ of the midpoint of its longest edge, and a
    /// query on it (found by a soak run of the property tests): the regions'
    /// `va`, `vb`, `vc` were rounding noise, and the answer 1.32, 1.2·10⁻⁸ or 0.085 away
    /// depending on the vertices' order.
    #[test]
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

    /// Slivers of every thinness (third vertex `10⁻³` to `10⁻¹²` of the longest edge off its
    /// line, f32 vertices) and points on them or at a known height above their plane inside
    /// them: the distance is that height, to within `10⁻¹²` of the triangle's size, whatever
    /// the vertices' order.
    #[test]
    fn slivers_of_any_thinness_give_the_distance_to_their_face() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut random = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = 0;
        for case in 0..4000 {
            let f32v = |v: DVec3| v.as_vec3().as_dvec3();
            let a = f32v(DVec3::new(random(), random(), random()) * 2.0 - 1.0);
            let b = f32v(DVec3::new(random(), random(), random()) * 2.0 - 1.0);
            let side = DVec3::new(random(), random(), random()) - 0.5;
            let thinness = 10f64.powf(-3.0 - 9.0 * random());
            let c =
                f32v(a + (b - a) * (0.05 + 0.9 * random()) + side * thinness * (b - a).length());
            let n = (b - a).cross(c - a);
            if n.length_squared() == 0.0 {
                continue;
            }
            let unit = n.normalize();
            let (u, v) = (random(), random());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let height = [0.0, 1e-3, -0.5][case % 3];
            let p = a + u * (b - a) + v * (c - a) + unit * height;
            let size = (b - a).length();
            for (x, y, z) in [(a, b, c), (b, c, a), (c, a, b)] {
                let q = closest_point_on_triangle(p, x, y, z);
                let distance = (q.point - p).length();
                assert!(
                    (distance - height.abs()).abs() <= 1e-12 * size + 1e-9 * height.abs(),
                    "case {case}: {distance} for height {height}, thinness {thinness:e}"
                );
            }
            checked += 1;
        }
        assert!(checked > 3000);
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
