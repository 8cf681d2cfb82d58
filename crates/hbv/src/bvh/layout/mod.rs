//! Layouts: a [`BuildTree`](crate::bvh::BuildTree) packed for traversal, each answering the
//! [`Accelerator`](crate::Accelerator) queries. Layouts never know which builder made the tree.
//!
//! [`LayoutKind`] names each layout (`wide8`, ...) and lays a tree out by name.
//!
//! | layout | nodes | traversal |
//! | --- | --- | --- |
//! | [`RecursiveLayout`] | n-ary, as built | depth first, children in stored order |
//! | [`SkipLayout`] | n-ary, depth-first array with skip pointers | stackless, fixed order (the seed's) |
//! | [`OrderedLayout`] | binary, siblings side by side | stack, nearer child first |
//! | [`WideLayout`] (`Wide4Layout`, `Wide8Layout`) | 4 or 8 children, boxes as SIMD lanes; triangles in packets of 4 | stack, nearest first, SIMD box and triangle tests |

mod binarize;
mod kind;
mod leaf_triangles;
mod ordered;
mod recursive;
mod skip;
mod stack;
mod wide;

pub use binarize::binarize;
pub use kind::{AnyLayout, LayoutKind, LayoutOptions, DIRECT_BUILD_MIN_TRIANGLES};
pub use ordered::OrderedLayout;
pub use recursive::RecursiveLayout;
pub use skip::SkipLayout;
pub(crate) use stack::TraversalStack;
pub(crate) use wide::LaneBoxes;
pub use wide::{Wide4Layout, Wide8Layout, WideLayout};
