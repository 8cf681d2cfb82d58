//! Queries about points rather than rays: the nearest point of the surface, and whether a point
//! lies inside a closed mesh.
//!
//! | query | files | how |
//! | --- | --- | --- |
//! | nearest surface point: the interface | [`NearestPointSearch`] (`nearest_point_search`), `answers`, `search_tally` | one point, a batch into a list or into [`ClosestPointColumns`], counted or not, the same methods for every searcher below; each writes one point's search and one batch's ([`AnswerRows`], [`BatchThreads`]) |
//! | nearest surface point: the search tree | [`ClosestPointTree`] (`closest_point_tree`), `search_tree`, `branch_and_bound` | branch and bound over an 8-child BVH (`search_tree`: [`SearchTreeConfig`]): conservative f32 bounds prune nodes (point–box, `box_bound`; near the leaves in a frame facing the surface, `node_frame`) and single triangles (their enclosing slab, cylinder and edge half-spaces: `triangle_enclosure`, eight at a time in an `enclosure_packet`), nearest child first; [`point_triangle`] decides in f64 (`point_triangle_lanes`: four triangles side by side, branch-free, the same bits; `search_lanes`: the AVX and portable forms of the search's lane steps) |
//! | nearest surface point: batches | `batches`, `query_order`, `query_points`, `candidate_grid`, `prefetch` | runs of points shared between threads; the search tree's points searched in Morton order, each seeded with its neighbour's answer (`query_order`), read in place from arrays ([`FlatPoints`]); on meshes of few large triangles, answered from a grid's candidate lists once it pays ([`CandidateGridConfig`]) |
//! | nearest point, first queries of a fresh tree | [`BuildTreeSearch`], [`ClosestPointsOnDemand`] (`on_demand`) | the same branch and bound over the builder's own tree, f64 decisions triangle by triangle, until the 8-child tree has paid for its making |
//! | nearest point, the reference | [`closest_point_brute_force`] (`brute_force`) | every triangle decided in f64, the nearest kept: what the tests compare every search with |
//! | inside a closed mesh | [`inside`] | one ray's parity, from one all-hits traversal (exact under the half-open edge rule); the majority of three for meshes that are not closed |
//! | inside, many points | [`InsideCells`] (`inside_cells`) | a grid whose cells no triangle touches are decided once (one exact test per run of them), so that only points near the surface need a ray |

mod answers;
mod batches;
mod box_bound;
mod branch_and_bound;
mod brute_force;
mod build_tree_search;
mod candidate_grid;
mod closest_point_tree;
mod enclosure_packet;
pub mod inside;
mod inside_cells;
mod nearest_point_search;
mod node_frame;
mod on_demand;
pub mod point_triangle;
mod point_triangle_lanes;
mod prefetch;
mod query_order;
mod query_points;
mod search_lanes;
mod search_tally;
mod search_tree;
mod triangle_enclosure;

pub use answers::{AnswerRows, ClosestPoint, ClosestPointColumns};
pub use batches::BatchThreads;
pub use brute_force::closest_point_brute_force;
pub use build_tree_search::BuildTreeSearch;
pub use candidate_grid::CandidateGridConfig;
pub use closest_point_tree::ClosestPointTree;
pub use inside::{contains, contains_along, contains_by_majority};
pub use inside_cells::{InsideCells, InsideCellsConfig};
pub use nearest_point_search::NearestPointSearch;
pub use on_demand::ClosestPointsOnDemand;
pub use point_triangle::{closest_point_on_triangle, TrianglePoint};
pub use query_points::{FlatPoints, QueryPoints};
pub use search_tally::{SearchTally, Tally};
pub use search_tree::SearchTreeConfig;
