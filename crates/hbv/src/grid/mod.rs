//! The uniform grid: cells of equal size over the scene's box, each listing the triangles that
//! overlap it, traversed cell by cell along the ray (3D-DDA) with mailboxes.
//!
//! | file | concept |
//! | --- | --- |
//! | `uniform_grid.rs` | [`UniformGrid`] and [`GridConfig`]: building the cell lists, the closest- and any-hit kernels |
//! | `grid_shape.rs` | [`GridShape`]: the grid's box, resolution (λ·N^(1/3) cells per axis) and cell boxes |
//! | `triangle_box.rs` | [`triangle_overlaps_box`]: exact separating-axis test (Akenine-Möller 2001) |
//! | `dda.rs` | [`CellWalk`]: the cells a ray crosses, in order (Amanatides & Woo 1987) |
//! | `mailbox.rs` | [`Mailbox`]: a ray never tests a triangle twice |
//! | `all_hits.rs` | [`AllHits`](crate::AllHits) for the grid: every hit along the ray, one walk |

mod all_hits;
mod dda;
mod grid_shape;
mod mailbox;
mod triangle_box;
mod uniform_grid;

pub use dda::CellWalk;
pub use grid_shape::GridShape;
pub use mailbox::Mailbox;
pub use triangle_box::triangle_overlaps_box;
pub use uniform_grid::{GridConfig, UniformGrid};
