//! When eight rays form a narrow beam: the test that decides whether a run of eight rays is traced
//! as one packet.

use std::arch::x86_64::*;

use crate::bvh::layout::wide::root_filter::RayColumns;
use crate::bvh::layout::wide::WideLayout;
use crate::geometry::Aabb;

/// A packet is traced as one while its rays stay within this many triangle packets' extents of
/// each other where they can meet the tree ([`BeamLimit`]).
///
/// Measured on camera rays at 128², 512² and 1024² pixels over six meshes when packets came in
/// (commit cbb6788): where packets were slower than single rays, their beams were wider than
/// about 4 extents; 2 left out bundles that gained, 8 took in bundles that lost (the dragon's
/// 512² camera, 0.79×).
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
/// (`[kx, ky, kz]`, as [`PreparedRay`](crate::geometry::PreparedRay) chooses them), and the
/// slopes `Sx`, `Sy` of each ray.
pub(super) struct Coherent {
    pub k: [usize; 3],
    pub slopes: [__m256; 2],
}

/// Whether eight rays (as columns) may be traced as one packet: all valid
/// ([`Ray::is_valid`](crate::geometry::Ray::is_valid)), one sign per direction component (so
/// one near plane per axis for every box), one dominant axis (one permutation of the watertight
/// test's axes, chosen as [`PreparedRay`](crate::geometry::PreparedRay) chooses it), and a beam
/// narrow enough to share nodes down to the leaves ([`BeamLimit`]). (The last decides only the
/// speed; the answers are the single rays' either way.)
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn is_coherent(rays: &RayColumns, limit: &BeamLimit) -> Option<Coherent> {
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

impl WideLayout<8> {
    /// The beam limit of this layout's packets ([`BeamLimit`]), if it has a tree.
    pub(super) fn beam_limit(&self) -> Option<BeamLimit> {
        self.root
            .map(|(_, bounds, _)| BeamLimit::new(&bounds, self.packet_extent))
    }
}
