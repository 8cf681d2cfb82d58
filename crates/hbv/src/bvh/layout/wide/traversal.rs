//! One ray's walk through a [`WideLayout`], kept as a state that advances one node at a time:
//! the single-ray queries run it to the end at once, the batch queries interleave several
//! (`stream.rs`). Both therefore take exactly the same steps for a ray.

use super::box_kernels::{box_scalar, BoxRay};
use super::kernels::BoxKernel;
use super::node::{is_leaf, leaf_span};
use super::WideLayout;
use crate::bvh::layout::stack::TraversalStack;
use crate::geometry::{PreparedRay, Ray};
use crate::stats::Counter;

/// A ray's traversal between two steps: the ray (its `tmax` shrinks as closer hits are found),
/// its box-test constants, the node or leaf to visit next and the postponed ones.
pub(super) struct Traversal {
    pub ray: PreparedRay,
    box_ray: BoxRay,
    /// `[box_tmin, box_tmax]`: the ray's interval widened for the box tests
    /// ([`PreparedRay::bound_errors_within`]); `box_tmax` follows `ray.tmax`.
    box_tmin: f32,
    box_tmax: f32,
    current: u32,
    /// Postponed children with their entry distances, the nearest on top.
    stack: TraversalStack<(u32, f32), 64>,
}

/// What one step left.
pub(super) enum Step {
    /// The traversal goes on.
    Continue,
    /// The traversal is over: every node that could hold an answer was visited, or the leaf
    /// visitor asked to stop.
    Done,
}

impl Traversal {
    /// A state holding no ray, to be set up with [`Traversal::restart`] (the batches' slots).
    #[inline(always)]
    pub fn idle() -> Self {
        let ray = PreparedRay::new(&Ray::new(glam::Vec3::ZERO, glam::Vec3::X));
        Self {
            box_ray: BoxRay::new(&ray),
            ray,
            box_tmin: 0.0,
            box_tmax: 0.0,
            current: 0,
            stack: TraversalStack::new(),
        }
    }

    /// The traversal of `ray` (valid: checked by the caller) through `layout`, or `None` when
    /// the ray cannot meet the tree: the tree is empty or the ray misses the root's box. That
    /// scalar test of the root box rejects most rays that miss everything (half or more of the
    /// camera rays of a scene without walls) at the cheapest point.
    #[inline(always)]
    pub fn start<const W: usize, C: Counter>(
        layout: &WideLayout<W>,
        ray: &Ray,
        counter: &mut C,
    ) -> Option<Self> {
        let (ray, box_ray, root) = Self::enter(layout, ray, counter)?;
        Some(Self::new(ray, box_ray, root))
    }

    /// [`Traversal::start`] for a ray known to meet the root's box (see
    /// [`Traversal::restart_meeting_root`]): `None` only for an empty tree.
    #[inline(always)]
    pub fn start_meeting_root<const W: usize, C: Counter>(
        layout: &WideLayout<W>,
        ray: &Ray,
        counter: &mut C,
    ) -> Option<Self> {
        let (root, _, scene_size) = layout.root?;
        counter.boxes_tested(1);
        let (ray, box_ray) = Self::prepare(ray, scene_size);
        Some(Self::new(ray, box_ray, root))
    }

    /// The traversal of the subtree at `node` (a node or a leaf reference) by `ray` (valid),
    /// over `[ray.tmin, tmax]`, in a tree of [`PreparedRay::scene_size`] `scene_size`: a ray of a
    /// packet that goes on alone from a node its packet reached (`ray_packet.rs`), `tmax` its
    /// closest hit so far.
    #[inline(always)]
    pub fn in_subtree(ray: &Ray, tmax: f32, scene_size: f32, node: u32) -> Self {
        let (mut prepared, box_ray) = Self::prepare(ray, scene_size);
        prepared.tmax = tmax;
        Self::new(prepared, box_ray, node)
    }

    #[inline(always)]
    fn new(ray: PreparedRay, box_ray: BoxRay, root: u32) -> Self {
        Self {
            box_ray,
            box_tmin: ray.box_tmin(),
            box_tmax: ray.box_tmax(),
            ray,
            current: root,
            stack: TraversalStack::new(),
        }
    }

    /// [`Traversal::start`] in place, reusing this state (and its stack's memory); `false`, and
    /// nothing to do, when the ray cannot meet the tree.
    #[inline(always)]
    pub fn restart<const W: usize, C: Counter>(
        &mut self,
        layout: &WideLayout<W>,
        ray: &Ray,
        counter: &mut C,
    ) -> bool {
        let Some((ray, box_ray, root)) = Self::enter(layout, ray, counter) else {
            return false;
        };
        self.reset(ray, box_ray, root);
        true
    }

    /// [`Traversal::restart`] for a ray known to meet the root's box (its test is skipped):
    /// `false` only for an empty tree. (Were the ray to miss the box after all, its traversal
    /// would find nothing at more cost: the box test is an early exit, not part of the answer.)
    #[inline(always)]
    pub fn restart_meeting_root<const W: usize, C: Counter>(
        &mut self,
        layout: &WideLayout<W>,
        ray: &Ray,
        counter: &mut C,
    ) -> bool {
        let Some((root, _, scene_size)) = layout.root else {
            return false;
        };
        counter.boxes_tested(1);
        let (ray, box_ray) = Self::prepare(ray, scene_size);
        self.reset(ray, box_ray, root);
        true
    }

    #[inline(always)]
    fn reset(&mut self, ray: PreparedRay, box_ray: BoxRay, root: u32) {
        self.box_ray = box_ray;
        self.box_tmin = ray.box_tmin();
        self.box_tmax = ray.box_tmax();
        self.ray = ray;
        self.current = root;
        self.stack.clear();
    }

    /// The prepared ray, with its box-test margins for the tree, its box-kernel constants and
    /// the root, if the ray meets the root's box (tested as the kernels test a child's box).
    #[inline(always)]
    fn enter<const W: usize, C: Counter>(
        layout: &WideLayout<W>,
        ray: &Ray,
        counter: &mut C,
    ) -> Option<(PreparedRay, BoxRay, u32)> {
        let (root, root_bounds, scene_size) = layout.root?;
        // The root box first, from what its test needs: about two thirds of a camera's rays
        // miss it, and skip the rest of the preparation.
        let setup = BoxSetup::new(ray, scene_size);
        counter.boxes_tested(1);
        let corners = [root_bounds.min, root_bounds.max];
        let (met, _) = box_scalar(
            corners,
            &setup.box_ray,
            ray.tmin - setup.box_margin,
            ray.tmax + setup.box_margin,
        );
        if !met {
            return None;
        }
        Some((setup.prepared(ray), setup.box_ray, root))
    }

    /// The prepared ray with its box-test margins for a tree of [`PreparedRay::scene_size`]
    /// `scene_size`, and its box-kernel constants: [`Traversal::enter`] without the root box's
    /// test.
    #[inline(always)]
    fn prepare(ray: &Ray, scene_size: f32) -> (PreparedRay, BoxRay) {
        let setup = BoxSetup::new(ray, scene_size);
        (setup.prepared(ray), setup.box_ray)
    }

    /// Visits the current node or leaf and chooses what comes next: [`Traversal::leaf_step`] or
    /// [`Traversal::node_step`].
    #[inline(always)]
    pub fn step<const W: usize, C, K, const NEAREST_FIRST: bool, const PREFETCH_NEXT: bool>(
        &mut self,
        layout: &WideLayout<W>,
        counter: &mut C,
        visit_leaf: impl FnMut(usize, usize, &mut PreparedRay, &mut C) -> bool,
    ) -> Step
    where
        C: Counter,
        K: BoxKernel<W>,
    {
        if self.at_leaf() {
            self.leaf_step(counter, visit_leaf)
        } else {
            self.node_step::<W, C, K, NEAREST_FIRST, PREFETCH_NEXT>(layout, counter)
        }
    }

    /// Whether the next step visits a leaf.
    #[inline(always)]
    pub fn at_leaf(&self) -> bool {
        is_leaf(self.current)
    }

    /// Visits the current leaf (see [`Traversal::at_leaf`]): `visit_leaf(first_packet,
    /// packet_count, ray, counter)` may shrink `ray.tmax` and returns `true` to end the
    /// traversal; otherwise the traversal goes on to the nearest postponed child that still
    /// begins within the (possibly shrunk) interval.
    #[inline(always)]
    pub fn leaf_step<C: Counter>(
        &mut self,
        counter: &mut C,
        mut visit_leaf: impl FnMut(usize, usize, &mut PreparedRay, &mut C) -> bool,
    ) -> Step {
        counter.node_visited();
        let (first, count) = leaf_span(self.current);
        if visit_leaf(first, count, &mut self.ray, counter) {
            return Step::Done;
        }
        self.box_tmax = self.ray.box_tmax();
        self.resume()
    }

    /// Visits the current node (not a leaf): its `W` child boxes are tested at once and the
    /// traversal goes on to the child [`WideLayout::descend`] chooses, or, when none is met, to
    /// the nearest postponed child still within the interval. With `PREFETCH_NEXT` the next
    /// node's memory is asked for at once (for interleaved rays, which visit it only after the
    /// others' steps).
    #[inline(always)]
    pub fn node_step<const W: usize, C, K, const NEAREST_FIRST: bool, const PREFETCH_NEXT: bool>(
        &mut self,
        layout: &WideLayout<W>,
        counter: &mut C,
    ) -> Step
    where
        C: Counter,
        K: BoxKernel<W>,
    {
        counter.node_visited();
        counter.boxes_tested(W as u32);
        let node = &layout.nodes[self.current as usize];
        let (mask, entry) = K::test(&node.boxes, &self.box_ray, self.box_tmin, self.box_tmax);
        if let Some(next) =
            layout.descend::<NEAREST_FIRST>(&node.children, mask, &entry, &mut self.stack)
        {
            if PREFETCH_NEXT {
                layout.prefetch(next);
            }
            self.current = next;
            return Step::Continue;
        }
        self.resume()
    }

    /// Goes on to the nearest postponed child that begins within the interval.
    #[inline(always)]
    fn resume(&mut self) -> Step {
        loop {
            match self.stack.pop() {
                Some((n, near)) if near <= self.box_tmax => {
                    self.current = n;
                    return Step::Continue;
                }
                Some(_) => continue,
                None => return Step::Done,
            }
        }
    }
}

/// What a ray's box tests need (its reciprocal direction, margins and box-kernel constants),
/// computed before the rest of its preparation so that the root box can be tested first.
struct BoxSetup {
    inv: glam::Vec3,
    box_margin: f32,
    slab_margin: f32,
    box_ray: BoxRay,
}

impl BoxSetup {
    #[inline(always)]
    fn new(ray: &Ray, scene_size: f32) -> Self {
        let inv = PreparedRay::inverse_of(ray.direction);
        let (box_margin, slab_margin) = PreparedRay::margins(ray.origin, ray.direction, scene_size);
        let box_ray = BoxRay::from_parts(ray.origin, ray.direction, inv, slab_margin);
        Self {
            inv,
            box_margin,
            slab_margin,
            box_ray,
        }
    }

    /// The rest: the prepared ray, with these margins.
    #[inline(always)]
    fn prepared(&self, ray: &Ray) -> PreparedRay {
        let mut prepared = PreparedRay::with_inverse(ray, self.inv);
        (prepared.box_margin, prepared.slab_margin) = (self.box_margin, self.slab_margin);
        prepared
    }
}
