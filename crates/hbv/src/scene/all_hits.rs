//! Every hit along a ray in a scene ([`Scene::intersect_all`]) and their number
//! ([`Scene::count`]): each instance the ray sees answers with its mesh's own all-hits query
//! ([`AllHits`]) on the ray carried into its space, and the lists are merged in the scene's
//! tie order.

use super::instance::Instance;
use rayon::prelude::*;

use super::{Scene, SceneHit, SceneMesh, SceneRay, BATCH_GRAIN};
use crate::all_hits::AllHits;
use crate::bvh::layout::AnyLayout;
use crate::geometry::{PreparedRay, Ray};
use crate::query::Hit;
use crate::BruteForce;

impl Scene {
    /// Every hit along the ray within its `[tmin, tmax]` on the instances it sees, sorted by
    /// `t`, then instance, then `prim` (the flattened scene's face order), each with its world
    /// normal. Within an instance the hits are those of [`AllHits`] on its mesh (a ray through
    /// an edge counts where it crosses, once); across instances the accuracy is that of
    /// [`Scene::intersect`] (module notes). Invalid rays have no hits.
    pub fn intersect_all(&self, ray: &SceneRay) -> Vec<SceneHit> {
        let mut found = Vec::new();
        let mut hits = Vec::new();
        self.for_each_instance_along(ray, |id, instance| {
            let mesh = &self.meshes[instance.mesh as usize];
            mesh.all_hits(&instance.carry(ray), &mut hits);
            found.extend(hits.iter().map(|h| SceneHit {
                t: h.t,
                u: h.u,
                v: h.v,
                prim: h.prim,
                instance: id,
                normal: instance.world_normal(&mesh.mesh.triangle(h.prim as usize)),
            }));
        });
        found.sort_unstable_by(|a, b| {
            a.t.total_cmp(&b.t)
                .then(a.instance.cmp(&b.instance))
                .then(a.prim.cmp(&b.prim))
        });
        found
    }

    /// The number of hits [`Scene::intersect_all`] finds, without their normals or a list.
    pub fn count(&self, ray: &SceneRay) -> usize {
        let mut count = 0;
        let mut hits = Vec::new();
        self.for_each_instance_along(ray, |_, instance| {
            let mesh = &self.meshes[instance.mesh as usize];
            mesh.all_hits(&instance.carry(ray), &mut hits);
            count += hits.len();
        });
        count
    }

    /// [`Scene::intersect_all`] of every ray, in parallel on the current rayon pool.
    pub fn intersect_all_batch(&self, rays: &[SceneRay]) -> Vec<Vec<SceneHit>> {
        rays.par_iter()
            .with_min_len(BATCH_GRAIN)
            .map(|ray| self.intersect_all(ray))
            .collect()
    }

    /// [`Scene::count`] of every ray, in parallel on the current rayon pool.
    pub fn count_batch(&self, rays: &[SceneRay]) -> Vec<usize> {
        rays.par_iter()
            .with_min_len(BATCH_GRAIN)
            .map(|ray| self.count(ray))
            .collect()
    }

    /// Calls `visit` with every live instance the ray sees (by mask) whose world box its whole
    /// `[tmin, tmax]` reaches, each once: the pending ones in turn, then the top level's indexed
    /// leaves, as [`Scene::intersect`] visits them, with the interval never shrunk.
    fn for_each_instance_along(&self, ray: &SceneRay, mut visit: impl FnMut(u32, &Instance)) {
        if !ray.ray.is_valid() || ray.mask == 0 {
            return;
        }
        let mut prepared = PreparedRay::new(&ray.ray);
        self.visit_instances(ray, &mut prepared, |id, _| {
            let instance = &self.instances[id as usize];
            if ray.sees(instance.mask) {
                visit(id, instance);
            }
            false
        });
    }
}

impl AllHits for SceneMesh {
    /// Every hit of the (local) `ray` on the mesh, sorted by `(t, prim)`: the wide layouts'
    /// all-hits traversal, or for the layouts that have none (recursive, skip, ordered) every
    /// triangle tested in turn, which answers the same list.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        match &self.layout {
            AnyLayout::Wide4(layout) => layout.all_hits(ray, hits),
            AnyLayout::Wide8(layout) => layout.all_hits(ray, hits),
            AnyLayout::Recursive(_) | AnyLayout::Skip(_) | AnyLayout::Ordered(_) => {
                BruteForce::new(&self.mesh).all_hits(ray, hits)
            }
        }
    }
}
