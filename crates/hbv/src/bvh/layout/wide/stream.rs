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
//! Each ray runs exactly the single-ray traversal — the same box and triangle tests, the same
//! order of children, the same culling — so its answer is exactly [`WideLayout`]'s single-ray
//! answer; only the order in which rays' steps are taken differs.

use super::{BoxKernel, WideLayout, LEAF, LEAF_COUNT_SHIFT, LEAF_FIRST_MASK};
use crate::bvh::layout::stack::TraversalStack;
use crate::bvh::layout::wide_kernels::{BoxRay, Lanes};
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::query::Hit;
use crate::stats::NoCount;

/// Rays in flight at once. Enough to cover a memory access with the others' steps; few enough
/// that their state stays in the L1 cache.
pub(super) const STREAMS: usize = 16;

/// One ray's traversal state, suspended between steps, with its answer so far.
struct RayInFlight<A> {
    ray: PreparedRay,
    box_ray: BoxRay,
    box_tmin: f32,
    box_tmax: f32,
    /// The node or leaf to visit at the next step.
    current: u32,
    /// Index of the ray in the batch.
    index: usize,
    answer: Option<A>,
    stack: TraversalStack<(u32, f32), 64>,
}

/// What a step of one ray's query left.
enum Step {
    /// The traversal goes on at `current`.
    Continue,
    /// The traversal is over.
    Done,
}

impl<const W: usize> WideLayout<W> {
    /// Closest hits of `rays` into `hits` (same length), [`STREAMS`] rays interleaved.
    pub(super) fn closest_hits_with<K: BoxKernel<W>>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
    ) {
        self.run_stream::<K, _, true>(rays, hits, |layout, first, count, ray, best| {
            layout.closest_hit_in_leaf(first, count, ray, best, &mut NoCount);
            false
        });
    }

    /// Any-hit answers of `rays` into `occluders` (the blocking triangle, or `None`), [`STREAMS`]
    /// rays interleaved.
    pub(super) fn any_hits_with<K: BoxKernel<W>>(
        &self,
        rays: &[Ray],
        occluders: &mut [Option<u32>],
    ) {
        self.run_stream::<K, _, false>(rays, occluders, |layout, first, count, ray, found| {
            *found = layout.any_hit_in_leaf(first, count, ray, &mut NoCount);
            found.is_some()
        });
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
    ) {
        assert_eq!(rays.len(), answers.len());
        answers.iter_mut().for_each(|a| *a = None);
        let Some((root, root_bounds)) = self.root else {
            return;
        };
        let mut next = 0;
        // The slots are reset in place for each new ray (a state holds its stack: too large to
        // move per ray); bit `i` of `busy` says whether slot `i` holds a ray.
        let idle = PreparedRay::new(&Ray::new(glam::Vec3::ZERO, glam::Vec3::X));
        let mut slots: [RayInFlight<A>; STREAMS] = std::array::from_fn(|_| RayInFlight {
            ray: idle,
            box_ray: BoxRay::new(&idle),
            box_tmin: 0.0,
            box_tmax: 0.0,
            current: root,
            index: 0,
            answer: None,
            stack: TraversalStack::new(),
        });
        let mut busy = 0u32;
        for (i, slot) in slots.iter_mut().enumerate() {
            if start_ray(slot, rays, &mut next, root, &root_bounds) {
                busy |= 1 << i;
            }
        }
        while busy != 0 {
            for i in Lanes(busy) {
                let r = &mut slots[i];
                if let Step::Done = self.step::<K, A, NEAREST_FIRST>(r, &visit_leaf) {
                    answers[r.index] = r.answer.take();
                    if !start_ray(r, rays, &mut next, root, &root_bounds) {
                        busy &= !(1 << i);
                    }
                }
            }
        }
    }

    /// One step of ray `r`: visits its current node or leaf, chooses what comes next and asks
    /// for its memory. The step of [`WideLayout`]'s single-ray traversal loop.
    #[inline(always)]
    fn step<K: BoxKernel<W>, A, const NEAREST_FIRST: bool>(
        &self,
        r: &mut RayInFlight<A>,
        visit_leaf: &impl Fn(&Self, usize, usize, &mut PreparedRay, &mut Option<A>) -> bool,
    ) -> Step {
        let current = r.current;
        if current & LEAF != 0 {
            let first = (current & LEAF_FIRST_MASK) as usize;
            let count = ((current & !LEAF) >> LEAF_COUNT_SHIFT) as usize + 1;
            if visit_leaf(self, first, count, &mut r.ray, &mut r.answer) {
                return Step::Done;
            }
            r.box_tmax = r.ray.box_tmax();
        } else {
            let node = &self.nodes[current as usize];
            let (mask, entry) = K::test(&node.boxes, &r.box_ray, r.box_tmin, r.box_tmax);
            if let Some(next) =
                self.descend::<NEAREST_FIRST>(&node.children, mask, &entry, &mut r.stack)
            {
                self.prefetch(next);
                r.current = next;
                return Step::Continue;
            }
        }
        loop {
            match r.stack.pop() {
                Some((n, near)) if near <= r.box_tmax => {
                    r.current = n;
                    return Step::Continue;
                }
                Some(_) => continue,
                None => return Step::Done,
            }
        }
    }
}

/// Sets `r` up for the next ray of `rays` from `*next` that can hit the tree (`root`, bounded by
/// `root_bounds`) and returns `true`, or `false` when none is left. The rays skipped (invalid,
/// or missing the root's box) keep their miss.
#[inline(always)]
fn start_ray<A>(
    r: &mut RayInFlight<A>,
    rays: &[Ray],
    next: &mut usize,
    root: u32,
    root_bounds: &Aabb,
) -> bool {
    while *next < rays.len() {
        let index = *next;
        *next += 1;
        let ray = &rays[index];
        if !ray.is_valid() {
            continue;
        }
        let mut prepared = PreparedRay::new(ray);
        prepared.bound_errors_within(root_bounds);
        if !root_bounds.hit_by(&prepared) {
            continue;
        }
        r.box_ray = BoxRay::new(&prepared);
        r.box_tmin = prepared.box_tmin();
        r.box_tmax = prepared.box_tmax();
        r.ray = prepared;
        r.current = root;
        r.index = index;
        r.answer = None;
        r.stack.clear();
        return true;
    }
    false
}
