//! hbv: hierarchical bounding volumes for ray tracing triangle meshes.
//!
//! The pieces, in the order data flows through them:
//! - [`mesh`]: [`TriangleMesh`] and its loaders (OBJ, PLY, glTF).
//! - [`geometry`]: boxes, rays and the watertight ray/triangle test.
//! - [`bvh`]: the build-time tree, its builders, its cost E\[X\] and the layouts that trace it.
//! - [`query`]: the [`Accelerator`] trait every structure answers, with batch queries.
//! - [`BruteForce`]: the reference every accelerator is tested against.

pub mod geometry;
pub mod mesh;

pub use mesh::{MeshError, TriangleMesh};
pub mod query;
pub mod stats;

pub use query::{Accelerator, Hit};
pub use stats::TraversalStats;
mod brute_force;
pub mod bvh;

pub use brute_force::BruteForce;
