//! Builders: each turns a mesh into a [`BuildTree`], knowing nothing of
//! how the tree will be laid out or traversed. [`BuilderKind`] names each builder
//! (`binned-sah`, ...) and makes it from its name and options.

mod binned_sah;
mod insertion;
mod kind;
mod lbvh;
mod leaf_policy;
mod median;
mod order;
mod ploc;
mod quality;
mod range_tree;
mod sweep_sah;

pub use binned_sah::{BinnedSahBuilder, BinnedSahConfig};
pub use insertion::{InsertionBuilder, InsertionConfig};
pub use kind::{BuilderKind, BuilderOptions};
pub use lbvh::{LbvhBuilder, LbvhConfig};
pub use leaf_policy::LeafPolicy;
pub use median::{MedianBuilder, MedianConfig};
pub use order::InsertionOrder;
pub use ploc::{PlocBuilder, PlocConfig};
pub use quality::BuildQuality;
pub use sweep_sah::{SweepSahBuilder, SweepSahConfig};

// What the direct wide build (`layout::wide`) uses of the binned SAH builder: its triangle
// records and its choice and application of one node's split.
pub(crate) use binned_sah::{BinCounts, NodeSplit};

// Shared by the top-down builders, which import them as `super::...`.
pub(crate) use range_tree::{bounds_and_centroid_bounds, prim_refs, PrimRef, SideBounds};
use range_tree::{RangeTree, Subtree, PARALLEL_SUBTREE_MIN, SAH_DEPTH_LIMIT};

use crate::bvh::BuildTree;
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

/// A tree construction algorithm. Every builder makes the same [`BuildTree`], so every layout,
/// cost and query works on any of them; degenerate triangles are left out of every tree.
pub trait Builder: Send + Sync {
    /// The name used on the command line and in tables (`insertion`, `binned-sah`, ...).
    fn name(&self) -> &'static str;

    /// Builds a tree over the non-degenerate triangles of `mesh`.
    fn build(&self, mesh: &TriangleMesh) -> BuildTree;
}

/// The box of every triangle of `mesh`, in face order; the empty box for a degenerate triangle,
/// which builders leave out of the tree (it is never hit).
pub fn primitive_bounds(mesh: &TriangleMesh) -> Vec<Aabb> {
    mesh.triangles()
        .map(|t| {
            if t.is_degenerate() {
                Aabb::EMPTY
            } else {
                t.bounds()
            }
        })
        .collect()
}

// What the top-down builders (binned and sweep SAH, median, LBVH) share: the triangles they
// sort and partition, and the compact binary tree they fill in parallel before it is copied
// into a `BuildTree`.
