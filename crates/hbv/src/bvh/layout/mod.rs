//! Layouts: a [`BuildTree`](crate::bvh::BuildTree) packed for traversal, each answering the
//! [`Accelerator`](crate::Accelerator) queries. Layouts never know which builder made the tree.

mod recursive;

pub use recursive::RecursiveLayout;
