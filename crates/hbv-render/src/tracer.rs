//! The two places where the renderer's rays meet acceleration structures.
//!
//! Every intersection ray (primary, reflected, transmitted) goes through
//! [`SceneTracer::intersect`] and every shadow ray through [`SceneTracer::occluded`]. Each names
//! its [`RayKind`], so a structure or cache per kind (a grid for primary rays, a shadow cache per
//! light, ...) plugs in here and nowhere else.

use std::sync::Arc;
use std::time::Instant;

use hbv::geometry::Ray;
use hbv::{Accelerator, Hit, TraversalStats, TriangleMesh};

use crate::query_caches::{QueryCacheConfig, QueryCaches};
use crate::ray_kind::{RayKind, RayStats};

/// The accelerators a frame is traced with: one for intersection rays, one for shadow rays (they
/// may be the same structure), and which ray kinds go through object caches.
#[derive(Clone)]
pub struct SceneTracer {
    intersection: Arc<dyn Accelerator>,
    shadow: Arc<dyn Accelerator>,
    caches: QueryCacheConfig,
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
    caches: Option<QueryCaches<'a>>,
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
        if let Some(caches) = &self.caches {
            stats.cache = caches.stats();
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
    /// Traces intersection rays with `intersection` and shadow rays with `shadow`.
    /// Traces intersection rays with `intersection` and shadow rays with `shadow`, through the
    /// default caches ([`QueryCacheConfig::default`]) when tallies come from
    /// [`SceneTracer::tally`].
    pub fn new(intersection: Arc<dyn Accelerator>, shadow: Arc<dyn Accelerator>) -> Self {
        SceneTracer {
            intersection,
            shadow,
            caches: QueryCacheConfig::default(),
        }
    }

    /// The same tracer with other caches.
    pub fn with_caches(self, caches: QueryCacheConfig) -> Self {
        SceneTracer { caches, ..self }
    }

    /// Which ray kinds go through caches.
    pub fn caches(&self) -> QueryCacheConfig {
        self.caches
    }

    /// A tally for one render thread, holding that thread's caches (a shadow cache per light, a
    /// last-hit cache per cached intersection ray kind) over the tracer's accelerators. `mesh`
    /// is the mesh the accelerators were built from: the caches test its triangles.
    pub fn tally<'a>(
        &'a self,
        mesh: &'a TriangleMesh,
        count_work: bool,
        time_queries: bool,
    ) -> RayTally<'a> {
        RayTally {
            caches: Some(QueryCaches::new(
                self.caches,
                mesh,
                self.intersection.as_ref(),
                self.shadow.as_ref(),
            )),
            ..RayTally::new(count_work, time_queries)
        }
    }

    /// The closest hit of a primary, reflected or transmitted ray, through the tally's last-hit
    /// cache for `kind` if it has one. The one intersection query of the renderer.
    #[inline]
    pub fn intersect(&self, ray: &Ray, kind: RayKind, tally: &mut RayTally) -> Option<Hit> {
        debug_assert!(!matches!(kind, RayKind::Shadow { .. }));
        let start = tally.time_queries.then(Instant::now);
        let mut work = TraversalStats::default();
        let cache = tally.caches.as_mut().and_then(|c| c.last_hit(kind));
        let hit = match (cache, tally.count_work) {
            (Some(cache), true) => cache.intersect_counted(ray, &mut work),
            (Some(cache), false) => cache.intersect(ray),
            (None, true) => self.intersection.intersect_counted(ray, &mut work),
            (None, false) => self.intersection.intersect(ray),
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
        let cache = tally.caches.as_mut().and_then(|c| c.shadow(light, sample));
        let blocked = match (cache, tally.count_work) {
            (Some(cache), true) => cache.occluded_counted(ray, &mut work),
            (Some(cache), false) => cache.occluded(ray),
            (None, true) => self.shadow.occluded_counted(ray, &mut work),
            (None, false) => self.shadow.occluded(ray),
        };
        tally.record(kind, work, start);
        tally.stats.shadow_blocked += blocked as u64;
        blocked
    }
}
