//! The f64 point–triangle routine of [`super::point_triangle`] for four triangles at once,
//! branch-free: one lane per triangle, every lane computing the very operations the scalar
//! routine computes for its triangle, so that each lane's answer is the scalar answer, bit for
//! bit.
//!
//! **Why.** The scalar routine picks the point's Voronoi region (three vertices, three edges,
//! the face) by up to six branches, which the CPU mispredicts often on a nearest-point query
//! (the region changes from one triangle to the next); a search that decides several triangles
//! per query paid for them about twice their instructions (measured). Here every region's
//! point is computed and the right one selected, four lanes of f64 side by side (one AVX
//! register, two SSE ones without AVX).
//!
//! **Bit-identical to the scalar routine.** Each lane's dot products, differences, quotients and
//! sums are the same IEEE operations in the same order as the scalar code's (Rust never fuses a
//! product and a sum on its own, in scalar or vector code), and a region is selected by the same
//! comparisons in the same priority (the first region whose test holds, in the scalar order
//! A, B, AB, C, AC, BC, face); a NaN fails every comparison in both forms. Values of regions
//! that are not selected (a division by zero, say) are computed and dropped, which changes
//! nothing. The unit test and the property tests compare every lane with
//! [`closest_point_on_triangle`](super::point_triangle::closest_point_on_triangle).

// The kernels loop over lanes by index, as the four-wide instructions they become do.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

use super::enclosure_packet::LANES;

/// Triangles decided side by side.
pub(super) const F64_LANES: usize = 4;

/// Four triangles' vertices in f64: `vertex[k][axis][lane]` is coordinate `axis` of vertex `k`
/// (`a`, `b`, `c`) of the triangle in `lane`.
type LaneTriangles = [[[f64; F64_LANES]; 3]; 3];

/// An enclosure packet's f32 vertices (`EnclosurePacket::vertex`): `[k][axis][lane]`, [`LANES`]
/// lanes, decided here half a packet ([`F64_LANES`] lanes) at a time.
pub(super) type PacketVertices = [[[f32; LANES]; 3]; 3];

/// The nearest points of four triangles to one query point, lane by lane:
/// `point[axis][lane] = (1-u-v) a + u b + v c`, and the computed squared distance
/// `distance_squared[lane] = |p - point|²` (the scalar routine's and its caller's `d²`).
#[derive(Clone, Copy, Debug)]
pub(super) struct LanePoints {
    pub point: [[f64; F64_LANES]; 3],
    pub u: [f64; F64_LANES],
    pub v: [f64; F64_LANES],
    pub distance_squared: [f64; F64_LANES],
}

/// Lane-wise `if mask { yes } else { no }`: a blend.
#[inline(always)]
fn select(
    mask: [bool; F64_LANES],
    yes: [f64; F64_LANES],
    no: [f64; F64_LANES],
) -> [f64; F64_LANES] {
    let mut out = [0.0; F64_LANES];
    for lane in 0..F64_LANES {
        out[lane] = if mask[lane] { yes[lane] } else { no[lane] };
    }
    out
}

/// Lane-wise `x - y`.
#[inline(always)]
fn sub(x: [f64; F64_LANES], y: [f64; F64_LANES]) -> [f64; F64_LANES] {
    let mut out = [0.0; F64_LANES];
    for lane in 0..F64_LANES {
        out[lane] = x[lane] - y[lane];
    }
    out
}

/// Lane-wise dot products `(x₀y₀ + x₁y₁) + x₂y₂`, glam's order.
#[inline(always)]
fn dot(x: &[[f64; F64_LANES]; 3], y: &[[f64; F64_LANES]; 3]) -> [f64; F64_LANES] {
    let mut out = [0.0; F64_LANES];
    for lane in 0..F64_LANES {
        out[lane] = (x[0][lane] * y[0][lane] + x[1][lane] * y[1][lane]) + x[2][lane] * y[2][lane];
    }
    out
}

/// Lane-wise `origin + s · along` per axis (glam's `origin + s * along`).
#[inline(always)]
fn along(
    origin: &[[f64; F64_LANES]; 3],
    s: [f64; F64_LANES],
    dir: &[[f64; F64_LANES]; 3],
) -> [[f64; F64_LANES]; 3] {
    let mut out = [[0.0; F64_LANES]; 3];
    for axis in 0..3 {
        for lane in 0..F64_LANES {
            out[axis][lane] = origin[axis][lane] + s[lane] * dir[axis][lane];
        }
    }
    out
}

/// The points of the four triangles of half `half` (lanes `4·half .. 4·half + 4`) of a
/// packet's `vertex` nearest to `p`, with their barycentrics and squared distances: Ericson's
/// §5.1.5 routine ([`closest_point_on_triangle`](super::point_triangle::closest_point_on_triangle),
/// whose notes give the regions and formulas) in every lane at once, each region's point
/// computed and the scalar routine's choice selected (module notes). The triangles must not be
/// degenerate, as for the scalar routine. Plain arrays, lane by lane (LLVM leaves much of it
/// scalar: [`avx::closest_points_on_half`] is the fast form and this its reference).
#[inline(always)]
pub(super) fn closest_points_on_half_portable(
    p: DVec3,
    vertex: &PacketVertices,
    half: usize,
) -> LanePoints {
    let mut t: LaneTriangles = [[[0.0; F64_LANES]; 3]; 3];
    for k in 0..3 {
        for axis in 0..3 {
            for l in 0..F64_LANES {
                t[k][axis][l] = vertex[k][axis][half * F64_LANES + l] as f64;
            }
        }
    }
    closest_points_on_lanes_portable(p, &t)
}

/// [`closest_points_on_half_portable`] for f64 vertices.
#[inline(always)]
fn closest_points_on_lanes_portable(p: DVec3, t: &LaneTriangles) -> LanePoints {
    let [a, b, c] = t;
    let p = [[p.x; F64_LANES], [p.y; F64_LANES], [p.z; F64_LANES]];
    let diff = |x: &[[f64; F64_LANES]; 3], y: &[[f64; F64_LANES]; 3]| {
        [sub(x[0], y[0]), sub(x[1], y[1]), sub(x[2], y[2])]
    };
    let ab = diff(b, a);
    let ac = diff(c, a);
    let ap = diff(&p, a);
    let bp = diff(&p, b);
    let cp = diff(&p, c);
    let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
    let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
    let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
    let mut in_a = [false; F64_LANES];
    let mut in_b = [false; F64_LANES];
    let mut in_ab = [false; F64_LANES];
    let mut in_c = [false; F64_LANES];
    let mut in_ac = [false; F64_LANES];
    let mut in_bc = [false; F64_LANES];
    let mut s_ab = [0.0; F64_LANES];
    let mut s_ac = [0.0; F64_LANES];
    let mut s_bc = [0.0; F64_LANES];
    let mut u = [0.0; F64_LANES];
    let mut v = [0.0; F64_LANES];
    for l in 0..F64_LANES {
        let vc = d1[l] * d4[l] - d3[l] * d2[l];
        let vb = d5[l] * d2[l] - d1[l] * d6[l];
        let va = d3[l] * d6[l] - d5[l] * d4[l];
        in_a[l] = d1[l] <= 0.0 && d2[l] <= 0.0;
        in_b[l] = d3[l] >= 0.0 && d4[l] <= d3[l];
        in_ab[l] = vc <= 0.0 && d1[l] >= 0.0 && d3[l] <= 0.0;
        in_c[l] = d6[l] >= 0.0 && d5[l] <= d6[l];
        in_ac[l] = vb <= 0.0 && d2[l] >= 0.0 && d6[l] <= 0.0;
        in_bc[l] = va <= 0.0 && d4[l] - d3[l] >= 0.0 && d5[l] - d6[l] >= 0.0;
        s_ab[l] = d1[l] / (d1[l] - d3[l]);
        s_ac[l] = d2[l] / (d2[l] - d6[l]);
        s_bc[l] = (d4[l] - d3[l]) / ((d4[l] - d3[l]) + (d5[l] - d6[l]));
        let denom = 1.0 / (va + vb + vc);
        u[l] = vb * denom;
        v[l] = vc * denom;
    }
    // The face, then each earlier region of the scalar order over it: the first that holds wins.
    let face = {
        let mut q = [[0.0; F64_LANES]; 3];
        for axis in 0..3 {
            for l in 0..F64_LANES {
                q[axis][l] = (a[axis][l] + u[l] * ab[axis][l]) + v[l] * ac[axis][l];
            }
        }
        q
    };
    let cb = diff(c, b);
    let on_bc = along(b, s_bc, &cb);
    let on_ac = along(a, s_ac, &ac);
    let on_ab = along(a, s_ab, &ab);
    let mut point = [[0.0; F64_LANES]; 3];
    for axis in 0..3 {
        let q = select(in_bc, on_bc[axis], face[axis]);
        let q = select(in_ac, on_ac[axis], q);
        let q = select(in_c, c[axis], q);
        let q = select(in_ab, on_ab[axis], q);
        let q = select(in_b, b[axis], q);
        point[axis] = select(in_a, a[axis], q);
    }
    let mut bc_u = [0.0; F64_LANES];
    for l in 0..F64_LANES {
        bc_u[l] = 1.0 - s_bc[l];
    }
    let (zero, one) = ([0.0; F64_LANES], [1.0; F64_LANES]);
    let u = select(in_bc, bc_u, u);
    let v = select(in_bc, s_bc, v);
    let (u, v) = (select(in_ac, zero, u), select(in_ac, s_ac, v));
    let (u, v) = (select(in_c, zero, u), select(in_c, one, v));
    let (u, v) = (select(in_ab, s_ab, u), select(in_ab, zero, v));
    let (u, v) = (select(in_b, one, u), select(in_b, zero, v));
    let (u, v) = (select(in_a, zero, u), select(in_a, zero, v));
    let gap = diff(&p, &point);
    LanePoints {
        point,
        u,
        v,
        distance_squared: dot(&gap, &gap),
    }
}

/// The half-packet routine in AVX intrinsics: the portable form's operations, one
/// instruction each (`vsubpd`, `vmulpd`, `vaddpd`, `vdivpd`, ordered comparisons that a NaN
/// fails, `vblendvpd`), in the same order.
#[cfg(target_arch = "x86_64")]
pub(super) mod avx {
    use std::arch::x86_64::*;

    use glam::DVec3;

    use super::{LanePoints, PacketVertices, F64_LANES, LANES};

    type V3 = [__m256d; 3];

    /// Lanes `4·half .. 4·half + 4` of `x`, widened to f64.
    #[inline(always)]
    unsafe fn load(x: &[f32; LANES], half: usize) -> __m256d {
        let four = &x[half * F64_LANES..half * F64_LANES + F64_LANES];
        // SAFETY: `four` is four f32, read unaligned.
        unsafe { _mm256_cvtps_pd(_mm_loadu_ps(four.as_ptr())) }
    }

    #[inline(always)]
    unsafe fn store(x: __m256d) -> [f64; F64_LANES] {
        let mut out = [0.0; F64_LANES];
        // SAFETY: `out` holds four f64, written unaligned.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), x) };
        out
    }

    #[inline(always)]
    unsafe fn sub3(x: V3, y: V3) -> V3 {
        [
            _mm256_sub_pd(x[0], y[0]),
            _mm256_sub_pd(x[1], y[1]),
            _mm256_sub_pd(x[2], y[2]),
        ]
    }

    /// `(x₀y₀ + x₁y₁) + x₂y₂`, the order of glam's `dot`.
    #[inline(always)]
    unsafe fn dot(x: V3, y: V3) -> __m256d {
        let xy = _mm256_add_pd(_mm256_mul_pd(x[0], y[0]), _mm256_mul_pd(x[1], y[1]));
        _mm256_add_pd(xy, _mm256_mul_pd(x[2], y[2]))
    }

    /// `origin + s · dir` per axis.
    #[inline(always)]
    unsafe fn along(origin: V3, s: __m256d, dir: V3) -> V3 {
        [
            _mm256_add_pd(origin[0], _mm256_mul_pd(s, dir[0])),
            _mm256_add_pd(origin[1], _mm256_mul_pd(s, dir[1])),
            _mm256_add_pd(origin[2], _mm256_mul_pd(s, dir[2])),
        ]
    }

    #[inline(always)]
    unsafe fn le(x: __m256d, y: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_LE_OQ>(x, y)
    }

    #[inline(always)]
    unsafe fn ge(x: __m256d, y: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_GE_OQ>(x, y)
    }

    /// Lane-wise `if mask { yes } else { no }`.
    #[inline(always)]
    unsafe fn select(mask: __m256d, yes: __m256d, no: __m256d) -> __m256d {
        _mm256_blendv_pd(no, yes, mask)
    }

    /// [`closest_points_on_half_portable`](super::closest_points_on_half_portable), one AVX
    /// register per value: the same operations in the same order.
    #[target_feature(enable = "avx")]
    #[inline]
    pub(in crate::proximity) unsafe fn closest_points_on_half(
        p: DVec3,
        t: &PacketVertices,
        half: usize,
    ) -> LanePoints {
        // SAFETY (the whole body): the caller checked for AVX; the loads and stores are those
        // of `load` and `store`.
        unsafe {
            // No closures here: they would be compiled without AVX (and not inlined).
            let a = [
                load(&t[0][0], half),
                load(&t[0][1], half),
                load(&t[0][2], half),
            ];
            let b = [
                load(&t[1][0], half),
                load(&t[1][1], half),
                load(&t[1][2], half),
            ];
            let c = [
                load(&t[2][0], half),
                load(&t[2][1], half),
                load(&t[2][2], half),
            ];
            let p = [
                _mm256_set1_pd(p.x),
                _mm256_set1_pd(p.y),
                _mm256_set1_pd(p.z),
            ];
            let zero = _mm256_setzero_pd();
            let one = _mm256_set1_pd(1.0);
            let ab = sub3(b, a);
            let ac = sub3(c, a);
            let ap = sub3(p, a);
            let bp = sub3(p, b);
            let cp = sub3(p, c);
            let (d1, d2) = (dot(ab, ap), dot(ac, ap));
            let (d3, d4) = (dot(ab, bp), dot(ac, bp));
            let (d5, d6) = (dot(ab, cp), dot(ac, cp));
            let vc = _mm256_sub_pd(_mm256_mul_pd(d1, d4), _mm256_mul_pd(d3, d2));
            let vb = _mm256_sub_pd(_mm256_mul_pd(d5, d2), _mm256_mul_pd(d1, d6));
            let va = _mm256_sub_pd(_mm256_mul_pd(d3, d6), _mm256_mul_pd(d5, d4));
            let e43 = _mm256_sub_pd(d4, d3);
            let e56 = _mm256_sub_pd(d5, d6);
            let in_a = _mm256_and_pd(le(d1, zero), le(d2, zero));
            let in_b = _mm256_and_pd(ge(d3, zero), le(d4, d3));
            let in_ab = _mm256_and_pd(_mm256_and_pd(le(vc, zero), ge(d1, zero)), le(d3, zero));
            let in_c = _mm256_and_pd(ge(d6, zero), le(d5, d6));
            let in_ac = _mm256_and_pd(_mm256_and_pd(le(vb, zero), ge(d2, zero)), le(d6, zero));
            let in_bc = _mm256_and_pd(_mm256_and_pd(le(va, zero), ge(e43, zero)), ge(e56, zero));
            // One division per lane, of the operands of the region it is used in (the
            // dividers are the slowest unit here; four divisions took longer than the scalar
            // routine's branches): the face's `1 / (va + vb + vc)`, or an edge's parameter.
            let num = select(in_bc, e43, one);
            let den = select(
                in_bc,
                _mm256_add_pd(e43, e56),
                _mm256_add_pd(_mm256_add_pd(va, vb), vc),
            );
            let num = select(in_ac, d2, num);
            let den = select(in_ac, _mm256_sub_pd(d2, d6), den);
            let num = select(in_ab, d1, num);
            let den = select(in_ab, _mm256_sub_pd(d1, d3), den);
            let quotient = _mm256_div_pd(num, den);
            let (s_ab, s_ac, s_bc, denom) = (quotient, quotient, quotient, quotient);
            let u = _mm256_mul_pd(vb, denom);
            let v = _mm256_mul_pd(vc, denom);
            let face = along(along(a, u, ab), v, ac);
            let on_bc = along(b, s_bc, sub3(c, b));
            let on_ac = along(a, s_ac, ac);
            let on_ab = along(a, s_ab, ab);
            let mut point = face;
            for i in 0..3 {
                let q = select(in_bc, on_bc[i], face[i]);
                let q = select(in_ac, on_ac[i], q);
                let q = select(in_c, c[i], q);
                let q = select(in_ab, on_ab[i], q);
                let q = select(in_b, b[i], q);
                point[i] = select(in_a, a[i], q);
            }
            let u = select(in_bc, _mm256_sub_pd(one, s_bc), u);
            let v = select(in_bc, s_bc, v);
            let (u, v) = (select(in_ac, zero, u), select(in_ac, s_ac, v));
            let (u, v) = (select(in_c, zero, u), select(in_c, one, v));
            let (u, v) = (select(in_ab, s_ab, u), select(in_ab, zero, v));
            let (u, v) = (select(in_b, one, u), select(in_b, zero, v));
            let (u, v) = (select(in_a, zero, u), select(in_a, zero, v));
            let gap = sub3(p, point);
            LanePoints {
                point: [store(point[0]), store(point[1]), store(point[2])],
                u: store(u),
                v: store(v),
                distance_squared: store(dot(gap, gap)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::proximity::point_triangle::closest_point_by_regions;

    /// Every lane equals the scalar routine, bit for bit (`u`, `v`, the point and `|p - q|²`),
    /// in both halves of a packet (the triangles in order, then reversed), in the portable
    /// form and in the AVX one where the CPU has AVX. The vertices are rounded to f32 first.
    fn assert_lanes_match_scalar(
        p: DVec3,
        tris: [[DVec3; 3]; F64_LANES],
    ) -> Result<(), TestCaseError> {
        let tris = tris.map(|t| t.map(|v| v.as_vec3().as_dvec3()));
        let mut vertex: PacketVertices = [[[0.0; LANES]; 3]; 3];
        for (lane, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                for axis in 0..3 {
                    vertex[k][axis][lane] = tri[k][axis] as f32;
                    vertex[k][axis][LANES - 1 - lane] = tri[k][axis] as f32;
                }
            }
        }
        let mut forms = Vec::new();
        for half in 0..LANES / F64_LANES {
            forms.push((
                closest_points_on_half_portable(p, &vertex, half),
                half,
                "portable",
            ));
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the CPU has AVX.
                let avx = unsafe { avx::closest_points_on_half(p, &vertex, half) };
                forms.push((avx, half, "avx"));
            }
        }
        for (lanes, half, form) in forms {
            for l in 0..F64_LANES {
                let lane = half * F64_LANES + l;
                let [a, b, c] = tris[if lane < F64_LANES {
                    lane
                } else {
                    LANES - 1 - lane
                }];
                let q = closest_point_by_regions(p, a, b, c);
                let d2 = (p - q.point).length_squared();
                let got = DVec3::new(lanes.point[0][l], lanes.point[1][l], lanes.point[2][l]);
                let bits = |x: f64| x.to_bits();
                let at = format!("lane {lane}, {form}");
                prop_assert_eq!(
                    q.point.to_array().map(bits),
                    got.to_array().map(bits),
                    "{}",
                    at
                );
                prop_assert_eq!(bits(q.u), bits(lanes.u[l]), "u, {}", at);
                prop_assert_eq!(bits(q.v), bits(lanes.v[l]), "v, {}", at);
                prop_assert_eq!(bits(d2), bits(lanes.distance_squared[l]), "d², {}", at);
            }
        }
        Ok(())
    }

    /// A vertex: a random f32 point (as the meshes' vertices are) at one of several scales.
    fn vertex(scale: f32) -> impl Strategy<Value = DVec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
            .prop_map(move |(x, y, z)| (glam::Vec3::new(x, y, z) * scale).as_dvec3())
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(256))]

        /// Random triangles (slivers and axis-aligned ones among them) and points in every
        /// region, near and far, at scales from 10⁻⁴ to 10¹⁸.
        #[test]
        fn lanes_are_the_scalar_routine(
            (p, tris) in prop_oneof![Just(1e-4f32), Just(1.0), Just(1e6), Just(1e18)].prop_flat_map(|s| (
                vertex(3.0 * s),
                prop::collection::vec((vertex(s), vertex(s), vertex(s), 0usize..5), F64_LANES),
            ))
        ) {
            let tris: Vec<[DVec3; 3]> = tris
                .into_iter()
                .map(|(a, mut b, mut c, shape)| {
                    match shape {
                        // Flat in one axis (walls), or a sliver along `ab`.
                        0..=2 => {
                            b[shape] = a[shape];
                            c[shape] = a[shape];
                        }
                        3 => c = a + (b - a) * 0.5 + (c - a) * 1e-6,
                        _ => {}
                    }
                    [a, b, c]
                })
                .collect();
            let tris: Vec<[DVec3; 3]> = tris.into_iter().map(|t| t.map(|v| v.as_vec3().as_dvec3())).collect();
            prop_assume!(tris.iter().all(|[a, b, c]| (*b - *a).cross(*c - *a).length_squared() > 0.0));
            assert_lanes_match_scalar(p, [tris[0], tris[1], tris[2], tris[3]])?;
            // A query point off the f32 grid (f64 queries).
            let off = p + DVec3::new(1e-9, -3e-10, 7e-11) * (1.0 + p.abs().max_element());
            assert_lanes_match_scalar(off, [tris[0], tris[1], tris[2], tris[3]])?;
        }
    }

    /// One point in each of the seven regions of the same triangle, one lane each, and points on
    /// the vertices, edges and face.
    #[test]
    fn each_region_matches_the_scalar_routine() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let points = [
            [-1.0, -1.0, 3.0],
            [2.0, -0.5, 1.0],
            [-0.5, 2.0, 0.0],
            [0.5, -1.0, 0.0],
            [-1.0, 0.25, 0.0],
            [1.0, 1.0, 0.0],
            [0.25, 0.25, -2.0],
            [0.0, 0.0, 0.0],
            [0.5, 0.5, 0.0],
            [0.1, 0.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        for p in points {
            assert_lanes_match_scalar(DVec3::from(p), [tri; F64_LANES]).unwrap();
        }
    }
}
