//! Batches of independent rays traced a few at a time, interleaved, so that one ray's wait for
//! memory overlaps the others' work.
//!
//! A single ray's traversal is a chain of dependent loads: the next node's address is known only
//! once the current node's boxes are tested. When the tree is larger than the caches, each step
//! waits for memory, and the processor has nothing else to do. Here [`STREAMS`] rays are in
//! flight at once: each step of one ray ends by choosing its next node and asking for its memory
//! (a prefetch); the other rays take their steps meanwhile; by the time the first ray comes
//! round again its node has arrived. (The idea is software pipelining of pointer chasing, as in
//! Kocberber et al. 2015, "Asynchronous memory access chaining", applied to BVH traversal.)
//!
//! Each ray runs exactly the single-ray traversal — the same [`Traversal`] steps: box and
//! triangle tests, order of children, culling — so its answer is exactly [`WideLayout`]'s
//! single-ray answer; only the order in which rays' steps are taken differs.

use super::kernels::BoxKernel;
use super::lanes::Lanes;
use super::root_filter::RayCursor;
use super::traversal::{Step, Traversal};
use super::WideLayout;
use crate::geometry::{PreparedRay, Ray};
use crate::stats::NoCount;
use std::mem::MaybeUninit;

/// Rays in flight at once. Enough to cover a memory access with the others' steps; few enough
/// that their state stays in the L1 cache.
pub(super) const STREAMS: usize = 16;

/// A layout up to this size stays in a core's L1 data cache (32–48 KiB on current x86 cores):
/// there is no memory latency for interleaved rays to hide, only their bookkeeping to pay
/// (measured on the 36-triangle Cornell box: single rays 12.2 Mrays/s, interleaved 9.9; teapot,
/// 0.4 MiB: single 4.9, interleaved 5.6).
pub(super) const INTERLEAVE_ABOVE_BYTES: usize = 32 << 10;

/// The leaf visit of the closest-hit batches, `|layout, first, count, ray, best| -> bool`:
/// tests a leaf's packets, keeps the closest hit in `best`, never ends the traversal early.
///
/// A macro, so that the closure is written inside the function that calls the batch. The
/// compiler leaves it out of line (inlining it into the stream loop was measured 5–9% slower),
/// and an out-of-line closure is compiled with the target features of the function it is
/// written in: written in `closest_hits_avx` it is AVX code, written in a generic helper it was
/// baseline SSE2 (two-operand forms and their register copies). Written as the argument of
/// [`WideLayout::trace_batch`], whose signature gives the closure the layout's type.
macro_rules! closest_leaf_visit {
    () => {
        |layout,
         first,
         count,
         ray: &mut crate::geometry::PreparedRay,
         best: &mut Option<crate::query::Hit>| {
            layout.closest_hit_in_leaf(first, count, ray, best, &mut crate::stats::NoCount);
            false
        }
    };
}
pub(super) use closest_leaf_visit;

/// The leaf visit of the any-hit batches: the blocking triangle into `found`, and `true`
/// (the traversal ends) when there is one. A macro for the reason given at
/// [`closest_leaf_visit!`].
macro_rules! any_leaf_visit {
    () => {
        |layout, first, count, ray: &mut crate::geometry::PreparedRay, found: &mut Option<u32>| {
            *found = layout.any_hit_in_leaf(first, count, ray, &mut crate::stats::NoCount);
            found.is_some()
        }
    };
}
pub(super) use any_leaf_visit;

impl<const W: usize> WideLayout<W> {
    /// Answers of `rays` into `answers` (same length): [`STREAMS`] rays interleaved, or, in a
    /// layout that does not interleave, each ray in turn; children nearest first (closest hit,
    /// and any hit from outside the tree) or in lane order. `visit` is
    /// [`closest_leaf_visit!`]'s or [`any_leaf_visit!`]'s closure, written at the caller.
    ///
    /// Rays come in blocks of eight, each first given to `block(rays, answers)` with its eight
    /// answers (still misses): it returns the rays to trace (those that may meet the tree:
    /// [`WideLayout::root_block`]), and may answer the others itself (a packet of coherent rays,
    /// `ray_packet.rs`). The last, shorter block is traced whole.
    #[inline(always)]
    pub(super) fn trace_batch<K: BoxKernel<W>, A, const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        answers: &mut [Option<A>],
        visit: impl Fn(&Self, usize, usize, &mut PreparedRay, &mut Option<A>) -> bool,
        block: impl FnMut(&[Ray; 8], &mut [Option<A>]) -> u32,
    ) {
        if self.interleave {
            self.run_stream::<K, _, NEAREST_FIRST>(rays, answers, visit, block);
        } else {
            self.run_in_turn::<K, _, NEAREST_FIRST>(rays, answers, visit, block);
        }
    }

    /// The block filter of batches without packets: the rays of the block that may meet the
    /// root box ([`BoxKernel::root_candidates`]).
    #[inline(always)]
    pub(super) fn root_block<K: BoxKernel<W>, A>(
        &self,
    ) -> impl FnMut(&[Ray; 8], &mut [Option<A>]) -> u32 + '_ {
        move |eight, _| match &self.root {
            Some((_, bounds, scene_size)) => K::root_candidates(eight, bounds, *scene_size),
            None => 0,
        }
    }

    /// The batch traversal of layouts too small to gain from interleaving: each ray in turn,
    /// with the rays that miss the root box left out eight at a time as in
    /// [`WideLayout::run_stream`] (the single-ray queries' steps, so their answers).
    #[inline(always)]
    fn run_in_turn<K: BoxKernel<W>, A, const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        answers: &mut [Option<A>],
        visit_leaf: impl Fn(&Self, usize, usize, &mut PreparedRay, &mut Option<A>) -> bool,
        mut block: impl FnMut(&[Ray; 8], &mut [Option<A>]) -> u32,
    ) {
        assert_eq!(rays.len(), answers.len());
        answers.iter_mut().for_each(|a| *a = None);
        if self.root.is_none() {
            return;
        }
        let mut cursor = RayCursor::new();
        while let Some(i) = cursor.next(rays, |first, eight| {
            block(eight, &mut answers[first..first + 8])
        }) {
            let ray = &rays[i];
            if !ray.is_valid() {
                continue;
            }
            // A fresh state per ray, as the single-ray queries make it: the compiler keeps it in
            // registers (one state reused for every ray ran the Cornell box's random rays 7%
            // slower).
            let traversal = if K::ROOT_FILTER_EXACT {
                Traversal::start_meeting_root(self, ray, &mut NoCount)
            } else {
                Traversal::start(self, ray, &mut NoCount)
            };
            let Some(mut traversal) = traversal else {
                continue;
            };
            let mut answer = None;
            while let Step::Continue = traversal.step::<W, NoCount, K, NEAREST_FIRST, false>(
                self,
                &mut NoCount,
                |first, count, ray, _| visit_leaf(self, first, count, ray, &mut answer),
            ) {}
            answers[i] = answer;
        }
    }

    /// The interleaved traversal. Every answer starts as a miss (`None`); `visit_leaf(layout,
    /// first, count, ray, answer)` tests a leaf, updates the ray's answer, and returns `true`
    /// when the query is answered.
    #[inline(always)]
    fn run_stream<K: BoxKernel<W>, A, const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        answers: &mut [Option<A>],
        visit_leaf: impl Fn(&Self, usize, usize, &mut PreparedRay, &mut Option<A>) -> bool,
        mut block: impl FnMut(&[Ray; 8], &mut [Option<A>]) -> u32,
    ) {
        assert_eq!(rays.len(), answers.len());
        answers.iter_mut().for_each(|a| *a = None);
        // Slot `i` traces ray `index[i]` (when bit `i` of `busy` is set), its answer so far in
        // `answer[i]`. The traversal states are reset in place for each new ray: each holds
        // its stack, too large to move around per ray.
        with_idle_traversals(|traversals| {
            let mut answer: [Option<A>; STREAMS] = std::array::from_fn(|_| None);
            let mut index = [0usize; STREAMS];
            let mut cursor = RayCursor::new();
            // Slots whose next step visits a node, and a leaf. Each round takes one step of every
            // busy ray as before, but all node steps first and then all leaf steps: whether a
            // step is a node's or a leaf's is then known from the loop, not from a branch on the
            // ray's state, which interleaved rays make unpredictable (about three mispredicted
            // branches per ray on the teapot).
            let (mut nodes, mut leaves) = (0u32, 0u32);
            for i in 0..STREAMS {
                if self.start_next::<K, A>(
                    rays,
                    answers,
                    &mut block,
                    &mut cursor,
                    &mut traversals[i],
                    &mut index[i],
                ) {
                    place(i, &traversals[i], &mut nodes, &mut leaves);
                }
            }
            while nodes | leaves != 0 {
                let (mut next_nodes, mut next_leaves) = (0u32, 0u32);
                for i in Lanes(nodes) {
                    let step = traversals[i]
                        .node_step::<W, NoCount, K, NEAREST_FIRST, true>(self, &mut NoCount);
                    if let Step::Done = step {
                        answers[index[i]] = answer[i].take();
                        if !self.start_next::<K, A>(
                            rays,
                            answers,
                            &mut block,
                            &mut cursor,
                            &mut traversals[i],
                            &mut index[i],
                        ) {
                            continue;
                        }
                    }
                    place(i, &traversals[i], &mut next_nodes, &mut next_leaves);
                }
                for i in Lanes(leaves) {
                    let found = &mut answer[i];
                    let step = traversals[i].leaf_step(&mut NoCount, |first, count, ray, _| {
                        visit_leaf(self, first, count, ray, found)
                    });
                    if let Step::Done = step {
                        answers[index[i]] = found.take();
                        if !self.start_next::<K, A>(
                            rays,
                            answers,
                            &mut block,
                            &mut cursor,
                            &mut traversals[i],
                            &mut index[i],
                        ) {
                            continue;
                        }
                    }
                    place(i, &traversals[i], &mut next_nodes, &mut next_leaves);
                }
                (nodes, leaves) = (next_nodes, next_leaves);
            }
        });
    }
}

/// Runs `work` with [`STREAMS`] idle traversal states, built in place.
///
/// Each state is 720 bytes, most of it its stack's uninitialized array. Built by
/// `std::array::from_fn`, each was made on the machine stack and then copied into the array,
/// uninitialized bytes and all (and the array copied again when returned from a constructor):
/// 11.5 KiB of `memcpy` or more per batch, about 4% of the time of a teapot camera ray traced
/// from Python in runs of 256. Written straight into their place, only the initialized fields
/// are stored.
#[inline(always)]
fn with_idle_traversals<R>(work: impl FnOnce(&mut [Traversal; STREAMS]) -> R) -> R {
    /// The slots, of which the first `initialized` are.
    struct Slots {
        slots: [MaybeUninit<Traversal>; STREAMS],
        initialized: usize,
    }
    impl Drop for Slots {
        fn drop(&mut self) {
            for slot in &mut self.slots[..self.initialized] {
                // SAFETY: the first `initialized` slots are initialized; each is dropped once.
                unsafe { slot.assume_init_drop() };
            }
        }
    }
    // Nothing is stored before the struct is in its place: moving it moves no bytes.
    let mut slots = Slots {
        slots: [const { MaybeUninit::uninit() }; STREAMS],
        initialized: 0,
    };
    for k in 0..STREAMS {
        slots.slots[k].write(Traversal::idle());
        slots.initialized = k + 1;
    }
    // SAFETY: every slot is initialized, and stays so until `slots` drops; `MaybeUninit<T>`
    // has `T`'s layout, so the array has `[T; STREAMS]`'s.
    let traversals = unsafe { &mut *(slots.slots.as_mut_ptr() as *mut [Traversal; STREAMS]) };
    work(traversals)
}

/// Puts slot `i` into the set of slots whose next step visits a node, or a leaf (without a
/// branch on which).
#[inline(always)]
fn place(i: usize, traversal: &Traversal, nodes: &mut u32, leaves: &mut u32) {
    let leaf = u32::from(traversal.at_leaf());
    *leaves |= leaf << i;
    *nodes |= (leaf ^ 1) << i;
}

impl<const W: usize> WideLayout<W> {
    /// Sets a slot's `traversal` up for the next ray that can meet the tree, and its `index`;
    /// the rays skipped (invalid, or missing the root's box: left out by the block filter
    /// `block`, see [`WideLayout::trace_batch`], or by [`Traversal::restart`] when that filter
    /// is not exact) keep their miss, or the answer the block filter gave them. `false` when no
    /// ray is left. (A function rather than a closure so that it is inlined into the kernel
    /// compiled with AVX: left out of line, the setup of each ray took 300 instructions.)
    #[inline(always)]
    fn start_next<K: BoxKernel<W>, A>(
        &self,
        rays: &[Ray],
        answers: &mut [Option<A>],
        block: &mut impl FnMut(&[Ray; 8], &mut [Option<A>]) -> u32,
        cursor: &mut RayCursor,
        traversal: &mut Traversal,
        index: &mut usize,
    ) -> bool {
        while let Some(i) = cursor.next(rays, |first, eight| {
            block(eight, &mut answers[first..first + 8])
        }) {
            let ray = &rays[i];
            if !ray.is_valid() {
                continue;
            }
            let started = if K::ROOT_FILTER_EXACT {
                traversal.restart_meeting_root(self, ray, &mut NoCount)
            } else {
                traversal.restart(self, ray, &mut NoCount)
            };
            if started {
                *index = i;
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{Builder, InsertionBuilder};
    use crate::mesh::procedural::torus;
    use crate::query::TraversalKernel;
    use glam::Vec3;
    use proptest::prelude::*;

    /// Batches answer exactly what single rays answer, interleaved or ray by ray (interleaving
    /// forced on and off), for both widths.
    fn check<const W: usize>(rays: &[Ray]) -> Result<(), TestCaseError>
    where
        WideLayout<W>: TraversalKernel,
    {
        let mesh = torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12);
        let tree = InsertionBuilder::default().build(&mesh);
        let mut layout = WideLayout::<W>::new(&tree, &mesh);
        for interleave in [true, false] {
            layout.interleave = interleave;
            let mut hits = vec![None; rays.len()];
            let mut occluders = vec![None; rays.len()];
            layout.closest_hits(rays, &mut hits);
            layout.occluders(rays, &mut occluders);
            for (i, ray) in rays.iter().enumerate() {
                let valid = ray.is_valid();
                let single = valid
                    .then(|| layout.closest_hit(ray, &mut NoCount))
                    .flatten();
                prop_assert_eq!(hits[i], single, "closest hit, ray {}", i);
                let blocked = valid && layout.any_hit(ray, &mut NoCount);
                prop_assert_eq!(occluders[i].is_some(), blocked, "any hit, ray {}", i);
            }
        }
        Ok(())
    }

    fn rays() -> impl Strategy<Value = Vec<Ray>> {
        let c = || prop_oneof![Just(0.0f32), Just(-1.0), Just(1.0), -3.0f32..3.0];
        let ray = (
            (c(), c(), c()),
            (c(), c(), c()),
            prop_oneof![Just(f32::INFINITY), 0.1f32..5.0],
        )
            .prop_map(|((ox, oy, oz), (dx, dy, dz), tmax)| {
                Ray::new(Vec3::new(ox, oy, oz), Vec3::new(dx, dy, dz)).with_interval(0.0, tmax)
            });
        prop::collection::vec(ray, 0..70)
    }

    /// Rays from a sphere around the torus's box (nearest first in any-hit batches) and from
    /// points inside it (lane order), aimed at random points of the box.
    fn rays_from(outside: bool) -> impl Strategy<Value = Vec<Ray>> {
        let c = || -1.0f32..1.0;
        let ray = ((c(), c(), c()), (c(), c(), c()), 0.5f32..1.0).prop_map(
            move |((ox, oy, oz), (tx, ty, tz), r)| {
                let o = Vec3::new(ox, oy, oz);
                let origin = if outside {
                    o.try_normalize().unwrap_or(Vec3::X) * (4.0 + 4.0 * r)
                } else {
                    o * Vec3::new(1.5, 1.5, 0.4) + Vec3::new(0.1, -0.2, 0.3)
                };
                let target = Vec3::new(tx * 2.0, ty * 2.0, tz * 0.5);
                Ray::new(origin, target - origin)
            },
        );
        prop::collection::vec(ray, 1..70)
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(200))]

        #[test]
        fn interleaved_batches_answer_like_single_rays(rays in rays()) {
            check::<4>(&rays)?;
            check::<8>(&rays)?;
        }

        /// Any-hit batches take children nearest first when most rays start outside the
        /// tree's box, in lane order otherwise: both answer as single rays do.
        #[test]
        fn batches_from_outside_and_inside_answer_like_single_rays(
            outside in rays_from(true),
            inside in rays_from(false),
        ) {
            let mesh = torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12);
            let layout = WideLayout::<8>::new(&InsertionBuilder::default().build(&mesh), &mesh);
            prop_assert!(layout.mostly_from_outside(&outside));
            prop_assert!(!layout.mostly_from_outside(&inside));
            check::<8>(&outside)?;
            check::<8>(&inside)?;
        }
    }
}
