//! Four triangles in structure-of-arrays form, tested against one ray at once: the leaf storage of
//! [`WideLayout`](super::WideLayout).
//!
//! The SIMD test is [`Triangle::intersect`] lane by lane, with the same IEEE operations in the same
//! order, so every lane it decides is decided with the scalar test's bits: the same hit or miss,
//! the same `t`, `u`, `v`. What it cannot decide in f32 — a ray within rounding distance of an
//! edge or a vertex, a grazing ray, a hit next to the origin of a ray that may start on the
//! surface — it leaves to the scalar test, which takes the exact (f64) path there.

// The scalar twin indexes vertices, axes and lanes with counters; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use crate::geometry::{
    shared_edge_error, PreparedRay, Triangle, TriangleHit, DEPTH_FLOOR, SHARED_EDGE_ERROR,
};

/// Four triangles, structure of arrays: `vertices[vertex][axis][lane]`, with their face ids.
/// A leaf whose count is not a multiple of 4 repeats its last triangle in the spare lanes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TrianglePacket {
    pub vertices: [[[f32; 4]; 3]; 3],
    pub ids: [u32; 4],
}

/// What [`TrianglePacket::test`] decided, lane by lane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PacketTest {
    /// Lanes certainly hit within `[tmin, tmax]`; [`PacketTest::hit`] gives each hit exactly as
    /// [`Triangle::intersect`] does.
    pub hit: u32,
    /// Lanes the f32 test cannot decide: ask [`Triangle::intersect`]. Every other lane is missed.
    pub undecided: u32,
    t: [f32; 4],
    /// The edge functions weighting `p1` and `p2`, and their sum (the determinant).
    v: [f32; 4],
    w: [f32; 4],
    det: [f32; 4],
}

impl PacketTest {
    /// The hit of lane `lane`, one of [`PacketTest::hit`]: `u = V / det`, `v = W / det` as in
    /// [`Triangle::intersect`] (divided here, for the lanes that are used, rather than for all).
    #[inline]
    pub fn hit(&self, lane: usize) -> TriangleHit {
        TriangleHit {
            t: self.t[lane],
            u: self.v[lane] / self.det[lane],
            v: self.w[lane] / self.det[lane],
        }
    }
}

impl TrianglePacket {
    /// Packs up to four triangles; spare lanes repeat the last one.
    pub fn new(triangles: &[(u32, Triangle)]) -> Self {
        assert!((1..=4).contains(&triangles.len()));
        let mut packet = Self {
            vertices: [[[0.0; 4]; 3]; 3],
            ids: [0; 4],
        };
        for lane in 0..4 {
            let (id, t) = triangles[lane.min(triangles.len() - 1)];
            for (v, p) in [t.p0, t.p1, t.p2].iter().enumerate() {
                for axis in 0..3 {
                    packet.vertices[v][axis][lane] = p[axis];
                }
            }
            packet.ids[lane] = id;
        }
        packet
    }

    pub fn triangle(&self, lane: usize) -> Triangle {
        let v = |k: usize| {
            glam::Vec3::new(
                self.vertices[k][0][lane],
                self.vertices[k][1][lane],
                self.vertices[k][2][lane],
            )
        };
        Triangle::new(v(0), v(1), v(2))
    }

    /// Whether lane `lane` repeats the previous lane's triangle (the padding of a short leaf).
    #[inline]
    pub fn repeats_previous(&self, lane: usize) -> bool {
        lane > 0 && self.ids[lane] == self.ids[lane - 1]
    }

    /// Tests the four triangles against the ray: [`Triangle::intersect`]'s f32 path, four lanes
    /// at once (SSE on x86_64, the scalar twin elsewhere).
    ///
    /// Per lane, with the sheared vertex coordinates `A, B, C` and edge functions `U, V, W` of
    /// [`Triangle::intersect`], and one error bound `e` for the three edge functions
    /// ([`crate::geometry::shared_edge_error`]: at least each edge's own bound, so every lane
    /// decided here is decided alike by [`Triangle::intersect`]):
    ///
    /// ```text
    ///   miss       if some edge function is certainly positive and another certainly negative
    ///   undecided  if some |E| ≤ e                                    (near an edge: f64 decides)
    ///   t = (U Az + V Bz + W Cz) / det,   det = U + V + W
    ///   r = 64 ε max|P − o| |Sz| + a,   a = e (|Az − t| + |Bz − t| + |Cz − t|) / |det|
    ///                                              (the error bound of `Triangle::depth_error`)
    ///   undecided  if |t| ≤ r and t + r ≥ tmin                       (next to the origin)
    ///   miss       if |t| ≤ r and t + r < tmin
    ///   undecided  if a > 256 ε |t| or |U Az + V Bz + W Cz| < 2^-100
    ///                                      (a coarse t: `Triangle::depth_is_coarse`)
    ///   hit        if tmin ≤ t ≤ tmax and t is finite, else miss
    /// ```
    #[inline]
    pub fn test(&self, ray: &PreparedRay) -> PacketTest {
        #[cfg(target_arch = "x86_64")]
        {
            self.test_sse(ray)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self.test_scalar(ray)
        }
    }

    /// The scalar definition of [`TrianglePacket::test`].
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    pub fn test_scalar(&self, ray: &PreparedRay) -> PacketTest {
        let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
        let o = ray.origin;
        let s = ray.shear;
        let mut out = PacketTest {
            hit: 0,
            undecided: 0,
            t: [0.0; 4],
            v: [0.0; 4],
            w: [0.0; 4],
            det: [0.0; 4],
        };
        for lane in 0..4 {
            // (sheared x, sheared y, depth coordinate, largest |component| of vertex - origin)
            let sheared = |v: usize| {
                let x = self.vertices[v][kx][lane] - o[kx];
                let y = self.vertices[v][ky][lane] - o[ky];
                let z = self.vertices[v][kz][lane] - o[kz];
                let m = x.abs().max(y.abs()).max(z.abs());
                (x - s.x * z, y - s.y * z, z, m)
            };
            let ((ax, ay, az, ma), (bx, by, bz, mb), (cx, cy, cz, mc)) =
                (sheared(0), sheared(1), sheared(2));
            let u = cx * by - cy * bx;
            let v = ax * cy - ay * cx;
            let w = bx * ay - by * ax;
            // SSE's `maxps`: the second operand when either is NaN.
            let max_ps = |a: f32, b: f32| if a > b { a } else { b };
            let sheared_max = max_ps(
                max_ps(max_ps(ax.abs(), ay.abs()), max_ps(bx.abs(), by.abs())),
                max_ps(cx.abs(), cy.abs()),
            );
            let m = max_ps(max_ps(ma, mb), mc);
            let e = shared_edge_error(m, sheared_max);
            let positive = u > e || v > e || w > e;
            let negative = u < -e || v < -e || w < -e;
            if positive && negative {
                continue;
            }
            let certain = u.abs() > e && v.abs() > e && w.abs() > e;
            if !certain {
                out.undecided |= 1 << lane;
                continue;
            }
            let det = u + v + w;
            let depths = [s.z * az, s.z * bz, s.z * cz];
            let depth = u * depths[0] + v * depths[1] + w * depths[2];
            let t = depth / det;
            let (error, amplified) = Triangle::depth_error(m, s.z, e, depths, t, det);
            if t.abs() > error && Triangle::depth_is_coarse(depth, amplified, t) {
                out.undecided |= 1 << lane;
                continue;
            }
            if t.abs() <= error {
                let beyond = t + error < ray.tmin;
                if !beyond {
                    out.undecided |= 1 << lane;
                }
                continue;
            }
            if t >= ray.tmin && t <= ray.tmax && t.is_finite() {
                out.hit |= 1 << lane;
                out.t[lane] = t;
                out.v[lane] = v;
                out.w[lane] = w;
                out.det[lane] = det;
            }
        }
        out
    }

    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn test_sse(&self, ray: &PreparedRay) -> PacketTest {
        use std::arch::x86_64::*;
        let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
        // SAFETY: SSE2 is part of the x86_64 baseline; each load reads one `[f32; 4]` array of
        // this 16-byte aligned packet (the unchecked axis indices are below 3: `PreparedRay`
        // sets them to a permutation of 0, 1, 2), and each store writes one `[f32; 4]`.
        unsafe {
            let [ox, oy, oz] = ray.origin_k.map(|o| _mm_set1_ps(o));
            let sx = _mm_set1_ps(ray.shear.x);
            let sy = _mm_set1_ps(ray.shear.y);
            let sz = _mm_set1_ps(ray.shear.z);
            let sign_bit = _mm_set1_ps(-0.0);
            let abs = |x: __m128| _mm_andnot_ps(sign_bit, x);
            // `kx`, `ky`, `kz` are a permutation of 0, 1, 2 (`PreparedRay`'s invariant).
            let axis = |v: usize, k: usize| self.vertices[v].get_unchecked(k).as_ptr();
            let sheared = |v: usize| {
                let x = _mm_sub_ps(_mm_load_ps(axis(v, kx)), ox);
                let y = _mm_sub_ps(_mm_load_ps(axis(v, ky)), oy);
                let z = _mm_sub_ps(_mm_load_ps(axis(v, kz)), oz);
                let m = _mm_max_ps(_mm_max_ps(abs(x), abs(y)), abs(z));
                (
                    _mm_sub_ps(x, _mm_mul_ps(sx, z)),
                    _mm_sub_ps(y, _mm_mul_ps(sy, z)),
                    z,
                    m,
                )
            };
            let ((ax, ay, az, ma), (bx, by, bz, mb), (cx, cy, cz, mc)) =
                (sheared(0), sheared(1), sheared(2));
            let u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
            let v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
            let w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
            let sheared_max = _mm_max_ps(
                _mm_max_ps(_mm_max_ps(abs(ax), abs(ay)), _mm_max_ps(abs(bx), abs(by))),
                _mm_max_ps(abs(cx), abs(cy)),
            );
            let m = _mm_max_ps(_mm_max_ps(ma, mb), mc);
            // `shared_edge_error`, lane by lane.
            let e = _mm_max_ps(
                _mm_set1_ps(f32::MIN_POSITIVE),
                _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(SHARED_EDGE_ERROR), m), sheared_max),
            );
            let minus_e = _mm_xor_ps(e, sign_bit);
            // Each edge function beyond the bound, above and below; `|E| > e` is one or the
            // other (NaN is neither, as in the scalar test).
            let (pu, pv, pw) = (_mm_cmpgt_ps(u, e), _mm_cmpgt_ps(v, e), _mm_cmpgt_ps(w, e));
            let (nu, nv, nw) = (
                _mm_cmplt_ps(u, minus_e),
                _mm_cmplt_ps(v, minus_e),
                _mm_cmplt_ps(w, minus_e),
            );
            let positive = _mm_or_ps(_mm_or_ps(pu, pv), pw);
            let negative = _mm_or_ps(_mm_or_ps(nu, nv), nw);
            let rejected = _mm_movemask_ps(_mm_and_ps(positive, negative)) as u32;
            let certain = _mm_and_ps(
                _mm_and_ps(_mm_or_ps(pu, nu), _mm_or_ps(pv, nv)),
                _mm_or_ps(pw, nw),
            );
            let certain = _mm_movemask_ps(certain) as u32;
            let uncertain = !rejected & !certain & 0xf;
            let open = !rejected & certain & 0xf;
            // The distances are computed whether or not a lane is open: an early return when
            // none is (42% of the teapot's packets) was a branch the predictor missed every
            // other time, and cost more than the 25 instructions it saved (teapot +15%).
            // Lanes that are not open may divide by a zero `det`; their bits are masked out.
            let det = _mm_add_ps(_mm_add_ps(u, v), w);
            let (za, zb, zc) = (_mm_mul_ps(sz, az), _mm_mul_ps(sz, bz), _mm_mul_ps(sz, cz));
            let depth = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(u, za), _mm_mul_ps(v, zb)),
                _mm_mul_ps(w, zc),
            );
            let t = _mm_div_ps(depth, det);
            // `Triangle::depth_error`, lane by lane.
            let spread = _mm_add_ps(
                _mm_add_ps(abs(_mm_sub_ps(za, t)), abs(_mm_sub_ps(zb, t))),
                abs(_mm_sub_ps(zc, t)),
            );
            let amplified = _mm_div_ps(_mm_mul_ps(e, spread), abs(det));
            let error = _mm_add_ps(
                _mm_mul_ps(
                    _mm_mul_ps(_mm_set1_ps(Triangle::NEAR_ORIGIN_ULPS * f32::EPSILON), m),
                    abs(sz),
                ),
                amplified,
            );
            let near = _mm_movemask_ps(_mm_cmple_ps(abs(t), error)) as u32;
            // `Triangle::depth_is_coarse`, lane by lane.
            let coarse = _mm_or_ps(
                _mm_cmpgt_ps(
                    amplified,
                    _mm_mul_ps(
                        _mm_set1_ps(Triangle::COARSE_DEPTH_ULPS * f32::EPSILON),
                        abs(t),
                    ),
                ),
                _mm_cmplt_ps(abs(depth), _mm_set1_ps(DEPTH_FLOOR)),
            );
            let coarse = _mm_movemask_ps(coarse) as u32 & !near;
            let tmin = _mm_set1_ps(ray.tmin);
            let beyond = _mm_movemask_ps(_mm_cmplt_ps(_mm_add_ps(t, error), tmin)) as u32;
            let in_range = _mm_and_ps(
                _mm_and_ps(
                    _mm_cmpge_ps(t, tmin),
                    _mm_cmple_ps(t, _mm_set1_ps(ray.tmax)),
                ),
                _mm_cmplt_ps(abs(t), _mm_set1_ps(f32::INFINITY)),
            );
            let in_range = _mm_movemask_ps(in_range) as u32;
            let mut out = PacketTest {
                hit: open & !near & !coarse & in_range,
                undecided: uncertain | (open & near & !beyond) | (open & coarse),
                t: [0.0; 4],
                v: [0.0; 4],
                w: [0.0; 4],
                det: [0.0; 4],
            };
            _mm_storeu_ps(out.t.as_mut_ptr(), t);
            _mm_storeu_ps(out.v.as_mut_ptr(), v);
            _mm_storeu_ps(out.w.as_mut_ptr(), w);
            _mm_storeu_ps(out.det.as_mut_ptr(), det);
            out
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::box_kernels::tests::ray_strategy;
    use super::*;
    use crate::geometry::Ray;
    use glam::Vec3;
    use proptest::prelude::*;

    /// Each lane's verdict against [`Triangle::intersect`], and the SIMD test against its twin.
    fn check(packet: &TrianglePacket, ray: &Ray) -> Result<(), TestCaseError> {
        let prepared = PreparedRay::new(ray);
        let scalar = packet.test_scalar(&prepared);
        let simd = packet.test(&prepared);
        prop_assert_eq!(simd.hit, scalar.hit);
        prop_assert_eq!(simd.undecided, scalar.undecided);
        for lane in 0..4 {
            let exact = packet.triangle(lane).intersect(&prepared);
            if scalar.hit >> lane & 1 == 1 {
                prop_assert_eq!(Some(scalar.hit(lane)), exact, "lane {}", lane);
                prop_assert_eq!(simd.hit(lane), scalar.hit(lane), "lane {}", lane);
            } else if scalar.undecided >> lane & 1 == 0 {
                prop_assert_eq!(exact, None, "lane {} decided miss", lane);
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(3000))]

        #[test]
        fn packet_test_decides_as_the_scalar_test(ray in ray_strategy(), pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, prop_oneof![Just(0.0f32), -2.0f32..2.0]), 12)) {
            let tris: Vec<(u32, Triangle)> = pts.chunks(3).enumerate().map(|(i, p)| {
                let v = |k: usize| Vec3::new(p[k].0, p[k].1, p[k].2);
                (i as u32, Triangle::new(v(0), v(1), v(2)))
            }).collect();
            check(&TrianglePacket::new(&tris), &ray)?;
        }

        /// The same at every scale, from coordinates near the smallest normal float (where
        /// products underflow) to near the largest (where shears overflow), with rays aimed at
        /// a vertex or an edge of one of the triangles, which share vertices. (It catches a
        /// bound made too small; the bound's floor at `2^-126` is not needed by any case it
        /// makes, since there the per-edge bounds underflow too: the floor is the proof's.)
        #[test]
        fn packet_test_at_extreme_scales(
            scale in prop_oneof![Just(1e-38f32), Just(1e-30), Just(1e-19), Just(1.0), Just(1e19), Just(1e30), Just(1e37)],
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 5),
            origin in (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0),
            (which, a) in (0usize..3, prop_oneof![Just(0.0f32), Just(0.5), 0.0f32..1.0]),
        ) {
            let v = |p: (f32, f32, f32)| Vec3::new(p.0, p.1, p.2) * scale;
            // Four triangles in a fan around pts[0], neighbours sharing an edge.
            let tris: Vec<(u32, Triangle)> = (0..4)
                .map(|i| (i as u32, Triangle::new(v(pts[0]), v(pts[1 + i]), v(pts[1 + (i + 1) % 4]))))
                .collect();
            let t = tris[0].1;
            let corners = [t.p0, t.p1, t.p2];
            let target = corners[which] + a * (corners[(which + 1) % 3] - corners[which]);
            let origin = v(origin);
            prop_assume!(target != origin && (target - origin).is_finite());
            check(&TrianglePacket::new(&tris), &Ray::new(origin, target - origin))?;
        }

        /// Intervals that begin or end exactly at a lane's hit distance, or one ulp to either
        /// side: both ends are inclusive, in the packet as in the scalar test. (Random
        /// intervals almost never end on a hit, so `t >= tmin` written as `t > tmin` passed
        /// the other tests.)
        #[test]
        fn packet_test_at_the_ends_of_the_interval(
            ray in ray_strategy(),
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 12),
        ) {
            let tris: Vec<(u32, Triangle)> = pts.chunks(3).enumerate().map(|(i, p)| {
                let v = |k: usize| Vec3::new(p[k].0, p[k].1, p[k].2);
                (i as u32, Triangle::new(v(0), v(1), v(2)))
            }).collect();
            let packet = TrianglePacket::new(&tris);
            let open = Ray { tmin: 0.0, tmax: f32::INFINITY, ..ray };
            let found = packet.test_scalar(&PreparedRay::new(&open));
            for lane in super::super::lanes::Lanes(found.hit) {
                let t = found.hit(lane).t;
                prop_assume!(t > 0.0 && t.is_finite());
                let below = f32::from_bits(t.to_bits() - 1);
                let above = f32::from_bits(t.to_bits() + 1);
                for (tmin, tmax) in [(t, f32::INFINITY), (0.0, t), (t, t), (below, t), (t, above), (above, f32::INFINITY), (0.0, below)] {
                    let bounded = Ray { tmin, tmax, ..open };
                    check(&packet, &bounded)?;
                    // The lane is hit exactly when its t lies in [tmin, tmax].
                    let test = packet.test(&PreparedRay::new(&bounded));
                    if test.undecided >> lane & 1 == 0 {
                        prop_assert_eq!(test.hit >> lane & 1 == 1, tmin <= t && t <= tmax, "lane {} in [{}, {}]", lane, tmin, tmax);
                    }
                }
            }
        }

        /// Rays leaving a point on one of the triangles, with and without an offset `tmin`:
        /// the near-origin rule.
        #[test]
        fn packet_test_on_rays_leaving_the_surface(
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 12),
            (a, b) in (0.0f32..1.0, 0.0f32..1.0),
            d in (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
            tmin in prop_oneof![Just(0.0f32), Just(1e-6), Just(1e-4), Just(1e-2)],
        ) {
            let tris: Vec<(u32, Triangle)> = pts.chunks(3).enumerate().map(|(i, p)| {
                let v = |k: usize| Vec3::new(p[k].0, p[k].1, p[k].2);
                (i as u32, Triangle::new(v(0), v(1), v(2)))
            }).collect();
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let t = tris[1].1;
            let origin = t.p0 + a * (t.p1 - t.p0) + b * (t.p2 - t.p0);
            let direction = Vec3::new(d.0, d.1, d.2);
            prop_assume!(direction.abs().max_element() > 1e-3);
            check(&TrianglePacket::new(&tris), &Ray::new(origin, direction).with_interval(tmin, f32::INFINITY))?;
        }
    }
}
