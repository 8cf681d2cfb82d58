//! Exact signs of the small polynomials that decide a ray's side of a triangle edge, for the
//! rays that touch an edge or a vertex exactly.
//!
//! Every input is an f32, so the product of two is exact in f64 (24 + 24 significant bits of
//! 53) and the product of three is exact as the sum of two f64s (`two_product`); a sum of such
//! terms is then kept exactly as a nonoverlapping expansion (Shewchuk, "Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997, §2), whose sign is
//! the sign of its largest component. Nothing overflows or underflows: a product of three f32s
//! lies between about 1e-135 and 4e115, well inside f64's normal range, and so do the rounding
//! errors `two_product` and `two_sum` split off.
//!
//! These are slow (a few microseconds) and called only where an f64 evaluation is within its
//! own rounding bound of zero: the ray passes exactly, or within about 1e-16 relative, through
//! an edge's line.

use glam::Vec3;

/// A sum of f64 terms held exactly: a nonoverlapping expansion, smallest component first, with
/// zero components dropped (Shewchuk's Grow-Expansion with zero elimination).
struct ExactSum {
    parts: [f64; Self::CAPACITY],
    len: usize,
    finite: bool,
}

impl ExactSum {
    /// Each term added lengthens the expansion by at most one component; the largest sum here
    /// has 48 terms (`plane_numerator`).
    const CAPACITY: usize = 50;

    fn new() -> Self {
        Self {
            parts: [0.0; Self::CAPACITY],
            len: 0,
            finite: true,
        }
    }

    /// Adds the f64 `b` exactly.
    fn add(&mut self, b: f64) {
        if !b.is_finite() {
            self.finite = false;
            return;
        }
        let mut carry = b;
        let mut kept = 0;
        for i in 0..self.len {
            let (sum, error) = two_sum(carry, self.parts[i]);
            carry = sum;
            if error != 0.0 {
                self.parts[kept] = error;
                kept += 1;
            }
        }
        if carry != 0.0 {
            self.parts[kept] = carry;
            kept += 1;
        }
        self.len = kept;
        assert!(self.len < Self::CAPACITY, "ExactSum holds at most 49 terms");
    }

    /// Adds the product `a b` exactly (as the rounded product and its rounding error).
    fn add_product(&mut self, a: f64, b: f64) {
        let (product, error) = two_product(a, b);
        self.add(error);
        self.add(product);
    }

    /// The exact sum rounded to an f64 (its components added smallest first: each is below
    /// half an ulp of the next, so the result is within a few ulps of the exact sum, and 0 only
    /// if that is 0), or `None` if a term was not finite.
    fn value(&self) -> Option<f64> {
        self.finite.then(|| {
            self.parts[..self.len]
                .iter()
                .fold(0.0, |sum, &part| sum + part)
        })
    }

    /// The sign of the exact sum (the sign of its largest component), or `None` if a term was
    /// not finite.
    fn sign(&self) -> Option<i8> {
        if !self.finite {
            return None;
        }
        Some(match self.len {
            0 => 0,
            n if self.parts[n - 1] > 0.0 => 1,
            _ => -1,
        })
    }
}

/// Whether `a + b` is an f64 without rounding.
pub(crate) fn sum_is_exact(a: f64, b: f64) -> bool {
    two_sum(a, b).1 == 0.0
}

/// Whether `a b` is exactly the f64 `product`.
pub(crate) fn product_is(a: f64, b: f64, product: f64) -> bool {
    two_product(a, b) == (product, 0.0)
}

/// The exact sign of `a b − c d` for f64s (whose products neither overflow nor underflow), or
/// `None` if one is not finite.
pub(crate) fn difference_of_products_sign(a: f64, b: f64, c: f64, d: f64) -> Option<i8> {
    let ((ab, ab_error), (cd, cd_error)) = (two_product(a, b), two_product(c, d));
    if ab_error == 0.0 && cd_error == 0.0 {
        // Both products exact (the usual case: coordinates of few significant bits).
        return ab.partial_cmp(&cd).map(|order| order as i8);
    }
    let mut sum = ExactSum::new();
    sum.add_product(a, b);
    sum.add_product(-c, d);
    sum.sign()
}

/// `a + b` as the rounded sum and its exact rounding error (Knuth's TwoSum; no condition on
/// the magnitudes).
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let sum = a + b;
    let b_virtual = sum - a;
    let a_virtual = sum - b_virtual;
    (sum, (a - a_virtual) + (b - b_virtual))
}

/// `a b` as the rounded product and its exact rounding error (Dekker's TwoProduct: each factor
/// split into two halves of 26 significant bits, whose products are exact; exact for
/// `|a b| < 2^996`). A fused multiply-add would take one instruction, but the library is built
/// for baseline x86-64, where `f64::mul_add` is a software routine ten times this cost.
#[inline]
pub(crate) fn two_product(a: f64, b: f64) -> (f64, f64) {
    let product = a * b;
    let (a_high, a_low) = split(a);
    let (b_high, b_low) = split(b);
    let error = ((a_high * b_high - product) + a_high * b_low + a_low * b_high) + a_low * b_low;
    (product, error)
}

/// `a` as `high + low`, each of at most 26 significant bits (Veltkamp's splitting, with the
/// factor `2^27 + 1`).
#[inline]
fn split(a: f64) -> (f64, f64) {
    let scaled = 134_217_729.0 * a;
    let high = scaled - (scaled - a);
    (high, a - high)
}

/// Adds `det[a, b, c]` (rows `a`, `b`, `c`), times `sign` (±1), to `sum`: six products of three
/// f32s, each exact as two f64s.
fn add_determinant(sum: &mut ExactSum, sign: f64, a: Vec3, b: Vec3, c: Vec3) {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    // a·(b × c), each term a product of two f32s (exact) and a third.
    for (first, second, third) in [
        (a.x * b.y, c.z, sign),
        (a.x * b.z, c.y, -sign),
        (a.y * b.x, c.z, -sign),
        (a.y * b.z, c.x, sign),
        (a.z * b.x, c.y, sign),
        (a.z * b.y, c.x, -sign),
    ] {
        sum.add_product(first * third, second);
    }
}

/// The numerator `Ng · (p0 − o)` of the parameter `t = Ng · (p0 − o) / Ng · d` at which the ray
/// `o + t d` meets the plane of the triangle `p0, p1, p2` (`Ng = (p1 − p0) × (p2 − p0)`), to
/// within `2^-26` of itself: in f64 where that is exact, in double-f64 where that is close
/// enough, else summed exactly and rounded once. It has the exact sign and is 0 exactly when
/// the exact value is. `None` if a coordinate is not finite.
///
/// With `Ng · w = det[p1 − p0, p2 − p0, w]` and linearity in each row (no difference is formed):
/// `Ng · (p0 − o) = det[p1, p2, p0] − det[p1, p2, o] + det[p0, p2, o] + det[p1, p0, o]`, 48
/// terms: thousands of operations, for the hits where the f64 value is too poorly
/// conditioned to give `t` to an f32 ulp (`Triangle::plane_distance`).
pub(crate) fn plane_numerator(p: [Vec3; 3], o: Vec3) -> Option<f64> {
    // `det[p0 − o, p1 − o, p2 − o]`, the same value, from the differences where they are exact
    // in f64 (nearly always): in f64 where that is exact (an origin exactly on an axis-aligned
    // face: tens of operations), else in double-f64 where that is close enough.
    if let [Some(a), Some(b), Some(c)] = p.map(|q| difference_if_exact(q, o)) {
        let value =
            determinant_if_exact_in_f64(a, b, c).or_else(|| determinant_in_double_f64(a, b, c));
        if value.is_some() {
            return value;
        }
    }
    let [p0, p1, p2] = p;
    let mut sum = ExactSum::new();
    add_determinant(&mut sum, 1.0, p1, p2, p0);
    add_determinant(&mut sum, -1.0, p1, p2, o);
    add_determinant(&mut sum, 1.0, p0, p2, o);
    add_determinant(&mut sum, 1.0, p1, p0, o);
    sum.value()
}

/// `det[a, b, c]` (rows) in double-f64 arithmetic (each of its six products split into a
/// leading f64 and a remainder by `two_product`, the sums carried by `two_sum`), if that is
/// within `2^-26` of it: its error is at most about `2^-96` of the terms' magnitudes `P` (the
/// remainders' own sum rounds), and it is kept where `P` is at most `2^70` times its value.
/// [`plane_numerator`] decides here an origin within f32 rounding of a slanted face (`P` about
/// `2^24` times `|value|`, beyond plain f64's reach for an ulp of `t`) in a few hundred
/// operations. `None` (the expansion decides) where the value is smaller still: zero or within
/// about `2^-70` of the terms.
fn determinant_in_double_f64(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<f64> {
    let (mut sum, mut low, mut magnitude) = (0.0, 0.0, 0.0);
    for (i, j, k, sign) in [
        (0, 1, 2, 1.0),
        (1, 2, 0, 1.0),
        (2, 0, 1, 1.0),
        (0, 2, 1, -1.0),
        (1, 0, 2, -1.0),
        (2, 1, 0, -1.0),
    ] {
        // a_i b_j c_k = (h + l) c_k = h c_k + l c_k: h c_k exactly as two f64s, l c_k rounded
        // (below 2^-105 of the term).
        let (h, l) = two_product(sign * a[i], b[j]);
        let (high, error) = two_product(h, c[k]);
        let (total, carried) = two_sum(sum, high);
        sum = total;
        low += carried + error + l * c[k];
        magnitude += high.abs();
    }
    let value = sum + low;
    (value.abs() * 2f64.powi(70) >= magnitude && magnitude.is_finite()).then_some(value)
}

/// The denominator `Ng · d` of [`plane_numerator`]'s parameter, summed exactly and rounded
/// once to f64 (`det[p1, p2, d] − det[p0, p2, d] − det[p1, p0, d]`, 36 terms). `None` if a
/// coordinate is not finite.
pub(crate) fn plane_denominator(p: [Vec3; 3], d: Vec3) -> Option<f64> {
    let [p0, p1, p2] = p;
    let exact = || {
        determinant_if_exact_in_f64(
            difference_if_exact(p1, p0)?,
            difference_if_exact(p2, p0)?,
            d.as_dvec3().to_array(),
        )
    };
    if let Some(value) = exact() {
        return Some(value);
    }
    let mut sum = ExactSum::new();
    add_determinant(&mut sum, 1.0, p1, p2, d);
    add_determinant(&mut sum, -1.0, p0, p2, d);
    add_determinant(&mut sum, -1.0, p1, p0, d);
    sum.value()
}

/// The exact sign of `det[p − o, q − o, d]` (rows), for f32 points `o`, `p`, `q` and an f32
/// vector `d`: which side of the plane through `o` spanned by `p − o` and `d` the point `q`
/// lies on. `None` if a coordinate is not finite.
///
/// The differences are not formed (`p − o` may not be exact even in f64); by linearity in each
/// row, `det[p − o, q − o, d] = det[p, q, d] − det[o, q, d] − det[p, o, d]`.
pub(crate) fn orientation_sign(o: Vec3, p: Vec3, q: Vec3, d: Vec3) -> Option<i8> {
    if !(o.is_finite() && p.is_finite() && q.is_finite() && d.is_finite()) {
        return None;
    }
    orientation_sign_if_exact_in_f64(o, p, q, d)
        .or_else(|| orientation_sign_by_expansion(o, p, q, d))
}

/// [`orientation_sign`] as a sum of 36 f64 terms kept exactly: for any f32 inputs.
fn orientation_sign_by_expansion(o: Vec3, p: Vec3, q: Vec3, d: Vec3) -> Option<i8> {
    let mut sum = ExactSum::new();
    add_determinant(&mut sum, 1.0, p, q, d);
    add_determinant(&mut sum, -1.0, o, q, d);
    add_determinant(&mut sum, -1.0, p, o, d);
    sum.sign()
}

/// `det[p − o, q − o, d] = (p − o) · ((q − o) × d)` evaluated in f64 with every rounding
/// error computed (`two_sum`, `two_product`): its sign if every error is zero (the value is then
/// exact), `None` otherwise. The rays that pass exactly through an edge come mostly from inputs
/// of few significant bits (integer or grid-aligned meshes, axis-aligned rays), for which all of
/// it is exact: a few dozen operations instead of the expansion's thousands.
fn orientation_sign_if_exact_in_f64(o: Vec3, p: Vec3, q: Vec3, d: Vec3) -> Option<i8> {
    let det = determinant_if_exact_in_f64(
        difference_if_exact(p, o)?,
        difference_if_exact(q, o)?,
        d.as_dvec3().to_array(),
    )?;
    Some((det > 0.0) as i8 - (det < 0.0) as i8)
}

/// `p − q` in f64, if no component rounds.
fn difference_if_exact(p: Vec3, q: Vec3) -> Option<[f64; 3]> {
    let (p, q) = (p.as_dvec3(), q.as_dvec3());
    let mut difference = [0.0; 3];
    for i in 0..3 {
        difference[i] = exact_sum(p[i], -q[i])?;
    }
    Some(difference)
}

/// `a + b` if it is an f64 without rounding.
fn exact_sum(a: f64, b: f64) -> Option<f64> {
    match two_sum(a, b) {
        (sum, 0.0) => Some(sum),
        _ => None,
    }
}

/// `det[a, b, d] = a · (b × d)` evaluated in f64, if no product or sum rounds.
fn determinant_if_exact_in_f64(a: [f64; 3], b: [f64; 3], d: [f64; 3]) -> Option<f64> {
    let exact_product = |a: f64, b: f64| match two_product(a, b) {
        (product, 0.0) => Some(product),
        _ => None,
    };
    let mut det = 0.0;
    for (i, j, k) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
        // (b × d)_i = b_j d_k − b_k d_j, then a_i times it.
        let cross = exact_sum(exact_product(b[j], d[k])?, -exact_product(b[k], d[j])?)?;
        det = exact_sum(det, exact_product(a[i], cross)?)?;
    }
    Some(det)
}

/// The exact sign of `(q_i − p_i) d_k − d_i (q_k − p_k)`, for f32 points `p`, `q` and an f32
/// vector `d`: the 2D cross product of the edge `q − p` and `d` in the coordinate plane of axes
/// `i` and `k`. `None` if a coordinate is not finite.
pub(crate) fn cross_sign(p: Vec3, q: Vec3, d: Vec3, i: usize, k: usize) -> Option<i8> {
    let (p, q, d) = (p.as_dvec3(), q.as_dvec3(), d.as_dvec3());
    let mut sum = ExactSum::new();
    // Each term a product of two f32s: exact in f64.
    for term in [q[i] * d[k], -p[i] * d[k], -d[i] * q[k], d[i] * p[k]] {
        sum.add(term);
    }
    sum.sign()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `det[p − o, q − o, d]` of integer points, in i128 (exact for coordinates below 2^24).
    fn integer_orientation(o: [i64; 3], p: [i64; 3], q: [i64; 3], d: [i64; 3]) -> i128 {
        let a: Vec<i128> = (0..3).map(|k| (p[k] - o[k]) as i128).collect();
        let b: Vec<i128> = (0..3).map(|k| (q[k] - o[k]) as i128).collect();
        let c: Vec<i128> = d.iter().map(|&x| x as i128).collect();
        a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])
    }

    fn vec(v: [i64; 3], scale: f32) -> Vec3 {
        Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) * scale
    }

    /// A small deterministic generator (SplitMix64).
    fn next(state: &mut u64) -> u64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// `plane_numerator` and `plane_denominator` of integer triangles and rays (where i128 is
    /// exact): the values close to the exact ones, exactly 0 for an origin on the plane or a
    /// direction along it.
    #[test]
    fn plane_parameters_match_integer_arithmetic() {
        let mut state = 7;
        let mut coordinate =
            |bits: u32| (next(&mut state) % (1 << bits)) as i64 - (1 << (bits - 1));
        for case in 0..2_000 {
            let mut point = |bits| [coordinate(bits), coordinate(bits), coordinate(bits)];
            // Coordinates of 20 bits (every product exact in f64) or 23 (the expansions).
            let bits = if case % 2 == 0 { 20 } else { 23 };
            let (p0, p1, p2) = (point(bits), point(bits), point(bits));
            let (e1, e2) = (
                [0, 1, 2].map(|k| p1[k] - p0[k]),
                [0, 1, 2].map(|k| p2[k] - p0[k]),
            );
            // Every third origin on the plane, every fifth direction along it.
            let o = if case % 3 == 0 {
                [0, 1, 2].map(|k| p1[k] + p2[k] - p0[k])
            } else {
                point(bits)
            };
            let d = if case % 5 == 0 {
                [0, 1, 2].map(|k| e1[k] - e2[k])
            } else {
                point(12)
            };
            let w = [0, 1, 2].map(|k| p0[k] - o[k]);
            let numerator = integer_orientation([0; 3], e1, e2, w);
            let denominator = integer_orientation([0; 3], e1, e2, d);
            let p = [vec(p0, 1.0), vec(p1, 1.0), vec(p2, 1.0)];
            let n = plane_numerator(p, vec(o, 1.0)).unwrap();
            let dn = plane_denominator(p, vec(d, 1.0)).unwrap();
            let close = |found: f64, exact: i128| {
                (found - exact as f64).abs() <= 4.0 * f64::EPSILON * (exact as f64).abs()
            };
            // The numerator to 2^-26 (double f64 where that is enough), the denominator to ulps.
            let near = (n - numerator as f64).abs() <= 2f64.powi(-26) * (numerator as f64).abs();
            assert!(near, "case {case}: numerator {n} against {numerator}");
            assert!(
                close(dn, denominator),
                "case {case}: denominator {dn} against {denominator}"
            );
            assert_eq!(n == 0.0, numerator == 0, "case {case}");
            assert_eq!(dn == 0.0, denominator == 0, "case {case}");
        }
        let infinite = Vec3::new(f32::INFINITY, 0.0, 0.0);
        let triangle = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert_eq!(plane_numerator(triangle, infinite), None);
        assert_eq!(plane_denominator(triangle, infinite), None);
    }

    #[test]
    fn sums_cancelling_far_apart_magnitudes_keep_their_sign() {
        let mut sum = ExactSum::new();
        for term in [1e100, 1.0, -1e100] {
            sum.add(term);
        }
        assert_eq!(sum.sign(), Some(1));
        let mut sum = ExactSum::new();
        for term in [1e-100, 1e100, -1e-100, -1e100] {
            sum.add(term);
        }
        assert_eq!(sum.sign(), Some(0));
        let mut sum = ExactSum::new();
        sum.add(f64::NAN);
        assert_eq!(sum.sign(), None);
    }

    #[test]
    fn orientation_matches_integer_arithmetic_on_coplanar_and_near_coplanar_points() {
        let mut state = 7;
        let mut zeros = 0;
        for case in 0..20_000 {
            let mut coordinate =
                |bits: u32| (next(&mut state) % (1 << bits)) as i64 - (1 << (bits - 1));
            let (wide, narrow) = if case % 4 < 2 { (20, 8) } else { (22, 20) };
            let o = [coordinate(wide), coordinate(wide), coordinate(wide)];
            let p = [coordinate(wide), coordinate(wide), coordinate(wide)];
            let d = [coordinate(narrow), coordinate(narrow), coordinate(narrow)];
            // Half the cases put q exactly on the plane (o, p − o, d), then nudge it by 0 or 1.
            let q = if case % 2 == 0 {
                let (alpha, beta) = (coordinate(3), coordinate(3));
                let nudge = [coordinate(2).signum(), 0, 0];
                [0, 1, 2].map(|k| o[k] + alpha * (p[k] - o[k]) + beta * d[k] + nudge[k])
            } else {
                [coordinate(wide), coordinate(wide), coordinate(wide)]
            };
            if q.iter().any(|x| x.abs() >= 1 << 24) {
                continue;
            }
            let expected = integer_orientation(o, p, q, d).signum() as i8;
            zeros += (expected == 0) as u32;
            // A power-of-two scale keeps every coordinate exact and every sign.
            let scale = [1.0, 2f32.powi(-60), 2f32.powi(40)][case % 3];
            let (o, p, q, d) = (vec(o, scale), vec(p, scale), vec(q, scale), vec(d, 1.0));
            assert_eq!(orientation_sign(o, p, q, d), Some(expected), "case {case}");
            assert_eq!(
                orientation_sign_by_expansion(o, p, q, d),
                Some(expected),
                "case {case}"
            );
            if let Some(sign) = orientation_sign_if_exact_in_f64(o, p, q, d) {
                assert_eq!(sign, expected, "case {case}");
            }
        }
        assert!(zeros > 1_000, "the test must reach exact zeros ({zeros})");
    }

    /// An origin whose components differ by 2^40 in magnitude, and a direction whose components
    /// differ the other way: f64 rounds in most cases, and the expansion decides.
    #[test]
    fn orientation_of_far_apart_magnitudes_is_decided_by_the_expansion() {
        let mut state = 13;
        let (mut zeros, mut by_expansion) = (0, 0);
        for case in 0..5_000 {
            let mut coordinate =
                |bits: u32| (next(&mut state) % (1 << bits)) as i64 - (1 << (bits - 1));
            let big = |x: i64| x << 40;
            let o = [big(coordinate(16)), coordinate(16), coordinate(16)];
            let p = [big(coordinate(16)), coordinate(16), coordinate(16)];
            let d = [coordinate(8), big(coordinate(8)), coordinate(8)];
            let q = if case % 2 == 0 {
                // On the line through o and p, or nudged off it in y.
                let alpha = coordinate(3);
                let nudge = [0, coordinate(2).signum(), 0];
                [0, 1, 2].map(|k| o[k] + alpha * (p[k] - o[k]) + nudge[k])
            } else {
                [big(coordinate(16)), coordinate(16), coordinate(16)]
            };
            let expected = integer_orientation(o, p, q, d).signum() as i8;
            zeros += (expected == 0) as u32;
            let (o, p, q, d) = (vec(o, 1.0), vec(p, 1.0), vec(q, 1.0), vec(d, 1.0));
            assert_eq!(orientation_sign(o, p, q, d), Some(expected), "case {case}");
            by_expansion += orientation_sign_if_exact_in_f64(o, p, q, d).is_none() as u32;
        }
        assert!(
            zeros > 500 && by_expansion > 2_500,
            "{zeros} zeros, {by_expansion} by expansion"
        );
    }

    #[test]
    fn difference_of_products_matches_integer_arithmetic() {
        let mut state = 17;
        for case in 0..20_000 {
            let mut factor = || (next(&mut state) % (1 << 30)) as i64 - (1 << 29);
            let (a, b, c) = (factor(), factor(), factor());
            // Every other case has a b = c d exactly.
            let d = if case % 2 == 0 && c != 0 && (a * b) % c == 0 {
                (a * b) / c
            } else {
                factor()
            };
            if d.abs() >= 1 << 53 {
                continue;
            }
            let expected = (a as i128 * b as i128 - c as i128 * d as i128).signum() as i8;
            let got = difference_of_products_sign(a as f64, b as f64, c as f64, d as f64);
            assert_eq!(got, Some(expected), "case {case}: {a} {b} {c} {d}");
        }
    }

    #[test]
    fn cross_sign_matches_integer_arithmetic() {
        let mut state = 11;
        for case in 0..20_000 {
            let mut coordinate =
                |bits: u32| (next(&mut state) % (1 << bits)) as i64 - (1 << (bits - 1));
            let p = [coordinate(23), coordinate(23), coordinate(23)];
            let d = [coordinate(4), coordinate(4), coordinate(4)];
            let q = if case % 2 == 0 {
                let step = coordinate(4);
                [0, 1, 2].map(|k| p[k] + step * d[k] + (case % 4 == 0) as i64)
            } else {
                [coordinate(23), coordinate(23), coordinate(23)]
            };
            let (i, k) = [(0, 2), (1, 2), (2, 0)][case % 3];
            let expected = ((q[i] - p[i]) as i128 * d[k] as i128
                - d[i] as i128 * (q[k] - p[k]) as i128)
                .signum() as i8;
            let got = cross_sign(vec(p, 1.0), vec(q, 1.0), vec(d, 1.0), i, k);
            assert_eq!(got, Some(expected), "case {case}");
        }
    }

    #[test]
    fn non_finite_coordinates_have_no_sign() {
        let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
        assert_eq!(orientation_sign(Vec3::ZERO, inf, Vec3::Y, Vec3::Z), None);
        assert_eq!(cross_sign(Vec3::ZERO, inf, Vec3::Z, 0, 2), None);
    }
}
