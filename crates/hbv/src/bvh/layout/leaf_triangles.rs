//! Triangles copied in leaf order, each leaf's run closed by a flag: the triangle storage of the
//! scalar layouts.

use crate::bvh::tree::{BuildTree, NodeId};
use crate::geometry::{PreparedRay, Ray, Triangle};
use crate::mesh::TriangleMesh;
use crate::query::{record_closer_hit, Hit};
use crate::stats::Counter;

/// Marks the last triangle of a leaf in [`LeafTriangles::ids`].
const LAST_IN_LEAF: u32 = 1 << 31;

/// The triangles of all leaves, leaf after leaf, with their face ids. A leaf is named by the
/// index of its first triangle; its run ends at the id carrying [`LAST_IN_LEAF`], so a node
/// needs no count field (and meshes may have up to 2^31 triangles).
#[derive(Clone, Debug, Default)]
pub(crate) struct LeafTriangles {
    triangles: Vec<Triangle>,
    ids: Vec<u32>,
}

impl LeafTriangles {
    /// Appends the triangles of leaf `leaf` of `tree` and returns the index of the first.
    pub fn push_leaf(&mut self, tree: &BuildTree, leaf: NodeId, mesh: &TriangleMesh) -> u32 {
        let first = self.triangles.len() as u32;
        let prims = tree.node(leaf).prims();
        for (k, &p) in prims.iter().enumerate() {
            self.triangles.push(mesh.triangle(p as usize));
            let last = if k + 1 == prims.len() {
                LAST_IN_LEAF
            } else {
                0
            };
            self.ids.push(p | last);
        }
        first
    }

    pub fn memory_bytes(&self) -> usize {
        self.triangles.len() * std::mem::size_of::<Triangle>() + self.ids.len() * 4
    }

    /// Tests the leaf starting at `first` for a closer hit than `best`, shrinking `ray.tmax`.
    #[inline]
    pub fn closest_hit<C: Counter>(
        &self,
        first: u32,
        ray: &mut PreparedRay,
        best: &mut Option<Hit>,
        counter: &mut C,
    ) {
        let mut i = first as usize;
        loop {
            let id = self.ids[i];
            counter.triangles_tested(1);
            record_closer_hit(&self.triangles[i], id & !LAST_IN_LEAF, ray, best);
            if id & LAST_IN_LEAF != 0 {
                return;
            }
            i += 1;
        }
    }

    /// The face id of the first triangle of the leaf starting at `first` that is hit, if any.
    #[inline]
    pub fn first_hit<C: Counter>(
        &self,
        first: u32,
        ray: &PreparedRay,
        counter: &mut C,
    ) -> Option<u32> {
        let mut i = first as usize;
        loop {
            counter.triangles_tested(1);
            if self.triangles[i].intersect(ray).is_some() {
                return Some(self.ids[i] & !LAST_IN_LEAF);
            }
            if self.ids[i] & LAST_IN_LEAF != 0 {
                return None;
            }
            i += 1;
        }
    }
}

/// A layout that keeps its triangles in [`LeafTriangles`] and reaches them through a traversal
/// loop calling `visit_leaf(first_triangle, ray, counter)` for each leaf whose box the ray hits
/// (stopping when it returns `true`). Both queries follow from that: see
/// [`closest_hit_in_leaves`] and [`any_hit_in_leaves`].
pub(crate) trait LeafVisitingLayout {
    fn leaves(&self) -> &LeafTriangles;

    fn traverse<C: Counter>(
        &self,
        ray: &mut PreparedRay,
        counter: &mut C,
        visit_leaf: impl FnMut(u32, &mut PreparedRay, &mut C) -> bool,
    );
}

/// The closest hit through a [`LeafVisitingLayout`]: every reached leaf may shrink `tmax`.
#[inline]
pub(crate) fn closest_hit_in_leaves<L: LeafVisitingLayout, C: Counter>(
    layout: &L,
    ray: &Ray,
    counter: &mut C,
) -> Option<Hit> {
    let mut prepared = PreparedRay::new(ray);
    let mut best = None;
    layout.traverse(&mut prepared, counter, |first, ray, counter| {
        layout.leaves().closest_hit(first, ray, &mut best, counter);
        false
    });
    best
}

/// Any hit through a [`LeafVisitingLayout`]: the first leaf with a hit ends the traversal;
/// returns the face id of the triangle found.
#[inline]
pub(crate) fn any_hit_in_leaves<L: LeafVisitingLayout, C: Counter>(
    layout: &L,
    ray: &Ray,
    counter: &mut C,
) -> Option<u32> {
    let mut prepared = PreparedRay::new(ray);
    let mut found = None;
    layout.traverse(&mut prepared, counter, |first, ray, counter| {
        found = layout.leaves().first_hit(first, ray, counter);
        found.is_some()
    });
    found
}
