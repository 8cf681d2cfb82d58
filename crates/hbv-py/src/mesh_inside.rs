//! The inside tests of one closed mesh (`hbv.BVH.contains`, `signed_distance`): the exact
//! parity of a ray's crossings (`hbv::proximity::contains`) until many points have been asked,
//! then an inside grid (`hbv::proximity::InsideCells`) that answers most points by a lookup and
//! most of the rest by a short segment, with the same answers.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use hbv::geometry::Ray;
use hbv::glam::{DVec3, Vec3};
use hbv::proximity::{contains, InsideCells, InsideCellsConfig};
use hbv::query::Hit;
use hbv::{AllHits, TriangleMesh};
use rayon::prelude::*;

/// The points asked of the inside tests after which the grid is made: about the number of
/// exact tests its making costs at 128 cells a side (one per run of free cells), so that a few
/// points never pay for it and many pay once (as `hbv.Scene`'s grid, scene.rs).
const INSIDE_CELLS_AFTER_POINTS: usize = 32_768;

/// A closed mesh's inside grid, made by the call whose points bring the points asked to
/// [`INSIDE_CELLS_AFTER_POINTS`] and kept (a BVH's mesh never changes).
#[derive(Default)]
pub struct InsideCellsOnDemand {
    /// The points asked so far, of every call.
    asked: AtomicUsize,
    /// The grid once made; `None` in it for a mesh that has none (no triangles).
    cells: OnceLock<Option<InsideCells>>,
}

impl InsideCellsOnDemand {
    /// The grid over `mesh` (closed) for a call of `rows` points: made now if these points
    /// bring the count to [`INSIDE_CELLS_AFTER_POINTS`], its free cells decided by
    /// `structure`'s exact test; `None` before.
    pub fn cells<A: AllHits + ?Sized>(
        &self,
        rows: usize,
        mesh: &TriangleMesh,
        structure: &A,
    ) -> Option<&InsideCells> {
        if let Some(cells) = self.cells.get() {
            return cells.as_ref();
        }
        let asked = self
            .asked
            .fetch_add(rows, Ordering::Relaxed)
            .saturating_add(rows);
        if asked < INSIDE_CELLS_AFTER_POINTS {
            return None;
        }
        let exact = |centres: &[DVec3]| -> Vec<bool> {
            centres
                .par_iter()
                .map(|c| contains(structure, c.as_vec3()))
                .collect()
        };
        self.cells
            .get_or_init(|| InsideCells::new(mesh, &InsideCellsConfig::default(), exact))
            .as_ref()
    }
}

/// Whether `point` lies inside the closed mesh that `structure` traces, the answer of
/// `contains(structure, point)`: from `cells` (made over that mesh) where the grid tells
/// (`InsideCells::decide`: the point's cell, or the segment to a known point nearby, whose
/// crossings the all-hits query counts, a crossing through an edge once); else by the ray.
/// `hits` is scratch space that a run of points reuses.
#[inline]
pub fn inside_closed<A: AllHits + ?Sized>(
    structure: &A,
    cells: Option<&InsideCells>,
    point: Vec3,
    hits: &mut Vec<Hit>,
) -> bool {
    if let Some(cells) = cells {
        let mut crossings = |known: DVec3| {
            let segment = Ray::new(point, known.as_vec3() - point).with_interval(0.0, 1.0);
            structure.all_hits(&segment, hits);
            hits.len()
        };
        if let Some(answer) = cells.decide(point.as_dvec3(), Some(&mut crossings)) {
            return answer;
        }
    }
    contains(structure, point)
}
