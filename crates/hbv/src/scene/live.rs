//! Live scenes: instances move, change mask and go, and the top level follows by a refit or a
//! rebuild, whichever is cheaper for the trace that follows.
//!
//! # The rule of [`Scene::update`]
//!
//! Let `c` be the instances added, moved or removed since the last build or update, and `n` the
//! live instances.
//!
//! 1. `c > REBUILD_FRACTION · n` (a quarter): rebuild by binned SAH. Most leaves moved, so a
//!    refit's boxes would overlap everywhere; and a refit costs about a tenth of a rebuild, so
//!    trying one first would buy little.
//! 2. Otherwise refit: new instances are inserted (greedy descent, Goldsmith & Salmon 1987),
//!    then every box is recomputed bottom-up (removed instances' leaves are empty boxes). If
//!    the refitted tree's SAH cost `Σ SA(n) / SA(root)` has grown past
//!    `REBUILD_COST_GROWTH` (1.3) times that of the last build, rebuild after all: the instances
//!    moved far enough that the old topology no longer fits them.
//!
//! Measured with `cargo run --release -p hbv --example scene_update` (10,000 instances of a
//! 70k-triangle mesh, a fraction moved by up to a fifth of the scene's width): refitting takes
//! a tenth of a rebuild's time or less; moving 1 % leaves the cost within a few percent of the
//! rebuilt tree's, 10 % grows it by about a quarter, 100 % by several times. The constants sit
//! where a refit still traces about as fast as a rebuild.
//!
//! Between a change and the update, queries still answer the scene as it is: a moved or added
//! instance is tested in turn, its leaf (whose box may be stale) skipped; a removed one is
//! never tested; a mask is read at every query.

use super::instance::{Instance, InstanceState};
use super::{InstanceId, InstanceTransform, Scene, SceneError};
use crate::bvh::InvariantError;
use crate::geometry::Aabb;

/// Rebuild when more than this fraction of the live instances changed since the last build or
/// update (module notes).
const REBUILD_FRACTION: f64 = 0.25;

/// Rebuild when a refit leaves the top level's SAH cost above this many times that of the
/// last build (module notes).
const REBUILD_COST_GROWTH: f32 = 1.3;

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
        Ok(())
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
    /// last build or update, by a refit or a rebuild (the rule is in the module notes of
    /// `scene/live.rs`: more than a quarter changed, or a refit whose SAH cost grew past 1.3
    /// times the last build's, rebuilds).
    pub fn update(&mut self) -> TopLevelUpdate {
        let changed = self.pending.len() + self.removed_since_update;
        if changed == 0 {
            return TopLevelUpdate::Unchanged;
        }
        let live = self.live_instance_count();
        if self.top_level.is_empty() || changed as f64 > REBUILD_FRACTION * live as f64 {
            self.build();
            return TopLevelUpdate::Rebuilt;
        }
        self.refit();
        if self.top_level.cost() > REBUILD_COST_GROWTH * self.top_level.built_cost() {
            self.build();
            return TopLevelUpdate::Rebuilt;
        }
        TopLevelUpdate::Refitted
    }

    /// Refits the top level whatever the changes: inserts the instances added since it was
    /// built or updated, recomputes every box bottom-up, keeps the topology. [`Scene::update`]
    /// chooses between this and [`Scene::build`]; call it directly to measure.
    pub fn refit(&mut self) {
        for &id in &self.pending {
            let instance = &self.instances[id as usize];
            if id >= self.top_level.instances_covered() && !instance.world_box.is_empty() {
                self.top_level.insert(id, instance.world_box);
            }
        }
        self.top_level.cover_instances(self.instances.len() as u32);
        let instances = &self.instances;
        self.top_level.refit(|id| instances[id as usize].world_box);
        self.index_pending();
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
