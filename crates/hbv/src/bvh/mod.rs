//! Bounding volume hierarchies: the build-time tree, its builders and cost, and its layouts.

pub mod build;
pub mod cost;
pub mod dynamic;
pub mod file;
pub mod layout;
pub mod measured_cost;
pub mod morton;
mod name_table;
pub mod optimize;
pub mod placement;
mod tree;
mod tree_cost;
mod tree_edits;

pub use cost::{expected_tests, sah_cost, SahWeights};
pub use name_table::UnknownName;
pub use tree::{BuildNode, BuildTree, InvariantError, NodeContent, NodeId, NodeList, TreeShape};
pub use tree_cost::TreeCost;
