//! Optimizers: improve a built tree in place, whatever builder made it.
//!
//! - [`ReinsertionOptimizer`] (`reinsertion.rs`): insertion-based optimization (Bittner, Hapala &
//!   Havran 2013): moves subtrees to where the tree cost grows least, with the placement search
//!   of the insertion builder.
//! - [`collapse_leaves`] (`collapse.rs`): replaces subtrees by single leaves where that lowers
//!   the SAH cost, up to a leaf size.
//!
//! A typical pipeline builds with leaves of one triangle, optimizes, then collapses:
//!
//! ```
//! use hbv::bvh::build::{Builder, InsertionBuilder};
//! use hbv::bvh::optimize::{collapse_leaves, CollapseConfig, ReinsertionOptimizer};
//! use hbv::bvh::expected_tests;
//! use hbv::mesh::procedural::torus;
//! use hbv::glam::Vec3;
//!
//! let mesh = torus(Vec3::ZERO, 2.0, 0.5, 48, 24);
//! let mut tree = InsertionBuilder::default().build(&mesh);
//! let report = ReinsertionOptimizer::default().optimize(&mut tree);
//! assert!(report.cost_after <= report.cost_before);
//! assert_eq!(report.cost_after, expected_tests(&tree));
//! collapse_leaves(&mut tree, &CollapseConfig::default());
//! tree.compact(); // drop the nodes the two steps released
//! ```

mod collapse;
mod reinsertion;

pub use collapse::{collapse_leaves, CollapseConfig};
pub use reinsertion::{
    ReinsertionConfig, ReinsertionOptimizer, ReinsertionReport, StopReason, MIN_BATCH,
    OPTIMIZE_BY_DEFAULT_MAX_TRIANGLES,
};
