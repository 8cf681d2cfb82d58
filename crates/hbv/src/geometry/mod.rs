//! Geometric primitives: boxes, rays and triangles, and the exact tests between them.

mod aabb;
pub(crate) mod directed_rounding;
mod edge_rule;
pub(crate) mod exact_sign;
mod ray;
mod triangle;

pub use aabb::Aabb;
pub use edge_rule::EdgeRule;
pub use ray::{PreparedRay, Ray};
pub(crate) use triangle::{shared_edge_error, DEPTH_FLOOR, SHARED_EDGE_ERROR};
pub use triangle::{Triangle, TriangleHit};
