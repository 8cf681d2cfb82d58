//! Wide nodes: 4 or 8 children per node, their boxes tested together with SIMD ([`WideLayout`]).
//!
//! | file | what it holds |
//! | --- | --- |
//! | `node.rs` | a node: `W` child boxes as SIMD lanes, and the references to nodes and leaves |
//! | `collapse.rs` | the layout made from a build tree: binary nodes collapsed into wide ones |
//! | `direct_build.rs` | the layout built from a mesh by binned SAH, without a build tree |
//! | `fragment.rs` | a part of a layout built by one task, and the parts joined |
//! | `leaf_packets.rs` | a leaf's triangles packed in fours |
//! | `box_kernels.rs` | `W` boxes against one ray: the scalar definition, SSE and AVX |
//! | `triangle_packet.rs` | four triangles against one ray, the leaves' storage |
//! | `kernels.rs` | the instruction set the queries run, chosen once per layout |
//! | `queries.rs` | closest hit and any hit, single rays and batches, per width |
//! | `traversal.rs` | one ray's walk, a node at a time |
//! | `descend.rs` | the order in which a ray takes a node's children |
//! | `prefetch.rs` | asking for the memory of postponed children early |
//! | `leaf.rs` | one ray at a leaf |
//! | `stream.rs` | batches interleaved, to hide memory latency |
//! | `root_filter.rs` | a batch's rays against the root box, eight at a time |
//! | `ray_packet/` | coherent rays traced eight at a time (8-wide nodes, AVX2) |
//! | `all_hits.rs` | every hit along a ray |
//! | `lanes.rs` | lane masks |
//! | `validate.rs` | the layout's invariants, checked |

mod all_hits;
mod box_kernels;
mod collapse;
mod descend;
mod direct_build;
mod fragment;
mod kernels;
mod lanes;
mod leaf;
mod leaf_packets;
mod node;
mod prefetch;
mod queries;
#[cfg(target_arch = "x86_64")]
mod ray_packet;
mod root_filter;
mod stream;
mod traversal;
mod triangle_packet;
mod validate;

pub(crate) use box_kernels::LaneBoxes;

use crate::geometry::{Aabb, PreparedRay};
use kernels::Kernels;
use node::WideNode;
use triangle_packet::TrianglePacket;

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
/// it, chosen when the layout is made; a scalar twin elsewhere, with identical answers); hit
/// children are visited nearest first, the others pushed with their entry distance and dropped
/// on pop when they lie beyond the closest hit so far.
#[derive(Clone, Debug)]
pub struct WideLayout<const W: usize> {
    nodes: Vec<WideNode<W>>,
    packets: Vec<TrianglePacket>,
    /// The root reference (a node, or a leaf for trees of one leaf), with the root's box and
    /// its [`PreparedRay::scene_size`](crate::geometry::PreparedRay::scene_size).
    root: Option<(u32, Aabb, f32)>,
    /// The kernels the queries run, chosen from what the CPU has when the layout is made
    /// (packets of coherent rays only for 8-wide nodes on a CPU with AVX2, unless turned off:
    /// [`WideLayout::with_ray_packets`]).
    kernels: Kernels,
    /// The median over triangle packets of their box's largest extent: the size of the
    /// patches rays tell apart at the leaves (what a packet of rays is compared with, in
    /// [`ray_packet`]).
    packet_extent: f32,
    /// Whether traversals prefetch the nodes they are about to visit: only for layouts larger
    /// than [`PREFETCH_ABOVE_BYTES`](prefetch::PREFETCH_ABOVE_BYTES), which the caches nearest
    /// the core cannot hold.
    prefetch: bool,
    /// Whether batches interleave their rays ([`stream`]): only for layouts larger than
    /// [`INTERLEAVE_ABOVE_BYTES`](stream::INTERLEAVE_ABOVE_BYTES); smaller ones answer each ray
    /// in turn.
    interleave: bool,
}

/// 4-wide nodes (SSE).
pub type Wide4Layout = WideLayout<4>;
/// 8-wide nodes (AVX where available).
pub type Wide8Layout = WideLayout<8>;

impl<const W: usize> WideLayout<W> {
    /// The layout of `nodes` and `packets` under the root reference and box `root` (`None` for
    /// an empty tree), with the kernels of this CPU and the settings its size calls for.
    fn from_parts(
        nodes: Vec<WideNode<W>>,
        packets: Vec<TrianglePacket>,
        root: Option<(u32, Aabb)>,
    ) -> Self {
        let mut layout = Self {
            nodes,
            packets,
            root: root
                .map(|(reference, bounds)| (reference, bounds, PreparedRay::scene_size(&bounds))),
            kernels: Kernels::for_this_cpu(W, true),
            packet_extent: 0.0,
            prefetch: false,
            interleave: false,
        };
        layout.packet_extent = collapse::median_packet_extent(&layout.packets);
        layout.prefetch = layout.memory_bytes() > prefetch::PREFETCH_ABOVE_BYTES;
        layout.interleave = layout.memory_bytes() > stream::INTERLEAVE_ABOVE_BYTES;
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
        self.kernels = Kernels::for_this_cpu(W, on);
        self
    }

    /// Whether batches trace packets of coherent rays ([`WideLayout::with_ray_packets`]).
    pub fn traces_ray_packets(&self) -> bool {
        self.kernels.traces_ray_packets()
    }

    /// Bytes of node and triangle data.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<WideNode<W>>()
            + self.packets.len() * std::mem::size_of::<TrianglePacket>()
    }
}
