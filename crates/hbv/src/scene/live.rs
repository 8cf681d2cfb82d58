//! Live scenes: instances move, change mask and go, and the top level follows by a refit or a
//! rebuild, whichever is cheaper for the trace that follows.
//!
//! # The rule of [`Scene::update`]
//!
//! 1. Refit: instances added since the last build or update are inserted (greedy descent,
//!    Goldsmith & Salmon 1987), then every box is recomputed bottom-up, the topology kept
//!    (a removed instance's leaf becomes an empty box, a hole).
//! 2. Rebuild by binned SAH instead when the refitted tree's SAH cost `Σ SA(n) / SA(root)` has
//!    grown past `REBUILD_COST_GROWTH` (1.25) times that of the last build (the instances
//!    moved far enough that the old topology no longer fits them), or when more than
//!    `REBUILD_HOLES` (a quarter) of its leaves are holes (memory and nodes walked for nothing).
//!
//! How many instances changed is not itself a reason to rebuild: a refit costs a few percent
//! of a rebuild whatever changed, and when every instance moves a little the refitted tree is
//! as good as a rebuilt one; the cost test says when it is not. Measured with
//! `cargo run --release -p hbv --example scene_update` (10,000 instances of a 69,696-triangle
//! torus on a grid, 2 cores shared with other work): a refit takes 0.18 to 0.29 ms and a
//! rebuild 5 to 8 ms, whatever fraction moved. Moving 1 %, 10 % or 100 % of the instances by
//! up to half a torus width leaves the refitted cost at 1.000, 1.002, 1.013 times the rebuilt
//! tree's, and by up to a grid cell at 1.002, 1.041, 1.275. 50,000 random closest-hit rays
//! (one thread) trace as fast on refits of cost up to 1.04 as on the rebuilt tree (0.77 to
//! 0.84 µs a ray on both); at 1.275 they take 0.99 to 1.00 µs against 0.80 to 0.82 (about a
//! quarter slower), at 1.40 a quarter to a third slower, at 3.2 2.5 times slower; instances
//! moved anywhere in the field make the cost 7 (1 % of them) to 250 (all). So 1.25: a refit is
//! kept where it traces as fast as a rebuild, and a rebuild, which costs as much as tracing
//! some seven thousand rays, is paid where the refit would lose a fifth or more on every ray.
//!
//! Between a change and the update, queries still answer the scene as it is: a moved or added
//! instance is tested in turn, its leaf (whose box may be stale) skipped; a removed one is
//! never tested; a mask is read at every query.

use super::instance::{Instance, InstanceState};
use super::{InstanceId, InstanceTransform, Scene, SceneError};
use crate::bvh::InvariantError;
use crate::geometry::Aabb;

/// Rebuild when a refit leaves the top level's SAH cost above this many times that of the
/// last build (module notes).
const REBUILD_COST_GROWTH: f32 = 1.25;

/// Rebuild when more than this fraction of the top level's leaves are removed instances'
/// (module notes).
const REBUILD_HOLES: f64 = 0.25;

/// What [`Scene::update`] did to the top level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TopLevelUpdate {
    /// Nothing had changed.
    Unchanged,
    /// New instances inserted and every box recomputed, the topology kept.
    Refitted,
    /// Built again by binned SAH, as [`Scene::build`] does.
    Rebuilt,
}

/// The SAH cost `Σ SA(node) / SA(root)` of the top level: the expected number of its boxes a
/// ray through the root box meets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TopLevelCost {
    /// The tree as it is now.
    pub current: f32,
    /// The tree as it was when last built.
    pub at_build: f32,
}

impl Scene {
    /// Moves instance `instance` to `transform`. Queries see the move at once (the instance is
    /// tested in turn until [`Scene::update`] or [`Scene::build`] puts it back into the top
    /// level). Refused for an id never handed out or removed.
    pub fn set_transform(
        &mut self,
        instance: InstanceId,
        transform: InstanceTransform,
    ) -> Result<(), SceneError> {
        let index = self.live_index(instance)?;
        let mesh = &self.meshes[self.instances[index].mesh as usize];
        let transform = mesh.placement(transform)?;
        self.place_instance(index, transform);
        Ok(())
    }

    /// Places live instance `index` by `transform` over its mesh's current box, and leaves it
    /// to be tested in turn until the next build or update.
    pub(super) fn place_instance(&mut self, index: usize, transform: InstanceTransform) {
        let old = self.instances[index];
        let mesh_box = self.meshes[old.mesh as usize].bounds;
        let moved = Instance {
            state: InstanceState::Pending,
            ..Instance::new(old.mesh, transform, old.mask, &mesh_box)
        };
        self.instances[index] = moved;
        if old.state == InstanceState::Indexed {
            self.pending.push(index as u32);
        }
        self.widen_box_growth(&moved);
    }

    /// Sets the mask of instance `instance`: rays see it only if their mask shares a bit with
    /// `mask`. Takes effect at once, no update needed. Refused for an id never handed out or
    /// removed.
    pub fn set_mask(&mut self, instance: InstanceId, mask: u32) -> Result<(), SceneError> {
        let index = self.live_index(instance)?;
        self.instances[index].mask = mask;
        Ok(())
    }

    /// Removes instance `instance`: from now on it is never hit, and its id stays a hole, never
    /// handed out again (every other id keeps its meaning). Refused for an id never handed out
    /// or already removed.
    pub fn remove_instance(&mut self, instance: InstanceId) -> Result<(), SceneError> {
        let index = self.live_index(instance)?;
        let removed = &mut self.instances[index];
        if removed.state == InstanceState::Pending {
            self.pending.retain(|&id| id as usize != index);
        }
        removed.state = InstanceState::Removed;
        removed.world_box = Aabb::EMPTY;
        self.removed_since_update += 1;
        Ok(())
    }

    /// Brings the top level up to date with the instances added, moved and removed since the
    /// last build or update: a refit, or a rebuild where the refitted tree's SAH cost grew
    /// past 1.25 times the last build's or more than a quarter of its leaves are removed
    /// instances' (the rule and its measurement are in the module notes of `scene/live.rs`).
    pub fn update(&mut self) -> TopLevelUpdate {
        if self.pending.is_empty() && self.removed_since_update == 0 {
            return TopLevelUpdate::Unchanged;
        }
        if self.top_level.is_empty() {
            self.build();
            return TopLevelUpdate::Rebuilt;
        }
        let holes = self.refit_top_level();
        let too_costly = self.top_level.cost() > REBUILD_COST_GROWTH * self.top_level.built_cost();
        if too_costly || holes as f64 > REBUILD_HOLES * self.top_level.leaf_count() as f64 {
            self.build();
            return TopLevelUpdate::Rebuilt;
        }
        TopLevelUpdate::Refitted
    }

    /// Refits the top level whatever the changes: inserts the instances added since it was
    /// built or updated, recomputes every box bottom-up, keeps the topology. [`Scene::update`]
    /// chooses between this and [`Scene::build`]; call it directly to measure.
    pub fn refit(&mut self) {
        self.refit_top_level();
    }

    /// [`Scene::refit`], returning the number of the top level's leaves that are holes.
    fn refit_top_level(&mut self) -> usize {
        for &id in &self.pending {
            let instance = &self.instances[id as usize];
            if id >= self.top_level.instances_covered() && !instance.world_box.is_empty() {
                self.top_level.insert(id, instance.world_box);
            }
        }
        self.top_level.cover_instances(self.instances.len() as u32);
        let instances = &self.instances;
        let holes = self.top_level.refit(|id| instances[id as usize].world_box);
        self.index_pending();
        holes
    }

    /// The top level's SAH cost now and at its last build (see [`TopLevelCost`]).
    pub fn top_level_cost(&self) -> TopLevelCost {
        TopLevelCost {
            current: self.top_level.cost(),
            at_build: self.top_level.built_cost(),
        }
    }

    /// Checks the top level against the instances: every node's box holds its children's,
    /// every leaf names an instance handed out, at most once, and every instance in the top
    /// level's care (not pending, not removed, its box not empty) has one leaf whose box holds
    /// its world box (so by the first check, every ancestor's box holds it too).
    pub fn validate(&self) -> Result<(), InvariantError> {
        let leaves = self.top_level.check_nesting().map_err(InvariantError)?;
        let mut leaf_of = vec![None; self.instances.len()];
        for (id, bounds) in leaves {
            let Some(slot) = leaf_of.get_mut(id as usize) else {
                return Err(InvariantError(format!(
                    "a leaf names instance {id}, never handed out"
                )));
            };
            if slot.replace(bounds).is_some() {
                return Err(InvariantError(format!("instance {id} has two leaves")));
            }
        }
        for (id, instance) in self.instances.iter().enumerate() {
            let indexed = instance.state == InstanceState::Indexed;
            if !indexed || instance.world_box.is_empty() {
                continue;
            }
            match leaf_of[id] {
                Some(leaf) if leaf.contains(&instance.world_box) => {}
                Some(leaf) => {
                    return Err(InvariantError(format!(
                        "instance {id}: leaf box {leaf:?} does not hold its world box {:?}",
                        instance.world_box
                    )))
                }
                None => {
                    return Err(InvariantError(format!(
                        "instance {id} is indexed but has no leaf"
                    )))
                }
            }
        }
        Ok(())
    }

    /// The index of live instance `instance`, or the error that names it.
    fn live_index(&self, instance: InstanceId) -> Result<usize, SceneError> {
        match self.instances.get(instance.0 as usize) {
            None => Err(SceneError::UnknownInstance {
                instance,
                instances: self.instances.len(),
            }),
            Some(i) if i.state == InstanceState::Removed => {
                Err(SceneError::RemovedInstance { instance })
            }
            Some(_) => Ok(instance.0 as usize),
        }
    }
}
