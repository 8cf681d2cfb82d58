//! A tree kept live while the scene changes: triangles are inserted, removed and moved, and the
//! tree follows without a rebuild. Incremental construction (Goldsmith & Salmon 1987) is
//! incremental by nature: an insertion here is one step of the insertion builder, a removal is
//! its inverse, and a move is a refit (boxes recomputed bottom-up, the topology kept), with the
//! reinsertion optimizer (Bittner, Hapala & Havran 2013) to win back what moves cost.
//!
//! # Triangle ids
//!
//! [`DynamicBvh::insert`] returns one id per triangle; the id names that triangle in hits and in
//! every other call until [`DynamicBvh::remove`] frees it. Freed ids are reused by later
//! insertions, smallest first, so ids stay dense (`0..capacity`) and a tree built from a mesh
//! ([`DynamicBvh::from_mesh`]) numbers its triangles in the mesh's face order, as every other
//! structure does.
//!
//! # Queries
//!
//! The live tree is traced directly ([`TraversalKernel`], so [`crate::Accelerator`]): a depth-first
//! walk of the `BuildTree` arena. Nothing has to be laid out again after a change, which is what
//! a scene that changes every frame needs. For many rays between changes, lay the tree out once
//! into any layout: `RecursiveLayout::new(dynamic.tree(), &dynamic.mesh())` (the ids agree:
//! [`DynamicBvh::mesh`] keeps every id at its index, freed ones as degenerate triangles).
//!
//! ```
//! use hbv::bvh::dynamic::{DynamicBvh, DynamicConfig};
//! use hbv::geometry::Ray;
//! use hbv::glam::Vec3;
//! use hbv::Accelerator;
//!
//! let mut scene = DynamicBvh::new(DynamicConfig::default());
//! let quad = [
//!     [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)],
//!     [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)],
//! ];
//! let ids = scene.insert(&quad).unwrap();
//! let down = Ray::new(Vec3::new(0.5, -0.5, 5.0), -Vec3::Z);
//! assert_eq!(scene.intersect(&down).unwrap().prim, ids[0]);
//!
//! // Lift the first triangle by 1, then let the tree follow.
//! let lifted = quad[0].map(|p| p + Vec3::Z);
//! scene.set_triangle(ids[0], lifted).unwrap();
//! scene.refit();
//! assert_eq!(scene.intersect(&down).unwrap().t, 4.0);
//!
//! scene.remove(&[ids[0]]).unwrap();
//! assert!(scene.intersect(&down).is_none());
//! scene.validate().unwrap();
//! ```

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fmt;

use glam::Vec3;

use super::optimize::{ReinsertionConfig, ReinsertionOptimizer, ReinsertionReport};
use super::placement::{PlacedItem, PlacementSearch};
use super::tree::{BuildTree, NodeContent, NodeId};
use crate::geometry::{Aabb, PreparedRay, Ray, Triangle};
use crate::mesh::TriangleMesh;
use crate::query::{record_closer_hit, Hit, TraversalKernel};
use crate::stats::Counter;

/// Marks a triangle that is in no leaf (freed, or degenerate).
const NO_LEAF: NodeId = NodeId::MAX;

/// Options of [`DynamicBvh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DynamicConfig {
    /// Most triangles a leaf may hold. Default 1, as the insertion builder.
    pub max_leaf_size: usize,
}

impl Default for DynamicConfig {
    fn default() -> Self {
        Self { max_leaf_size: 1 }
    }
}

/// Why a change to a [`DynamicBvh`] was refused; the tree is then unchanged.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DynamicError {
    /// The id names no triangle: never given out, or removed.
    UnknownId(u32),
    /// The same id twice in one call.
    RepeatedId(u32),
    /// A vertex with a NaN or infinite coordinate (`index` in the call's list).
    NotFinite { index: usize },
    /// More than 2^32 − 1 triangles.
    TooMany,
}

impl fmt::Display for DynamicError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DynamicError::UnknownId(id) => write!(f, "triangle id {id} names no triangle"),
            DynamicError::RepeatedId(id) => write!(f, "triangle id {id} is given twice"),
            DynamicError::NotFinite { index } => {
                write!(f, "triangle {index} has a coordinate that is not finite")
            }
            DynamicError::TooMany => write!(f, "more than 2^32 - 1 triangles"),
        }
    }
}

impl std::error::Error for DynamicError {}

/// A bounding volume hierarchy over a changing set of triangles.
///
/// - [`insert`](DynamicBvh::insert): each triangle goes where E\[X\] grows least, found by the
///   branch-and-bound [`PlacementSearch`] of the insertion builder (the same tree as
///   `InsertionBuilder` with input order, when built from nothing).
/// - [`remove`](DynamicBvh::remove): the triangle leaves its leaf; an emptied leaf is detached,
///   a parent left with one child is spliced out, and the boxes above shrink to their children.
/// - [`set_triangle`](DynamicBvh::set_triangle) then [`refit`](DynamicBvh::refit): moved
///   triangles' leaves get their new boxes and every ancestor is refitted, up to the first box
///   that does not change. Until `refit`, queries may miss moved triangles.
/// - [`optimize`](DynamicBvh::optimize): reinsertion passes to win back the quality that moves
///   (refits keep a topology made for other positions) and removals cost.
///
/// Boxes stay tight (each the union of what is below it) through every operation.
#[derive(Default)]
pub struct DynamicBvh {
    config: DynamicConfig,
    tree: BuildTree,
    /// The triangle of each id; `None` for a freed id.
    triangles: Vec<Option<Triangle>>,
    /// The box of each id in the tree; empty for freed ids and degenerate triangles.
    bounds: Vec<Aabb>,
    /// The leaf holding each id, or [`NO_LEAF`].
    leaf_of: Vec<NodeId>,
    /// Freed ids, smallest first.
    free: BinaryHeap<Reverse<u32>>,
    /// Ids moved by `set_triangle` since the last refit.
    moved: Vec<u32>,
    search: PlacementSearch,
}

impl DynamicBvh {
    pub fn new(config: DynamicConfig) -> Self {
        Self {
            config: DynamicConfig {
                max_leaf_size: config.max_leaf_size.max(1),
            },
            ..Self::default()
        }
    }

    /// A tree over every triangle of `mesh`, inserted in face order: triangle `i` has id `i`.
    pub fn from_mesh(mesh: &TriangleMesh, config: DynamicConfig) -> Self {
        let mut bvh = Self::new(config);
        let triangles: Vec<[Vec3; 3]> = mesh.triangles().map(|t| [t.p0, t.p1, t.p2]).collect();
        bvh.insert(&triangles)
            .expect("a mesh has finite vertices and fewer than 2^32 triangles");
        bvh
    }

    /// Takes over `tree`, built by any builder over `mesh`: triangle `i` has id `i`. The
    /// leaf size becomes at least the tree's largest leaf.
    pub fn from_tree(mesh: &TriangleMesh, tree: BuildTree, config: DynamicConfig) -> Self {
        let mut bvh = Self::new(config);
        let n = mesh.triangle_count();
        bvh.triangles = mesh.triangles().map(Some).collect();
        bvh.bounds = vec![Aabb::EMPTY; n];
        bvh.leaf_of = vec![NO_LEAF; n];
        let mut max_leaf = bvh.config.max_leaf_size;
        tree.walk(|node, _| {
            let prims = tree.node(node).prims();
            max_leaf = max_leaf.max(prims.len());
            for &p in prims {
                bvh.leaf_of[p as usize] = node;
                bvh.bounds[p as usize] = mesh.triangle(p as usize).bounds();
            }
        });
        bvh.config.max_leaf_size = max_leaf;
        bvh.tree = tree;
        bvh
    }

    /// Adds `triangles` to the tree and returns their ids, in order. Degenerate triangles get
    /// an id but stay out of the tree (they are never hit) until moved to a proper shape.
    pub fn insert(&mut self, triangles: &[[Vec3; 3]]) -> Result<Vec<u32>, DynamicError> {
        if let Some(index) = triangles
            .iter()
            .position(|t| !t.iter().all(|p| p.is_finite()))
        {
            return Err(DynamicError::NotFinite { index });
        }
        let new_slots = triangles.len().saturating_sub(self.free.len());
        if self.triangles.len() + new_slots > NO_LEAF as usize {
            return Err(DynamicError::TooMany);
        }
        let mut ids = Vec::with_capacity(triangles.len());
        for &[a, b, c] in triangles {
            let id = match self.free.pop() {
                Some(Reverse(id)) => id,
                None => {
                    self.triangles.push(None);
                    self.bounds.push(Aabb::EMPTY);
                    self.leaf_of.push(NO_LEAF);
                    (self.triangles.len() - 1) as u32
                }
            };
            self.triangles[id as usize] = Some(Triangle::new(a, b, c));
            self.place(id);
            ids.push(id);
        }
        Ok(ids)
    }

    /// Takes the triangles `ids` out of the tree and frees their ids.
    pub fn remove(&mut self, ids: &[u32]) -> Result<(), DynamicError> {
        self.check_ids(ids.iter().copied())?;
        for &id in ids {
            self.take_out(id);
            self.triangles[id as usize] = None;
            self.free.push(Reverse(id));
        }
        // A freed id must not be refitted later.
        let triangles = &self.triangles;
        self.moved.retain(|&id| triangles[id as usize].is_some());
        Ok(())
    }

    /// Moves triangle `id` to the vertices `triangle`. The tree learns of it at the next
    /// [`DynamicBvh::refit`].
    pub fn set_triangle(&mut self, id: u32, triangle: [Vec3; 3]) -> Result<(), DynamicError> {
        self.check_ids([id])?;
        if !triangle.iter().all(|p| p.is_finite()) {
            return Err(DynamicError::NotFinite { index: 0 });
        }
        let [a, b, c] = triangle;
        self.triangles[id as usize] = Some(Triangle::new(a, b, c));
        self.moved.push(id);
        Ok(())
    }

    /// Brings the tree up to date with the triangles moved since the last refit: each moved
    /// triangle's leaf gets the union of its triangles' new boxes, and the ancestors are
    /// refitted bottom-up, each stopping at the first box that does not change. The topology is
    /// kept, except that a triangle that became degenerate leaves the tree and one that stopped
    /// being degenerate is inserted. Cost O(moved × depth).
    pub fn refit(&mut self) {
        let mut moved = std::mem::take(&mut self.moved);
        moved.sort_unstable();
        moved.dedup();
        for id in moved {
            let tri = self.triangles[id as usize].expect("moved ids are live");
            let leaf = self.leaf_of[id as usize];
            match (leaf == NO_LEAF, tri.is_degenerate()) {
                (true, true) => {}
                (true, false) => self.place(id),
                (false, true) => self.take_out(id),
                (false, false) => {
                    self.bounds[id as usize] = tri.bounds();
                    self.fit_leaf(leaf);
                }
            }
        }
    }

    /// Brings the tree up to date with the triangles moved since the last refit by taking each
    /// out and placing it again where E\[X\] grows least at its new position, in the order they
    /// were moved. Costs about a removal and an insertion per triangle (µs) where
    /// [`DynamicBvh::refit`] costs a walk up the tree, but keeps the tree as good as insertion
    /// builds it, where refitting a topology made for the old positions can make it many times
    /// worse under large, incoherent motion (see `hbv experiment dynamic` in BENCHMARKS.md).
    pub fn reinsert_moved(&mut self) {
        let mut moved = std::mem::take(&mut self.moved);
        let mut seen = std::collections::HashSet::new();
        moved.retain(|&id| seen.insert(id));
        for &id in &moved {
            self.take_out(id);
        }
        for id in moved {
            self.place(id);
        }
    }

    /// Reinsertion optimization of the live tree (see [`ReinsertionOptimizer`]).
    pub fn optimize(&mut self, config: ReinsertionConfig) -> ReinsertionReport {
        let report = ReinsertionOptimizer::new(config).optimize(&mut self.tree);
        // The optimizer renumbers the nodes: find every triangle's leaf again.
        self.leaf_of.fill(NO_LEAF);
        let (tree, leaf_of) = (&self.tree, &mut self.leaf_of);
        tree.walk(|node, _| {
            for &p in tree.node(node).prims() {
                leaf_of[p as usize] = node;
            }
        });
        report
    }

    pub fn config(&self) -> &DynamicConfig {
        &self.config
    }

    /// The live tree; its leaves hold triangle ids.
    pub fn tree(&self) -> &BuildTree {
        &self.tree
    }

    /// The box of each id as the tree knows it (empty for freed ids and triangles out of the
    /// tree): what [`BuildTree::validate`] checks the tree against.
    pub fn prim_bounds(&self) -> &[Aabb] {
        &self.bounds
    }

    /// Number of live triangles (degenerate ones included).
    pub fn len(&self) -> usize {
        self.triangles.len() - self.free.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// One more than the largest id ever given out (and not yet reclaimed).
    pub fn capacity(&self) -> usize {
        self.triangles.len()
    }

    /// The triangle of `id`, `None` for a freed id.
    pub fn triangle(&self, id: u32) -> Option<Triangle> {
        self.triangles.get(id as usize).copied().flatten()
    }

    /// The triangles as a mesh with id `i` at face `i`; a freed id is a degenerate triangle (all
    /// three corners at the origin), never hit. What layouts and [`crate::BruteForce`] take.
    pub fn mesh(&self) -> TriangleMesh {
        let mut positions = Vec::with_capacity(3 * self.triangles.len());
        for t in &self.triangles {
            match t {
                Some(t) => positions.extend([t.p0, t.p1, t.p2]),
                None => positions.extend([Vec3::ZERO; 3]),
            }
        }
        let indices = (0..self.triangles.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        TriangleMesh::new(positions, indices).expect("the triangles are finite")
    }

    /// Checks the tree's invariants ([`BuildTree::validate`]) and that every triangle's leaf is
    /// known and its box up to date (there is no pending move).
    pub fn validate(&self) -> Result<(), super::InvariantError> {
        self.tree
            .validate(&self.bounds, self.config.max_leaf_size)?;
        let fail = |s: String| Err(super::InvariantError(s));
        for (id, t) in self.triangles.iter().enumerate() {
            let leaf = self.leaf_of[id];
            let in_tree = t.is_some_and(|t| !t.is_degenerate());
            if in_tree != (leaf != NO_LEAF) {
                return fail(format!("triangle {id}: leaf {leaf} is wrong"));
            }
            if in_tree && !self.tree.node(leaf).prims().contains(&(id as u32)) {
                return fail(format!("triangle {id} is not in its leaf {leaf}"));
            }
            if in_tree && self.moved.is_empty() && self.bounds[id] != t.unwrap().bounds() {
                return fail(format!("triangle {id} has a stale box"));
            }
        }
        Ok(())
    }

    /// Puts live id `id` into the tree where E\[X\] grows least, unless it is degenerate.
    fn place(&mut self, id: u32) {
        let tri = self.triangles[id as usize].expect("placed ids are live");
        if tri.is_degenerate() {
            return;
        }
        let b = tri.bounds();
        let item = PlacedItem {
            bounds: b,
            own_cost: b.surface_area(),
            may_join_leaf: true,
        };
        let (placement, _) = self
            .search
            .find(&self.tree, &item, self.config.max_leaf_size);
        self.bounds[id as usize] = b;
        self.leaf_of[id as usize] = self.tree.attach_prim(placement, id, b);
    }

    /// Takes `id` out of its leaf (if it is in one): an emptied leaf is detached and released,
    /// otherwise the leaf and its ancestors shrink to what they still hold.
    fn take_out(&mut self, id: u32) {
        let leaf = std::mem::replace(&mut self.leaf_of[id as usize], NO_LEAF);
        self.bounds[id as usize] = Aabb::EMPTY;
        if leaf == NO_LEAF {
            return;
        }
        if let NodeContent::Leaf(prims) = &mut self.tree.node_mut(leaf).content {
            prims.retain(|p| *p != id);
            if !prims.is_empty() {
                self.fit_leaf(leaf);
                return;
            }
        }
        self.tree.detach(leaf);
        self.tree.release(leaf);
    }

    /// Sets `leaf`'s box to the union of its triangles' boxes and refits its ancestors.
    fn fit_leaf(&mut self, leaf: NodeId) {
        let fitted = self
            .tree
            .node(leaf)
            .prims()
            .iter()
            .fold(Aabb::EMPTY, |b, &p| b.union(&self.bounds[p as usize]));
        self.tree.node_mut(leaf).bounds = fitted;
        self.tree.refit_from(leaf);
    }

    /// Every id live, and none twice.
    fn check_ids(&self, ids: impl IntoIterator<Item = u32>) -> Result<(), DynamicError> {
        let mut seen = std::collections::HashSet::new();
        for id in ids {
            if self.triangle(id).is_none() {
                return Err(DynamicError::UnknownId(id));
            }
            if !seen.insert(id) {
                return Err(DynamicError::RepeatedId(id));
            }
        }
        Ok(())
    }

    /// Depth-first walk of the live tree; `visit_leaf` tests a leaf's triangles and returns
    /// `true` to stop.
    #[inline]
    fn traverse<C: Counter>(
        &self,
        ray: &mut PreparedRay,
        counter: &mut C,
        mut visit_leaf: impl FnMut(&mut PreparedRay, &[u32]) -> bool,
    ) {
        let Some(root) = self.tree.root() else {
            return;
        };
        ray.bound_errors_within(&self.tree.node(root).bounds);
        let mut stack: Vec<NodeId> = vec![root];
        while let Some(id) = stack.pop() {
            let node = self.tree.node(id);
            counter.boxes_tested(1);
            if !node.bounds.hit_by(ray) {
                continue;
            }
            counter.node_visited();
            match &node.content {
                NodeContent::Leaf(prims) => {
                    counter.triangles_tested(prims.len() as u32);
                    if visit_leaf(ray, prims) {
                        return;
                    }
                }
                NodeContent::Internal(children) => stack.extend(children.iter().rev()),
            }
        }
    }

    fn live(&self, id: u32) -> &Triangle {
        self.triangles[id as usize]
            .as_ref()
            .expect("leaves hold live ids")
    }
}

impl TraversalKernel for DynamicBvh {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        let mut prepared = PreparedRay::new(ray);
        let mut best = None;
        self.traverse(&mut prepared, counter, |ray, prims| {
            for &p in prims {
                record_closer_hit(self.live(p), p, ray, &mut best);
            }
            false
        });
        best
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        let mut prepared = PreparedRay::new(ray);
        let mut found = false;
        self.traverse(&mut prepared, counter, |ray, prims| {
            found = prims.iter().any(|&p| self.live(p).intersect(ray).is_some());
            found
        });
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{Builder, InsertionBuilder, InsertionConfig, InsertionOrder};
    use crate::mesh::procedural::icosphere;

    #[test]
    fn from_mesh_is_the_insertion_builders_tree_in_input_order() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 2);
        let dynamic = DynamicBvh::from_mesh(&mesh, DynamicConfig::default());
        let built = InsertionBuilder::new(InsertionConfig {
            order: InsertionOrder::Input,
            max_leaf_size: 1,
        })
        .build(&mesh);
        assert_eq!(dynamic.tree(), &built);
        dynamic.validate().unwrap();
    }

    #[test]
    fn any_builders_tree_can_be_taken_over() {
        use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig};
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
        let mut dynamic = DynamicBvh::from_tree(&mesh, tree, DynamicConfig::default());
        dynamic.validate().unwrap();
        dynamic.remove(&[0, 5, 9]).unwrap();
        let t = mesh.triangle(0);
        dynamic.insert(&[[t.p0, t.p1, t.p2]]).unwrap();
        dynamic.validate().unwrap();
    }

    #[test]
    fn freed_ids_are_reused_smallest_first() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 1);
        let mut dynamic = DynamicBvh::from_mesh(&mesh, DynamicConfig::default());
        let t = dynamic.triangle(0).unwrap();
        dynamic.remove(&[7, 3]).unwrap();
        assert_eq!(dynamic.len(), mesh.triangle_count() - 2);
        let ids = dynamic.insert(&[[t.p0, t.p1, t.p2]; 3]).unwrap();
        assert_eq!(ids, vec![3, 7, mesh.triangle_count() as u32]);
        dynamic.validate().unwrap();
    }

    #[test]
    fn bad_calls_are_refused_and_change_nothing() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 1);
        let mut dynamic = DynamicBvh::from_mesh(&mesh, DynamicConfig::default());
        let before = dynamic.tree().clone();
        assert_eq!(dynamic.remove(&[1, 999]), Err(DynamicError::UnknownId(999)));
        assert_eq!(dynamic.remove(&[1, 1]), Err(DynamicError::RepeatedId(1)));
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)];
        assert_eq!(
            dynamic.insert(&[[Vec3::ZERO, Vec3::X, Vec3::Y], nan]),
            Err(DynamicError::NotFinite { index: 1 })
        );
        assert_eq!(
            dynamic.set_triangle(0, nan),
            Err(DynamicError::NotFinite { index: 0 })
        );
        assert_eq!(dynamic.tree(), &before);
        dynamic.remove(&[2]).unwrap();
        assert_eq!(
            dynamic.set_triangle(2, nan),
            Err(DynamicError::UnknownId(2))
        );
        assert_eq!(dynamic.len(), mesh.triangle_count() - 1);
        dynamic.validate().unwrap();
    }

    #[test]
    fn removing_everything_leaves_an_empty_tree() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 1);
        let mut dynamic = DynamicBvh::from_mesh(&mesh, DynamicConfig { max_leaf_size: 3 });
        let ids: Vec<u32> = (0..mesh.triangle_count() as u32).collect();
        dynamic.remove(&ids).unwrap();
        assert!(dynamic.tree().is_empty() && dynamic.is_empty());
        dynamic.validate().unwrap();
    }
}
