//! Whether a point lies inside a scene's closed meshes ([`Scene::contains`]).
//!
//! A point is inside the scene when it is inside one of the instances it sees: the union of
//! the instances' solids, as a flattened scene of closed meshes that overlap would have it by
//! the generalized winding number's `≥ 1` rule, not by the parity of all crossings (two
//! overlapping instances would cancel). Each instance whose world box holds the point answers
//! by its mesh's exact parity test ([`proximity::contains`](crate::proximity::contains)) on
//! the point carried into its space, `A^-1 (p - b)` in f64 rounded to f32. A point within that
//! rounding of an instance's surface may be reported either way, as on a single mesh.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{Scene, SceneRay, BATCH_GRAIN};
use crate::geometry::PreparedRay;
use crate::proximity;

impl Scene {
    /// Whether `point` lies inside any instance (module notes). The meshes must be closed
    /// ([`TriangleMesh::is_closed`](crate::TriangleMesh::is_closed)). A point with a NaN or
    /// infinite coordinate is outside.
    pub fn contains(&self, point: DVec3) -> bool {
        self.contains_with_mask(point, SceneRay::ALL)
    }

    /// [`Scene::contains`] among the instances whose mask shares a bit with `mask`.
    pub fn contains_with_mask(&self, point: DVec3, mask: u32) -> bool {
        if !point.is_finite() || mask == 0 {
            return false;
        }
        // The instances whose boxes hold the point: those a ray from it meets over [0, 0]
        // (any direction without a zero component; the walk grows the boxes for the rounding
        // of the origin to f32).
        let probe = SceneRay::from_f64(point, DVec3::new(0.54, 0.69, -0.48))
            .with_interval(0.0, 0.0)
            .with_mask(mask);
        let mut prepared = PreparedRay::new(&probe.ray);
        let mut inside = false;
        self.visit_instances(&probe, &mut prepared, |id, _| {
            let instance = &self.instances[id as usize];
            if probe.sees(instance.mask) {
                let local: Vec3 = instance
                    .transform
                    .inverse()
                    .transform_point3(point)
                    .as_vec3();
                inside = proximity::contains(&self.meshes[instance.mesh as usize], local);
            }
            inside
        });
        inside
    }

    /// [`Scene::contains_with_mask`] of every point, with `masks[i]` for point `i`, or every
    /// mask bit when `masks` is `None`; in parallel on the current rayon pool. Panics if
    /// `masks` is not as long as `points`.
    pub fn contains_batch(&self, points: &[DVec3], masks: Option<&[u32]>) -> Vec<bool> {
        if let Some(masks) = masks {
            assert_eq!(masks.len(), points.len(), "one mask per point");
        }
        points
            .par_iter()
            .enumerate()
            .with_min_len(BATCH_GRAIN)
            .map(|(i, p)| self.contains_with_mask(*p, masks.map_or(SceneRay::ALL, |m| m[i])))
            .collect()
    }
}
