//! The two places where the renderer's rays meet acceleration structures.
//!
//! Every intersection ray (primary, reflected, transmitted) goes through
//! [`SceneTracer::intersect`] and every shadow ray through [`SceneTracer::occluded`]. Each names
//! its [`RayKind`], so a structure or cache per kind (a grid for primary rays, a shadow cache per
//! light, ...) plugs in here and nowhere else.

use std::sync::Arc;
use std::time::Instant;

use hbv::geometry::Ray;
use hbv::{Accelerator, Hit, TraversalStats};

use crate::ray_kind::{RayKind, RayStats};

/// The accelerators a frame is traced with: one for intersection rays, one for shadow rays (they
/// may be the same structure).
#[derive(Clone)]
pub struct SceneTracer {
    intersection: Arc<dyn Accelerator>,
    shadow: Arc<dyn Accelerator>,
}

/// What one render thread records about its queries: totals per ray kind, and the work of the
/// pixel being rendered (for the heatmaps).
#[derive(Clone, Debug, Default)]
pub struct RayTally {
    pub stats: RayStats,
    /// Work of the queries since the last [`RayTally::take_pixel_work`].
    pub pixel_work: TraversalStats,
    /// Use the counted queries (nodes visited, boxes and triangles tested).
    pub count_work: bool,
    /// Time every query (two clock reads per ray).
    pub time_queries: bool,
}

impl RayTally {
    /// A tally that counts work and/or times queries as asked.
    pub fn new(count_work: bool, time_queries: bool) -> Self {
        RayTally {
            count_work,
            time_queries,
            ..Default::default()
        }
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
    pub fn new(intersection: Arc<dyn Accelerator>, shadow: Arc<dyn Accelerator>) -> Self {
        SceneTracer {
            intersection,
            shadow,
        }
    }

    /// The closest hit of a primary, reflected or transmitted ray. The one intersection query
    /// of the renderer.
    #[inline]
    pub fn intersect(&self, ray: &Ray, kind: RayKind, tally: &mut RayTally) -> Option<Hit> {
        debug_assert!(!matches!(kind, RayKind::Shadow { .. }));
        let start = tally.time_queries.then(Instant::now);
        let mut work = TraversalStats::default();
        let hit = if tally.count_work {
            self.intersection.intersect_counted(ray, &mut work)
        } else {
            self.intersection.intersect(ray)
        };
        tally.record(kind, work, start);
        hit
    }

    /// Whether anything blocks a shadow ray towards a sample of light `light`. The one shadow
    /// query of the renderer.
    #[inline]
    pub fn occluded(&self, ray: &Ray, light: u32, tally: &mut RayTally) -> bool {
        let kind = RayKind::Shadow { light };
        let start = tally.time_queries.then(Instant::now);
        let mut work = TraversalStats::default();
        let blocked = if tally.count_work {
            self.shadow.occluded_counted(ray, &mut work)
        } else {
            self.shadow.occluded(ray)
        };
        tally.record(kind, work, start);
        blocked
    }
}
