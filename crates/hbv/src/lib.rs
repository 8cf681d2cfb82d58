//! hbv: hierarchical bounding volumes for ray tracing triangle meshes.
//!
//! The pieces, in the order data flows through them:
//! - [`mesh`]: [`TriangleMesh`] and its loaders (OBJ, PLY, glTF).
//! - [`geometry`]: boxes, rays and the watertight ray/triangle test.
//! - [`bvh`]: the build-time tree, its builders, its cost E\[X\] and the layouts that trace it.
//! - [`query`]: the [`Accelerator`] trait every structure answers, with batch queries.
//! - [`BruteForce`]: the reference every accelerator is tested against.
//! - [`grid`]: the uniform grid (3D-DDA, mailboxes); [`cache`]: shadow and last-hit caches;
//!   [`scene_accelerators`]: one structure per ray type.
//! - [`scene`]: many meshes placed by instances (transforms, masks) in a two-level BVH.
//! - [`atomic_file`]: files written whole or not at all (saved trees, and the command line's
//!   outputs).
//!
//! ```
//! use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig};
//! use hbv::bvh::{expected_tests, layout::RecursiveLayout};
//! use hbv::geometry::Ray;
//! use hbv::mesh::procedural::icosphere;
//! use hbv::Accelerator;
//! use hbv::glam::Vec3;
//!
//! let mesh = icosphere(Vec3::ZERO, 1.0, 3);
//! let tree = InsertionBuilder::new(InsertionConfig::default()).build(&mesh);
//! assert!(expected_tests(&tree) > 1.0);
//! let bvh = RecursiveLayout::new(&tree, &mesh);
//! let hit = bvh.intersect(&Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z)).unwrap();
//! assert!((hit.t - 4.0).abs() < 0.05);
//! assert!(bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
//! ```

pub mod geometry;
pub mod mesh;

pub use mesh::{MeshError, TriangleMesh};
pub mod query;
pub mod stats;

pub use query::{Accelerator, Hit};
pub use stats::TraversalStats;
mod brute_force;
pub mod bvh;
pub mod cache;
pub mod grid;
pub mod scene_accelerators;

pub use brute_force::BruteForce;

pub mod all_hits;
pub mod atomic_file;
pub mod batch_threads;
pub mod proximity;
pub mod scene;

pub use all_hits::AllHits;
pub use scene::Scene;

/// The property tests' case counts (`PROPTEST_CASES`, `HBV_PROPTEST_SCALE`), one file for these
/// unit tests and the integration tests.
#[cfg(test)]
#[path = "../tests/common/cases.rs"]
mod proptest_cases;

/// The vector types of the API (`Vec3`), re-exported so that users need not match its version.
pub use glam;
