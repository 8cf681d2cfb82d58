//! Queries about points rather than rays: the nearest point of the surface, and whether a point
//! lies inside a closed mesh.
//!
//! | query | file | how |
//! | --- | --- | --- |
//! | nearest surface point | [`closest_point`] | branch and bound over an 8-child BVH (`search_tree`): conservative f32 bounds prune nodes (point–box, `box_bound`; near the leaves in a frame facing the surface, `node_frame`) and single triangles (their enclosing slab, cylinder and edge half-spaces: `triangle_enclosure`, `enclosure_packet`), nearest child first; [`point_triangle`] decides in f64 (`point_triangle_lanes`: four triangles side by side, branch-free, the same bits; `search_lanes`: the AVX and portable forms of the search's lane steps) |
//! | nearest point, first queries of a fresh tree | [`BuildTreeSearch`], [`ClosestPointsOnDemand`] | the same branch and bound over the builder's own tree, f64 decisions triangle by triangle, until the 8-child tree has paid for its making (`on_demand`) |
//! | inside a closed mesh | [`inside`] | one ray's parity, from one all-hits traversal (exact under the half-open edge rule); the majority of three for meshes that are not closed |

mod box_bound;
mod build_tree_search;
mod candidate_grid;
pub mod closest_point;
mod enclosure_packet;
pub mod inside;
mod node_frame;
mod on_demand;
pub mod point_triangle;
mod point_triangle_lanes;
mod prefetch;
mod query_order;
mod query_points;
mod search_lanes;
mod search_tree;
mod triangle_enclosure;

pub use build_tree_search::BuildTreeSearch;
pub use candidate_grid::CandidateGridConfig;
pub use closest_point::{
    closest_point_brute_force, ClosestPoint, ClosestPointColumns, ClosestPointTree, SearchTally,
};
pub use inside::{contains, contains_along, contains_by_majority};
pub use on_demand::ClosestPointsOnDemand;
pub use point_triangle::{closest_point_on_triangle, TrianglePoint};
pub use query_points::{FlatPoints, QueryPoints};
pub use search_tree::SearchTreeConfig;
