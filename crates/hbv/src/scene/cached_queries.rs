//! The queries a scene's object caches ask of it: one `(instance, prim)` tested alone against a
//! world ray, the triangle that blocks a shadow ray, and the closest- and any-hit queries with
//! their work counted (what `hbv experiment seed-claims` reports per ray).
//!
//! The caches themselves are [`crate::cache::SceneShadowCache`] and
//! [`crate::cache::SceneLastHitCache`]; they answer exactly as [`Scene::intersect`] and
//! [`Scene::occluded`] do because the one-triangle test here is the very test the scene runs on
//! that triangle: the same carried ray ([`Instance::carry`] depends on the ray's origin and
//! direction only), the same stored triangle, the same watertight test.

use super::instance::{Instance, InstanceState};
use super::{InstanceId, Scene, SceneError, SceneHit, SceneRay};
use crate::geometry::{PreparedRay, Ray, Triangle, TriangleHit};
use crate::stats::TraversalStats;
use crate::Accelerator;

/// A hit on one triangle of one instance, with what a closest-hit cache needs to bound the
/// next query by it.
#[derive(Clone, Copy, Debug)]
struct PrimHit {
    hit: TriangleHit,
    /// The triangle in its mesh's space.
    triangle: Triangle,
    /// The world ray carried into the instance's space.
    carried: Ray,
}

impl PrimHit {
    /// A `tmax` at or beyond every `t` the scene can compute for the closest hit of a ray that
    /// hits this triangle at `t_c`:
    ///
    /// ```text
    ///   t_c + 2^-16 |t_c| + 64 ε max_k ‖p_k − o'‖∞ / max_i |d'_i|
    /// ```
    ///
    /// in the instance's space (`p_k` the local vertices, `(o', d')` the carried ray; `t` is the
    /// same parameter in both spaces). The closest hit's computed `t` is at most `t_c` (the
    /// scene computes `t_c` for this triangle exactly so), and the slack covers the boxes'
    /// rounding on the way to it, as in [`crate::cache::LastHitCache`]: the margin past `t_c`
    /// only lets a traversal visit a little more, it never changes which hit is the closest.
    fn closest_hit_bound(&self) -> f32 {
        let t = self.hit.t;
        let origin = self.carried.origin;
        let reach = [self.triangle.p0, self.triangle.p1, self.triangle.p2]
            .map(|p| (p - origin).abs().max_element())
            .into_iter()
            .fold(0.0f32, f32::max);
        let slack = t.abs() * (1.0 / 65_536.0)
            + 64.0 * f32::EPSILON * reach / self.carried.direction.abs().max_element();
        t + slack
    }
}

impl Scene {
    /// Triangle `prim` of instance `instance`'s mesh, alone, against the world ray: the ray is
    /// carried into the instance's space by its inverse transform and the triangle tested there
    /// by the watertight test every layout uses, within the ray's `[tmin, tmax]`; the ray's mask
    /// must see the instance. The answer is the one [`Scene::intersect`] would give were this
    /// the only triangle of the scene (its `t`, `u`, `v` bit for bit, its world normal).
    ///
    /// `Ok(None)` for a miss, an invalid ray, a mask that does not see the instance, and a
    /// `prim` that no hit can name (beyond the mesh's triangles, or a degenerate one).
    /// [`SceneError::UnknownInstance`] or [`SceneError::RemovedInstance`] for an id that is not
    /// a live instance.
    pub fn intersect_prim(
        &self,
        ray: &SceneRay,
        instance: InstanceId,
        prim: u32,
    ) -> Result<Option<SceneHit>, SceneError> {
        match self.instances.get(instance.0 as usize) {
            None => {
                return Err(SceneError::UnknownInstance {
                    instance,
                    instances: self.instances.len(),
                })
            }
            Some(i) if i.state == InstanceState::Removed => {
                return Err(SceneError::RemovedInstance { instance })
            }
            Some(_) => {}
        }
        let Some(found) = self.prim_hit(ray, instance.0, prim) else {
            return Ok(None);
        };
        if found.triangle.is_degenerate() {
            return Ok(None);
        }
        let owner = &self.instances[instance.0 as usize];
        Ok(Some(SceneHit {
            t: found.hit.t,
            u: found.hit.u,
            v: found.hit.v,
            prim,
            instance: instance.0,
            normal: owner.world_normal(&found.triangle),
        }))
    }

    /// Whether `(instance, prim)` alone blocks the ray ([`Scene::intersect_prim`] hits it);
    /// false for an id that is not a live instance (a cache may hold one removed since).
    #[inline]
    pub(crate) fn prim_blocks(&self, ray: &SceneRay, instance: u32, prim: u32) -> bool {
        self.prim_hit(ray, instance, prim).is_some()
    }

    /// When `(instance, prim)` alone is hit by the ray, a `tmax` that keeps the ray's closest
    /// hit in the scene within `[tmin, tmax]` (see `PrimHit::closest_hit_bound`); `None` when it
    /// is not hit, or the id is not a live instance.
    #[inline]
    pub(crate) fn closest_hit_bound(
        &self,
        ray: &SceneRay,
        instance: u32,
        prim: u32,
    ) -> Option<f32> {
        self.prim_hit(ray, instance, prim)
            .map(|found| found.closest_hit_bound())
    }

    /// [`Scene::intersect_prim`] without the checks a caller's ids need: `None` also for an id
    /// that is not a live instance.
    #[inline]
    fn prim_hit(&self, ray: &SceneRay, instance: u32, prim: u32) -> Option<PrimHit> {
        let owner = self.instances.get(instance as usize)?;
        if owner.state == InstanceState::Removed || !ray.sees(owner.mask) || !ray.ray.is_valid() {
            return None;
        }
        let mesh = &self.meshes[owner.mesh as usize].mesh;
        if prim as usize >= mesh.triangle_count() {
            return None;
        }
        let triangle = mesh.triangle(prim as usize);
        let carried = owner.carry(ray);
        let hit = triangle.intersect(&PreparedRay::new(&carried))?;
        Some(PrimHit {
            hit,
            triangle,
            carried,
        })
    }

    /// Any hit, returning the `(instance, prim)` that blocks the ray (the first one found, not
    /// necessarily the nearest): what a shadow cache remembers. `Some` exactly when
    /// [`Scene::occluded`] is true.
    pub fn occluder(&self, ray: &SceneRay) -> Option<(InstanceId, u32)> {
        self.occluder_with(ray, |layout, carried| layout.occluder(carried))
    }

    /// [`Scene::occluder`], adding the work done to `stats` (see [`Scene::intersect_counted`]).
    pub fn occluder_counted(
        &self,
        ray: &SceneRay,
        stats: &mut TraversalStats,
    ) -> Option<(InstanceId, u32)> {
        stats.rays += 1;
        self.occluder_with(ray, |layout, carried| {
            count_entry(stats, |entry| layout.occluder_counted(carried, entry))
        })
    }

    /// [`Scene::occluded`], adding the work done to `stats` (see [`Scene::intersect_counted`]).
    pub fn occluded_counted(&self, ray: &SceneRay, stats: &mut TraversalStats) -> bool {
        self.occluder_counted(ray, stats).is_some()
    }

    /// [`Scene::intersect`], adding the work done to `stats`: one ray; the boxes, nodes and
    /// triangles the instances' meshes test; and each instance entered (its leaf of the top
    /// level, where the ray is carried into its space) as one node visited. The top level's own
    /// box tests are not counted.
    pub fn intersect_counted(
        &self,
        ray: &SceneRay,
        stats: &mut TraversalStats,
    ) -> Option<SceneHit> {
        stats.rays += 1;
        if !ray.ray.is_valid() || ray.mask == 0 {
            return None;
        }
        let mut best: Option<SceneHit> = None;
        let mut prepared = PreparedRay::new(&ray.ray);
        self.visit_instances(ray, &mut prepared, |id, prepared| {
            let instance = &self.instances[id as usize];
            if !ray.sees(instance.mask) {
                return false;
            }
            let world = ray.with_interval(ray.ray.tmin, prepared.tmax);
            let layout = &self.meshes[instance.mesh as usize].layout;
            let carried = instance.carry(&world);
            let hit = count_entry(stats, |entry| layout.intersect_counted(&carried, entry));
            if let Some(hit) = hit.filter(|h| SceneHit::keep_closer(&mut best, id, h)) {
                prepared.tmax = hit.t;
            }
            false
        });
        best.map(|hit| self.with_normal(hit))
    }

    /// The first `(instance, prim)` that `occluder(layout, carried ray)` reports among the
    /// instances the ray sees.
    fn occluder_with(
        &self,
        ray: &SceneRay,
        mut occluder: impl FnMut(&crate::bvh::layout::AnyLayout, &Ray) -> Option<u32>,
    ) -> Option<(InstanceId, u32)> {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return None;
        }
        let mut found = None;
        let mut prepared = PreparedRay::new(&ray.ray);
        self.visit_instances(ray, &mut prepared, |id, _| {
            let instance: &Instance = &self.instances[id as usize];
            if !ray.sees(instance.mask) {
                return false;
            }
            let layout = &self.meshes[instance.mesh as usize].layout;
            found = occluder(layout, &instance.carry(ray)).map(|prim| (InstanceId(id), prim));
            found.is_some()
        });
        found
    }
}

/// Runs one instance's counted query into a fresh count and adds its work to `stats`, the
/// instance entered as one node visited (its own `rays` count is that entry).
#[inline]
fn count_entry<T>(stats: &mut TraversalStats, query: impl FnOnce(&mut TraversalStats) -> T) -> T {
    let mut entry = TraversalStats::default();
    let answer = query(&mut entry);
    stats.nodes_visited += entry.nodes_visited + entry.rays;
    stats.boxes_tested += entry.boxes_tested;
    stats.triangles_tested += entry.triangles_tested;
    stats.mailbox_skips += entry.mailbox_skips;
    answer
}
