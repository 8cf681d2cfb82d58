//! The uniform grid accelerator: cell lists, and the closest- and any-hit walks through them.

use rayon::prelude::*;

use super::{triangle_overlaps_box, CellWalk, GridShape, Mailbox};
use crate::geometry::{Aabb, PreparedRay, Ray, Triangle};
use crate::mesh::TriangleMesh;
use crate::query::{record_closer_hit, Hit, TraversalKernel};
use crate::stats::Counter;

/// Options of [`UniformGrid`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridConfig {
    /// Density λ: `λ · N^(1/3)` cells along the longest axis (`λ³ N` cells for a cube).
    pub lambda: f64,
    /// Whether each query keeps a [`Mailbox`] so that no triangle is tested twice.
    pub mailbox: bool,
}

impl Default for GridConfig {
    /// λ = 2 (8 cells per triangle for a cube, about 2–4 triangles per non-empty cell on
    /// surface meshes), mailboxes on.
    fn default() -> Self {
        Self {
            lambda: 2.0,
            mailbox: true,
        }
    }
}

/// A uniform grid over a mesh: every non-degenerate triangle listed in each cell it overlaps
/// (exact triangle–box test, not its bounding box), traversed cell by cell along the ray.
///
/// Cell lists are stored in compressed sparse row form: the triangles of cell `c` are
/// `items[starts[c] .. starts[c + 1]]`, indices into `triangles` (face ids in `prims`).
///
/// Exactness: answers equal brute force's bit for bit (each triangle is decided by the same
/// [`Triangle::intersect`], ties by the same rule). Three margins make the walk conservative:
/// - cells list every triangle within [`GridShape::pad`] of them (f64 decisions), which covers
///   the rounding of the f64 walk;
/// - the walk starts a margin (`t_margin`) before `tmin` and runs as far past `tmax`;
/// - the closest-hit walk stops after a cell only if the best hit is *strictly* nearer than the
///   cell's exit minus that margin, which covers the rounding of the triangle test's `t` (a
///   triangle whose true crossing lies beyond the exit cannot then compute a `t` as near, nor an
///   equal `t` with a smaller id).
///
/// A ray whose origin is so far from the grid that f64 cannot place it within the pad falls
/// back to testing every triangle (never met in practice: some 2^26 times the scene's size away).
#[derive(Clone, Debug)]
pub struct UniformGrid {
    config: GridConfig,
    /// `None` when the mesh has no triangle of non-zero area.
    shape: Option<GridShape>,
    starts: Vec<u32>,
    items: Vec<u32>,
    triangles: Vec<Triangle>,
    prims: Vec<u32>,
    /// Largest |coordinate| of the grid's box, for the per-ray margins.
    magnitude: f64,
}

impl UniformGrid {
    /// Builds the grid over `mesh` (in parallel on the current rayon pool).
    pub fn new(mesh: &TriangleMesh, config: GridConfig) -> Self {
        let (prims, triangles): (Vec<u32>, Vec<Triangle>) = mesh
            .triangles()
            .enumerate()
            .filter(|(_, t)| !t.is_degenerate())
            .map(|(i, t)| (i as u32, t))
            .unzip();
        if triangles.is_empty() {
            return Self {
                config,
                shape: None,
                starts: vec![0],
                items: Vec::new(),
                triangles,
                prims,
                magnitude: 0.0,
            };
        }
        let bounds = triangles
            .iter()
            .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
        let shape = GridShape::new(&bounds, triangles.len(), config.lambda);
        let (starts, items) = cell_lists(&shape, &triangles);
        let magnitude = shape.lo.abs().max(shape.hi().abs()).max_element();
        Self {
            config,
            shape: Some(shape),
            starts,
            items,
            triangles,
            prims,
            magnitude,
        }
    }

    pub fn config(&self) -> &GridConfig {
        &self.config
    }

    /// The grid's cells; `None` for a mesh without a triangle of non-zero area.
    pub fn shape(&self) -> Option<&GridShape> {
        self.shape.as_ref()
    }

    /// Entries of all cell lists: triangles per cell times cells (a triangle counts once per
    /// cell that lists it).
    pub fn listed(&self) -> usize {
        self.items.len()
    }

    /// Bytes of cell offsets, cell lists and triangles.
    pub fn memory_bytes(&self) -> usize {
        self.starts.len() * 4
            + self.items.len() * 4
            + self.triangles.len() * std::mem::size_of::<Triangle>()
            + self.prims.len() * 4
    }

    /// The triangles (indices into `self.triangles`) listed in cell `cell`.
    #[inline]
    pub(super) fn cell_items(&self, cell: usize) -> &[u32] {
        &self.items[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }

    /// How far, in `t`, the walk looks beyond where the triangle test could place a hit:
    ///
    /// ```text
    ///   margin(t) = 2^-16 |t| + 64 ε · M / max_i |d_i|
    /// ```
    ///
    /// where `M` bounds the ray's distance to any point of the grid (∞-norm) and ε = 2^-23. The
    /// second term is the error of the sheared-frame `t` of Woop et al. (a few ulps of the
    /// vertices' coordinates relative to the origin, divided by the dominant direction
    /// component), with a wide factor; the first is the box slack of the BVH layouts
    /// (`PreparedRay::BOX_SLACK`, 2^-18) with a margin of 4.
    #[inline]
    pub(super) fn t_margin(&self, ray: &Ray, t: f64) -> f64 {
        let m = ray.origin.as_dvec3().abs().max_element() + self.magnitude;
        let d = ray.direction.abs().max_element() as f64;
        t.abs() * (1.0 / 65_536.0) + 64.0 * f32::EPSILON as f64 * m / d
    }

    /// Whether f64 cannot walk this ray accurately within the pad (origin absurdly far away).
    #[inline]
    pub(super) fn beyond_f64(&self, shape: &GridShape, ray: &Ray) -> bool {
        ray.origin.as_dvec3().abs().max_element() * (1.0 / 4_503_599_627_370_496.0) * 64.0
            > shape.pad
    }

    /// The listed triangles (non-degenerate, in face order) and their face ids.
    pub(super) fn listed_triangles(&self) -> (&[Triangle], &[u32]) {
        (&self.triangles, &self.prims)
    }

    /// Tests `local` (an index into `self.triangles`) unless the mailbox has seen it.
    #[inline]
    fn test_closest<C: Counter>(
        &self,
        local: u32,
        mailbox: &mut Mailbox,
        ray: &mut PreparedRay,
        best: &mut Option<Hit>,
        counter: &mut C,
    ) {
        if self.config.mailbox && mailbox.seen_or_post(local) {
            counter.mailbox_skipped();
            return;
        }
        counter.triangles_tested(1);
        let i = local as usize;
        record_closer_hit(&self.triangles[i], self.prims[i], ray, best);
    }

    /// Every triangle, in face order: the fallback for rays f64 cannot walk.
    fn closest_in_all<C: Counter>(&self, ray: &mut PreparedRay, counter: &mut C) -> Option<Hit> {
        let mut best = None;
        counter.triangles_tested(self.triangles.len() as u32);
        for (t, &prim) in self.triangles.iter().zip(&self.prims) {
            record_closer_hit(t, prim, ray, &mut best);
        }
        best
    }

    /// The any-hit walk, returning the blocking triangle's face id.
    fn first_blocker<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        let shape = self.shape.as_ref()?;
        let prepared = PreparedRay::new(ray);
        if self.beyond_f64(shape, ray) {
            counter.triangles_tested(self.triangles.len() as u32);
            return self
                .triangles
                .iter()
                .position(|t| t.intersect(&prepared).is_some())
                .map(|i| self.prims[i]);
        }
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let from = tmin - self.t_margin(ray, tmin);
        let to = tmax + self.t_margin(ray, tmax);
        let mut walk = CellWalk::new(shape, ray, from, to)?;
        let mut mailbox = Mailbox::new();
        loop {
            counter.node_visited();
            for &local in self.cell_items(walk.cell()) {
                if self.config.mailbox && mailbox.seen_or_post(local) {
                    counter.mailbox_skipped();
                    continue;
                }
                counter.triangles_tested(1);
                if self.triangles[local as usize]
                    .intersect(&prepared)
                    .is_some()
                {
                    return Some(self.prims[local as usize]);
                }
            }
            if !walk.advance() {
                return None;
            }
        }
    }
}

impl TraversalKernel for UniformGrid {
    /// Walks the cells from the ray's entry; after each cell, stops if the best hit so far lies
    /// (with margin) before the cell's exit: no triangle of a later cell can be nearer.
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        let shape = self.shape.as_ref()?;
        let mut prepared = PreparedRay::new(ray);
        if self.beyond_f64(shape, ray) {
            return self.closest_in_all(&mut prepared, counter);
        }
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let from = tmin - self.t_margin(ray, tmin);
        let to = tmax + self.t_margin(ray, tmax);
        let mut walk = CellWalk::new(shape, ray, from, to)?;
        let mut mailbox = Mailbox::new();
        let mut best: Option<Hit> = None;
        loop {
            counter.node_visited();
            for &local in self.cell_items(walk.cell()) {
                self.test_closest(local, &mut mailbox, &mut prepared, &mut best, counter);
            }
            if let Some(hit) = best {
                let exit = walk.exit_t();
                if (hit.t as f64) < exit - self.t_margin(ray, exit) {
                    return best;
                }
            }
            if !walk.advance() {
                return best;
            }
        }
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        self.first_blocker(ray, counter).is_some()
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        self.first_blocker(ray, counter)
    }
}

/// The cell lists in CSR form: for each triangle (in parallel) the cells its padded bounding
/// box spans, kept where the exact overlap test with the padded cell says so; then a counting
/// sort by cell, which keeps each list in ascending triangle order.
fn cell_lists(shape: &GridShape, triangles: &[Triangle]) -> (Vec<u32>, Vec<u32>) {
    let pairs: Vec<(u32, u32)> = triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, t)| {
            overlapped_cells(shape, t)
                .into_iter()
                .map(move |c| (c as u32, i as u32))
        })
        .collect();
    let mut starts = vec![0u32; shape.cell_count() + 1];
    for &(c, _) in &pairs {
        starts[c as usize + 1] += 1;
    }
    for c in 0..shape.cell_count() {
        starts[c + 1] += starts[c];
    }
    let mut fill = starts.clone();
    let mut items = vec![0u32; pairs.len()];
    for (c, i) in pairs {
        let slot = &mut fill[c as usize];
        items[*slot as usize] = i;
        *slot += 1;
    }
    (starts, items)
}

/// The cells whose padded box the triangle overlaps.
fn overlapped_cells(shape: &GridShape, t: &Triangle) -> Vec<usize> {
    let b = t.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let first: [u32; 3] = std::array::from_fn(|k| shape.axis_cell(k, lo[k] - shape.pad));
    let last: [u32; 3] = std::array::from_fn(|k| shape.axis_cell(k, hi[k] + shape.pad));
    let vertices = [t.p0.as_dvec3(), t.p1.as_dvec3(), t.p2.as_dvec3()];
    let single = first == last;
    let mut cells = Vec::new();
    for z in first[2]..=last[2] {
        for y in first[1]..=last[1] {
            for x in first[0]..=last[0] {
                let c = [x, y, z];
                let (clo, chi) = shape.padded_cell(c);
                if single || triangle_overlaps_box(vertices, clo, chi) {
                    cells.push(shape.cell_index(c));
                }
            }
        }
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::procedural::icosphere;
    use crate::Accelerator;
    use glam::Vec3;

    #[test]
    fn every_triangle_is_listed_and_lists_are_sorted() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let grid = UniformGrid::new(&mesh, GridConfig::default());
        let shape = grid.shape().unwrap();
        let mut seen = vec![false; mesh.triangle_count()];
        for c in 0..shape.cell_count() {
            let items = grid.cell_items(c);
            assert!(items.windows(2).all(|w| w[0] < w[1]));
            for &i in items {
                seen[i as usize] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
        // Exact overlap lists fewer cells than bounding boxes would.
        let boxed: usize = mesh
            .triangles()
            .map(|t| {
                let b = t.bounds();
                (0..3)
                    .map(|k| {
                        let lo = shape.axis_cell(k, b.min[k] as f64 - shape.pad);
                        let hi = shape.axis_cell(k, b.max[k] as f64 + shape.pad);
                        (hi - lo + 1) as usize
                    })
                    .product::<usize>()
            })
            .sum();
        assert!(
            grid.listed() < boxed * 3 / 4,
            "{} of {boxed}",
            grid.listed()
        );
    }

    #[test]
    fn empty_and_degenerate_meshes_miss() {
        let empty = TriangleMesh::new(vec![], vec![]).unwrap();
        let degenerate =
            TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]).unwrap();
        for mesh in [empty, degenerate] {
            let grid = UniformGrid::new(&mesh, GridConfig::default());
            let ray = Ray::new(Vec3::NEG_ONE, Vec3::ONE);
            assert!(grid.intersect(&ray).is_none());
            assert!(!grid.occluded(&ray));
        }
    }

    #[test]
    fn mailbox_saves_tests_and_changes_nothing() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 4);
        let with = UniformGrid::new(&mesh, GridConfig::default());
        let without = UniformGrid::new(
            &mesh,
            GridConfig {
                mailbox: false,
                ..GridConfig::default()
            },
        );
        let (mut a, mut b) = (Default::default(), Default::default());
        for k in 0..200 {
            let o = Vec3::new(-3.0, (k as f32 * 0.37).sin(), (k as f32 * 0.71).cos());
            let ray = Ray::new(o, Vec3::new(1.0, 0.01 * k as f32 - 1.0, 0.3));
            assert_eq!(
                with.intersect_counted(&ray, &mut a),
                without.intersect_counted(&ray, &mut b)
            );
        }
        assert!(a.mailbox_skips > 0 && b.mailbox_skips == 0);
        assert_eq!(a.triangles_tested + a.mailbox_skips, b.triangles_tested);
    }
}
