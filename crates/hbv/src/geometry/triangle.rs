use glam::{DVec3, Vec3};

use super::exact_sign;
use super::{Aabb, EdgeRule, PreparedRay};

/// A triangle by its three vertices, in the order of the mesh file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub p0: Vec3,
    pub p1: Vec3,
    pub p2: Vec3,
}

/// Where a ray meets a triangle: `point = o + t d = (1-u-v) p0 + u p1 + v p2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

impl Triangle {
    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Self {
        Self { p0, p1, p2 }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.p0.min(self.p1).min(self.p2),
            self.p0.max(self.p1).max(self.p2),
        )
    }

    pub fn centroid(&self) -> Vec3 {
        (self.p0 + self.p1 + self.p2) / 3.0
    }

    /// Twice the area's vector, `(p1 - p0) × (p2 - p0)`, in f64.
    pub fn scaled_normal(&self) -> DVec3 {
        let e1 = self.p1.as_dvec3() - self.p0.as_dvec3();
        let e2 = self.p2.as_dvec3() - self.p0.as_dvec3();
        e1.cross(e2)
    }

    /// Whether the triangle has zero area: its vertices are coincident or collinear.
    ///
    /// The edge vectors of f32 vertices are exact in f64 (for vertices within 2^29 of each other
    /// in magnitude), and two products of equal real value round to the same f64, so an exactly
    /// collinear triangle gives an exactly zero cross product. Such triangles are never hit: the
    /// intersection test's determinant could be a rounding residue instead of zero.
    pub fn is_degenerate(&self) -> bool {
        self.scaled_normal() == DVec3::ZERO
    }

    /// Watertight ray/triangle intersection (Woop, Benthin & Wald 2013, "Watertight Ray/Triangle
    /// Intersection", JCGT 2(1)), two-sided, over the closed interval `[ray.tmin, ray.tmax]`.
    ///
    /// The vertices are translated to the ray origin and sheared so that the ray becomes the +z
    /// axis of a frame whose z is its dominant axis: for each vertex `P' = P - o`,
    ///
    /// ```text
    ///   Px = P'[kx] - Sx P'[kz]      Py = P'[ky] - Sy P'[kz]      Pz = Sz P'[kz]
    /// ```
    ///
    /// and the 2D edge functions of the projected triangle at the origin are
    ///
    /// ```text
    ///   U = Cx By - Cy Bx   (weight of p0)      A = p0', B = p1', C = p2'
    ///   V = Ax Cy - Ay Cx   (weight of p1)
    ///   W = Bx Ay - By Ax   (weight of p2)
    /// ```
    ///
    /// The ray meets the triangle when U, V, W share a sign (zeros allowed: edges and vertices
    /// count), at `t = (U Az + V Bz + W Cz) / det` with `u = V / det`, `v = W / det`
    /// (`det = U + V + W`), where `Az = Sz P'[kz]` for each vertex.
    ///
    /// Two refinements of that `t`, from its error bound (`depth_error`):
    ///
    /// - within its bound of the origin (a ray starting on the surface), its sign is rounding
    ///   noise, so `t` is recomputed from the plane equation with the exact sign (see
    ///   `plane_distance`);
    /// - where the bound's edge part, which the quotient amplifies on slivers and huge triangles
    ///   seen at a slant, exceeds 256 ulps of `t` (`COARSE_DEPTH_ULPS`), or where the
    ///   depth products fall below f32's normal range (a direction of length 1e30 on a small
    ///   triangle), the f32 `t` may be off by far more than an ulp (1e-3 relative on a triangle
    ///   1e-5 wide), so the triangle is decided in f64 (`intersect_near_edge`: its `t` and
    ///   barycentrics are within an ulp or so).
    ///
    /// Elsewhere the sheared-frame `t` is kept, within a few ulps of the exact one.
    ///
    /// Why it is watertight, and exact: the f32 edge functions come with an error bound per edge
    /// (`edge_error`); where an edge function exceeds its bound its sign is certain (the sign of
    /// the exactly sheared geometry). Only when some edge function is within its bound of zero —
    /// a ray within rounding distance of an edge or vertex, or a grazing ray — is the triangle
    /// decided in f64 (`intersect_near_edge`), and an edge whose f64 function is within its own
    /// bound of zero by exact arithmetic. Which precision decides an edge depends only on
    /// that edge, and each vertex is transformed by the same operations whichever triangle it
    /// belongs to, so both triangles of a shared edge decide it alike: no ray slips between
    /// them, and none is lost at a silhouette to rounding. Every edge sign is therefore the
    /// exact one; a ray through an edge's line exactly (a zero edge function) is decided by
    /// the [`EdgeRule`]: here [`EdgeRule::Closed`], so a touch is a hit.
    #[inline]
    pub fn intersect(&self, ray: &PreparedRay) -> Option<TriangleHit> {
        self.intersect_by(ray, EdgeRule::Closed)
    }

    /// [`Triangle::intersect`] with the given rule for a ray that passes exactly through an edge
    /// or a vertex: [`EdgeRule::Closed`] (every triangle having the edge or vertex is hit: the
    /// closest- and any-hit queries) or [`EdgeRule::HalfOpen`] (exactly one crossing where a
    /// surface is crossed: counts and inside tests). Either rule changes only the rays whose
    /// edge functions are exactly zero, decided on the rare near-edge path.
    #[inline(always)]
    pub fn intersect_by(&self, ray: &PreparedRay, rule: EdgeRule) -> Option<TriangleHit> {
        let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
        let s = ray.shear;
        let a = self.p0 - ray.origin;
        let b = self.p1 - ray.origin;
        let c = self.p2 - ray.origin;

        let ax = a[kx] - s.x * a[kz];
        let ay = a[ky] - s.y * a[kz];
        let bx = b[kx] - s.x * b[kz];
        let by = b[ky] - s.y * b[kz];
        let cx = c[kx] - s.x * c[kz];
        let cy = c[ky] - s.y * c[kz];

        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;

        // Each edge function's f32 sign is certain when it exceeds its error bound; the bound
        // of an edge depends only on that edge's two vertices (see `edge_error`).
        let (ma, mb, mc) = (
            a.abs().max_element(),
            b.abs().max_element(),
            c.abs().max_element(),
        );
        let eu = edge_error(mb.max(mc), bx, by, cx, cy);
        let ev = edge_error(mc.max(ma), cx, cy, ax, ay);
        let ew = edge_error(ma.max(mb), ax, ay, bx, by);
        let positive = u > eu || v > ev || w > ew;
        let negative = u < -eu || v < -ev || w < -ew;
        if positive && negative {
            return None;
        }
        let certain = u.abs() > eu && v.abs() > ev && w.abs() > ew;
        if !certain {
            // Near an edge or a vertex (or a grazing ray): decide in f64.
            return self.intersect_near_edge(ray, [u, v, w], [eu, ev, ew], rule);
        }
        // All three certain and of one sign: the determinant is their sum, never zero.
        let det = u + v + w;

        let az = s.z * a[kz];
        let bz = s.z * b[kz];
        let cz = s.z * c[kz];
        let depth = u * az + v * bz + w * cz;
        let mut t = depth / det;
        let (error, amplified) = Self::depth_error(
            ma.max(mb).max(mc),
            s.z,
            eu.max(ev).max(ew),
            [az, bz, cz],
            t,
            det,
        );
        if t.abs() > error && Self::depth_is_coarse(depth, amplified, t) {
            // A sliver (or a depth below f32's normal range): f64 decides, with the signs found
            // certain here.
            return self.intersect_near_edge(ray, [u, v, w], [eu, ev, ew], rule);
        }
        if t.abs() <= error {
            // The hit is within its error bound of the origin, so the sign of `t` is rounding
            // noise: whether it lies before or after `tmin` is decided by the exact plane
            // distance, not by rounding — unless `tmin` lies beyond all the exact `t` can be.
            // (Which `t` is reported depends on the ray and the triangle, not on the interval:
            // a segment ending at a reported hit finds it.)
            if t + error < ray.tmin {
                return None;
            }
            t = self.plane_distance(ray);
        }
        Self::accept(ray, t, v / det, w / det)
    }

    /// A bound on the error of the f32 `t = (U Az + V Bz + W Cz) / det` of
    /// [`Triangle::intersect`], for a hit whose edge functions are each certain and of one sign:
    ///
    /// ```text
    ///   |t − t*| ≤ 64 ε M |Sz|  +  e (|Az − t| + |Bz − t| + |Cz − t|) / |det|
    /// ```
    ///
    /// (`M` the largest |component| of a vertex relative to the origin, `e` a bound on every edge
    /// function's error, `ε = 2^-23`.) `t` is a weighted mean of the depths `Z`, with weights
    /// `U, V, W / det`; moving an edge function by `δ` moves it by `δ (Z − t) / det`. The first
    /// term covers the rounding of the depths, products and quotient (a few ulps of `M |Sz|`,
    /// with a wide margin); the second the edge functions' own error, which the quotient
    /// amplifies where `det` is small against them: a huge or sliver triangle seen at a slant.
    /// (Before this second term, the test took `64 ε M |Sz|` for the whole error: a ray
    /// leaving a surface beside a 1,500-long sliver met it at `t = 0.035` where the exact
    /// plane distance was `−0.00014`.)
    ///
    /// Returns the bound and its second term (the amplified edge error, which
    /// [`Triangle::depth_is_coarse`] weighs).
    ///
    /// The wide layouts' packet test computes the same bound with its shared `e`, never
    /// smaller, in the same order: what it decides against the interval, this test decides
    /// alike.
    #[inline(always)]
    pub(crate) fn depth_error(
        max_component: f32,
        shear_z: f32,
        edge_error: f32,
        depths: [f32; 3],
        t: f32,
        det: f32,
    ) -> (f32, f32) {
        let [az, bz, cz] = depths;
        let spread = ((az - t).abs() + (bz - t).abs()) + (cz - t).abs();
        let amplified = edge_error * spread / det.abs();
        (
            Self::NEAR_ORIGIN_ULPS * f32::EPSILON * max_component * shear_z.abs() + amplified,
            amplified,
        )
    }

    /// Whether the f32 `t` of [`Triangle::intersect`] (from `depth = U Az + V Bz + W Cz`, with
    /// [`Triangle::depth_error`]'s amplified edge error `amplified`) is too coarse to report:
    ///
    /// ```text
    ///   amplified > COARSE_DEPTH_ULPS · ε · |t|     or     |depth| < 2^-100
    /// ```
    ///
    /// The first is a sliver or a huge triangle seen at a slant, where `det` is small against
    /// the edge functions' error. On ordinary triangles that term is 8 to 64 `ε |t|` (a bound:
    /// the error itself is 1 to 3 ulps). Measured over the hits of random rays on the six
    /// meshes of `../shared/scenes` (scans and models, 36 to 871,414 triangles; BENCHMARKS.md):
    /// below 256 the error stays within about 10 ulps; 0.2–0.7 % of hits lie
    /// above, and their error grows with the term (1e-3 relative on a triangle 1e-5 wide). The
    /// second is a depth whose products may have left f32's normal range and lost their
    /// precision (each product's absolute error is then up to 2^-150, which `det` may
    /// amplify); above 2^-100 that is below 2^-48 of `t`. A NaN (an overflow) is neither: such
    /// a `t` is no hit.
    #[inline(always)]
    pub(crate) fn depth_is_coarse(depth: f32, amplified: f32, t: f32) -> bool {
        amplified > Self::COARSE_DEPTH_ULPS * f32::EPSILON * t.abs() || depth.abs() < DEPTH_FLOOR
    }

    /// The largest amplified edge error, in `ε |t|`, at which [`Triangle::intersect`] keeps its
    /// f32 `t` ([`Triangle::depth_is_coarse`]).
    pub(crate) const COARSE_DEPTH_ULPS: f32 = 256.0;

    /// A hit at `t` with barycentrics `(u, v)` if `t` is finite and inside `[tmin, tmax]`.
    #[inline]
    fn accept(ray: &PreparedRay, t: f32, u: f32, v: f32) -> Option<TriangleHit> {
        // NaN fails both comparisons; an infinite `t` (overflow, or a direction parallel to the
        // plane to f64 precision) is no hit.
        (t >= ray.tmin && t <= ray.tmax && t.is_finite()).then_some(TriangleHit { t, u, v })
    }

    /// The test of [`Triangle::intersect`] for the rare case where some f32 edge function is
    /// within its error bound of zero: the ray passes within rounding distance of an edge or a
    /// vertex, or grazes the triangle.
    ///
    /// The three edge functions are recomputed in f64 from the exact vertex differences and an
    /// f64 shear (error about 1e-16 instead of 1e-7: a grazing ray that passes a hair inside a
    /// thin projected triangle is found). Each edge keeps its f32 sign where that was certain,
    /// takes the f64 sign where that is certain (beyond its own bound, [`edge_error_f64`]), and
    /// otherwise its exact sign ([`Triangle::exact_edge_sign`]): whether an edge's sign comes
    /// from f32, f64 or exact arithmetic depends only on that edge, and the edge functions of
    /// a shared edge are exact negatives in each, so the two triangles of every edge decide it
    /// alike — watertight. An edge function that is exactly zero (the ray passes through the
    /// edge's line) counts as the `rule` says. The hit's `t` is the plane's
    /// ([`Triangle::plane_distance`]: to an ulp, exactly where f64 is not enough).
    #[cold]
    fn intersect_near_edge(
        &self,
        ray: &PreparedRay,
        f32_edges: [f32; 3],
        bounds: [f32; 3],
        rule: EdgeRule,
    ) -> Option<TriangleHit> {
        let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
        let d = ray.direction.as_dvec3();
        let (sx, sy) = (d[kx] / d[kz], d[ky] / d[kz]);
        let o = ray.origin.as_dvec3();
        let (a, b, c) = (
            self.p0.as_dvec3() - o,
            self.p1.as_dvec3() - o,
            self.p2.as_dvec3() - o,
        );
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let mut exact = [cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax];
        let (ma, mb, mc) = (
            a.abs().max_element(),
            b.abs().max_element(),
            c.abs().max_element(),
        );
        let f64_bounds = [
            edge_error_f64(mb.max(mc), bx, by, cx, cy),
            edge_error_f64(mc.max(ma), cx, cy, ax, ay),
            edge_error_f64(ma.max(mb), ax, ay, bx, by),
        ];
        // Edge k runs from vertex `first[k]` to `second[k]` (`U` is the edge p1 → p2, and so on).
        let (first, second) = ([1, 2, 0], [2, 0, 1]);
        let points = [self.p0, self.p1, self.p2];
        let sheared = [(ax, ay), (bx, by), (cx, cy)];
        // Whether the f64 sheared coordinates are the exactly sheared ones (found on first need).
        let mut shears_exactly = None;

        let mut sign = |k: usize| -> i8 {
            let (f, e) = (f32_edges[k], bounds[k]);
            if f > e {
                return 1;
            } else if f < -e {
                return -1;
            }
            let value = exact[k];
            if value.abs() > f64_bounds[k] {
                return if value > 0.0 { 1 } else { -1 };
            }
            let f64_sign = (value > 0.0) as i8 - (value < 0.0) as i8;
            let (p, q) = (points[first[k]], points[second[k]]);
            let exact_sign =
                if *shears_exactly.get_or_insert_with(|| self.shears_exactly(ray, [sx, sy])) {
                    // `E = Qx Py − Qy Px` of exact coordinates: two products, summed exactly.
                    let ((px, py), (qx, qy)) = (sheared[first[k]], sheared[second[k]]);
                    exact_sign::difference_of_products_sign(qx, py, qy, px)
                } else {
                    Self::exact_edge_sign(ray, p, q)
                };
            // (`None`: a coordinate is not finite after all; the f64 sign is all there is.)
            match exact_sign {
                Some(0) => {
                    exact[k] = 0.0;
                    match rule {
                        EdgeRule::Closed => 0,
                        EdgeRule::HalfOpen => Self::moved_edge_sign(ray, p, q).unwrap_or(0),
                    }
                }
                Some(sign) => sign,
                None => f64_sign,
            }
        };
        let signs = [sign(0), sign(1), sign(2)];
        if signs.contains(&1) && signs.contains(&-1) {
            return None;
        }
        let [u, v, w] = exact;
        let det = u + v + w;
        if det == 0.0 || self.parallel_to(ray) {
            // The ray is parallel to the triangle's plane. (Where it lies in the plane every
            // edge function is exactly 0, and the f64 ones are rounding noise whose signs may
            // agree: the exact test, not `det`, says so. Before it, a ray in the plane of a
            // slanted triangle was a hit at a `t` made of noise.)
            return None;
        }
        // The edges are decided; `t` is the plane's, to an ulp (the sheared frame's f64 `t`,
        // a weighted mean of the vertices' depths, loses to their cancellation what
        // `plane_distance` keeps).
        let t = self.plane_distance(ray);
        Self::accept(ray, t, (v / det) as f32, (w / det) as f32)
    }
}

impl Triangle {
    /// The exact sign of the edge function of the edge `p → q` (`E = Qx Py − Qy Px` in the ray's
    /// exactly sheared frame; `U` of [`Triangle::intersect`] is the edge p1 → p2). `None` if a
    /// coordinate is not finite.
    ///
    /// In the frame's axes (`kx`, `ky`, `kz`, and `P' = P − o`) the edge function is a
    /// determinant over the direction's dominant component,
    ///
    /// ```text
    ///   E = det[Q', P', d] / d_kz
    /// ```
    ///
    /// (the sheared points are `P' − (P'_kz / d_kz) d`, and subtracting multiples of `d` from
    /// the rows does not change the determinant), evaluated exactly (`exact_sign`).
    fn exact_edge_sign(ray: &PreparedRay, p: Vec3, q: Vec3) -> Option<i8> {
        let (o, d, p, q) = Self::in_frame(ray, [ray.origin, ray.direction, p, q]);
        Some(exact_sign::orientation_sign(o, q, p, d)? * Self::towards_z(d))
    }

    /// Whether the f64 sheared coordinates of [`Triangle::intersect_near_edge`] are exact: the
    /// vertex differences `P' = P − o`, the shear constants `Sx = d_kx / d_kz`, `Sy`, and
    /// `P'_kx − Sx P'_kz`, `P'_ky − Sy P'_kz` each without rounding (checked by computing every
    /// rounding error). True for axis-aligned rays (`Sx = Sy = 0`) and others of dyadic slopes
    /// over coordinates of few significant bits: the usual source of rays exactly through an
    /// edge, whose edge functions are then two products summed exactly.
    fn shears_exactly(&self, ray: &PreparedRay, shear: [f64; 2]) -> bool {
        let (kx, ky, kz) = (ray.kx, ray.ky, ray.kz);
        let (o, d) = (ray.origin.as_dvec3(), ray.direction.as_dvec3());
        let [sx, sy] = shear;
        let exact_slope = |s: f64, k: usize| exact_sign::product_is(s, d[kz], d[k]);
        exact_slope(sx, kx)
            && exact_slope(sy, ky)
            && [self.p0, self.p1, self.p2].iter().all(|p| {
                let p = p.as_dvec3();
                let difference = |k: usize| exact_sign::sum_is_exact(p[k], -o[k]);
                let (x, y, z) = (p[kx] - o[kx], p[ky] - o[ky], p[kz] - o[kz]);
                // A slope of 0 (an axis-aligned ray, or one in an axis plane) shears nothing.
                let sheared = |along: f64, s: f64| {
                    s == 0.0
                        || (exact_sign::product_is(s, z, s * z)
                            && exact_sign::sum_is_exact(along, -(s * z)))
                };
                difference(kx)
                    && difference(ky)
                    && difference(kz)
                    && sheared(x, sx)
                    && sheared(y, sy)
            })
    }

    /// The sign [`EdgeRule::HalfOpen`] gives an edge function that is exactly zero (the ray
    /// passes through the edge's line): the sign `E` takes when the ray is moved by an
    /// infinitesimal `ε` along the frame's x axis, or failing that (an edge parallel to x)
    /// `ε²` along y (Edelsbrunner & Mücke's simulation of simplicity, 1990). Moving the ray
    /// to `(ε, ε²)` gives `E + ε ∂E/∂x + ε² ∂E/∂y`, with `∂E/∂x = Qy − Py` and
    /// `∂E/∂y = Px − Qx`. Both are zero only for an edge parallel to the ray, whose triangle is
    /// parallel to the ray and missed anyway.
    ///
    /// Every triangle a ray meets sees the same moved ray, a ray in general position: of two
    /// triangles sharing an edge the ray crosses, exactly one is hit; of a fan around a vertex
    /// where the ray crosses the surface, exactly one; where it only touches the surface,
    /// none or two.
    fn moved_edge_sign(ray: &PreparedRay, p: Vec3, q: Vec3) -> Option<i8> {
        let (_, d, p, q) = Self::in_frame(ray, [ray.origin, ray.direction, p, q]);
        // `(Qy − Py) d_z = (q_y − p_y) d_z − d_y (q_z − p_z)`: the origin cancels; and
        // `(Px − Qx) d_z` alike on x.
        let along_x = exact_sign::cross_sign(p, q, d, 1, 2)?;
        let sign = if along_x != 0 {
            along_x
        } else {
            exact_sign::cross_sign(q, p, d, 0, 2)?
        };
        Some(sign * Self::towards_z(d))
    }

    /// Points and vectors in the ray's frame axes: `(v_kx, v_ky, v_kz)`.
    fn in_frame(ray: &PreparedRay, vectors: [Vec3; 4]) -> (Vec3, Vec3, Vec3, Vec3) {
        let [a, b, c, d] = vectors.map(|v| Vec3::new(v[ray.kx], v[ray.ky], v[ray.kz]));
        (a, b, c, d)
    }

    /// The sign of the direction's dominant component (never zero for a valid ray).
    fn towards_z(direction_in_frame: Vec3) -> i8 {
        if direction_in_frame.z > 0.0 {
            1
        } else {
            -1
        }
    }

    /// Whether the ray's direction is exactly parallel to the triangle's plane:
    /// `Ng · d = det[p1 − p0, p2 − p0, d] = 0`, by Shewchuk's adaptive `orient3d` on the exact
    /// f64 edge vectors (an f32 difference is exact in f64), exact in sign.
    #[inline]
    fn parallel_to(&self, ray: &PreparedRay) -> bool {
        let coord = |p: glam::DVec3| robust::Coord3D {
            x: p.x,
            y: p.y,
            z: p.z,
        };
        let (p0, p1, p2) = (self.p0.as_dvec3(), self.p1.as_dvec3(), self.p2.as_dvec3());
        robust::orient3d(
            coord(p1 - p0),
            coord(p2 - p0),
            coord(ray.direction.as_dvec3()),
            coord(glam::DVec3::ZERO),
        ) == 0.0
    }

    /// The rounding part of [`Triangle::depth_error`], in ulps of the vertices' coordinates
    /// relative to the origin (scaled by the shear): Woop's `t` rounds by a few of them (the
    /// shear and the depth products); 64 leaves a wide margin.
    pub(crate) const NEAR_ORIGIN_ULPS: f32 = 64.0;

    /// The ray parameter where the ray meets the triangle's plane, `t = Ng · (p0 − o) / Ng · d`
    /// with `Ng = (p1 − p0) × (p2 − p0)`: within an ulp of the exact value, with its exact
    /// sign, and exactly 0 for an origin on the plane.
    ///
    /// Used where Woop's sheared-frame `t` is not good enough: for hits next to the ray's
    /// origin (whose sheared `t` rounds the exact `t = 0` of an origin on the surface to a tiny
    /// value of either sign), and for every hit decided in f64 (`intersect_near_edge`: near
    /// edges, slivers, huge triangles at a slant), where the sheared frame's f64 `t` was still
    /// 0.4 % off on a sliver of aspect 10⁷ hit at a grazing angle next to the origin (a new
    /// user's sweep).
    ///
    /// First in f64, from the exact vertex differences, with the error bound of each dot
    /// product (`7 ε₆₄` times the sum of its terms' magnitudes, the cross product's included:
    /// each product and sum rounds once, the differences at most once). Where either bound
    /// exceeds `2^23` times its value (so that `t` might be off by more than `2^-25` of
    /// itself, a quarter of an f32 ulp), that one is evaluated more exactly instead
    /// (`exact_sign::plane_numerator`: double-f64, else exact; `plane_denominator`: exact;
    /// Shewchuk's expansions, "Adaptive Precision Floating-Point Arithmetic and Fast Robust
    /// Geometric Predicates", 1997). That happens where the origin is on or within about
    /// `10⁻⁷` relative of the plane, or the ray or the
    /// edges are as close to parallel: the quotient then carries the exact values' signs, and
    /// a 0 is a 0. (Before, the numerator's sign came from `robust::orient3d`, exact, but its
    /// value only to within its own error bound.)
    #[inline]
    fn plane_distance(&self, ray: &PreparedRay) -> f32 {
        let (p0, p1, p2) = (self.p0.as_dvec3(), self.p1.as_dvec3(), self.p2.as_dvec3());
        let (o, d) = (ray.origin.as_dvec3(), ray.direction.as_dvec3());
        let (e1, e2, w) = (p1 - p0, p2 - p0, p0 - o);
        let normal = e1.cross(e2);
        // The magnitudes of the cross product's terms, |e1_y e2_z| + |e1_z e2_y|, ...
        let (a1, a2) = (e1.abs(), e2.abs());
        let terms = DVec3::new(
            a1.y * a2.z + a1.z * a2.y,
            a1.z * a2.x + a1.x * a2.z,
            a1.x * a2.y + a1.y * a2.x,
        );
        let (mut numerator, mut denominator) = (normal.dot(w), normal.dot(d));
        let conditioned = |value: f64, bound: f64| value.abs() * WELL_CONDITIONED >= bound;
        let points = [self.p0, self.p1, self.p2];
        if !conditioned(numerator, terms.dot(w.abs())) {
            match exact_sign::plane_numerator(points, ray.origin) {
                Some(exact) => numerator = exact,
                None => return f32::NAN,
            }
        }
        if numerator == 0.0 {
            return 0.0;
        }
        if !conditioned(denominator, terms.dot(d.abs())) {
            match exact_sign::plane_denominator(points, ray.direction) {
                Some(exact) => denominator = exact,
                None => return f32::NAN,
            }
        }
        let quotient = numerator / denominator;
        let t = quotient as f32;
        if t == 0.0 && quotient != 0.0 {
            // Below f32's range: the nearest nonzero f32 of the quotient's sign, since ahead of
            // the origin is not behind it (`-0.0` would pass `t >= 0`).
            return f32::from_bits(1).copysign(t);
        }
        t
    }
}

/// The error bound of an f32 edge function of [`Triangle::intersect`] for the edge `(p, q)`:
///
/// ```text
///   |fl(E) − E| ≤ 8 ε · max(‖p − o‖∞, ‖q − o‖∞) · (|px| + |py| + |qx| + |qy|)
/// ```
///
/// where `E = qx py − qy px` is the edge function of the exactly sheared coordinates and `ε` the
/// f32 epsilon (2^-23). Each sheared coordinate carries an absolute error of at most about
/// `5 ε M / 2` (the vertex difference, the shear constant, the product and the subtraction each
/// round once; `|S| ≤ 1` on the dominant axis), which the products multiply by the other
/// coordinates; their own rounding adds at most `3 ε M (…) / 2`. The factor 8 leaves a margin of
/// about 2 over that sum. The bound depends only on the edge's two vertices, so both triangles
/// of a shared edge agree on whether its f32 sign is certain. The wide layouts' packet test
/// (`bvh/layout/wide/triangle_packet.rs`) uses one larger bound for all three edges,
/// [`shared_edge_error`]: what it finds certain, this bound finds certain too.
#[inline]
fn edge_error(max_component: f32, px: f32, py: f32, qx: f32, qy: f32) -> f32 {
    (EDGE_ERROR * max_component) * (((px.abs() + py.abs()) + qx.abs()) + qy.abs())
}

/// [`edge_error`] for the f64 edge functions of [`Triangle::intersect_near_edge`]: the same
/// analysis with f64's `ε = 2^-52` (the vertex differences, the shear constants, the products and
/// the subtraction each round once), and a margin of 4 instead of 2. Every value here comes from
/// f32 coordinates, so no product underflows.
fn edge_error_f64(max_component: f64, px: f64, py: f64, qx: f64, qy: f64) -> f64 {
    16.0 * f64::EPSILON * max_component * (px.abs() + py.abs() + qx.abs() + qy.abs())
}

/// The smallest depth numerator `U Az + V Bz + W Cz` whose f32 products are trusted
/// ([`Triangle::depth_is_coarse`]): 2^-100.
pub(crate) const DEPTH_FLOOR: f32 = f32::from_bits(27 << 23);

/// How many times its f64 value a dot product's sum of term magnitudes may be for
/// [`Triangle::plane_distance`] to keep the f64 quotient: `2^23`, so that with the `7 ε₆₄`
/// rounding of each the quotient is within `2 · 7 · 2^-29 < 2^-25` of itself (with the final
/// rounding, within an f32 ulp).
const WELL_CONDITIONED: f64 = (1u64 << 23) as f64;

/// `8 ε` of [`edge_error`].
const EDGE_ERROR: f32 = 8.0 * f32::EPSILON;

/// One bound for all three edge functions of a triangle, at least each [`edge_error`]: the
/// cheaper bound of the wide layouts' packet test, which leaves a few more lanes to
/// [`Triangle::intersect`] and decides the others exactly as it does.
///
/// ```text
///   e = max(2^-126, (5 · 8 ε · M) · P),   M = max |vertex − origin| over the three vertices,
///                                         P = max |sheared x|, |sheared y| over the three vertices
/// ```
///
/// Each edge's sum of four magnitudes is at most `4 P` and its `max_component` at most `M`, so
/// in exact arithmetic `e ≥ 5/4 · eE`; the factor 5/4 covers the rounding of both bounds
/// (`5 (1 − ε)² > 4 (1 + ε)⁵`). Where `eE` is below the smallest normal float (`2^-126`), the
/// floor covers it; where it is above, the edge's coordinates are large enough (`m ≳ 2^-55`)
/// that every product and sum above is a normal float and the relative error analysis holds.
/// A NaN `P` (an overflowing shear) propagates: nothing is then certain.
///
/// `max_sheared` and the floor are taken as SSE's `maxps` does (the second operand when either
/// is NaN), so that the SIMD test and its scalar twin agree bit for bit.
#[inline]
pub(crate) fn shared_edge_error(max_component: f32, max_sheared: f32) -> f32 {
    let e = (SHARED_EDGE_ERROR * max_component) * max_sheared;
    if f32::MIN_POSITIVE > e {
        f32::MIN_POSITIVE
    } else {
        e
    }
}

/// `5 · 8 ε` of [`shared_edge_error`] (exact: `5 · 2^-20`).
pub(crate) const SHARED_EDGE_ERROR: f32 = 5.0 * EDGE_ERROR;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    fn tri() -> Triangle {
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)
    }

    fn hit(t: &Triangle, o: Vec3, d: Vec3) -> Option<TriangleHit> {
        t.intersect(&PreparedRay::new(&Ray::new(o, d)))
    }

    #[test]
    fn barycentrics_follow_rays_md_convention() {
        let h = hit(&tri(), Vec3::new(0.25, 0.5, 1.0), -Vec3::Z).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn two_sided_and_scaled_direction() {
        let h = hit(&tri(), Vec3::new(0.2, 0.2, -2.0), Vec3::new(0.0, 0.0, 4.0)).unwrap();
        assert!((h.t - 0.5).abs() < 1e-6);
    }

    #[test]
    fn vertices_and_edges_count() {
        for p in [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
        ] {
            assert!(hit(&tri(), p + Vec3::Z, -Vec3::Z).is_some(), "{p}");
        }
        assert!(hit(&tri(), Vec3::new(0.5, 0.5001, 1.0), -Vec3::Z).is_none());
    }

    #[test]
    fn interval_is_closed() {
        let r = Ray::new(Vec3::new(0.25, 0.25, 2.0), -Vec3::Z);
        assert!(tri()
            .intersect(&PreparedRay::new(&r.with_interval(2.0, 3.0)))
            .is_some());
        assert!(tri()
            .intersect(&PreparedRay::new(&r.with_interval(0.0, 2.0)))
            .is_some());
        assert!(tri()
            .intersect(&PreparedRay::new(&r.with_interval(0.0, 1.999)))
            .is_none());
        assert!(tri()
            .intersect(&PreparedRay::new(&r.with_interval(2.001, 3.0)))
            .is_none());
    }

    #[test]
    fn parallel_ray_and_behind_origin_miss() {
        assert!(hit(&tri(), Vec3::new(-1.0, 0.2, 0.0), Vec3::X).is_none());
        assert!(hit(&tri(), Vec3::new(0.2, 0.2, 1.0), Vec3::Z).is_none());
    }

    #[test]
    fn origin_on_the_surface_hits_at_exactly_zero() {
        // A wall in the plane z = 0.3 (not representable exactly: the same f32 everywhere), and
        // rays leaving points on it sideways, so that z is not the dominant axis of the ray.
        let z = 0.3f32;
        let wall = Triangle::new(
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(2.0, -1.0, z),
            Vec3::new(-1.0, 2.0, z),
        );
        for k in 0..100 {
            let a = k as f32 * 0.37;
            let o = Vec3::new(0.1 + 0.003 * k as f32, 0.2, z);
            // Never 0 in z: a ray inside the plane is parallel to it, and misses.
            let d = Vec3::new(a.cos(), a.sin(), 0.05 * (k as f32 - 49.5) / 50.0);
            let h = wall
                .intersect(&PreparedRay::new(&Ray::new(o, d)))
                .expect("starts on the wall");
            assert_eq!(h.t, 0.0, "ray {k}");
        }
    }

    #[test]
    fn an_origin_exactly_on_a_slanted_face_hits_it_at_zero() {
        // A face of an icosphere and a ray starting exactly on its plane (so exact rational
        // arithmetic says): the f64 plane distance came out a hair negative and lost the face
        // the ray starts on, where Embree hit it at t = 5e-10. Found against Embree.
        let face = Triangle::new(
            Vec3::new(1.7236627, 1.685341, -1.7856686),
            Vec3::new(1.685341, 1.7856686, -1.7236627),
            Vec3::new(1.7856686, 1.7236627, -1.685341),
        );
        let o = Vec3::new(1.7457268, 1.7083832, -1.7405623);
        for d in [
            Vec3::new(-0.11094283, 0.651853, 0.75018615),
            Vec3::new(0.11094283, -0.651853, -0.75018615),
        ] {
            let hit = face
                .intersect(&PreparedRay::new(&Ray::new(o, d)))
                .expect("starts on the face");
            assert_eq!(hit.t, 0.0, "{d}");
        }
    }

    #[test]
    fn near_origin_hits_have_the_exact_sign() {
        // Origin one ulp above or below the plane z = 1: the hit is behind or ahead, exactly.
        let wall = Triangle::new(
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(-1.0, 2.0, 1.0),
        );
        let d = Vec3::new(1.0, 0.3, -0.01);
        let above = Vec3::new(0.1, 0.1, 1.0f32.next_up());
        let below = Vec3::new(0.1, 0.1, 1.0f32.next_down());
        assert!(
            wall.intersect(&PreparedRay::new(&Ray::new(above, d)))
                .unwrap()
                .t
                > 0.0
        );
        assert!(wall
            .intersect(&PreparedRay::new(&Ray::new(below, d)))
            .is_none());
    }

    #[test]
    fn degenerate_detection() {
        assert!(!tri().is_degenerate());
        assert!(Triangle::new(Vec3::ZERO, Vec3::ONE, Vec3::splat(2.0)).is_degenerate());
        assert!(Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::ZERO).is_degenerate());
        let third = 1.0f32 / 3.0;
        assert!(
            Triangle::new(Vec3::ZERO, Vec3::splat(third), Vec3::splat(2.0 * third)).is_degenerate()
        );
    }
}
