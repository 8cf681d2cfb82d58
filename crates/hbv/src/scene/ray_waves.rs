//! Scene batches traced in waves: the rays of a batch meet each mesh together, so that the
//! mesh's interleaved batch ([`Accelerator::intersect_into`], `bvh/layout/wide/stream.rs`)
//! hides one ray's memory waits behind the others' work, as on a single mesh.
//!
//! A wave is a chunk of [`WAVE`] rays (one rayon task). First each ray walks the top level
//! once, with its whole interval, and keeps every instance it sees (by mask) with the distance
//! at which it enters the instance's grown world box, sorted nearest first. Then, in rounds,
//! every ray still going takes its next instance, unless that one is entered beyond its best
//! `t` so far (then no later one can hold a nearer hit, and the ray is done); the rays of a
//! round are carried into their instances' spaces, gathered by mesh, and each mesh traces its
//! rays in one batch, each up to its ray's best `t`. An any-hit ray is done at its first hit.
//!
//! **Answers equal the single-ray queries' bit for bit.** A mesh's closest hit on a ray over
//! `[tmin, tmax]` is the least `(t, prim)` among the triangles whose computed `t` lies in the
//! interval, and a triangle's computed `t` does not depend on the interval
//! (`geometry/triangle.rs`); [`SceneHit::is_closer`] then keeps the least
//! `(t, instance, prim)` over all instances traced, in whatever order they come, so the
//! answer is that least triple over the instances the ray sees, as [`Scene::intersect`]'s.
//! An instance is left out only where the walk of [`Scene::intersect`] would cull it: its grown
//! box entered beyond `best + m`, the entry computed as the walk's box test computes it, `m`
//! the ray's box margin ([`PreparedRay::bound_errors_within`]) for a box holding every live
//! instance's grown world box, as the walk's is for its root box: it covers the entry's
//! rounding and the triangle test's.
//! The batch and the single-ray answers of every layout are the same (`stream.rs`), and any
//! hit is whether some triangle of a seen instance accepts the ray, whatever the order.
//! `tests/scene_batches.rs` checks the equality on random live scenes.

use std::ops::Range;

use rayon::prelude::*;

use super::{Scene, SceneHit, SceneRay};
use crate::bvh::layout::AnyLayout;
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::query::{Accelerator, Hit};

/// Rays in one wave (one rayon task): enough that each mesh of a scene of tens of meshes gets
/// tens of rays a round, more than the 16 its batches keep in flight.
const WAVE: usize = 4096;

/// An instance a ray may meet: where the ray enters its grown world box, and its id.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    entry: f32,
    instance: u32,
}

/// What a wave knows of one ray: its candidates `list[next..end]` still to trace, and its box
/// margin `m`.
#[derive(Clone, Copy, Debug)]
struct WaveRay {
    next: u32,
    end: u32,
    margin: f32,
}

/// A round's work: ray `ray` of the wave carried into instance `instance`, whose mesh is `mesh`.
#[derive(Clone, Copy, Debug)]
struct Visit {
    mesh: u32,
    ray: u32,
    instance: u32,
}

/// The rays of one wave, their candidates and their round's work, reused from round to round.
struct Wave<'a> {
    scene: &'a Scene,
    rays: &'a [SceneRay],
    state: Vec<WaveRay>,
    list: Vec<Candidate>,
    /// The rays still going.
    active: Vec<u32>,
    visits: Vec<Visit>,
    carried: Vec<Ray>,
}

impl Scene {
    /// [`Scene::intersect`] of every ray, traced in waves (module notes) on the current rayon
    /// pool.
    pub(super) fn intersect_waves(&self, rays: &[SceneRay]) -> Vec<Option<SceneHit>> {
        let bounds = self.bounds();
        let mut hits = vec![None; rays.len()];
        rays.par_chunks(WAVE)
            .zip(hits.par_chunks_mut(WAVE))
            .for_each(|(rays, hits)| Wave::new(self, rays, &bounds).closest(hits));
        hits
    }

    /// [`Scene::occluded`] of every ray, traced in waves (module notes) on the current rayon
    /// pool.
    pub(super) fn occluded_waves(&self, rays: &[SceneRay]) -> Vec<bool> {
        let bounds = self.bounds();
        let mut occluded = vec![false; rays.len()];
        rays.par_chunks(WAVE)
            .zip(occluded.par_chunks_mut(WAVE))
            .for_each(|(rays, occluded)| Wave::new(self, rays, &bounds).any(occluded));
        occluded
    }
}

impl<'a> Wave<'a> {
    /// Walks the top level once for each ray, over its whole interval, and keeps the instances
    /// it sees nearest first; `bounds` holds every instance's world box.
    fn new(scene: &'a Scene, rays: &'a [SceneRay], bounds: &Aabb) -> Self {
        let mut wave = Self {
            scene,
            rays,
            state: Vec::with_capacity(rays.len()),
            list: Vec::with_capacity(rays.len() * 4),
            active: Vec::with_capacity(rays.len()),
            visits: Vec::with_capacity(rays.len()),
            carried: Vec::with_capacity(rays.len()),
        };
        for (k, ray) in rays.iter().enumerate() {
            let start = wave.list.len() as u32;
            let mut margin = 0.0;
            if ray.ray.is_valid() && ray.mask != 0 {
                let pad = scene.box_pad(&ray.ray);
                let grown = Aabb::new(bounds.min - pad, bounds.max + pad);
                margin = PreparedRay::margins(
                    ray.ray.origin,
                    ray.ray.direction,
                    PreparedRay::scene_size(&grown),
                )
                .0;
                let mut prepared = PreparedRay::new(&ray.ray);
                let list = &mut wave.list;
                scene.visit_instances(ray, &mut prepared, |id, prepared| {
                    let instance = &scene.instances[id as usize];
                    if ray.sees(instance.mask) {
                        list.push(Candidate {
                            entry: entry(&instance.world_box, pad, prepared),
                            instance: id,
                        });
                    }
                    false
                });
                list[start as usize..].sort_unstable_by(|a, b| {
                    a.entry
                        .total_cmp(&b.entry)
                        .then(a.instance.cmp(&b.instance))
                });
                if wave.list.len() as u32 > start {
                    wave.active.push(k as u32);
                }
            }
            wave.state.push(WaveRay {
                next: start,
                end: wave.list.len() as u32,
                margin,
            });
        }
        wave
    }

    /// Closest hits into `hits`, one per ray (module notes).
    fn closest(mut self, hits: &mut [Option<SceneHit>]) {
        let scene = self.scene;
        let mut answers: Vec<Option<Hit>> = Vec::with_capacity(self.rays.len());
        loop {
            // Each ray's next instance entered within its best `t` (plus its margin).
            let (state, list) = (&mut self.state, &self.list);
            self.active.retain(|&k| {
                let s = &mut state[k as usize];
                let reach = hits[k as usize].map_or(self.rays[k as usize].ray.tmax, |h| h.t);
                s.next < s.end && list[s.next as usize].entry <= reach + s.margin
            });
            if self.active.is_empty() {
                break;
            }
            self.gather(|k| hits[k as usize].map(|h| h.t));
            answers.clear();
            answers.resize(self.carried.len(), None);
            self.trace_by_mesh(|layout, rays, range| {
                layout.intersect_into(rays, &mut answers[range]);
            });
            for (visit, answer) in self.visits.iter().zip(&answers) {
                let Some(hit) = answer else { continue };
                SceneHit::keep_closer(&mut hits[visit.ray as usize], visit.instance, hit);
            }
        }
        for hit in hits.iter_mut() {
            *hit = hit.map(|h| scene.with_normal(h));
        }
    }

    /// Any-hit answers into `occluded`, one per ray (module notes).
    fn any(mut self, occluded: &mut [bool]) {
        let mut answers: Vec<bool> = Vec::with_capacity(self.rays.len());
        loop {
            let state = &self.state;
            self.active.retain(|&k| {
                let s = &state[k as usize];
                !occluded[k as usize] && s.next < s.end
            });
            if self.active.is_empty() {
                break;
            }
            self.gather(|_| None);
            answers.clear();
            answers.resize(self.carried.len(), false);
            self.trace_by_mesh(|layout, rays, range| {
                layout.occluded_into(rays, &mut answers[range]);
            });
            for (visit, &hit) in self.visits.iter().zip(&answers) {
                occluded[visit.ray as usize] |= hit;
            }
        }
    }

    /// The round's visits: each active ray takes its next candidate, carried into that
    /// instance's space over `[tmin, best]` (`best(k)`, or the ray's own `tmax`); sorted by mesh.
    fn gather(&mut self, best: impl Fn(u32) -> Option<f32>) {
        let scene = self.scene;
        self.visits.clear();
        for &k in &self.active {
            let s = &mut self.state[k as usize];
            let instance = self.list[s.next as usize].instance;
            s.next += 1;
            self.visits.push(Visit {
                mesh: scene.instances[instance as usize].mesh,
                ray: k,
                instance,
            });
        }
        self.visits
            .sort_unstable_by_key(|v| (u64::from(v.mesh) << 32) | u64::from(v.ray));
        self.carried.clear();
        for visit in &self.visits {
            let ray = &self.rays[visit.ray as usize];
            let tmax = best(visit.ray).unwrap_or(ray.ray.tmax);
            let world = ray.with_interval(ray.ray.tmin, tmax);
            self.carried
                .push(scene.instances[visit.instance as usize].carry(&world));
        }
    }

    /// Calls `trace(layout, rays, range)` for each mesh's run of the round's carried rays.
    fn trace_by_mesh(&self, mut trace: impl FnMut(&AnyLayout, &[Ray], Range<usize>)) {
        let mut start = 0;
        while start < self.visits.len() {
            let mesh = self.visits[start].mesh;
            let end = start
                + self.visits[start..]
                    .iter()
                    .position(|v| v.mesh != mesh)
                    .unwrap_or(self.visits.len() - start);
            let layout = &self.scene.meshes[mesh as usize].layout;
            trace(layout, &self.carried[start..end], start..end);
            start = end;
        }
    }
}

/// Where the ray enters `world_box` grown by `pad` on every side: the largest near-plane slab
/// distance `fl(fl(plane ± pad - o) · fl(1/d))`, each computed as the top level's box test
/// computes it (`scene/grown_box_lanes.rs`); a NaN distance (an origin on a plane with a zero
/// direction component, an overflowing `1/d`) leaves its axis unconstrained.
#[inline]
fn entry(world_box: &Aabb, pad: f32, ray: &PreparedRay) -> f32 {
    let mut near = f32::NEG_INFINITY;
    for axis in 0..3 {
        let plane = if ray.negative[axis] {
            world_box.max[axis] + pad
        } else {
            world_box.min[axis] + -pad
        };
        near = near.max((plane - ray.origin[axis]) * ray.inv_direction[axis]);
    }
    near
}
