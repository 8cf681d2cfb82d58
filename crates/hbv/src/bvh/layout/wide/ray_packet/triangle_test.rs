//! The packet's triangle test: one triangle against the packet's eight rays, with the bits the
//! single-ray test gives each.

use std::arch::x86_64::*;

use super::packet_rays::PacketRays;
use crate::bvh::layout::wide::TrianglePacket;
use crate::geometry::{Triangle, DEPTH_FLOOR, SHARED_EDGE_ERROR};

/// What [`test_triangle`] decided, ray by ray: as
/// [`PacketTest`](super::super::triangle_packet::PacketTest), with lanes for rays instead of
/// triangles.
pub(super) struct LaneTest {
    pub hit: u32,
    pub undecided: u32,
    pub t: __m256,
    pub v: __m256,
    pub w: __m256,
    pub det: __m256,
}

/// Triangle `lane` of `triangles` against the packet's rays within `[tmin, tmax]`:
/// [`TrianglePacket::test`]'s operations (see its doc for the decision rule) in the same order,
/// with the triangle's vertex coordinates broadcast and each ray's origin, shear and interval in
/// its lane, so that each ray is decided with the bits [`Triangle::intersect`] gives it.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn test_triangle(
    triangles: &TrianglePacket,
    lane: usize,
    rays: &PacketRays,
    tmax: __m256,
) -> LaneTest {
    let [kx, ky, kz] = rays.k;
    let [ox, oy, oz] = rays.origin_k;
    let [sx, sy, sz] = rays.shear;
    let sign_bit = _mm256_set1_ps(-0.0);
    let abs = |x: __m256| _mm256_andnot_ps(sign_bit, x);
    let coordinate = |v: usize, k: usize| _mm256_set1_ps(triangles.vertices[v][k][lane]);
    let sheared = |v: usize| {
        let x = _mm256_sub_ps(coordinate(v, kx), ox);
        let y = _mm256_sub_ps(coordinate(v, ky), oy);
        let z = _mm256_sub_ps(coordinate(v, kz), oz);
        let m = _mm256_max_ps(_mm256_max_ps(abs(x), abs(y)), abs(z));
        (
            _mm256_sub_ps(x, _mm256_mul_ps(sx, z)),
            _mm256_sub_ps(y, _mm256_mul_ps(sy, z)),
            z,
            m,
        )
    };
    let ((ax, ay, az, ma), (bx, by, bz, mb), (cx, cy, cz, mc)) =
        (sheared(0), sheared(1), sheared(2));
    let u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
    let v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
    let w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
    let sheared_max = _mm256_max_ps(
        _mm256_max_ps(
            _mm256_max_ps(abs(ax), abs(ay)),
            _mm256_max_ps(abs(bx), abs(by)),
        ),
        _mm256_max_ps(abs(cx), abs(cy)),
    );
    let m = _mm256_max_ps(_mm256_max_ps(ma, mb), mc);
    // `shared_edge_error`, lane by lane.
    let e = _mm256_max_ps(
        _mm256_set1_ps(f32::MIN_POSITIVE),
        _mm256_mul_ps(
            _mm256_mul_ps(_mm256_set1_ps(SHARED_EDGE_ERROR), m),
            sheared_max,
        ),
    );
    let minus_e = _mm256_xor_ps(e, sign_bit);
    let gt = |x: __m256, y: __m256| _mm256_cmp_ps::<_CMP_GT_OQ>(x, y);
    let lt = |x: __m256, y: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(x, y);
    let (pu, pv, pw) = (gt(u, e), gt(v, e), gt(w, e));
    let (nu, nv, nw) = (lt(u, minus_e), lt(v, minus_e), lt(w, minus_e));
    let positive = _mm256_or_ps(_mm256_or_ps(pu, pv), pw);
    let negative = _mm256_or_ps(_mm256_or_ps(nu, nv), nw);
    let rejected = _mm256_movemask_ps(_mm256_and_ps(positive, negative)) as u32;
    let certain = _mm256_and_ps(
        _mm256_and_ps(_mm256_or_ps(pu, nu), _mm256_or_ps(pv, nv)),
        _mm256_or_ps(pw, nw),
    );
    let certain = _mm256_movemask_ps(certain) as u32;
    let uncertain = !rejected & !certain & 0xff;
    let open = !rejected & certain & 0xff;
    let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
    let (za, zb, zc) = (
        _mm256_mul_ps(sz, az),
        _mm256_mul_ps(sz, bz),
        _mm256_mul_ps(sz, cz),
    );
    let depth = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(u, za), _mm256_mul_ps(v, zb)),
        _mm256_mul_ps(w, zc),
    );
    let t = _mm256_div_ps(depth, det);
    // `Triangle::depth_error`, lane by lane.
    let spread = _mm256_add_ps(
        _mm256_add_ps(abs(_mm256_sub_ps(za, t)), abs(_mm256_sub_ps(zb, t))),
        abs(_mm256_sub_ps(zc, t)),
    );
    let amplified = _mm256_div_ps(_mm256_mul_ps(e, spread), abs(det));
    let error = _mm256_add_ps(
        _mm256_mul_ps(
            _mm256_mul_ps(_mm256_set1_ps(Triangle::NEAR_ORIGIN_ULPS * f32::EPSILON), m),
            abs(sz),
        ),
        amplified,
    );
    let near = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(abs(t), error)) as u32;
    // `Triangle::depth_is_coarse`, lane by lane.
    let coarse = _mm256_or_ps(
        gt(
            amplified,
            _mm256_mul_ps(
                _mm256_set1_ps(Triangle::COARSE_DEPTH_ULPS * f32::EPSILON),
                abs(t),
            ),
        ),
        lt(abs(depth), _mm256_set1_ps(DEPTH_FLOOR)),
    );
    let coarse = _mm256_movemask_ps(coarse) as u32 & !near;
    let tmin = rays.tmin;
    let beyond = _mm256_movemask_ps(lt(_mm256_add_ps(t, error), tmin)) as u32;
    let in_range = _mm256_and_ps(
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(t, tmin),
            _mm256_cmp_ps::<_CMP_LE_OQ>(t, tmax),
        ),
        lt(abs(t), _mm256_set1_ps(f32::INFINITY)),
    );
    let in_range = _mm256_movemask_ps(in_range) as u32;
    LaneTest {
        hit: open & !near & !coarse & in_range,
        undecided: uncertain | (open & near & !beyond) | (open & coarse),
        t,
        v,
        w,
        det,
    }
}
