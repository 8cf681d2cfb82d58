//! The constants of a packet's eight rays, one AVX lane each: what its box and triangle tests
//! read, computed as the single ray computes them.

use std::arch::x86_64::*;

use super::beam::Coherent;
use super::PACKET_RAYS;
use crate::bvh::layout::wide::root_filter::{RayColumns, RootTest};
use crate::geometry::{PreparedRay, Ray};

/// The constants of a packet's eight rays, one lane each: what the box and triangle tests read.
/// Each lane holds exactly what [`PreparedRay`] and [`BoxRay`](super::super::box_kernels::BoxRay)
/// hold for its ray.
pub(super) struct PacketRays<'r> {
    pub rays: &'r [Ray; PACKET_RAYS],
    pub scene_size: f32,
    pub origin: [__m256; 3],
    pub inv_direction: [__m256; 3],
    /// The origin on the axes `kx`, `ky`, `kz` (shared by the packet), and the shear.
    pub origin_k: [__m256; 3],
    pub shear: [__m256; 3],
    pub tmin: __m256,
    pub box_tmin: __m256,
    pub box_margin: __m256,
    pub slab_margin: __m256,
    /// Which side of a box is the near plane on each axis (shared by the packet).
    pub near_side: [usize; 3],
    pub k: [usize; 3],
}

impl<'r> PacketRays<'r> {
    /// The constants of `rays` (coherent as `coherent` says, with their `columns` and the root
    /// test `root` of a tree of [`PreparedRay::scene_size`] `scene_size`), computed as
    /// [`PreparedRay::new`] computes them, lane by lane: the reciprocals and margins are the
    /// root test's, the shear the same correctly rounded quotients.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub unsafe fn new(
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
    pub fn alone(&self, lane: usize, tmax: f32) -> PreparedRay {
        let mut ray = PreparedRay::new(&self.rays[lane]);
        ray.bound_errors_within_size(self.scene_size);
        ray.tmax = tmax;
        ray
    }
}
