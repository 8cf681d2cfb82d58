//! Scenes: many meshes, each placed by any number of instances, in a two-level BVH.
//!
//! Each mesh gets its own BVH once ([`Scene::add_mesh`], any builder and layout by
//! [`SceneStructure`]); each instance places a mesh by an affine [`InstanceTransform`] in f64
//! and carries a 32-bit mask ([`Scene::add_instance`]); the top level is a BVH over the
//! instances' world boxes ([`Scene::build`]). A ray visits the instances whose boxes it meets,
//! nearest first; in each it is carried into the instance's space by the inverse transform and
//! traced by the mesh's layout.
//!
//! ```
//! use hbv::glam::{DAffine3, DVec3, Vec3};
//! use hbv::geometry::Ray;
//! use hbv::mesh::procedural::icosphere;
//! use hbv::scene::{InstanceTransform, Scene, SceneRay};
//!
//! let mut scene = Scene::new();
//! let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
//! let left = InstanceTransform::from_translation(DVec3::new(-3.0, 0.0, 0.0)).unwrap();
//! let right = InstanceTransform::new(DAffine3::from_scale_rotation_translation(
//!     DVec3::splat(2.0),
//!     Default::default(),
//!     DVec3::new(3.0, 0.0, 0.0),
//! ))
//! .unwrap();
//! scene.add_instance(sphere, left, 0b01).unwrap();
//! let big = scene.add_instance(sphere, right, 0b10).unwrap();
//! scene.build();
//!
//! // From the far right, along -x: the big sphere (radius 2 at x = 3) is hit first, at x ≈ 5.
//! let ray = SceneRay::new(Ray::new(Vec3::new(10.0, 0.0, 0.0), -Vec3::X));
//! let hit = scene.intersect(&ray).unwrap();
//! assert_eq!(hit.instance, big.0);
//! assert!((hit.t - 5.0).abs() < 0.1);
//! assert!(hit.normal.x > 0.9); // outward, towards the ray
//! // A ray that sees only the small sphere passes through the big one.
//! let hit = scene.intersect(&ray.with_mask(0b01)).unwrap();
//! assert!((hit.t - 12.0).abs() < 0.1);
//! ```
//!
//! # Accuracy
//!
//! The answer on instance `i` is exact (watertight, as on a single mesh) for the carried ray
//! `(o', d')`: `A^-1 (o - b)` and `A^-1 d` computed in f64 and rounded to f32. Mapped back,
//! that ray's point at `t` is within `u κ (|o - b| + t |d|)` of the world ray's `o + t d`
//! (∞-norms, `u = 2^-24`, `κ` the transform's [`InstanceTransform::conditioning`]; the f64 steps
//! add at most `2^-50 κ (|o| + |b|)`). The flattened scene ([`Scene::flattened`]) rounds the
//! mapped vertices instead, moving each by at most `u S` (`S` the largest world coordinate of
//! the instance's box). Both moves together are within (now in the 2-norm, `√3` times larger)
//!
//! ```text
//!   ε = 2^-22 (κ (|o - b| + t |d|) + S) + 2^-48 κ (|o| + |b|)
//! ```
//!
//! So the scene and a brute force over the flattened triangles ([`FlattenedScene::intersect`])
//! disagree on hit or miss, or on which triangle is hit, only for rays whose line passes within
//! `ε` of an edge of a triangle involved, where two different triangles are hit at `t`s
//! within the bound below (a near tie), or where a hit lies within that bound of `tmin` or
//! `tmax` (a ray starting on a surface: the other's hit may fall just outside the interval).
//! Where both hit the same triangle, `t` agrees to
//!
//! ```text
//!   |t_scene - t_flat| ≤ ε / |n̂ · d| + 2^-20 (κ + 1) D / |d|,
//! ```
//!
//! `n̂` the triangle's unit normal and `D` the largest `|p - o|` of its world vertices: moving
//! the plane or the ray by `ε` moves the hit along the ray by `ε / |n̂ · d|`, and each triangle
//! test's own `t` is within a few ulps of its coordinates relative to the origin, over `|d|`
//! (the local test's over `|d'| ≥ |d| / ‖A‖`, its coordinates up to `‖A^-1‖` times the world
//! ones). The bound is relative to the coordinates' size, not to `t`: an instance far from the
//! origin is answered as precisely as f32 holds its world coordinates, no better.
//! `crates/hbv/tests/scene.rs` checks both statements ray by ray and counts the rays excused.
//!
//! **No ray is lost at an instance's box**: world boxes are the mesh box's corners mapped in
//! f64 and rounded outwards, and the top level tests them grown by `2^-22 κ (2 |o| + |b| + S)`
//! (largest `κ` and `|b| + S` of the scene), more than the carried ray's move above for points
//! inside the box, so every point the carried ray can hit lies in the box the world ray is
//! tested against.
//!
//! **Ties** are decided as on the flattened scene: at equal `t`, the smaller instance, then the
//! smaller `prim` ([`SceneHit::is_closer`]), whatever order the instances are visited in.
//!
//! # Live scenes
//!
//! Instances move ([`Scene::set_transform`]), change mask ([`Scene::set_mask`]) and go
//! ([`Scene::remove_instance`]); [`Scene::update`] then brings the top level up to date by a
//! refit or a rebuild (the rule is in `scene/live.rs`, [`TopLevelUpdate`]). Queries answer the
//! scene as it is now at every moment: instances added or moved since the last build or update
//! are tested in turn, their stale leaves skipped. **Ids are stable**: an instance's id is the
//! order of its [`Scene::add_instance`] call for as long as the scene lives; a removed instance
//! leaves a hole that is never hit and whose id is never handed out again (later calls with it
//! are refused with [`SceneError::RemovedInstance`]), so the `instance` of every answer keeps
//! meaning what it meant.

mod all_hits;
mod brute_force;
mod cached_queries;
mod closest_point;
mod error;
mod gltf;
mod gltf_write;
mod grown_box_lanes;
mod inside;
mod instance;
mod live;
mod mesh_motion;
mod ray_waves;
mod scene_file;
mod scene_hit;
mod structure;
mod summary;
mod top_level;
mod transform;
mod wide_top_level;

pub use brute_force::FlattenedScene;
pub use closest_point::{SceneClosestPoint, SceneNearestPoints};
pub use error::SceneError;
pub use live::{TopLevelCost, TopLevelUpdate};
pub use scene_file::AnyBvhFile;
pub use scene_hit::{SceneHit, SceneRay};
pub use structure::SceneStructure;
pub use summary::{MeshSummary, SceneSummary};
pub use transform::InstanceTransform;

use std::sync::{Arc, OnceLock};

use crate::bvh::layout::AnyLayout;
use crate::bvh::BuildTree;
use crate::geometry::directed_rounding::f32_above;
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::mesh::{MeshError, TriangleMesh};
use crate::proximity::ClosestPointTree;
use crate::query::Accelerator;
use glam::{DAffine3, DVec3};
use instance::{Instance, InstanceState};
use top_level::TopLevel;

/// A mesh's id in its scene: the order of [`Scene::add_mesh`] calls, from 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct MeshId(pub u32);

/// An instance's id in its scene: the order of [`Scene::add_instance`] calls, from 0, never
/// reused after [`Scene::remove_instance`]. Hits report it as [`SceneHit::instance`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct InstanceId(pub u32);

/// A mesh of a scene with its structure, built once however many instances place it.
#[derive(Clone, Debug)]
struct SceneMesh {
    /// The vertices as stored: relative to `origin` ([`Scene::add_mesh_f64`]).
    mesh: TriangleMesh,
    /// Where the stored vertices' origin lies in the coordinates the mesh was given in: zero,
    /// or a float64 mesh's centre. Every instance's transform is composed with the translation
    /// by it when placed, so instances place the mesh as given.
    origin: DVec3,
    /// `mesh.bounds()`, kept for placing and moving its instances.
    bounds: Aabb,
    layout: AnyLayout,
    /// The tree `layout` was laid out from, kept once the mesh's vertices have moved
    /// ([`Scene::set_mesh_positions`]) for refitting it the next time.
    tree: Option<BuildTree>,
    /// The mesh's nearest-point search tree: made by the first nearest-point query that
    /// needs it, shared by every later one, dropped when the vertices move.
    search: OnceLock<Arc<ClosestPointTree>>,
}

impl SceneMesh {
    /// The transform that places the stored vertices where `transform` places the mesh as
    /// given: `transform` itself, or for a float64 mesh stored relative to `c`, `(A, A c + b)`.
    fn placement(&self, transform: InstanceTransform) -> Result<InstanceTransform, SceneError> {
        if self.origin == DVec3::ZERO {
            return Ok(transform);
        }
        InstanceTransform::new(transform.affine() * DAffine3::from_translation(self.origin))
    }
}

/// Meshes, their instances and the top-level BVH over the instances (module notes).
///
/// Instances added or moved since the last [`Scene::build`] or [`Scene::update`] are answered
/// too, each tested in turn, until the next build or update puts them into the top level.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    structure: SceneStructure,
    meshes: Vec<SceneMesh>,
    instances: Vec<Instance>,
    top_level: TopLevel,
    /// The instances in [`InstanceState::Pending`], in the order they became so: tested in turn.
    pending: Vec<u32>,
    /// Removals since the last build or update: their empty leaves are still in `top_level`.
    removed_since_update: usize,
    /// The largest `κ` of any instance the top level may lead to, and the largest `|b| + S`:
    /// what the top level's box growth of a ray is computed from (module notes). They only grow
    /// as instances are added or moved, and are recomputed over the live instances when the
    /// top level is built or updated, so they always cover every instance a walk can visit.
    largest_conditioning: f64,
    largest_offset: f64,
}

/// Rays handed to one rayon task at least, as in the meshes' batches.
const BATCH_GRAIN: usize = 256;

/// The best hit found so far, its normal not yet computed.
type BestHit = Option<SceneHit>;

impl Scene {
    /// An empty scene whose meshes are built by binned SAH and laid out in wide-8 nodes.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty scene whose meshes are built and laid out as `structure` says.
    pub fn with_structure(structure: SceneStructure) -> Self {
        Self {
            structure,
            ..Self::default()
        }
    }

    /// Adds `mesh` and builds its BVH; instances place it by the id returned.
    pub fn add_mesh(&mut self, mesh: TriangleMesh) -> MeshId {
        let s = &self.structure;
        let layout =
            s.layout
                .build_and_lay_out(&mesh, s.builder, &s.builder_options, &s.layout_options);
        self.push_mesh(mesh, layout, DVec3::ZERO)
    }

    /// Adds `mesh` with the BVH `tree` already built over it (by any builder), laid out as the
    /// scene's structure says: no second build.
    pub fn add_built_mesh(&mut self, mesh: TriangleMesh, tree: &BuildTree) -> MeshId {
        let s = &self.structure;
        let layout = s.layout.lay_out(tree, &mesh, &s.layout_options);
        self.push_mesh(mesh, layout, DVec3::ZERO)
    }

    /// Adds a mesh given in float64, for coordinates far from the origin (a building at UTM
    /// `(500000, 5000000, 0)`): its vertices are stored in float32 relative to the centre `c`
    /// of their box, and every instance's transform `(A, b)` becomes `(A, A c + b)` in f64.
    /// The mesh then answers as precisely as it would at the origin (the scene's accuracy
    /// bound, module notes, with the stored mesh's size for `S` and the ray's origin as close
    /// as [`SceneRay::from_f64`] keeps it). [`Scene::mesh`] returns the stored, relative mesh.
    ///
    /// Refused, naming the vertex or face, for a coordinate that is not finite, an index out of
    /// range, or a vertex farther than [`MAX_COORDINATE`](crate::mesh::MAX_COORDINATE) from the
    /// centre.
    pub fn add_mesh_f64(
        &mut self,
        positions: &[DVec3],
        triangles: &[[u32; 3]],
    ) -> Result<MeshId, MeshError> {
        if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::invalid(
                crate::mesh::MeshSource::Arrays,
                format!("vertex {vertex}"),
                format!("coordinate {} is not finite", positions[vertex]),
            ));
        }
        let (lo, hi) = positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let centre = if positions.is_empty() {
            DVec3::ZERO
        } else {
            lo * 0.5 + hi * 0.5
        };
        let relative = positions.iter().map(|p| (*p - centre).as_vec3()).collect();
        let mesh = TriangleMesh::new(relative, triangles.to_vec())?;
        let s = &self.structure;
        let layout =
            s.layout
                .build_and_lay_out(&mesh, s.builder, &s.builder_options, &s.layout_options);
        Ok(self.push_mesh(mesh, layout, centre))
    }

    fn push_mesh(&mut self, mesh: TriangleMesh, layout: AnyLayout, origin: DVec3) -> MeshId {
        let bounds = mesh.bounds();
        self.meshes.push(SceneMesh {
            mesh,
            origin,
            bounds,
            layout,
            tree: None,
            search: OnceLock::new(),
        });
        MeshId(self.meshes.len() as u32 - 1)
    }

    /// Places mesh `mesh` by `transform`, seen by rays whose mask shares a bit with `mask`.
    /// Refused with [`SceneError::UnknownMesh`] for an id this scene did not hand out.
    pub fn add_instance(
        &mut self,
        mesh: MeshId,
        transform: InstanceTransform,
        mask: u32,
    ) -> Result<InstanceId, SceneError> {
        let Some(scene_mesh) = self.meshes.get(mesh.0 as usize) else {
            return Err(SceneError::UnknownMesh {
                mesh,
                meshes: self.meshes.len(),
            });
        };
        let transform = scene_mesh.placement(transform)?;
        let instance = Instance::new(mesh.0, transform, mask, &scene_mesh.bounds);
        self.widen_box_growth(&instance);
        self.pending.push(self.instances.len() as u32);
        self.instances.push(instance);
        Ok(InstanceId(self.instances.len() as u32 - 1))
    }

    /// Builds the top-level BVH over the world boxes of every live instance (binned SAH, traced
    /// in 8-wide nodes: `scene/top_level.rs`).
    pub fn build(&mut self) {
        self.top_level = TopLevel::build(self.instances.iter().map(|i| i.world_box));
        self.index_pending();
    }

    /// How the scene's meshes are built and laid out.
    pub fn structure(&self) -> &SceneStructure {
        &self.structure
    }

    pub fn mesh_count(&self) -> usize {
        self.meshes.len()
    }

    /// The number of instance ids handed out, removed ones included: ids are `0..instance_count`.
    pub fn instance_count(&self) -> usize {
        self.instances.len()
    }

    /// The number of instances not removed.
    pub fn live_instance_count(&self) -> usize {
        self.instances
            .iter()
            .filter(|i| i.state != InstanceState::Removed)
            .count()
    }

    /// The mesh of id `mesh`, as added.
    pub fn mesh(&self, mesh: MeshId) -> Option<&TriangleMesh> {
        self.meshes.get(mesh.0 as usize).map(|m| &m.mesh)
    }

    /// The world box of instance `instance` (see the module notes): `None` for an id the scene
    /// did not hand out or that was removed, [`Aabb::EMPTY`] for an instance of an empty mesh.
    pub fn instance_bounds(&self, instance: InstanceId) -> Option<Aabb> {
        self.instances
            .get(instance.0 as usize)
            .filter(|i| i.state != InstanceState::Removed)
            .map(|i| i.world_box)
    }

    /// A box holding every world-space point of every instance.
    pub fn bounds(&self) -> Aabb {
        self.instances
            .iter()
            .fold(Aabb::EMPTY, |b, i| b.union(&i.world_box))
    }

    /// The scene as one world-space mesh, instance by instance (see [`FlattenedScene`]), a
    /// removed instance a hole of no faces; fails when a mapped vertex does not fit in f32.
    pub fn flattened(&self) -> Result<FlattenedScene, MeshError> {
        FlattenedScene::new(self.instances.iter().map(|i| {
            (i.state != InstanceState::Removed).then(|| {
                (
                    &self.meshes[i.mesh as usize].mesh,
                    i.transform.affine(),
                    i.mask,
                )
            })
        }))
    }

    /// The closest hit along the ray among the instances it sees; ties to the smaller instance,
    /// then the smaller `prim`. Invalid rays ([`Ray::is_valid`]) miss.
    pub fn intersect(&self, ray: &SceneRay) -> Option<SceneHit> {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return None;
        }
        let mut best: BestHit = None;
        let mut prepared = PreparedRay::new(&ray.ray);
        self.visit_instances(ray, &mut prepared, |id, prepared| {
            self.closest_in(id, ray, prepared, &mut best);
            false
        });
        best.map(|hit| self.with_normal(hit))
    }

    /// `hit` with its world normal, computed from its instance's triangle.
    pub(super) fn with_normal(&self, hit: SceneHit) -> SceneHit {
        let i = &self.instances[hit.instance as usize];
        let triangle = self.meshes[i.mesh as usize]
            .mesh
            .triangle(hit.prim as usize);
        SceneHit {
            normal: i.world_normal(&triangle),
            ..hit
        }
    }

    /// Whether anything the ray sees is hit within its `[tmin, tmax]`; stops at the first hit.
    pub fn occluded(&self, ray: &SceneRay) -> bool {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return false;
        }
        let hit_in = |id: u32| {
            let instance = &self.instances[id as usize];
            ray.sees(instance.mask)
                && self.meshes[instance.mesh as usize]
                    .layout
                    .occluded(&instance.carry(ray))
        };
        let mut occluded = false;
        let mut prepared = PreparedRay::new(&ray.ray);
        self.visit_instances(ray, &mut prepared, |id, _| {
            occluded = hit_in(id);
            occluded
        });
        occluded
    }

    /// Calls `visit(id, prepared)` with every live instance the ray may meet, each once: the
    /// instances not yet in the top level in turn, then the top level's leaves whose boxes the
    /// ray meets within `prepared`'s interval, nearest first (stale leaves of moved or removed
    /// instances skipped). `visit` may shrink `prepared.tmax`, which culls farther boxes, and
    /// returns whether to stop. Masks are `visit`'s to check.
    pub(crate) fn visit_instances(
        &self,
        ray: &SceneRay,
        prepared: &mut PreparedRay,
        mut visit: impl FnMut(u32, &mut PreparedRay) -> bool,
    ) {
        for &id in &self.pending {
            if visit(id, prepared) {
                return;
            }
        }
        self.top_level
            .walk(prepared, self.box_pad(&ray.ray), |id, prepared| {
                self.instances[id as usize].state == InstanceState::Indexed && visit(id, prepared)
            });
    }

    /// [`Scene::intersect`] of every ray, in parallel on the current rayon pool: the rays
    /// traced in waves, each mesh meeting many at once (`scene/ray_waves.rs`), with the
    /// single-ray answers bit for bit.
    pub fn intersect_batch(&self, rays: &[SceneRay]) -> Vec<Option<SceneHit>> {
        self.intersect_waves(rays)
    }

    /// [`Scene::occluded`] of every ray, in parallel on the current rayon pool, in waves as
    /// [`Scene::intersect_batch`].
    pub fn occluded_batch(&self, rays: &[SceneRay]) -> Vec<bool> {
        self.occluded_waves(rays)
    }

    /// Traces instance `id`'s mesh with the ray carried into its space, up to the best `t` so
    /// far, and keeps its hit if it is closer (ties: smaller instance, then smaller `prim`).
    #[inline]
    fn closest_in(&self, id: u32, ray: &SceneRay, prepared: &mut PreparedRay, best: &mut BestHit) {
        let instance = &self.instances[id as usize];
        if !ray.sees(instance.mask) {
            return;
        }
        let world = ray.with_interval(ray.ray.tmin, prepared.tmax);
        let layout = &self.meshes[instance.mesh as usize].layout;
        let Some(hit) = layout.intersect(&instance.carry(&world)) else {
            return;
        };
        if SceneHit::keep_closer(best, id, &hit) {
            prepared.tmax = hit.t;
        }
    }

    /// Makes the box growth cover `instance` too (see `largest_conditioning`).
    fn widen_box_growth(&mut self, instance: &Instance) {
        if let Some((conditioning, offset)) = instance.box_growth_terms() {
            self.largest_conditioning = self.largest_conditioning.max(conditioning);
            self.largest_offset = self.largest_offset.max(offset);
        }
    }

    /// After the top level was built or updated to hold every live instance's current box:
    /// nothing is pending any more, and the box growth is that of the live instances alone.
    fn index_pending(&mut self) {
        for &id in &self.pending {
            self.instances[id as usize].state = InstanceState::Indexed;
        }
        self.pending.clear();
        self.removed_since_update = 0;
        (self.largest_conditioning, self.largest_offset) = (0.0, 0.0);
        for i in 0..self.instances.len() {
            let instance = self.instances[i];
            self.widen_box_growth(&instance);
        }
    }

    /// How far the top level grows each box for `ray`: `2^-22 κ (2 |o| + |b| + S)` with the
    /// scene's largest `κ` and `|b| + S` (module notes), rounded up.
    fn box_pad(&self, ray: &Ray) -> f32 {
        let origin = f64::from(ray.origin.abs().max_element());
        let pad = self.largest_conditioning * (2.0 * origin + self.largest_offset)
            / f64::from(1u32 << 22);
        f32_above(pad).max(f32::MIN_POSITIVE)
    }
}
