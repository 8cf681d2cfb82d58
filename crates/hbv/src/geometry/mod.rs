//! Geometric primitives: boxes, rays and triangles, and the exact tests between them.

mod aabb;
mod ray;
mod triangle;

pub use aabb::Aabb;
pub use ray::{PreparedRay, Ray};
pub(crate) use triangle::{edge_error, EDGE_ERROR};
pub use triangle::{Triangle, TriangleHit};
