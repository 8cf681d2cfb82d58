//! The reference answer: every triangle tested against every ray.

use crate::geometry::{EdgeRule, PreparedRay, Ray, Triangle};
use crate::mesh::TriangleMesh;
use crate::query::{record_closer_hit, Hit, TraversalKernel};
use crate::stats::Counter;

/// Tests every non-degenerate triangle, in face order. O(n) per ray: the reference that every
/// accelerator is tested against, never a fast path.
#[derive(Clone, Debug)]
pub struct BruteForce {
    /// `(face id, triangle)` of every non-degenerate triangle, in face order.
    triangles: Vec<(u32, Triangle)>,
}

impl BruteForce {
    pub fn new(mesh: &TriangleMesh) -> Self {
        let triangles = mesh
            .triangles()
            .enumerate()
            .filter(|(_, t)| !t.is_degenerate())
            .map(|(i, t)| (i as u32, t))
            .collect();
        Self { triangles }
    }
}

impl TraversalKernel for BruteForce {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        let mut prepared = PreparedRay::new(ray);
        let mut best: Option<Hit> = None;
        counter.triangles_tested(self.triangles.len() as u32);
        // Face order and a strict `<` give the smallest id among equal `t`.
        for (prim, tri) in &self.triangles {
            record_closer_hit(tri, *prim, &mut prepared, &mut best);
        }
        best
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        let prepared = PreparedRay::new(ray);
        for (i, (_, tri)) in self.triangles.iter().enumerate() {
            if tri.intersect(&prepared).is_some() {
                counter.triangles_tested(i as u32 + 1);
                return true;
            }
        }
        counter.triangles_tested(self.triangles.len() as u32);
        false
    }
}

impl crate::all_hits::AllHits for BruteForce {
    /// Every non-degenerate triangle tested; the reference of the accelerated all-hits queries.
    fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        hits.clear();
        if !ray.is_valid() {
            return;
        }
        let prepared = PreparedRay::new(ray);
        for (prim, tri) in &self.triangles {
            if let Some(h) = tri.intersect_by(&prepared, EdgeRule::HalfOpen) {
                hits.push(Hit {
                    t: h.t,
                    prim: *prim,
                    u: h.u,
                    v: h.v,
                });
            }
        }
        crate::all_hits::sort_hits(hits);
    }
}
