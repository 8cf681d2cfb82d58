//! The wide layout's queries: closest hit and any hit, one ray at a time or in batches.
//!
//! Each query branches once, at its top, on the layout's [`Kernels`] into a traversal compiled
//! for them. The queries are implemented once per width: 4-wide layouts always run the baseline
//! kernels, 8-wide ones whatever the CPU allows, so only `WideLayout<8>` has the entry points
//! compiled with AVX (and the packets of rays, with AVX2).

#[cfg(target_arch = "x86_64")]
use super::kernels::AvxBoxes;
use super::kernels::{BaselineBoxes, BoxKernel, Kernels};
use super::stream;
use super::traversal::{Step, Traversal};
use super::WideLayout;
use crate::geometry::{PreparedRay, Ray};
use crate::query::{Hit, TraversalKernel};
use crate::stats::Counter;

impl<const W: usize> WideLayout<W> {
    /// One ray's traversal (valid: checked by the caller), nearest child first when
    /// `NEAREST_FIRST`: each leaf reached goes to `visit_leaf(first_packet, packet_count, ray,
    /// counter)`, which returns `true` to stop. See [`Traversal::step`].
    #[inline(always)]
    pub(super) fn traverse<C: Counter, K: BoxKernel<W>, const NEAREST_FIRST: bool>(
        &self,
        ray: &Ray,
        counter: &mut C,
        mut visit_leaf: impl FnMut(usize, usize, &mut PreparedRay, &mut C) -> bool,
    ) {
        let Some(mut traversal) = Traversal::start(self, ray, counter) else {
            return;
        };
        while let Step::Continue =
            traversal.step::<W, C, K, NEAREST_FIRST, false>(self, counter, &mut visit_leaf)
        {
        }
    }

    /// The closest hit of `ray` (valid), with box kernel `K`.
    #[inline(always)]
    fn closest_hit_with<C: Counter, K: BoxKernel<W>>(
        &self,
        ray: &Ray,
        counter: &mut C,
    ) -> Option<Hit> {
        let mut best = None;
        self.traverse::<C, K, true>(ray, counter, |first, count, ray, counter| {
            self.closest_hit_in_leaf(first, count, ray, &mut best, counter);
            false
        });
        best
    }

    /// A triangle that blocks `ray` (valid), with box kernel `K`.
    #[inline(always)]
    fn any_hit_with<C: Counter, K: BoxKernel<W>>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        let mut found = None;
        self.traverse::<C, K, false>(ray, counter, |first, count, ray, counter| {
            found = self.any_hit_in_leaf(first, count, ray, counter);
            found.is_some()
        });
        found
    }

    /// The closest-hit batch with the baseline kernels.
    fn closest_hits_baseline(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let block = self.root_block::<BaselineBoxes, _>();
        self.trace_batch::<BaselineBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    /// The any-hit batch with the baseline kernels, children nearest first or in lane order
    /// ([`WideLayout::mostly_from_outside`]).
    fn any_hits_baseline<const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        occluders: &mut [Option<u32>],
    ) {
        let block = self.root_block::<BaselineBoxes, _>();
        self.trace_batch::<BaselineBoxes, _, NEAREST_FIRST>(
            rays,
            occluders,
            stream::any_leaf_visit!(),
            block,
        )
    }

    /// Whether `origin` lies outside the tree's box (or the tree is empty).
    #[inline(always)]
    fn starts_outside_tree(&self, origin: glam::Vec3) -> bool {
        self.root.as_ref().is_some_and(|(_, bounds, _)| {
            !(bounds.min.cmple(origin).all() && origin.cmple(bounds.max).all())
        })
    }

    /// The order in which an any-hit batch takes a node's children: nearest first when most of
    /// its rays start outside the tree's box, judged from 16 of them spread over the batch, in
    /// lane order (no sorting) otherwise. One order for the batch, so that its loop does not
    /// choose per step; a sample is enough for a choice of speed (checking every ray cost 25
    /// instructions a ray).
    ///
    /// Which child holds a blocker first cannot be known, and sorting costs instructions. A
    /// ray from outside (a camera's, a sensor's, sunlight) meets the surface facing it first,
    /// and nearest first finds it sooner: camera rays +5–11%, rays from a sphere around the
    /// mesh +1–6% (measured when this choice came in, commit 52b905f). A ray that leaves a
    /// surface (a shadow or bounce ray) meets its blockers in no such order, and there the
    /// sorting made it 16–22% slower.
    /// Either order finds a blocker if there is one: only the speed, and which blocker is
    /// reported, depend on it. (Single rays keep lane order: the renderer's shadow rays leave
    /// surfaces, and choosing per ray cost their kernel 2% more instructions.)
    #[inline(always)]
    pub(super) fn mostly_from_outside(&self, rays: &[Ray]) -> bool {
        const SAMPLE: usize = 16;
        let stride = rays.len().div_ceil(SAMPLE).max(1);
        let (sampled, outside) = rays.iter().step_by(stride).fold((0, 0), |(n, out), r| {
            (n + 1, out + usize::from(self.starts_outside_tree(r.origin)))
        });
        2 * outside > sampled
    }
}

/// 4-wide nodes: the baseline kernels whatever the CPU (a node's four boxes are one SSE register
/// per axis and side).
impl TraversalKernel for WideLayout<4> {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        self.closest_hit_with::<C, BaselineBoxes>(ray, counter)
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        self.any_hit_prim(ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        self.any_hit_with::<C, BaselineBoxes>(ray, counter)
    }

    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_hits_baseline(rays, hits)
    }

    fn occluders(&self, rays: &[Ray], occluders: &mut [Option<u32>]) {
        if self.mostly_from_outside(rays) {
            self.any_hits_baseline::<true>(rays, occluders)
        } else {
            self.any_hits_baseline::<false>(rays, occluders)
        }
    }
}

/// 8-wide nodes: AVX where the CPU has it, and packets of coherent rays in batches where it has
/// AVX2 (chosen when the layout is made).
impl TraversalKernel for WideLayout<8> {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        match self.kernels {
            Kernels::Baseline => self.closest_hit_with::<C, BaselineBoxes>(ray, counter),
            // SAFETY: the AVX kernels are chosen only on a CPU that reported AVX.
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx | Kernels::AvxRayPackets => unsafe { self.closest_hit_avx(ray, counter) },
        }
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        self.any_hit_prim(ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        match self.kernels {
            Kernels::Baseline => self.any_hit_with::<C, BaselineBoxes>(ray, counter),
            // SAFETY: the AVX kernels are chosen only on a CPU that reported AVX.
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx | Kernels::AvxRayPackets => unsafe { self.any_hit_avx(ray, counter) },
        }
    }

    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        match self.kernels {
            Kernels::Baseline => self.closest_hits_baseline(rays, hits),
            // SAFETY: chosen only on a CPU that reported AVX.
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx => unsafe { self.closest_hits_avx(rays, hits) },
            // SAFETY: chosen only on a CPU that reported AVX and AVX2.
            #[cfg(target_arch = "x86_64")]
            Kernels::AvxRayPackets => unsafe { self.closest_hits_avx2(rays, hits) },
        }
    }

    fn occluders(&self, rays: &[Ray], occluders: &mut [Option<u32>]) {
        // The order of children is chosen with the kernel, before it is entered, so that each
        // kernel holds one traversal loop.
        match (self.kernels, self.mostly_from_outside(rays)) {
            (Kernels::Baseline, true) => self.any_hits_baseline::<true>(rays, occluders),
            (Kernels::Baseline, false) => self.any_hits_baseline::<false>(rays, occluders),
            // SAFETY (these four): `Avx` is chosen only on a CPU that reported AVX,
            // `AvxRayPackets` only on one that reported AVX and AVX2.
            #[cfg(target_arch = "x86_64")]
            (Kernels::Avx, true) => unsafe { self.any_hits_avx::<true>(rays, occluders) },
            #[cfg(target_arch = "x86_64")]
            (Kernels::Avx, false) => unsafe { self.any_hits_avx::<false>(rays, occluders) },
            #[cfg(target_arch = "x86_64")]
            (Kernels::AvxRayPackets, true) => unsafe {
                self.any_hits_avx2::<true>(rays, occluders)
            },
            #[cfg(target_arch = "x86_64")]
            (Kernels::AvxRayPackets, false) => unsafe {
                self.any_hits_avx2::<false>(rays, occluders)
            },
        }
    }
}

/// The entry points compiled with AVX (and AVX2): 8-wide nodes only. Call each only when the
/// layout's `Kernels` say so.
#[cfg(target_arch = "x86_64")]
impl WideLayout<8> {
    /// The closest-hit traversal compiled with AVX. Call only when the CPU has AVX.
    #[target_feature(enable = "avx")]
    unsafe fn closest_hit_avx<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        self.closest_hit_with::<C, AvxBoxes>(ray, counter)
    }

    /// The any-hit traversal compiled with AVX. Call only when the CPU has AVX.
    #[target_feature(enable = "avx")]
    unsafe fn any_hit_avx<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        self.any_hit_with::<C, AvxBoxes>(ray, counter)
    }

    /// The closest-hit batch compiled with AVX. Call only when the CPU has AVX.
    #[target_feature(enable = "avx")]
    unsafe fn closest_hits_avx(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let block = self.root_block::<AvxBoxes, _>();
        self.trace_batch::<AvxBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    /// The any-hit batch compiled with AVX, children nearest first or in lane order. Call
    /// only when the CPU has AVX.
    #[target_feature(enable = "avx")]
    unsafe fn any_hits_avx<const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        occluders: &mut [Option<u32>],
    ) {
        let block = self.root_block::<AvxBoxes, _>();
        self.trace_batch::<AvxBoxes, _, NEAREST_FIRST>(
            rays,
            occluders,
            stream::any_leaf_visit!(),
            block,
        )
    }
}
