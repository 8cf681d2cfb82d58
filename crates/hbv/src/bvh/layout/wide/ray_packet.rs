//! Packets of eight coherent rays traced through the 8-wide layout together, one ray per AVX
//! lane (Wald, Slusallek, Benthin & Wagner 2001, "Interactive rendering with coherent ray
//! tracing", for packets; Benthin, Wald, Woop, Ernst & Mark 2012, "Combining single and packet
//! ray tracing for arbitrary ray distributions", for leaving a packet once few of its rays are
//! left).
//!
//! Camera rays in pixel order, a lidar's scan lines and sunlight are bundles of nearly parallel
//! rays: neighbours visit almost the same nodes and triangles. Eight of them that share their
//! direction signs and dominant axis (and so the near planes of every box and the axes of the
//! watertight test's shear), and whose beam is narrow against the leaves' size
//! ([`BeamLimit`]), walk the tree once:
//!
//! - at a node, each child's box is tested against the eight rays at once: the single-ray slab
//!   test ([`box_scalar`](super::box_kernels::box_scalar)) lane by lane, with the box's
//!   planes broadcast and each ray's origin, reciprocal and margins in its lane;
//! - a child is visited by the rays that meet it (its lane mask), nearest first by the least
//!   entry distance among them; a postponed child keeps its eight entry distances, and on pop
//!   each ray drops out whose interval (shrunk to its closest hit so far) ends before its entry,
//!   as the single ray does;
//! - at a leaf, each triangle is tested against the rays of the mask at once: the packet test of
//!   [`TrianglePacket::test`] transposed (one triangle, eight rays), the same IEEE operations in
//!   the same order lane by lane, with the lanes it cannot decide left to the scalar test;
//! - once fewer than [`SINGLE_BELOW`] rays reach a node, each goes on alone through that
//!   subtree ([`Traversal`]), where a packet would test eight lanes for one or two.
//!
//! Every ray tests the boxes it would test alone (those its own conservative test meets, less
//! those beyond its own closest hit) and every triangle of the leaves it reaches with the
//! single-ray test's bits; its closest hit is the least `(t, prim)` of those hits, whatever the
//! order, and it is blocked if any of them is a hit. So each ray's answer is exactly its
//! single-ray answer (tested below; for any hit, the blocking triangle may be another), and only
//! the work is shared.

use std::arch::x86_64::*;

use super::box_kernels::LaneBoxes;
use super::kernels::AvxBoxes;
use super::lanes::Lanes;
use super::leaf::undecided_lane;
use super::node::is_leaf;
use super::root_filter::{RayColumns, RootTest};
use super::traversal::{Step, Traversal};
use super::{TrianglePacket, WideLayout};
use crate::bvh::layout::stack::TraversalStack;
use crate::geometry::{Aabb, EdgeRule, PreparedRay, Ray, Triangle, DEPTH_FLOOR, SHARED_EDGE_ERROR};
use crate::query::Hit;
use crate::stats::NoCount;

/// Rays in a packet: one AVX register of f32.
pub(super) const PACKET_RAYS: usize = 8;

/// A node reached by fewer of a packet's rays than this is searched by each of them alone (two
/// and three measured alike in instructions per ray on camera rays; one and four or more cost
/// 2–7 % more).
const SINGLE_BELOW: u32 = 3;

/// A packet is traced as one while its rays stay within this many triangle packets' extents of
/// each other where they can meet the tree ([`BeamLimit`]).
///
/// Measured on camera rays at 128², 512² and 1024² pixels over six meshes (BENCHMARKS.md,
/// session 18): where packets were slower than single rays, their beams were wider than about
/// 4 extents; 2 left out bundles that gained, 8 took in bundles that lost (the dragon's 512²
/// camera, 0.79×).
const MAX_BEAM_WIDTH: f32 = 4.0;

/// How far apart a packet's rays may be: [`MAX_BEAM_WIDTH`] times the layout's typical
/// triangle packet extent `L` (the median over its packets of their box's largest extent),
/// where they can meet the tree.
///
/// Eight rays share the nodes of a subtree while the beam they span is narrower than the
/// subtree's box. Near the leaves, whose boxes are about `L` across, rays farther apart than
/// that reach different leaves, and a packet then tests eight lanes for one or two rays. In
/// the frame of the packet's dominant axis `kz`, ray `i` is at depth `z` (along `kz`, from its
/// origin) at `o_i + z (Sx_i, Sy_i, 1)`, with the slopes `Sx = d[kx] / d[kz]`,
/// `Sy = d[ky] / d[kz]` of the watertight test's shear; at the same depth it is within
/// `|o_i − o_0|∞ + z max(|Sx_i − Sx_0|, |Sy_i − Sy_0|)` of the first ray on every axis. Up to the
/// far side of the tree's box along `kz`, `z ≤ |c[kz] − o_0[kz]| + h[kz]` (its centre `c` and
/// half extent `h`). The packet is traced as one when that bound is at most
/// `MAX_BEAM_WIDTH · L` for every ray.
pub(super) struct BeamLimit {
    center: [f32; 3],
    half_extent: [f32; 3],
    width: f32,
}

impl BeamLimit {
    /// The limit for a tree of box `bounds` whose triangle packets are `packet_extent` across.
    pub fn new(bounds: &Aabb, packet_extent: f32) -> Self {
        Self {
            center: bounds.center().to_array(),
            half_extent: (bounds.extent() / 2.0).to_array(),
            width: MAX_BEAM_WIDTH * packet_extent,
        }
    }
}

/// What [`is_coherent`] found of a coherent packet: the dominant axis and the other two
/// (`[kx, ky, kz]`, as [`PreparedRay`] chooses them), and the slopes `Sx`, `Sy` of each ray.
struct Coherent {
    k: [usize; 3],
    slopes: [__m256; 2],
}

/// Whether eight rays (as columns) may be traced as one packet: all valid ([`Ray::is_valid`]),
/// one sign per direction component (so one near plane per axis for every box), one dominant
/// axis (one permutation of the watertight test's axes, chosen as [`PreparedRay`] chooses it),
/// and a beam narrow enough to share nodes down to the leaves ([`BeamLimit`]). (The last decides
/// only the speed; the answers are the single rays' either way.)
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn is_coherent(rays: &RayColumns, limit: &BeamLimit) -> Option<Coherent> {
    let RayColumns {
        origin: o,
        direction: d,
        tmin,
        tmax,
    } = *rays;
    let sign_bit = _mm256_set1_ps(-0.0);
    let abs = |x: __m256| _mm256_andnot_ps(sign_bit, x);
    let and = _mm256_and_ps;
    let finite = |x: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(abs(x), _mm256_set1_ps(f32::INFINITY));
    let ge = |x: __m256, y: __m256| _mm256_cmp_ps::<_CMP_GE_OQ>(x, y);
    let (ax, ay, az) = (abs(d[0]), abs(d[1]), abs(d[2]));
    let valid = and(
        and(
            and(and(finite(o[0]), finite(o[1])), finite(o[2])),
            and(and(finite(d[0]), finite(d[1])), finite(d[2])),
        ),
        and(
            ge(
                _mm256_max_ps(_mm256_max_ps(ax, ay), az),
                _mm256_set1_ps(f32::MIN_POSITIVE),
            ),
            and(
                _mm256_cmp_ps::<_CMP_ORD_Q>(tmin, tmin),
                _mm256_cmp_ps::<_CMP_ORD_Q>(tmax, tmax),
            ),
        ),
    );
    // `PreparedRay`'s choice of `kz`: x if it is the largest (ties to x), else y if at least z.
    let on_x = _mm256_movemask_ps(and(ge(ax, ay), ge(ax, az)));
    let on_y = _mm256_movemask_ps(_mm256_andnot_ps(and(ge(ax, ay), ge(ax, az)), ge(ay, az)));
    let shared = |mask: i32| matches!(mask, 0 | 0xff);
    if _mm256_movemask_ps(valid) != 0xff
        || !(shared(_mm256_movemask_ps(d[0]))
            && shared(_mm256_movemask_ps(d[1]))
            && shared(_mm256_movemask_ps(d[2]))
            && shared(on_x)
            && shared(on_y))
    {
        return None;
    }
    let kz = if on_x != 0 {
        0
    } else if on_y != 0 {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let slopes = [_mm256_div_ps(d[kx], d[kz]), _mm256_div_ps(d[ky], d[kz])];
    // Lane 0's value in every lane, and how far each lane's is from it.
    let first = |x: __m256| _mm256_permutevar8x32_ps(x, _mm256_setzero_si256());
    let apart = |x: __m256| abs(_mm256_sub_ps(x, first(x)));
    let reach = (limit.center[kz] - _mm256_cvtss_f32(o[kz])).abs() + limit.half_extent[kz];
    let width = _mm256_add_ps(
        _mm256_max_ps(_mm256_max_ps(apart(o[0]), apart(o[1])), apart(o[2])),
        _mm256_mul_ps(
            _mm256_set1_ps(reach),
            _mm256_max_ps(apart(slopes[0]), apart(slopes[1])),
        ),
    );
    let narrow = _mm256_cmp_ps::<_CMP_LE_OQ>(width, _mm256_set1_ps(limit.width));
    (_mm256_movemask_ps(narrow) == 0xff).then_some(Coherent {
        k: [kx, ky, kz],
        slopes,
    })
}

/// The constants of a packet's eight rays, one lane each: what the box and triangle tests read.
/// Each lane holds exactly what [`PreparedRay`] and [`BoxRay`] hold for its ray.
pub(super) struct PacketRays<'r> {
    rays: &'r [Ray; PACKET_RAYS],
    scene_size: f32,
    origin: [__m256; 3],
    inv_direction: [__m256; 3],
    /// The origin on the axes `kx`, `ky`, `kz` (shared by the packet), and the shear.
    origin_k: [__m256; 3],
    shear: [__m256; 3],
    tmin: __m256,
    box_tmin: __m256,
    box_margin: __m256,
    slab_margin: __m256,
    /// Which side of a box is the near plane on each axis (shared by the packet).
    near_side: [usize; 3],
    k: [usize; 3],
}

impl<'r> PacketRays<'r> {
    /// The constants of `rays` (coherent as `coherent` says, with their `columns` and the root
    /// test `root` of a tree of [`PreparedRay::scene_size`] `scene_size`), computed as
    /// [`PreparedRay::new`] computes them, lane by lane: the reciprocals and margins are the
    /// root test's, the shear the same correctly rounded quotients.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(
        rays: &'r [Ray; PACKET_RAYS],
        columns: &RayColumns,
        root: &RootTest,
        coherent: &Coherent,
        scene_size: f32,
    ) -> Self {
        let [kx, ky, kz] = coherent.k;
        let (o, d) = (columns.origin, columns.direction);
        // The shared direction signs (the first lane's), as `is_sign_negative` reads them.
        let negative = d.map(|c| _mm256_movemask_ps(c) & 1 == 1);
        Self {
            rays,
            scene_size,
            origin: o,
            inv_direction: root.inverse,
            origin_k: [o[kx], o[ky], o[kz]],
            shear: [
                coherent.slopes[0],
                coherent.slopes[1],
                _mm256_div_ps(_mm256_set1_ps(1.0), d[kz]),
            ],
            tmin: columns.tmin,
            box_tmin: _mm256_sub_ps(columns.tmin, root.box_margin),
            box_margin: root.box_margin,
            slab_margin: root.slab_margin,
            near_side: negative.map(usize::from),
            k: coherent.k,
        }
    }

    /// Ray `lane` prepared alone, with `tmax` as the end of its interval.
    #[inline(always)]
    fn alone(&self, lane: usize, tmax: f32) -> PreparedRay {
        let mut ray = PreparedRay::new(&self.rays[lane]);
        ray.bound_errors_within_size(self.scene_size);
        ray.tmax = tmax;
        ray
    }
}

/// Lane `lane` of `x`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn lane_of(x: __m256, lane: usize) -> f32 {
    let mut values = [0.0f32; PACKET_RAYS];
    // SAFETY: the store writes the eight lanes into `values`.
    unsafe { _mm256_storeu_ps(values.as_mut_ptr(), x) };
    values[lane]
}

/// The lanes of bit mask `bits` as an AVX mask (all ones in lane `i` if bit `i` is set).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn lane_mask(bits: u32) -> __m256 {
    let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let set = _mm256_and_si256(_mm256_set1_epi32(bits as i32), bit);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, bit))
}

/// The least of the eight lanes of `x`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn horizontal_min(x: __m256) -> f32 {
    let x = _mm256_min_ps(x, _mm256_permute2f128_ps::<1>(x, x));
    let x = _mm256_min_ps(x, _mm256_shuffle_ps::<0b01_00_11_10>(x, x));
    let x = _mm256_min_ps(x, _mm256_shuffle_ps::<0b10_11_00_01>(x, x));
    _mm256_cvtss_f32(x)
}

/// What [`test_triangle`] decided, ray by ray: as [`PacketTest`](super::triangle_packet::PacketTest),
/// with lanes for rays instead of triangles.
struct LaneTest {
    hit: u32,
    undecided: u32,
    t: __m256,
    v: __m256,
    w: __m256,
    det: __m256,
}

/// Triangle `lane` of `triangles` against the packet's rays within `[tmin, tmax]`:
/// [`TrianglePacket::test`]'s operations (see its doc for the decision rule) in the same order,
/// with the triangle's vertex coordinates broadcast and each ray's origin, shear and interval in
/// its lane, so that each ray is decided with the bits [`Triangle::intersect`] gives it.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn test_triangle(
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

/// The eight children's boxes of a node against the rays of `rays` (a lane mask), whose box
/// intervals end at `box_tmax`: for each child, the rays that meet it and their entry
/// distances, by the single-ray slab test
/// ([`box_scalar`](super::box_kernels::box_scalar)) lane by lane. (Every slot is
/// tested, empty ones too: skipping them cost more in branches than it saved.)
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn test_children(
    boxes: &LaneBoxes<8>,
    packet: &PacketRays,
    box_tmax: __m256,
    rays: u32,
) -> ([u32; 8], [__m256; 8]) {
    let mut met = [0u32; 8];
    let mut entry = [_mm256_setzero_ps(); 8];
    let (o, inv) = (packet.origin, packet.inv_direction);
    for child in 0..8 {
        let mut near = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm256_set1_ps(f32::INFINITY);
        for axis in 0..3 {
            let side = packet.near_side[axis];
            let n = _mm256_set1_ps(boxes[side][axis][child]);
            let f = _mm256_set1_ps(boxes[1 - side][axis][child]);
            near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(n, o[axis]), inv[axis]), near);
            far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(f, o[axis]), inv[axis]), far);
        }
        let near = _mm256_max_ps(near, packet.box_tmin);
        let far = _mm256_add_ps(_mm256_min_ps(far, box_tmax), packet.slab_margin);
        met[child] = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32 & rays;
        entry[child] = near;
    }
    (met, entry)
}

/// One stack entry: a child postponed with the rays that meet its box and their entry distances.
#[derive(Clone, Copy)]
struct Postponed {
    node: u32,
    rays: u32,
    entry: __m256,
}

/// What a packet's traversal looks for, and keeps, ray by ray: the closest hit
/// ([`ClosestHits`]) or a blocking triangle ([`Occluders`]).
pub(super) trait PacketQuery {
    /// What the query answers for a ray.
    type Answer;

    /// The query's state for a packet of rays (`columns`) before any node is visited.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self;

    /// The answer for ray `lane`, once the traversal is over.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn answer(&self, lane: usize) -> Option<Self::Answer>;

    /// The end of each ray's interval for box tests: `tmax` (shrunk to the closest hit so far)
    /// plus its box margin.
    fn box_tmax(&self) -> __m256;

    /// The rays still searching (a lane mask): all but those an any-hit query has answered.
    fn searching(&self) -> u32;

    /// Tests the triangles of leaf reference `leaf` against the rays of `lanes`.
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        lanes: u32,
        packet: &PacketRays,
    );

    /// Ray `lane` alone through the subtree at reference `node` (a node or a leaf).
    ///
    /// # Safety
    /// The CPU has AVX2.
    unsafe fn go_alone(
        &mut self,
        layout: &WideLayout<8>,
        node: u32,
        lane: usize,
        packet: &PacketRays,
    );
}

/// The closest hit so far of each ray of a packet. `tmax` is each ray's interval end: its
/// closest hit's `t` once it has one (bit set in `found`), its own `tmax` before.
pub(super) struct ClosestHits {
    tmax: __m256,
    /// `tmax + box_margin`: the end of each ray's interval for box tests.
    box_tmax: __m256,
    prim: __m256i,
    u: __m256,
    v: __m256,
    found: u32,
}

impl ClosestHits {
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(columns: &RayColumns, packet: &PacketRays) -> Self {
        Self {
            tmax: columns.tmax,
            box_tmax: _mm256_add_ps(columns.tmax, packet.box_margin),
            prim: _mm256_setzero_si256(),
            u: _mm256_setzero_ps(),
            v: _mm256_setzero_ps(),
            found: 0,
        }
    }

    /// The closest hit of ray `lane` so far.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn hit(&self, lane: usize) -> Option<Hit> {
        if self.found >> lane & 1 == 0 {
            return None;
        }
        let mut prim = [0u32; PACKET_RAYS];
        // SAFETY: AVX2 is enabled; the store writes eight lanes into an 8-element array.
        unsafe { _mm256_storeu_si256(prim.as_mut_ptr() as *mut __m256i, self.prim) };
        // SAFETY: AVX2 is enabled.
        let lane_of = |x: __m256| unsafe { lane_of(x, lane) };
        Some(Hit {
            t: lane_of(self.tmax),
            prim: prim[lane],
            u: lane_of(self.u),
            v: lane_of(self.v),
        })
    }

    /// Records `hit` for ray `lane` if it is closer than that ray's best
    /// ([`Hit::is_closer_than`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn record_one(&mut self, lane: usize, hit: Hit, packet: &PacketRays) {
        // SAFETY: AVX2 is enabled.
        if !hit.is_closer_than(&unsafe { self.hit(lane) }) {
            return;
        }
        // SAFETY: AVX2 is enabled.
        let only = unsafe { lane_mask(1 << lane) };
        self.tmax = _mm256_blendv_ps(self.tmax, _mm256_set1_ps(hit.t), only);
        self.box_tmax = _mm256_add_ps(self.tmax, packet.box_margin);
        self.u = _mm256_blendv_ps(self.u, _mm256_set1_ps(hit.u), only);
        self.v = _mm256_blendv_ps(self.v, _mm256_set1_ps(hit.v), only);
        self.prim = _mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(self.prim),
            _mm256_castsi256_ps(_mm256_set1_epi32(hit.prim as i32)),
            only,
        ));
        self.found |= 1 << lane;
    }

    /// The hits of `test` in lanes `hit` on triangle `prim`: those nearer than each ray's best
    /// taken at once, those at exactly its `tmax` (a tie, or a hit at the end of the interval)
    /// by the tie rule, one by one.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn record(&mut self, hit: u32, prim: u32, test: &LaneTest, packet: &PacketRays) {
        // SAFETY (this block): AVX2 is enabled.
        unsafe {
            let closer = _mm256_and_ps(
                lane_mask(hit),
                _mm256_cmp_ps::<_CMP_LT_OQ>(test.t, self.tmax),
            );
            let closer_bits = _mm256_movemask_ps(closer) as u32;
            if closer_bits != 0 {
                self.tmax = _mm256_blendv_ps(self.tmax, test.t, closer);
                self.box_tmax = _mm256_add_ps(self.tmax, packet.box_margin);
                self.u = _mm256_blendv_ps(self.u, _mm256_div_ps(test.v, test.det), closer);
                self.v = _mm256_blendv_ps(self.v, _mm256_div_ps(test.w, test.det), closer);
                self.prim = _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(self.prim),
                    _mm256_castsi256_ps(_mm256_set1_epi32(prim as i32)),
                    closer,
                ));
                self.found |= closer_bits;
            }
            let ties = hit & !closer_bits;
            if ties != 0 {
                self.record_ties(ties, prim, test, packet);
            }
        }
    }

    /// [`ClosestHits::record`]'s hits at exactly a ray's `tmax`: rare.
    #[cold]
    #[target_feature(enable = "avx2")]
    unsafe fn record_ties(&mut self, ties: u32, prim: u32, test: &LaneTest, packet: &PacketRays) {
        for lane in Lanes(ties) {
            // SAFETY (this block): AVX2 is enabled.
            unsafe {
                let hit = Hit {
                    t: lane_of(test.t, lane),
                    prim,
                    u: lane_of(test.v, lane) / lane_of(test.det, lane),
                    v: lane_of(test.w, lane) / lane_of(test.det, lane),
                };
                self.record_one(lane, hit, packet);
            }
        }
    }
}

impl PacketQuery for ClosestHits {
    type Answer = Hit;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self {
        // SAFETY: AVX2 is enabled.
        unsafe { Self::new(columns, packet) }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn answer(&self, lane: usize) -> Option<Hit> {
        // SAFETY: AVX2 is enabled.
        unsafe { self.hit(lane) }
    }

    #[inline(always)]
    fn box_tmax(&self) -> __m256 {
        self.box_tmax
    }

    #[inline(always)]
    fn searching(&self) -> u32 {
        0xff
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        lanes: u32,
        packet: &PacketRays,
    ) {
        for triangles in layout.leaf_packets(leaf) {
            for k in 0..4 {
                if triangles.repeats_previous(k) {
                    // Spare lanes repeat the leaf's last triangle, to the end of the packet.
                    break;
                }
                // SAFETY (this block): AVX2 is enabled.
                unsafe {
                    let test = test_triangle(triangles, k, packet, self.tmax);
                    let hit = test.hit & lanes;
                    if hit != 0 {
                        self.record(hit, triangles.ids[k], &test, packet);
                    }
                    for lane in Lanes(test.undecided & lanes) {
                        let ray = packet.alone(lane, lane_of(self.tmax, lane));
                        if let Some(h) = undecided_lane(triangles, k, &ray, EdgeRule::Closed) {
                            let hit = Hit {
                                t: h.t,
                                prim: triangles.ids[k],
                                u: h.u,
                                v: h.v,
                            };
                            self.record_one(lane, hit, packet);
                        }
                    }
                }
            }
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn go_alone(
        &mut self,
        layout: &WideLayout<8>,
        node: u32,
        lane: usize,
        packet: &PacketRays,
    ) {
        // SAFETY: AVX2 is enabled.
        let tmax = unsafe { lane_of(self.tmax, lane) };
        let mut traversal =
            Traversal::in_subtree(&packet.rays[lane], tmax, packet.scene_size, node);
        let mut found = None;
        while let Step::Continue = traversal.step::<8, NoCount, AvxBoxes, true, false>(
            layout,
            &mut NoCount,
            |first, count, ray, counter| {
                layout.closest_hit_in_leaf(first, count, ray, &mut found, counter);
                false
            },
        ) {}
        if let Some(hit) = found {
            // SAFETY: AVX2 is enabled.
            unsafe { self.record_one(lane, hit, packet) };
        }
    }
}

/// The blocking triangle found so far for each ray of a packet (bit set in `blocked`).
pub(super) struct Occluders {
    tmax: __m256,
    box_tmax: __m256,
    blocked: u32,
    occluder: [u32; PACKET_RAYS],
}

impl Occluders {
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(columns: &RayColumns, packet: &PacketRays) -> Self {
        Self {
            tmax: columns.tmax,
            box_tmax: _mm256_add_ps(columns.tmax, packet.box_margin),
            blocked: 0,
            occluder: [0; PACKET_RAYS],
        }
    }

    fn block(&mut self, lane: usize, prim: u32) {
        self.blocked |= 1 << lane;
        self.occluder[lane] = prim;
    }
}

impl PacketQuery for Occluders {
    type Answer = u32;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn start(columns: &RayColumns, packet: &PacketRays) -> Self {
        // SAFETY: AVX2 is enabled.
        unsafe { Self::new(columns, packet) }
    }

    #[inline]
    unsafe fn answer(&self, lane: usize) -> Option<u32> {
        (self.blocked >> lane & 1 == 1).then_some(self.occluder[lane])
    }

    #[inline(always)]
    fn box_tmax(&self) -> __m256 {
        self.box_tmax
    }

    #[inline(always)]
    fn searching(&self) -> u32 {
        !self.blocked & 0xff
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn visit_leaf(
        &mut self,
        layout: &WideLayout<8>,
        leaf: u32,
        mut lanes: u32,
        packet: &PacketRays,
    ) {
        for triangles in layout.leaf_packets(leaf) {
            for k in 0..4 {
                if triangles.repeats_previous(k) {
                    break;
                }
                // SAFETY (this block): AVX2 is enabled.
                unsafe {
                    let test = test_triangle(triangles, k, packet, self.tmax);
                    for lane in Lanes(test.hit & lanes) {
                        self.block(lane, triangles.ids[k]);
                    }
                    for lane in Lanes(test.undecided & lanes & !test.hit) {
                        let ray = packet.alone(lane, lane_of(self.tmax, lane));
                        if undecided_lane(triangles, k, &ray, EdgeRule::Closed).is_some() {
                            self.block(lane, triangles.ids[k]);
                        }
                    }
                }
                lanes &= !self.blocked;
                if lanes == 0 {
                    return;
                }
            }
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn go_alone(
        &mut self,
        layout: &WideLayout<8>,
        node: u32,
        lane: usize,
        packet: &PacketRays,
    ) {
        // SAFETY: AVX2 is enabled.
        let tmax = unsafe { lane_of(self.tmax, lane) };
        let mut traversal =
            Traversal::in_subtree(&packet.rays[lane], tmax, packet.scene_size, node);
        let mut found = None;
        while let Step::Continue = traversal.step::<8, NoCount, AvxBoxes, true, false>(
            layout,
            &mut NoCount,
            |first, count, ray, counter| {
                found = layout.any_hit_in_leaf(first, count, ray, counter);
                found.is_some()
            },
        ) {}
        if let Some(prim) = found {
            self.block(lane, prim);
        }
    }
}

impl WideLayout<8> {
    /// The beam limit of this layout's packets ([`BeamLimit`]), if it has a tree.
    pub(super) fn beam_limit(&self) -> Option<BeamLimit> {
        self.root
            .map(|(_, bounds, _)| BeamLimit::new(&bounds, self.packet_extent))
    }

    /// The block filter of the batches with packets ([`WideLayout::trace_batch`]): the eight
    /// rays against the root box at once; if they are coherent ([`is_coherent`] within
    /// `limit`, [`WideLayout::beam_limit`]), traced as a
    /// packet for query `Q`, their answers written to `answers` (eight), and none handed on;
    /// otherwise those that meet the root box handed on, to be traced alone. The caller checks
    /// that the CPU has AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn packet_block<Q: PacketQuery>(
        &self,
        rays: &[Ray; PACKET_RAYS],
        answers: &mut [Option<Q::Answer>],
        limit: &BeamLimit,
    ) -> u32 {
        let Some((root, bounds, scene_size)) = self.root else {
            return 0;
        };
        // SAFETY (this block): AVX2 is enabled.
        unsafe {
            let columns = RayColumns::of(rays);
            let test = RootTest::of(&columns, &bounds, scene_size);
            if test.met == 0 {
                return 0;
            }
            let Some(coherent) = is_coherent(&columns, limit) else {
                return test.met;
            };
            let packet = PacketRays::new(rays, &columns, &test, &coherent, scene_size);
            let mut query = Q::start(&columns, &packet);
            self.trace_packet(root, test.met, &packet, &mut query);
            for (lane, answer) in answers.iter_mut().enumerate() {
                *answer = query.answer(lane);
            }
        }
        0
    }

    /// The packet traversal (module notes) of the rays `active` from the root reference `root`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn trace_packet<Q: PacketQuery>(
        &self,
        root: u32,
        active: u32,
        packet: &PacketRays,
        query: &mut Q,
    ) {
        let mut stack: TraversalStack<Postponed, 64> = TraversalStack::new();
        let (mut current, mut lanes) = (root, active);
        'walk: loop {
            lanes &= query.searching();
            // SAFETY (this block): AVX2 is enabled.
            unsafe {
                if lanes.count_ones() < SINGLE_BELOW {
                    for lane in Lanes(lanes) {
                        query.go_alone(self, current, lane, packet);
                    }
                } else if is_leaf(current) {
                    query.visit_leaf(self, current, lanes, packet);
                } else {
                    let node = &self.nodes[current as usize];
                    let (met, entry) = test_children(&node.boxes, packet, query.box_tmax(), lanes);
                    if let Some(next) =
                        self.descend_packet(&node.children, &met, &entry, &mut stack)
                    {
                        (current, lanes) = next;
                        continue;
                    }
                }
            }
            loop {
                let searching = query.searching();
                let Some(p) = stack.pop().filter(|_| searching != 0) else {
                    break 'walk;
                };
                let within = _mm256_cmp_ps::<_CMP_LE_OQ>(p.entry, query.box_tmax());
                let rays = p.rays & searching & _mm256_movemask_ps(within) as u32;
                if rays != 0 {
                    (current, lanes) = (p.node, rays);
                    break;
                }
            }
        }
    }

    /// The step from a node to its children for a packet: of the children some ray meets
    /// (`met[child]`, its rays), returns the nearest — by the least entry distance of its rays —
    /// with its rays, and pushes the others farthest first (and asks for their memory early);
    /// `None` when no ray meets any child.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn descend_packet(
        &self,
        children: &[u32; 8],
        met: &[u32; 8],
        entry: &[__m256; 8],
        stack: &mut TraversalStack<Postponed, 64>,
    ) -> Option<(u32, u32)> {
        let mut order = [(0.0f32, 0usize); 8];
        let mut n = 0;
        for child in 0..8 {
            if met[child] == 0 {
                continue;
            }
            // SAFETY: AVX2 is enabled.
            let key = unsafe {
                let inside = lane_mask(met[child]);
                horizontal_min(_mm256_blendv_ps(
                    _mm256_set1_ps(f32::INFINITY),
                    entry[child],
                    inside,
                ))
            };
            // Insertion by decreasing key: the nearest ends last.
            let mut k = n;
            while k > 0 && order[k - 1].0 < key {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = (key, child);
            n += 1;
        }
        if n == 0 {
            return None;
        }
        for &(_, child) in &order[..n - 1] {
            self.prefetch(children[child]);
            stack.push(Postponed {
                node: children[child],
                rays: met[child],
                entry: entry[child],
            });
        }
        let nearest = order[n - 1].1;
        Some((children[nearest], met[nearest]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder};
    use crate::mesh::procedural::{default_scene, icosphere, torus};
    use crate::mesh::TriangleMesh;
    use crate::query::TraversalKernel;
    use glam::Vec3;
    use proptest::prelude::*;

    fn avx2() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// Every run of eight consecutive rays, and the whole batch, answers exactly as each ray
    /// alone: closest hits, and whether each is blocked. Returns how many runs were packets.
    fn check_packets(layout: &WideLayout<8>, rays: &[Ray]) -> Result<usize, TestCaseError> {
        prop_assert!(layout.traces_ray_packets());
        let limit = layout
            .root
            .map(|(_, b, _)| BeamLimit::new(&b, layout.packet_extent));
        let closest: Vec<Option<Hit>> = rays
            .iter()
            .map(|r| {
                r.is_valid()
                    .then(|| layout.closest_hit(r, &mut NoCount))
                    .flatten()
            })
            .collect();
        let blocked: Vec<bool> = rays
            .iter()
            .map(|r| r.is_valid() && layout.any_hit(r, &mut NoCount))
            .collect();
        let mut packets = 0;
        for (k, eight) in rays.chunks_exact(PACKET_RAYS).enumerate() {
            let span = k * PACKET_RAYS..(k + 1) * PACKET_RAYS;
            let columns_of = |eight: &[Ray]| {
                // SAFETY: the caller checked AVX2.
                unsafe { RayColumns::of(eight.try_into().unwrap()) }
            };
            if limit
                .as_ref()
                // SAFETY: as above.
                .is_some_and(|limit| unsafe { is_coherent(&columns_of(eight), limit).is_some() })
            {
                packets += 1;
            }
            let mut hits = [None; PACKET_RAYS];
            layout.closest_hits(eight, &mut hits);
            prop_assert_eq!(&hits[..], &closest[span.clone()], "{:?}", eight);
            let mut occluders = [None; PACKET_RAYS];
            layout.occluders(eight, &mut occluders);
            let found: Vec<bool> = occluders.iter().map(Option::is_some).collect();
            prop_assert_eq!(&found[..], &blocked[span], "{:?}", eight);
        }
        // The whole batch, interleaved and ray by ray (as large and small layouts trace it).
        for interleave in [false, true] {
            let mut layout = layout.clone();
            layout.interleave = interleave;
            let mut hits = vec![None; rays.len()];
            let mut occluders = vec![None; rays.len()];
            layout.closest_hits(rays, &mut hits);
            layout.occluders(rays, &mut occluders);
            prop_assert_eq!(&hits, &closest, "interleaved: {}", interleave);
            let found: Vec<bool> = occluders.iter().map(Option::is_some).collect();
            prop_assert_eq!(&found, &blocked, "interleaved: {}", interleave);
        }
        Ok(packets)
    }

    fn layouts() -> Vec<(TriangleMesh, WideLayout<8>)> {
        let meshes = [
            torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12),
            icosphere(Vec3::new(-0.3, 0.2, 0.1), 1.2, 2),
            default_scene(1),
        ];
        meshes
            .into_iter()
            .map(|m| {
                let tree = BinnedSahBuilder::default().build(&m);
                let layout = WideLayout::<8>::new(&tree, &m);
                (m, layout)
            })
            .collect()
    }

    fn v((x, y, z): (f32, f32, f32)) -> Vec3 {
        Vec3::new(x, y, z)
    }

    fn unit() -> impl Strategy<Value = (f32, f32, f32)> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
    }

    /// How the eight rays of a bundle differ: not at all, by rounding, by a little, by a lot.
    fn spread() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(1e-6), Just(1e-3), Just(3e-2)]
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(300))]

        /// Bundles from one place towards near one point of the mesh's box or one of its
        /// vertices (where the lanes' exact tests decide), with random intervals.
        #[test]
        fn converging_bundles_answer_as_single_rays(
            mesh in 0usize..3,
            from in unit(),
            to in unit(),
            vertex in prop::option::of(0usize..10_000),
            spread in spread(),
            jitter in prop::collection::vec((unit(), unit()), PACKET_RAYS),
            interval in prop_oneof![
                Just((0.0f32, f32::INFINITY)),
                (0.0f32..0.5, 0.5f32..1.5),
            ],
        ) {
            prop_assume!(avx2());
            let all = layouts();
            let (mesh, layout) = &all[mesh];
            let b = mesh.bounds();
            let (c, size) = (b.center(), b.extent().max_element());
            let origin = c + v(from).normalize_or(Vec3::X) * 3.0 * size;
            let target = match vertex {
                Some(k) => mesh.positions()[k % mesh.positions().len()],
                None => c + v(to) * 0.5 * size,
            };
            let length = (target - origin).length();
            let rays: Vec<Ray> = jitter
                .iter()
                .map(|&(o, t)| {
                    let (o, t) = (origin + v(o) * spread * size, target + v(t) * spread * size);
                    Ray::new(o, t - o).with_interval(interval.0 * length, interval.1 * length)
                })
                .collect();
            check_packets(layout, &rays)?;
        }

        /// Parallel rays (sunlight) from a row of points, and rays leaving points on the
        /// surface (shadow and bounce rays, `tmin` 0 or a little more): the origins lie on
        /// triangles, where the near-origin rule decides.
        #[test]
        fn parallel_and_leaving_bundles_answer_as_single_rays(
            mesh in 0usize..3,
            direction in unit(),
            start in 0usize..10_000,
            (a, b) in (0.0f32..1.0, 0.0f32..1.0),
            step in prop_oneof![Just(0.0f32), Just(1e-4), Just(1e-2)],
            on_surface in any::<bool>(),
            tmin in prop_oneof![Just(0.0f32), Just(1e-5)],
        ) {
            prop_assume!(avx2());
            let all = layouts();
            let (mesh, layout) = &all[mesh];
            let d = v(direction);
            prop_assume!(d.abs().max_element() > 1e-3);
            let size = mesh.bounds().extent().max_element();
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let rays: Vec<Ray> = (0..PACKET_RAYS)
                .map(|i| {
                    let origin = if on_surface {
                        // Points on neighbouring triangles.
                        let t = mesh.triangle((start + i) % mesh.triangle_count());
                        t.p0 + a * (t.p1 - t.p0) + b * (t.p2 - t.p0)
                    } else {
                        mesh.bounds().center() - 2.0 * size * d.normalize()
                            + Vec3::new(0.0, 1.0, 0.5) * step * size * i as f32
                    };
                    Ray::new(origin, d).with_interval(tmin, f32::INFINITY)
                })
                .collect();
            check_packets(layout, &rays)?;
        }
    }

    /// Camera rays in pixel order over a torus, from outside and from inside its box: most
    /// packets are coherent, and every one answers as its rays alone.
    #[test]
    fn camera_packets_answer_as_single_rays() {
        if !avx2() {
            return;
        }
        let mesh = torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12);
        for tree in [
            BinnedSahBuilder::default().build(&mesh),
            InsertionBuilder::default().build(&mesh),
        ] {
            let layout = WideLayout::<8>::new(&tree, &mesh);
            for eye in [Vec3::new(4.0, 3.0, 5.0), Vec3::new(0.1, -0.2, 0.3)] {
                let forward = (Vec3::new(0.1, -0.2, 0.3) - eye).normalize_or(Vec3::Z);
                let right = forward.cross(Vec3::Y).normalize();
                let up = right.cross(forward);
                let mut rays = Vec::new();
                // 8 pixels span about 1.9°, as 8 of a 512-pixel image over 120°.
                for y in 0..96 {
                    for x in 0..128 {
                        let sx = (x as f32 + 0.5) / 128.0 * 2.0 - 1.0;
                        let sy = (y as f32 + 0.5) / 96.0 * 2.0 - 1.0;
                        rays.push(Ray::new(eye, forward + 0.6 * (sx * right - sy * up)));
                    }
                }
                let packets = check_packets(&layout, &rays).unwrap();
                assert!(packets > rays.len() / PACKET_RAYS / 3, "{packets} packets");
            }
        }
    }

    /// Packets among invalid rays and rays that miss the tree: a run with an invalid ray is
    /// traced ray by ray, a run that misses is answered at once.
    #[test]
    fn runs_with_invalid_or_missing_rays_answer_as_single_rays() {
        if !avx2() {
            return;
        }
        let (_, layout) = layouts().swap_remove(0);
        let eye = Vec3::new(4.0, 3.0, 5.0);
        let mut rays: Vec<Ray> = (0..64)
            .map(|i| {
                Ray::new(
                    eye,
                    Vec3::new(0.1, -0.2, 0.3) - eye + Vec3::X * 1e-3 * i as f32,
                )
            })
            .collect();
        rays[3].direction = Vec3::ZERO;
        rays[12].origin.x = f32::NAN;
        rays[21].tmin = f32::NAN;
        rays[30].direction = Vec3::new(1e-39, 0.0, 0.0);
        for r in &mut rays[40..48] {
            r.direction = -r.direction;
        }
        let packets = check_packets(&layout, &rays).unwrap();
        assert!(packets >= 3, "{packets} packets");
    }
}
