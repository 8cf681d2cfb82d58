//! Wide nodes: 4 or 8 children per node, their boxes tested together with SIMD.

mod all_hits;
mod box_kernels;
#[cfg(target_arch = "x86_64")]
mod ray_packet;
mod root_filter;
mod stream;
mod traversal;
mod triangle_packet;

use traversal::{Step, Traversal};

pub(super) use triangle_packet::TrianglePacket;

use super::binarize::binary_form;
use super::stack::TraversalStack;
use crate::bvh::tree::{BuildTree, NodeId};
use crate::geometry::{Aabb, EdgeRule, PreparedRay, Ray, TriangleHit};
use crate::mesh::TriangleMesh;
use crate::query::{record_hit, Hit, TraversalKernel};
use crate::stats::{Counter, NoCount};
use box_kernels::{BoxRay, LaneBoxes, Lanes};

/// Bit 31 of a child reference: the child is a leaf.
const LEAF: u32 = 1 << 31;
/// A leaf reference: bits 27..31 hold the number of triangle packets minus one (1 to 16
/// packets), bits 0..27 the first packet.
const LEAF_COUNT_SHIFT: u32 = 27;
const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;
/// Most triangles in one leaf: 16 packets of 4.
const MAX_LEAF_TRIANGLES: usize = 64;

/// A node with up to `W` children: their boxes in structure-of-arrays form (one SIMD load per
/// axis and side), and a reference to each (a node, or a leaf's triangle packets).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct WideNode<const W: usize> {
    boxes: LaneBoxes<W>,
    children: [u32; W],
}

/// A BVH of `W`-wide nodes (W = 4 or 8) collapsed from the binary tree, with SIMD box tests,
/// nearest-first traversal, and leaf triangles in packets of four tested together.
///
/// **Collapse** (after Wald et al. 2008, "Getting rid of packets"; Dammertz et al. 2008): each
/// wide node starts from a binary node's two children and repeatedly opens the child with the
/// largest surface area — the one most rays reach — until it has `W` children or only leaves.
/// A subtree of at most four triangles becomes one leaf: testing four triangles in one packet
/// costs what testing one does. (An SAH-optimal collapse by dynamic programming, Ylitie et al.
/// 2017, tested 3–4% fewer boxes per ray but traced 5–15% slower here: BENCHMARKS.md.)
///
/// **Traversal**: the `W` child boxes are tested at once (SSE for 4, AVX for 8 where the CPU has
/// it, chosen at run time; a scalar twin elsewhere, with identical answers); hit children are
/// visited nearest first, the others pushed with their entry distance and dropped on pop when
/// they lie beyond the closest hit so far.
#[derive(Clone, Debug)]
pub struct WideLayout<const W: usize> {
    nodes: Vec<WideNode<W>>,
    packets: Vec<TrianglePacket>,
    /// The root reference (a node, or a leaf for trees of one leaf), with the root's box and
    /// its [`PreparedRay::scene_size`].
    root: Option<(u32, Aabb, f32)>,
    use_avx: bool,
    /// Whether batches trace coherent runs of eight rays as packets ([`ray_packet`]): 8-wide
    /// nodes on a CPU with AVX2, unless turned off ([`WideLayout::with_ray_packets`]).
    packets_of_rays: bool,
    /// The median over triangle packets of their box's largest extent: the size of the
    /// patches rays tell apart at the leaves (what a packet of rays is compared with, in
    /// [`ray_packet`]).
    packet_extent: f32,
    /// Whether traversals prefetch the nodes they are about to visit: only for layouts larger
    /// than [`PREFETCH_ABOVE_BYTES`], which the caches nearest the core cannot hold.
    prefetch: bool,
    /// Whether batches interleave their rays ([`stream`]): only for layouts larger than
    /// [`INTERLEAVE_ABOVE_BYTES`]; smaller ones answer each ray in turn.
    interleave: bool,
}

/// A layout up to this size stays in a core's L1 data cache (32–48 KiB on current x86 cores):
/// there is no memory latency for interleaved rays to hide, only their bookkeeping to pay
/// (measured on the 36-triangle Cornell box: single rays 12.2 Mrays/s, interleaved 9.9; teapot,
/// 0.4 MiB: single 4.9, interleaved 5.6).
const INTERLEAVE_ABOVE_BYTES: usize = 32 << 10;

/// Layouts up to this size stay in a core's L2 cache (1–2 MiB on current x86 cores) once warm;
/// prefetching their nodes only costs instructions (measured: 80 per ray on a 0.4 MiB tree).
const PREFETCH_ABOVE_BYTES: usize = 2 << 20;

/// 4-wide nodes (SSE).
pub type Wide4Layout = WideLayout<4>;
/// 8-wide nodes (AVX where available).
pub type Wide8Layout = WideLayout<8>;

impl<const W: usize> WideLayout<W> {
    const VALID_WIDTH: () = assert!(W == 4 || W == 8, "WideLayout supports widths 4 and 8");

    /// Lays out `tree` (binarized, then collapsed to `W`-wide nodes).
    pub fn new(tree: &BuildTree, mesh: &TriangleMesh) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_WIDTH;
        let binary = binary_form(tree);
        let counts = binary.triangle_counts();
        let mut layout = Self {
            nodes: Vec::new(),
            packets: Vec::new(),
            root: None,
            use_avx: detect_avx(),
            packets_of_rays: W == 8 && detect_avx2(),
            packet_extent: 0.0,
            prefetch: false,
            interleave: false,
        };
        if let Some(root) = binary.root() {
            // About 3.3 triangles per packet and 4 packets per node in the shared scenes:
            // room for all of them at once, rather than copies as the arrays grow.
            let packets = counts[root as usize] as usize / 3 + 1;
            layout.packets.reserve(packets);
            layout.nodes.reserve(packets / 3 + 1);
            let reference = layout.emit(&binary, &counts, mesh, root);
            let bounds = binary.node(root).bounds;
            layout.root = Some((reference, bounds, PreparedRay::scene_size(&bounds)));
        }
        layout.packet_extent = median_packet_extent(&layout.packets);
        layout.prefetch = layout.memory_bytes() > PREFETCH_ABOVE_BYTES;
        layout.interleave = layout.memory_bytes() > INTERLEAVE_ABOVE_BYTES;
        layout
    }

    /// This layout with packets of coherent rays in its batches on (the default, where the CPU
    /// has AVX2 and `W` is 8) or off.
    ///
    /// Batches ([`Accelerator::intersect_batch`](crate::Accelerator::intersect_batch),
    /// `occluded_batch` and the `_into` forms) trace each run of eight consecutive rays that
    /// share direction signs and dominant axis and form a narrow beam (camera rays in pixel
    /// order, a lidar's scan lines, sunlight) as one packet, one ray per AVX lane, and the
    /// other rays one by one, interleaved. The answers are the same either way; off, every ray
    /// is traced alone (for comparisons of the two).
    pub fn with_ray_packets(mut self, on: bool) -> Self {
        self.packets_of_rays = on && W == 8 && detect_avx2();
        self
    }

    /// Whether batches trace packets of coherent rays ([`WideLayout::with_ray_packets`]).
    pub fn traces_ray_packets(&self) -> bool {
        self.packets_of_rays
    }

    /// Whether the traversals run the AVX kernels (8-wide nodes on a CPU with AVX; only then is
    /// an AVX entry point called). Callers outside this module that pass a leaf visitor write it
    /// in a function compiled with AVX then (see `all_hits.rs`).
    pub(super) fn traverses_with_avx(&self) -> bool {
        W == 8 && self.use_avx
    }

    /// Bytes of node and triangle data.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<WideNode<W>>()
            + self.packets.len() * std::mem::size_of::<TrianglePacket>()
    }

    /// Emits the subtree at binary node `id` as the collapse `plan` says, and returns its
    /// reference. Iterative over a work list, so that no depth overflows the call stack; no
    /// allocation per node (a leaf's triangles are gathered into one reused list).
    fn emit(&mut self, binary: &BuildTree, counts: &[u32], mesh: &TriangleMesh, id: NodeId) -> u32 {
        let is_leaf = |c: NodeId| binary.node(c).is_leaf() || counts[c as usize] as usize <= 4;
        let mut prims = Vec::new();
        if is_leaf(id) {
            binary.prims_below_into(id, &mut prims);
            return self.emit_leaf(mesh, &prims);
        }
        let root = self.nodes.len() as u32;
        self.nodes.push(WideNode::empty());
        let mut work: Vec<(NodeId, u32)> = vec![(id, root)];
        while let Some((id, slot)) = work.pop() {
            let mut node = WideNode::empty();
            let (children, count) = collapse::<W>(binary, counts, id);
            for (lane, &c) in children[..count].iter().enumerate() {
                node.set_box(lane, &binary.node(c).bounds);
                node.children[lane] = if is_leaf(c) {
                    binary.prims_below_into(c, &mut prims);
                    self.emit_leaf(mesh, &prims)
                } else {
                    let index = self.nodes.len() as u32;
                    self.nodes.push(WideNode::empty());
                    work.push((c, index));
                    index
                };
            }
            self.nodes[slot as usize] = node;
        }
        root
    }

    /// Packs `prims` into triangle packets and returns the leaf reference; more than a leaf holds
    /// (only from builders' leaves of up to 255 triangles) become a node over several leaves.
    fn emit_leaf(&mut self, mesh: &TriangleMesh, prims: &[u32]) -> u32 {
        if prims.len() > MAX_LEAF_TRIANGLES {
            let index = self.nodes.len() as u32;
            self.nodes.push(WideNode::empty());
            let mut node = WideNode::empty();
            for (lane, group) in prims.chunks(prims.len().div_ceil(W)).enumerate() {
                let bounds = group.iter().fold(Aabb::EMPTY, |b, &p| {
                    b.union(&mesh.triangle(p as usize).bounds())
                });
                node.set_box(lane, &bounds);
                node.children[lane] = self.emit_leaf(mesh, group);
            }
            self.nodes[index as usize] = node;
            return index;
        }
        let first = self.packets.len() as u32;
        assert!(
            first <= LEAF_FIRST_MASK,
            "too many triangle packets for the wide layout"
        );
        for chunk in prims.chunks(4) {
            let triangles: [(u32, crate::geometry::Triangle); 4] = std::array::from_fn(|k| {
                let p = chunk[k.min(chunk.len() - 1)];
                (p, mesh.triangle(p as usize))
            });
            self.packets
                .push(TrianglePacket::new(&triangles[..chunk.len()]));
        }
        let count = prims.len().div_ceil(4) as u32;
        LEAF | ((count - 1) << LEAF_COUNT_SHIFT) | first
    }

    /// One ray's traversal (valid: checked by the caller), nearest child first when
    /// `NEAREST_FIRST`: each leaf reached goes to `visit_leaf(first_packet, packet_count, ray,
    /// counter)`, which returns `true` to stop. See [`Traversal::step`].
    #[inline(always)]
    fn traverse<C: Counter, K: BoxKernel<W>, const NEAREST_FIRST: bool>(
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
}

impl<const W: usize> WideLayout<W> {
    /// The step from a node to its children: of the children whose boxes the ray meets (`mask`,
    /// entering at `entry`), returns the one to visit next and pushes the others, with their
    /// entry distances, onto `stack` (and asks for their memory early); `None` when none is met.
    ///
    /// Nearest first (closest hit): the nearest child is visited next and the others are pushed
    /// farthest first, so that they are popped in order of distance (Wald et al. 2008 order
    /// wide-node children the same way). Any hit (`NEAREST_FIRST = false`): every met child must
    /// be searched unless a hit ends the query, so they are taken in lane order, unsorted.
    #[inline(always)]
    fn descend<const NEAREST_FIRST: bool>(
        &self,
        children: &[u32; W],
        mask: u32,
        entry: &[f32; W],
        stack: &mut TraversalStack<(u32, f32), 64>,
    ) -> Option<u32> {
        let mut hits = Lanes(mask);
        let first = hits.next()?;
        let rest = hits.0;
        if !NEAREST_FIRST {
            if rest & rest.wrapping_sub(1) == 0 {
                // One or two: as below, without a branch on which.
                let second = if rest == 0 {
                    first
                } else {
                    rest.trailing_zeros() as usize
                };
                self.prefetch(children[second]);
                stack.push_if((children[second], entry[second]), rest != 0);
                return Some(children[first]);
            }
            for lane in hits {
                self.prefetch(children[lane]);
                stack.push((children[lane], entry[lane]));
            }
            return Some(children[first]);
        }
        if rest & rest.wrapping_sub(1) == 0 {
            // One or two children met (most nodes): visit the nearer, postpone the other if
            // there is one. Selects, not branches, on which case it is: it is unpredictable.
            let second = if rest == 0 {
                first
            } else {
                rest.trailing_zeros() as usize
            };
            let (near, far) = if entry[second] < entry[first] {
                (second, first)
            } else {
                (first, second)
            };
            self.prefetch(children[far]);
            stack.push_if((children[far], entry[far]), rest != 0);
            return Some(children[near]);
        }
        let item = |lane: usize| (children[lane], entry[lane]);
        let exchange = |x: &mut (u32, f32), y: &mut (u32, f32)| {
            let swap = x.1 < y.1;
            let (p, q) = (*x, *y);
            *x = if swap { q } else { p };
            *y = if swap { p } else { q };
        };
        let rest2 = rest & (rest - 1);
        if rest2 & (rest2 - 1) == 0 {
            // Three: a sorting network of three compare-exchanges, as selects.
            let (mut a, mut b, mut c) = (
                item(first),
                item(rest.trailing_zeros() as usize),
                item(rest2.trailing_zeros() as usize),
            );
            exchange(&mut a, &mut b);
            exchange(&mut b, &mut c);
            exchange(&mut a, &mut b);
            // a ≥ b ≥ c by entry distance: the farthest goes deepest into the stack.
            self.prefetch(a.0);
            stack.push(a);
            self.prefetch(b.0);
            stack.push(b);
            return Some(c.0);
        }
        let rest3 = rest2 & (rest2 - 1);
        if rest3 & (rest3 - 1) == 0 {
            // Four: five compare-exchanges.
            let (mut a, mut b, mut c, mut d) = (
                item(first),
                item(rest.trailing_zeros() as usize),
                item(rest2.trailing_zeros() as usize),
                item(rest3.trailing_zeros() as usize),
            );
            exchange(&mut a, &mut b);
            exchange(&mut c, &mut d);
            exchange(&mut a, &mut c);
            exchange(&mut b, &mut d);
            exchange(&mut b, &mut c);
            for x in [a, b, c] {
                self.prefetch(x.0);
                stack.push(x);
            }
            return Some(d.0);
        }
        // Five or more: insertion sort by decreasing entry distance (at most 8 entries).
        let mut order = [(0u32, 0.0f32); W];
        let mut n = 0;
        for lane in Lanes(mask) {
            let item = (children[lane], entry[lane]);
            let mut k = n;
            while k > 0 && order[k - 1].1 < item.1 {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = item;
            n += 1;
        }
        for &item in &order[..n - 1] {
            self.prefetch(item.0);
            stack.push(item);
        }
        Some(order[n - 1].0)
    }
}

impl<const W: usize> WideLayout<W> {
    /// Asks the CPU to start loading the node or leaf that `reference` names, every cache line
    /// of it: postponed children are fetched while the nearer subtree is traversed.
    #[inline(always)]
    fn prefetch(&self, reference: u32) {
        #[cfg(target_arch = "x86_64")]
        if self.prefetch {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let address = if reference & LEAF != 0 {
                let first = (reference & LEAF_FIRST_MASK) as usize;
                self.packets.as_ptr().wrapping_add(first) as *const i8
            } else {
                self.nodes.as_ptr().wrapping_add(reference as usize) as *const i8
            };
            // Four lines: a whole 8-wide node (256 bytes), or a 4-wide node and its neighbour,
            // or a leaf's first packet (160 bytes) and most of its second. (Two lines, counting
            // on the adjacent-line prefetcher, traced the dragon 40% slower.) A fixed count
            // keeps this branch-free.
            for line in 0..4 {
                // SAFETY: a prefetch is a hint; it never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(address.wrapping_add(64 * line)) };
            }
        }
    }
}

impl<const W: usize> WideNode<W> {
    fn empty() -> Self {
        Self {
            boxes: [[[f32::INFINITY; W]; 3], [[f32::NEG_INFINITY; W]; 3]],
            children: [0; W],
        }
    }

    fn set_box(&mut self, lane: usize, bounds: &Aabb) {
        for axis in 0..3 {
            self.boxes[0][axis][lane] = bounds.min[axis];
            self.boxes[1][axis][lane] = bounds.max[axis];
        }
    }
}

/// The children of a wide node made from binary node `id`, and how many there are: start from
/// its two children and open the internal child of largest surface area until there are `W` or
/// none can be opened. A child whose subtree holds at most four triangles is not opened: it
/// becomes one leaf.
fn collapse<const W: usize>(
    binary: &BuildTree,
    counts: &[u32],
    id: NodeId,
) -> ([NodeId; W], usize) {
    let mut children = [0; W];
    let mut count = 0;
    for &c in binary.node(id).children() {
        children[count] = c;
        count += 1;
    }
    while count < W {
        let openable = children[..count]
            .iter()
            .enumerate()
            .filter(|(_, &c)| !binary.node(c).is_leaf() && counts[c as usize] > 4)
            .max_by(|(_, &a), (_, &b)| {
                binary
                    .node(a)
                    .bounds
                    .surface_area()
                    .total_cmp(&binary.node(b).bounds.surface_area())
            });
        let Some((k, _)) = openable else {
            break;
        };
        // `swap_remove` of slot `k`, then the opened node's two children at the end.
        let opened = children[k];
        count -= 1;
        children[k] = children[count];
        for &c in binary.node(opened).children() {
            children[count] = c;
            count += 1;
        }
    }
    (children, count)
}

/// The median over `packets` of the largest extent of each packet's box (0 for none).
fn median_packet_extent(packets: &[TrianglePacket]) -> f32 {
    let mut extents: Vec<f32> = packets
        .iter()
        .map(|p| {
            let (mut lo, mut hi) = (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY);
            for lane in 0..4 {
                let t = p.triangle(lane);
                lo = lo.min(t.p0).min(t.p1).min(t.p2);
                hi = hi.max(t.p0).max(t.p1).max(t.p2);
            }
            (hi - lo).max_element()
        })
        .collect();
    if extents.is_empty() {
        return 0.0;
    }
    let middle = extents.len() / 2;
    *extents.select_nth_unstable_by(middle, f32::total_cmp).1
}

fn detect_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx") && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

fn detect_avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// How a traversal tests the `W` boxes of a node. The traversal is compiled once per kernel, so
/// the AVX one is compiled with AVX enabled and its box test inlined into the loop.
trait BoxKernel<const W: usize> {
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]);

    /// Whether [`BoxKernel::root_candidates`] decides every valid ray exactly as
    /// [`Traversal::restart`] does, so that the batches may skip that test of the root box.
    const ROOT_FILTER_EXACT: bool = false;

    /// Which of eight rays may meet the root box `bounds` (bit `i` for `rays[i]`): a ray left
    /// out is one the traversal's set-up would reject ([`root_filter`]). All eight by default.
    #[inline(always)]
    fn root_candidates(rays: &[Ray; 8], bounds: &Aabb, scene_size: f32) -> u32 {
        root_filter::all_candidates(rays, bounds, scene_size)
    }
}

/// SSE, four lanes at a time: the x86_64 baseline.
#[cfg(target_arch = "x86_64")]
struct SseBoxes;

#[cfg(target_arch = "x86_64")]
impl<const W: usize> BoxKernel<W> for SseBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        let mut mask = 0;
        let mut entry = [0.0f32; W];
        for offset in (0..W).step_by(4) {
            let (m, e) = box_kernels::boxes_sse(boxes, offset, ray, tmin, tmax);
            mask |= m << offset;
            entry[offset..offset + 4].copy_from_slice(&e);
        }
        (mask, entry)
    }
}

/// AVX, eight lanes at once; used only for `W == 8` on CPUs with AVX, from functions compiled
/// with AVX enabled.
#[cfg(target_arch = "x86_64")]
struct AvxBoxes;

#[cfg(target_arch = "x86_64")]
impl<const W: usize> BoxKernel<W> for AvxBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        assert!(W == 8);
        // SAFETY: W == 8, so the cast is to the same type; the AVX kernel is only reached through
        // `WideLayout::*_avx`, which run only when the CPU reported AVX.
        let boxes8 = unsafe { &*(boxes as *const LaneBoxes<W> as *const LaneBoxes<8>) };
        let (mask, e) = unsafe { box_kernels::boxes_avx(boxes8, ray, tmin, tmax) };
        let mut entry = [0.0f32; W];
        entry.copy_from_slice(&e);
        (mask, entry)
    }

    const ROOT_FILTER_EXACT: bool = true;

    #[inline(always)]
    fn root_candidates(rays: &[Ray; 8], bounds: &Aabb, scene_size: f32) -> u32 {
        // SAFETY: as for `test`, reached only when the CPU reported AVX.
        unsafe { root_filter::root_candidates_avx(rays, bounds, scene_size) }
    }
}

/// The portable fallback.
#[cfg(not(target_arch = "x86_64"))]
struct ScalarBoxes;

#[cfg(not(target_arch = "x86_64"))]
impl<const W: usize> BoxKernel<W> for ScalarBoxes {
    #[inline(always)]
    fn test(boxes: &LaneBoxes<W>, ray: &BoxRay, tmin: f32, tmax: f32) -> (u32, [f32; W]) {
        box_kernels::boxes_scalar(boxes, ray, tmin, tmax)
    }
}

#[cfg(target_arch = "x86_64")]
type DefaultBoxes = SseBoxes;
#[cfg(not(target_arch = "x86_64"))]
type DefaultBoxes = ScalarBoxes;

impl<const W: usize> WideLayout<W> {
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

    #[inline(always)]
    fn any_hit_with<C: Counter, K: BoxKernel<W>>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        let mut found = None;
        self.traverse::<C, K, false>(ray, counter, |first, count, ray, counter| {
            found = self.any_hit_in_leaf(first, count, ray, counter);
            found.is_some()
        });
        found
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
    /// mesh +1–6% (BENCHMARKS.md, session 10). A ray that leaves a surface (a shadow or bounce
    /// ray) meets its blockers in no such order, and there the sorting made it 16–22% slower.
    /// Either order finds a blocker if there is one: only the speed, and which blocker is
    /// reported, depend on it. (Single rays keep lane order: the renderer's shadow rays leave
    /// surfaces, and choosing per ray cost their kernel 2% more instructions.)
    #[inline(always)]
    fn mostly_from_outside(&self, rays: &[Ray]) -> bool {
        const SAMPLE: usize = 16;
        let stride = rays.len().div_ceil(SAMPLE).max(1);
        let (sampled, outside) = rays.iter().step_by(stride).fold((0, 0), |(n, out), r| {
            (n + 1, out + usize::from(self.starts_outside_tree(r.origin)))
        });
        2 * outside > sampled
    }

    /// Tests the `count` triangle packets from `first` for a hit closer than `best`, shrinking
    /// `ray.tmax`: the SIMD test decides what it can, the scalar test the undecided lanes.
    ///
    /// The first packet is tested before the loop over the others: most leaves hold one packet,
    /// and a loop around it led the compiler to hoist the ray's constants out of it into
    /// registers it then spilled (measured: 26 more instructions per leaf).
    #[inline(always)]
    fn closest_hit_in_leaf<C: Counter>(
        &self,
        first: usize,
        count: usize,
        ray: &mut PreparedRay,
        best: &mut Option<Hit>,
        counter: &mut C,
    ) {
        let packets = &self.packets[first..first + count];
        closest_hit_in_packet(&packets[0], ray, best, counter);
        for packet in &packets[1..] {
            closest_hit_in_packet(packet, ray, best, counter);
        }
    }

    /// The triangle packets of leaf reference `leaf` (bit [`LEAF`] set).
    #[inline(always)]
    fn leaf_packets(&self, leaf: u32) -> &[TrianglePacket] {
        let first = (leaf & LEAF_FIRST_MASK) as usize;
        let count = ((leaf & !LEAF) >> LEAF_COUNT_SHIFT) as usize + 1;
        &self.packets[first..first + count]
    }

    /// The face id of a triangle of the `count` packets from `first` that the ray hits, if any.
    /// (The first packet before the loop, as in [`WideLayout::closest_hit_in_leaf`].)
    #[inline(always)]
    fn any_hit_in_leaf<C: Counter>(
        &self,
        first: usize,
        count: usize,
        ray: &PreparedRay,
        counter: &mut C,
    ) -> Option<u32> {
        let packets = &self.packets[first..first + count];
        if let Some(found) = any_hit_in_packet(&packets[0], ray, counter) {
            return Some(found);
        }
        for packet in &packets[1..] {
            if let Some(found) = any_hit_in_packet(packet, ray, counter) {
                return Some(found);
            }
        }
        None
    }

    /// The closest-hit traversal compiled with AVX. Call only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn closest_hit_avx<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        self.closest_hit_with::<C, AvxBoxes>(ray, counter)
    }

    /// The any-hit traversal compiled with AVX. Call only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn any_hit_avx<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        self.any_hit_with::<C, AvxBoxes>(ray, counter)
    }
}

/// [`WideLayout`]'s closest-hit test of one triangle packet: records a hit closer than `best`,
/// shrinking `ray.tmax`. (A function, not a closure: closures in these kernels were left out of
/// line, compiled without the caller's AVX.)
#[inline(always)]
fn closest_hit_in_packet<C: Counter>(
    packet: &TrianglePacket,
    ray: &mut PreparedRay,
    best: &mut Option<Hit>,
    counter: &mut C,
) {
    counter.triangles_tested(4);
    let test = packet.test(ray);
    for lane in Lanes(test.hit) {
        record_hit(test.hit(lane), packet.ids[lane], ray, best);
    }
    for lane in Lanes(test.undecided) {
        if let Some(h) = undecided_lane(packet, lane, ray, EdgeRule::Closed) {
            record_hit(h, packet.ids[lane], ray, best);
        }
    }
}

/// The scalar test ([`crate::geometry::Triangle::intersect_by`]) of a lane the packet test
/// left undecided: a ray within rounding distance of an edge or a vertex, or a hit next to its
/// origin. Rare, and kept out of line: inlined, the scalar test doubled the size of the
/// closest-hit leaf visit (3.5 to 7.2 KB) and made closest hits from Python 2–5 % slower on one
/// thread (BENCHMARKS.md, session 17).
#[cold]
#[inline(never)]
pub(super) fn undecided_lane(
    packet: &TrianglePacket,
    lane: usize,
    ray: &PreparedRay,
    rule: EdgeRule,
) -> Option<TriangleHit> {
    packet.triangle(lane).intersect_by(ray, rule)
}

/// [`WideLayout`]'s any-hit test of one triangle packet: the face id of a triangle the ray hits.
#[inline(always)]
fn any_hit_in_packet<C: Counter>(
    packet: &TrianglePacket,
    ray: &PreparedRay,
    counter: &mut C,
) -> Option<u32> {
    counter.triangles_tested(4);
    let test = packet.test(ray);
    if test.hit != 0 {
        return Some(packet.ids[test.hit.trailing_zeros() as usize]);
    }
    for lane in Lanes(test.undecided) {
        if undecided_lane(packet, lane, ray, EdgeRule::Closed).is_some() {
            return Some(packet.ids[lane]);
        }
    }
    None
}

impl<const W: usize> WideLayout<W> {
    /// Calls `visit` with the triangle packets of every leaf whose box the ray's whole interval
    /// reaches (the interval is never shrunk), in any-hit order: the traversal of the queries
    /// that want every hit. The ray is valid (checked by the caller).
    pub(super) fn for_each_leaf_reached(
        &self,
        ray: &Ray,
        mut visit: impl FnMut(&[TrianglePacket], &PreparedRay),
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe { self.for_each_leaf_reached_avx(ray, &mut visit) };
        }
        self.for_each_leaf_reached_with::<DefaultBoxes>(ray, &mut visit)
    }

    #[inline(always)]
    fn for_each_leaf_reached_with<K: BoxKernel<W>>(
        &self,
        ray: &Ray,
        visit: &mut impl FnMut(&[TrianglePacket], &PreparedRay),
    ) {
        self.traverse::<NoCount, K, false>(ray, &mut NoCount, |first, count, ray, _| {
            visit(&self.packets[first..first + count], ray);
            false
        });
    }

    /// The all-leaves traversal compiled with AVX. Call only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn for_each_leaf_reached_avx(
        &self,
        ray: &Ray,
        visit: &mut impl FnMut(&[TrianglePacket], &PreparedRay),
    ) {
        self.for_each_leaf_reached_with::<AvxBoxes>(ray, visit)
    }
}

impl<const W: usize> TraversalKernel for WideLayout<W> {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe { self.closest_hit_avx(ray, counter) };
        }
        self.closest_hit_with::<C, DefaultBoxes>(ray, counter)
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        self.any_hit_prim(ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe { self.any_hit_avx(ray, counter) };
        }
        self.any_hit_with::<C, DefaultBoxes>(ray, counter)
    }

    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        #[cfg(target_arch = "x86_64")]
        if self.packets_of_rays {
            // SAFETY: set only on a CPU that reported AVX and AVX2.
            return unsafe { self.closest_hits_avx2(rays, hits) };
        }
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe { self.closest_hits_avx(rays, hits) };
        }
        let block = self.root_block::<DefaultBoxes, _>();
        self.trace_batch::<DefaultBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    fn occluders(&self, rays: &[Ray], occluders: &mut [Option<u32>]) {
        // Chosen before the kernel is entered, so that each kernel holds one traversal loop.
        let nearest_first = self.mostly_from_outside(rays);
        #[cfg(target_arch = "x86_64")]
        if self.packets_of_rays {
            // SAFETY: set only on a CPU that reported AVX and AVX2.
            return unsafe {
                if nearest_first {
                    self.any_hits_avx2::<true>(rays, occluders)
                } else {
                    self.any_hits_avx2::<false>(rays, occluders)
                }
            };
        }
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe {
                if nearest_first {
                    self.any_hits_avx::<true>(rays, occluders)
                } else {
                    self.any_hits_avx::<false>(rays, occluders)
                }
            };
        }
        let (visit, block) = (
            stream::any_leaf_visit!(),
            self.root_block::<DefaultBoxes, _>(),
        );
        if nearest_first {
            self.trace_batch::<DefaultBoxes, _, true>(rays, occluders, visit, block)
        } else {
            self.trace_batch::<DefaultBoxes, _, false>(rays, occluders, visit, block)
        }
    }
}

impl<const W: usize> WideLayout<W> {
    /// The closest-hit batch compiled with AVX. Call only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn closest_hits_avx(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let block = self.root_block::<AvxBoxes, _>();
        self.trace_batch::<AvxBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    /// The closest-hit batch with packets of coherent rays ([`ray_packet`]), compiled with
    /// AVX2. Call only when [`WideLayout::packets_of_rays`] is set (8-wide, AVX2).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn closest_hits_avx2(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        // SAFETY: `packets_of_rays` is set only for W == 8: the cast is to the same type.
        let layout = unsafe { &*(self as *const Self as *const WideLayout<8>) };
        let Some(limit) = layout.beam_limit() else {
            return hits.fill(None);
        };
        // SAFETY (the closure): compiled with AVX2, as this function is.
        let block = |eight: &[Ray; 8], out: &mut [Option<Hit>]| unsafe {
            layout.packet_block::<ray_packet::ClosestHits>(eight, out, &limit)
        };
        self.trace_batch::<AvxBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    /// The any-hit batch with packets of coherent rays, as
    /// [`WideLayout::closest_hits_avx2`]; single rays take children nearest first or in lane
    /// order, packets nearest first.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn any_hits_avx2<const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        occluders: &mut [Option<u32>],
    ) {
        // SAFETY: `packets_of_rays` is set only for W == 8: the cast is to the same type.
        let layout = unsafe { &*(self as *const Self as *const WideLayout<8>) };
        let Some(limit) = layout.beam_limit() else {
            return occluders.fill(None);
        };
        // SAFETY (the closure): compiled with AVX2, as this function is.
        let block = |eight: &[Ray; 8], out: &mut [Option<u32>]| unsafe {
            layout.packet_block::<ray_packet::Occluders>(eight, out, &limit)
        };
        let visit = stream::any_leaf_visit!();
        self.trace_batch::<AvxBoxes, _, NEAREST_FIRST>(rays, occluders, visit, block)
    }

    /// The any-hit batch compiled with AVX, children nearest first or in lane order. Call
    /// only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
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
