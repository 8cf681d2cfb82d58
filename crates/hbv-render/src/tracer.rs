//! The two places where the renderer's rays meet acceleration structures.
//!
//! Every intersection ray (primary, reflected, transmitted) goes through
//! [`SceneTracer::intersect`] and every shadow ray through [`SceneTracer::occluded`]. Each names
//! its [`RayKind`], so a structure or cache per kind (a grid for primary rays, a shadow cache per
//! light, ...) plugs in here and nowhere else.
//!
//! A tracer traces either the two-level scene ([`SceneTracer::two_level`]: hbv's
//! [`hbv::scene::Scene`], one BVH per mesh and a top level over the instances) or the flattened
//! scene ([`SceneTracer::new`]: any accelerator per ray kind over one world-space mesh). Both go
//! through the object caches [`QueryCacheConfig`] enables (the mesh caches of `hbv::cache` over
//! the flattened scene, the scene caches keyed by `(instance, prim)` over the two-level one), and
//! both count their work when asked (the counted queries).

use std::sync::Arc;
use std::time::Instant;

use hbv::geometry::Ray;
use hbv::scene::SceneRay;
use hbv::{Accelerator, TraversalStats};

use crate::query_caches::{FlatQueryCaches, QueryCacheConfig, SceneQueryCaches};
use crate::ray_kind::{RayKind, RayStats};
use crate::scene::{HitFace, Scene, SurfaceHit};

/// The structures a frame is traced with, and which ray kinds go through object caches.
#[derive(Clone)]
pub struct SceneTracer {
    structures: Structures,
    caches: QueryCacheConfig,
}

#[derive(Clone)]
enum Structures {
    /// Over the flattened scene ([`Scene::flat`]): one accelerator for intersection rays, one
    /// for shadow rays (they may be the same structure).
    Flat {
        intersection: Arc<dyn Accelerator>,
        shadow: Arc<dyn Accelerator>,
    },
    /// The two-level scene ([`Scene::two_level`]) for every ray.
    TwoLevel(Arc<hbv::scene::Scene>),
}

/// What one render thread records about its queries: totals per ray kind, and the work of the
/// pixel being rendered (for the heatmaps); and the thread's object caches, when it has them
/// (see [`SceneTracer::tally`]).
pub struct RayTally<'a> {
    /// Totals so far; the caches' hits and misses are added by [`RayTally::into_stats`].
    pub stats: RayStats,
    /// Work of the queries since the last [`RayTally::take_pixel_work`].
    pub pixel_work: TraversalStats,
    /// Use the counted queries (nodes visited, boxes and triangles tested).
    pub count_work: bool,
    /// Time every query (two clock reads per ray).
    pub time_queries: bool,
    caches: Option<TallyCaches<'a>>,
}

/// One render thread's object caches, over the structures of the tracer that made them.
enum TallyCaches<'a> {
    Flat(FlatQueryCaches<'a>),
    TwoLevel(SceneQueryCaches<'a>),
}

impl RayTally<'static> {
    /// A tally without caches that counts work and/or times queries as asked.
    pub fn new(count_work: bool, time_queries: bool) -> Self {
        RayTally {
            stats: RayStats::default(),
            pixel_work: TraversalStats::default(),
            count_work,
            time_queries,
            caches: None,
        }
    }
}

impl RayTally<'_> {
    /// The totals, with the caches' hits and misses per ray kind.
    pub fn into_stats(self) -> RayStats {
        let mut stats = self.stats;
        match &self.caches {
            Some(TallyCaches::Flat(caches)) => stats.cache = caches.stats(),
            Some(TallyCaches::TwoLevel(caches)) => stats.cache = caches.stats(),
            None => {}
        }
        stats
    }

    /// The pixel's work so far, resetting it for the next pixel.
    pub fn take_pixel_work(&mut self) -> TraversalStats {
        std::mem::take(&mut self.pixel_work)
    }

    fn record(&mut self, kind: RayKind, work: TraversalStats, start: Option<Instant>) {
        let k = kind.index();
        self.stats.rays[k] += 1;
        if self.count_work {
            self.stats.work[k] += work;
            self.pixel_work += work;
        }
        if let Some(start) = start {
            self.stats.query_nanos[k] += start.elapsed().as_nanos() as u64;
        }
    }
}

impl SceneTracer {
    /// Traces the flattened scene ([`Scene::flat`]): intersection rays with `intersection` and
    /// shadow rays with `shadow`, both built over the flattened scene's mesh, through the
    /// default caches ([`QueryCacheConfig::default`]) when tallies come from
    /// [`SceneTracer::tally`].
    pub fn new(intersection: Arc<dyn Accelerator>, shadow: Arc<dyn Accelerator>) -> Self {
        SceneTracer {
            structures: Structures::Flat {
                intersection,
                shadow,
            },
            caches: QueryCacheConfig::default(),
        }
    }

    /// Traces every ray with `scene`, the two-level form of the scene rendered
    /// ([`Scene::two_level`]), through the default caches ([`QueryCacheConfig::default`]: the
    /// scene's own, [`hbv::cache::SceneShadowCache`] and [`hbv::cache::SceneLastHitCache`])
    /// when tallies come from [`SceneTracer::tally`].
    pub fn two_level(scene: Arc<hbv::scene::Scene>) -> Self {
        SceneTracer {
            structures: Structures::TwoLevel(scene),
            caches: QueryCacheConfig::default(),
        }
    }

    /// Whether this tracer traces the two-level scene.
    pub fn is_two_level(&self) -> bool {
        matches!(self.structures, Structures::TwoLevel(_))
    }

    /// The same tracer with other caches.
    pub fn with_caches(self, caches: QueryCacheConfig) -> Self {
        SceneTracer { caches, ..self }
    }

    /// Which ray kinds go through caches.
    pub fn caches(&self) -> QueryCacheConfig {
        self.caches
    }

    /// A tally for one render thread of `scene`, holding that thread's caches (a shadow cache
    /// per light, a last-hit cache per cached intersection ray kind). A flat tracer's caches
    /// wrap its accelerators, which must have been built over `scene`'s flattened mesh: the
    /// caches test its triangles. A two-level tracer's caches wrap its two-level scene.
    pub fn tally<'a>(
        &'a self,
        scene: &'a Scene,
        count_work: bool,
        time_queries: bool,
    ) -> RayTally<'a> {
        match &self.structures {
            Structures::Flat {
                intersection,
                shadow,
            } => RayTally {
                caches: Some(TallyCaches::Flat(FlatQueryCaches::new(
                    self.caches,
                    scene.flat_mesh(),
                    intersection.as_ref(),
                    shadow.as_ref(),
                ))),
                ..RayTally::new(count_work, time_queries)
            },
            Structures::TwoLevel(two_level) => RayTally {
                caches: Some(TallyCaches::TwoLevel(SceneQueryCaches::over_scene(
                    self.caches,
                    two_level,
                ))),
                ..RayTally::new(count_work, time_queries)
            },
        }
    }

    /// The closest hit of a primary, reflected or transmitted ray, through the tally's last-hit
    /// cache for `kind` if it has one. The one intersection query of the renderer.
    #[inline]
    pub fn intersect(&self, ray: &Ray, kind: RayKind, tally: &mut RayTally) -> Option<SurfaceHit> {
        debug_assert!(!matches!(kind, RayKind::Shadow { .. }));
        let start = tally.time_queries.then(Instant::now);
        let mut work = TraversalStats::default();
        let hit = match &self.structures {
            Structures::Flat { intersection, .. } => {
                let cache = match &mut tally.caches {
                    Some(TallyCaches::Flat(caches)) => caches.last_hit(kind),
                    _ => None,
                };
                let hit = match (cache, tally.count_work) {
                    (Some(cache), true) => cache.intersect_counted(ray, &mut work),
                    (Some(cache), false) => cache.intersect(ray),
                    (None, true) => intersection.intersect_counted(ray, &mut work),
                    (None, false) => intersection.intersect(ray),
                };
                hit.map(|h| SurfaceHit {
                    t: h.t,
                    u: h.u,
                    v: h.v,
                    face: HitFace::Flat(h.prim),
                })
            }
            Structures::TwoLevel(scene) => {
                let ray = SceneRay::new(*ray);
                let cache = match &mut tally.caches {
                    Some(TallyCaches::TwoLevel(caches)) => caches.last_hit(kind),
                    _ => None,
                };
                let hit = match (cache, tally.count_work) {
                    (Some(cache), true) => cache.intersect_counted(&ray, &mut work),
                    (Some(cache), false) => cache.intersect(&ray),
                    (None, true) => scene.intersect_counted(&ray, &mut work),
                    (None, false) => scene.intersect(&ray),
                };
                hit.map(|h| SurfaceHit {
                    t: h.t,
                    u: h.u,
                    v: h.v,
                    face: HitFace::Instanced {
                        instance: h.instance,
                        prim: h.prim,
                        normal: h.normal,
                    },
                })
            }
        };
        tally.record(kind, work, start);
        hit
    }

    /// Whether anything blocks a shadow ray towards sample `sample` of light `light`, through
    /// the tally's shadow cache of that light (or light sample) if it has one. The one shadow
    /// query of the renderer.
    #[inline]
    pub fn occluded(&self, ray: &Ray, light: u32, sample: u32, tally: &mut RayTally) -> bool {
        let kind = RayKind::Shadow { light };
        let start = tally.time_queries.then(Instant::now);
        let mut work = TraversalStats::default();
        let blocked = match &self.structures {
            Structures::Flat { shadow, .. } => {
                let cache = match &mut tally.caches {
                    Some(TallyCaches::Flat(caches)) => caches.shadow(light, sample),
                    _ => None,
                };
                match (cache, tally.count_work) {
                    (Some(cache), true) => cache.occluded_counted(ray, &mut work),
                    (Some(cache), false) => cache.occluded(ray),
                    (None, true) => shadow.occluded_counted(ray, &mut work),
                    (None, false) => shadow.occluded(ray),
                }
            }
            Structures::TwoLevel(scene) => {
                let ray = SceneRay::new(*ray);
                let cache = match &mut tally.caches {
                    Some(TallyCaches::TwoLevel(caches)) => caches.shadow(light, sample),
                    _ => None,
                };
                match (cache, tally.count_work) {
                    (Some(cache), true) => cache.occluded_counted(&ray, &mut work),
                    (Some(cache), false) => cache.occluded(&ray),
                    (None, true) => scene.occluded_counted(&ray, &mut work),
                    (None, false) => scene.occluded(&ray),
                }
            }
        };
        tally.record(kind, work, start);
        tally.stats.shadow_blocked += blocked as u64;
        blocked
    }
}
