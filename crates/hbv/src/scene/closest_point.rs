//! The nearest surface point of a scene to a query point, with the instance it lies on
//! ([`Scene::closest_point`], [`SceneNearestPoints`]).
//!
//! Each instance is searched in its own space when its transform keeps distances in
//! proportion (a similarity: `AᵀA = s² I`, rotations, mirrors and uniform scales), by its
//! mesh's nearest-point search ([`ClosestPointTree`]) on the query point carried by `A^-1`; the
//! point found is mapped back by `A` in f64, and the nearest in local space is the nearest in
//! world space. Any other transform (a non-uniform scale, a shear) bends distances, so the
//! local nearest point need not be the world one: such an instance is searched in world space,
//! every triangle of its mesh mapped by `A` in f64 and decided in f64 (as
//! [`closest_point_brute_force`](crate::proximity::closest_point_brute_force) does), a cost
//! linear in its triangles.
//!
//! Instances are visited nearest world box first by a best-first walk of the top level
//! (`TopLevel::nearest_first`), after the instances added or moved since its last build or
//! update, stopping at the first box farther than the best distance so far.

use glam::DVec3;

use super::instance::{Instance, InstanceState};
use std::sync::Arc;

use rayon::prelude::*;

use super::{Scene, SceneMesh, SceneRay, SceneStructure, BATCH_GRAIN};
use crate::proximity::{closest_point_on_triangle, ClosestPointTree, NearestPointSearch};

/// The nearest surface point of a scene to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneClosestPoint {
    /// The nearest point in world space, `A ((1-u-v) p0 + u p1 + v p2) + b` in f64.
    pub point: DVec3,
    /// The world distance from the query point to `point`.
    pub distance: f64,
    /// The instance the point lies on; among instances at the same distance, the smallest.
    pub instance: u32,
    /// The triangle of the instance's mesh; among its triangles at the same distance, the
    /// smallest.
    pub prim: u32,
    pub u: f64,
    pub v: f64,
}

/// A scene's nearest-point queries, with or without a mask. Each mesh's search tree
/// ([`ClosestPointTree`]) is made by the first query that reaches one of its instances and
/// kept by the scene for every later query, until the mesh's vertices move.
pub struct SceneNearestPoints<'a> {
    scene: &'a Scene,
}

impl Scene {
    /// The scene's nearest-point queries ([`SceneNearestPoints`]).
    pub fn nearest_points(&self) -> SceneNearestPoints<'_> {
        SceneNearestPoints { scene: self }
    }

    /// The nearest surface point of every live instance whose mask is not zero to `p` (module
    /// notes).
    pub fn closest_point(&self, p: DVec3) -> Option<SceneClosestPoint> {
        self.nearest_points().closest_point(p)
    }

    /// The nearest surface point to each of `points` among the live instances whose mask
    /// shares a bit with `masks[i]` (every instance whose mask is not zero when `masks` is
    /// `None`), in parallel on the current rayon pool. Panics if `masks` is not as long as
    /// `points`.
    pub fn closest_point_batch(
        &self,
        points: &[DVec3],
        masks: Option<&[u32]>,
    ) -> Vec<Option<SceneClosestPoint>> {
        if let Some(masks) = masks {
            assert_eq!(masks.len(), points.len(), "one mask per point");
        }
        let search = self.nearest_points();
        points
            .par_iter()
            .enumerate()
            .with_min_len(BATCH_GRAIN)
            .map(|(i, p)| search.closest_point_with_mask(*p, masks.map_or(SceneRay::ALL, |m| m[i])))
            .collect()
    }
}

impl SceneMesh {
    /// The mesh's nearest-point search tree, made on first use from the tree its layout was
    /// laid out from when the scene kept it, else from a new build by `structure`.
    fn search_tree(&self, structure: &SceneStructure) -> &ClosestPointTree {
        self.search.get_or_init(|| {
            let built;
            let tree = match &self.tree {
                Some(tree) => tree,
                None => {
                    built = structure
                        .builder
                        .build(&self.mesh, &structure.builder_options);
                    &built
                }
            };
            Arc::new(ClosestPointTree::new(tree, &self.mesh))
        })
    }
}

impl SceneNearestPoints<'_> {
    /// The nearest surface point to `p` of every live instance whose mask is not zero; ties to
    /// the smaller instance, then the smaller `prim`. `None` for a point with a NaN or infinite
    /// coordinate, or a scene with no triangle.
    pub fn closest_point(&self, p: DVec3) -> Option<SceneClosestPoint> {
        self.closest_point_with_mask(p, SceneRay::ALL)
    }

    /// [`SceneNearestPoints::closest_point`] among the instances whose mask shares a bit with
    /// `mask`.
    pub fn closest_point_with_mask(&self, p: DVec3, mask: u32) -> Option<SceneClosestPoint> {
        if !p.is_finite() {
            return None;
        }
        let scene = self.scene;
        let mut best: Option<SceneClosestPoint> = None;
        // Searches instance `id` (if the mask sees it), keeps its point if nearer (ties: the
        // smaller instance, then prim), and returns the best distance so far.
        let mut consider = |id: u32| {
            let instance = &scene.instances[id as usize];
            if instance.mask & mask != 0 {
                if let Some(found) = self.closest_on(id, instance, p) {
                    let closer = best.is_none_or(|b| {
                        found.distance < b.distance
                            || (found.distance == b.distance
                                && (id, found.prim) < (b.instance, b.prim))
                    });
                    if closer {
                        best = Some(found);
                    }
                }
            }
            best.map_or(f64::INFINITY, |b| b.distance)
        };
        // Instances added or moved since the last build or update, in turn; then the top
        // level's current leaves, nearest box first, until a box is farther than the best
        // distance (one as far may hold a tie, and is searched).
        let mut bound = f64::INFINITY;
        for &id in &scene.pending {
            if scene.instances[id as usize].state == InstanceState::Pending {
                bound = consider(id);
            }
        }
        scene.top_level.nearest_first(p, |id, _| {
            if scene.instances[id as usize].state == InstanceState::Indexed {
                bound = consider(id);
            }
            bound
        });
        best
    }

    /// The nearest point to `p` on instance `id`: in its space for a similarity, else in world
    /// space triangle by triangle (module notes).
    fn closest_on(&self, id: u32, instance: &Instance, p: DVec3) -> Option<SceneClosestPoint> {
        let affine = instance.transform.affine();
        if is_similarity(&instance.transform) {
            let scene = self.scene;
            let local = scene.meshes[instance.mesh as usize]
                .search_tree(&scene.structure)
                .closest_point(instance.transform.inverse().transform_point3(p))?;
            let point = affine.transform_point3(local.point);
            return Some(SceneClosestPoint {
                point,
                distance: (p - point).length(),
                instance: id,
                prim: local.prim,
                u: local.u,
                v: local.v,
            });
        }
        let mesh = &self.scene.meshes[instance.mesh as usize].mesh;
        let mut best: Option<SceneClosestPoint> = None;
        let mut best_d2 = f64::INFINITY;
        for (prim, t) in mesh.triangles().enumerate() {
            if t.is_degenerate() {
                continue;
            }
            let [a, b, c] = [t.p0, t.p1, t.p2].map(|v| affine.transform_point3(v.as_dvec3()));
            let q = closest_point_on_triangle(p, a, b, c);
            let d2 = (p - q.point).length_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = Some(SceneClosestPoint {
                    point: q.point,
                    distance: d2.sqrt(),
                    instance: id,
                    prim: prim as u32,
                    u: q.u,
                    v: q.v,
                });
            }
        }
        best
    }
}

/// Whether `transform`'s linear part keeps distances in proportion: `AᵀA = s² I` to within
/// `2^-40` relative (far above f64 rounding of a product of rotations and one scale).
fn is_similarity(transform: &super::InstanceTransform) -> bool {
    let a = transform.affine().matrix3;
    let gram = a.transpose() * a;
    let scale2 = (gram.x_axis.x + gram.y_axis.y + gram.z_axis.z) / 3.0;
    let tolerance = scale2 / (1u64 << 40) as f64;
    let identity = glam::DMat3::IDENTITY * scale2;
    (0..3).all(|c| (gram.col(c) - identity.col(c)).abs().max_element() <= tolerance)
}
