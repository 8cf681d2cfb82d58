//! Queries about points rather than rays: the nearest point of the surface, and whether a point
//! lies inside a closed mesh.
//!
//! | query | file | how |
//! | --- | --- | --- |
//! | nearest surface point | [`closest_point`] | branch and bound over a BVH: point–box distance prunes, nearest child first; [`point_triangle`] decides |
//! | inside a closed mesh | [`inside`] | majority of three ray parity counts, each from one all-hits traversal |

pub mod closest_point;
pub mod inside;
pub mod point_triangle;

pub use closest_point::{closest_point_brute_force, ClosestPoint, ClosestPointTree};
pub use inside::contains;
pub use point_triangle::{closest_point_on_triangle, TrianglePoint};
