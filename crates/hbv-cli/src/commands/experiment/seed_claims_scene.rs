//! `hbv experiment seed-claims` on a scene of instances: do the seed's object caches and its
//! per-ray-type structures pay when many instances share meshes?
//!
//! The ray sets are the mesh form's (`seed_claims.rs`), made on the flattened scene: a camera
//! over the scene's box in scanline order, the mirror, diffuse and shadow rays at its hits in
//! pixel order, and shadow rays from random surface points. Three structures answer them:
//!
//! | structure | what | caches |
//! | --- | --- | --- |
//! | `two-level` | the [`Scene`]: one BVH per shared mesh (binned SAH, wide-8), a top level over the instances | [`SceneLastHitCache`], [`SceneShadowCache`], keyed by `(instance, prim)` |
//! | `flat-wide8` | one BVH (binned SAH, wide-8) over the flattened world triangles ([`Scene::flattened`]) | [`hbv::cache::LastHitCache`], [`hbv::cache::ShadowCache`] |
//! | `grid` | a uniform grid with mailboxes over the flattened triangles | as `flat-wide8` |
//!
//! Timings are interleaved as in the mesh form; tests per ray are counted on every ray (for
//! `two-level`, those of the meshes' BVHs, each instance entered counting as a node; the top
//! level's box tests are not counted). `mismatches` compares each cached answer with its
//! structure's plain one (must be 0); `vs two-level` counts the rays whose `(instance, prim)`
//! (or occlusion) differs between a flattened structure and the two-level scene, which the
//! rounding of the transforms allows near edges and ties (bound in `hbv::scene`).

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context};
use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::cache::{CacheStats, SceneLastHitCache, SceneShadowCache};
use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::scene::{FlattenedScene, Scene, SceneHit, SceneRay};
use hbv::{Accelerator, Hit, TraversalStats};
use hbv_cli::ray_sets::Stage;
use serde::Serialize;

use super::instanced_field::instanced_field;
use super::seed_claims::{ray_sets, MeshTraced, SeedClaimsArgs};
use super::traced::{
    count_row, print_rows, time_cached, time_plain, CachedQueries, Query, Row, Traced,
};
use crate::commands::median::median;

/// Where the scene comes from.
pub enum SceneSource<'a> {
    File(&'a Path),
    /// The built-in field of `instances` instances ([`instanced_field`]).
    BuiltIn {
        instances: u32,
    },
}

#[derive(Serialize)]
pub struct SceneReport {
    scene: String,
    meshes: usize,
    instances: usize,
    /// Triangles stored (each shared mesh once) and seen (every instance's).
    triangles_stored: usize,
    triangles_seen: usize,
    scene_build_seconds: f64,
    flat_bvh_build_seconds: f64,
    grid_build_seconds: f64,
    grid_resolution: [u32; 3],
    grid_memory_bytes: usize,
    camera: [u32; 2],
    repeat: u32,
    rows: Vec<SceneRow>,
}

#[derive(Serialize)]
struct SceneRow {
    #[serde(flatten)]
    row: Row,
    /// Rays whose answer differs from the two-level scene's (0 for `two-level` itself).
    differs_from_two_level: usize,
}

/// Every structure on every set of one scene.
pub fn measure_scene(source: SceneSource, args: &SeedClaimsArgs) -> anyhow::Result<SceneReport> {
    let start = Instant::now();
    let (scene, name) = match source {
        SceneSource::File(path) => (
            Scene::load(path).context("cannot load scene")?,
            path.display().to_string(),
        ),
        SceneSource::BuiltIn { instances } => (
            instanced_field(instances),
            format!("built-in field ({instances} instances of 3 shared meshes on a ground plane)"),
        ),
    };
    let scene_build_seconds = start.elapsed().as_secs_f64();
    let flat = scene
        .flattened()
        .with_context(|| format!("{name}: cannot flatten the scene into world coordinates"))?;
    if flat.mesh.triangle_count() == flat.mesh.degenerate_count() {
        bail!("{name} has no triangle of non-zero area: there is nothing to trace");
    }
    let triangles_stored = (0..scene.mesh_count() as u32)
        .filter_map(|m| scene.mesh(hbv::scene::MeshId(m)))
        .map(|m| m.triangle_count())
        .sum();

    let start = Instant::now();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&flat.mesh);
    let flat_bvh = LayoutKind::Wide8.lay_out(&tree, &flat.mesh, &LayoutOptions::default());
    let flat_bvh_build_seconds = start.elapsed().as_secs_f64();
    drop(tree);
    let start = Instant::now();
    let grid = UniformGrid::new(
        &flat.mesh,
        GridConfig {
            lambda: args.lambda,
            mailbox: true,
        },
    );
    let grid_build_seconds = start.elapsed().as_secs_f64();
    let grid_resolution = grid.shape().map_or([0; 3], |s| s.resolution);
    let grid_memory_bytes = grid.memory_bytes();

    let two_level = TwoLevel(&scene);
    let flat_structures: [(&str, &dyn Accelerator); 2] =
        [("flat-wide8", &flat_bvh), ("grid", &grid)];

    let stage = Stage::new(&scene.bounds());
    let ([width, height], sets) = ray_sets(&flat.mesh, &stage, args, |primary| {
        primary
            .iter()
            .map(|r| {
                scene
                    .intersect(&SceneRay::new(*r))
                    .map(|h| face_hit(&flat, &h))
            })
            .collect()
    });

    let mut rows = Vec::new();
    for (set, query, rays) in &sets {
        rows.push(SceneRow {
            row: count_row(set, *query, rays, "two-level", &two_level),
            differs_from_two_level: 0,
        });
        for (structure, accel) in flat_structures {
            let traced = MeshTraced {
                accel,
                mesh: &flat.mesh,
            };
            rows.push(SceneRow {
                row: count_row(set, *query, rays, structure, &traced),
                differs_from_two_level: differences(*query, rays, &scene, &flat, accel),
            });
        }
    }
    for round in 0..=args.repeat {
        let mut k = 0;
        for (_, query, rays) in &sets {
            let plain = time_plain(*query, rays, &two_level);
            let cached = time_cached(*query, rays, &two_level);
            record(&mut rows[k].row, round, plain, cached);
            k += 1;
            for (_, accel) in flat_structures {
                let traced = MeshTraced {
                    accel,
                    mesh: &flat.mesh,
                };
                let plain = time_plain(*query, rays, &traced);
                let cached = time_cached(*query, rays, &traced);
                record(&mut rows[k].row, round, plain, cached);
                k += 1;
            }
        }
    }
    for SceneRow { row, .. } in &mut rows {
        row.mrays_per_second = median(&row.runs);
        row.cached_mrays_per_second = median(&row.cached_runs);
    }
    Ok(SceneReport {
        scene: name,
        meshes: scene.mesh_count(),
        instances: scene.live_instance_count(),
        triangles_stored,
        triangles_seen: flat.mesh.triangle_count(),
        scene_build_seconds,
        flat_bvh_build_seconds,
        grid_build_seconds,
        grid_resolution,
        grid_memory_bytes,
        camera: [width, height],
        repeat: args.repeat,
        rows,
    })
}

/// Keeps a round's timings (the first round warms up and is dropped).
fn record(row: &mut Row, round: u32, plain: f64, cached: f64) {
    if round > 0 {
        row.runs.push(plain);
        row.cached_runs.push(cached);
    }
}

/// The scene's hit as a hit on the flattened mesh (its face id `offsets[instance] + prim`).
fn face_hit(flat: &FlattenedScene, hit: &SceneHit) -> Hit {
    Hit {
        t: hit.t,
        prim: flat.offsets[hit.instance as usize] + hit.prim,
        u: hit.u,
        v: hit.v,
    }
}

/// Rays whose `(instance, prim)` (closest) or occlusion differs between `accel` over the
/// flattened scene and the two-level scene.
fn differences(
    query: Query,
    rays: &[Ray],
    scene: &Scene,
    flat: &FlattenedScene,
    accel: &dyn Accelerator,
) -> usize {
    rays.iter()
        .filter(|ray| {
            let scene_ray = SceneRay::new(**ray);
            match query {
                Query::Closest => {
                    let a = scene.intersect(&scene_ray).map(|h| (h.instance, h.prim));
                    let b = accel.intersect(ray).map(|h| flat.instance_of(h.prim));
                    a != b
                }
                Query::Occluded => scene.occluded(&scene_ray) != accel.occluded(ray),
            }
        })
        .count()
}

/// The two-level scene as a structure under measurement; its rays see every instance.
struct TwoLevel<'a>(&'a Scene);

/// The scene's caches.
struct SceneCaches<'a> {
    last: SceneLastHitCache<'a>,
    shadow: SceneShadowCache<'a>,
}

impl Traced for TwoLevel<'_> {
    type Hit = SceneHit;
    type Caches<'b>
        = SceneCaches<'b>
    where
        Self: 'b;

    fn closest(&self, ray: &Ray) -> Option<SceneHit> {
        self.0.intersect(&SceneRay::new(*ray))
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.0.occluded(&SceneRay::new(*ray))
    }
    fn closest_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<SceneHit> {
        self.0.intersect_counted(&SceneRay::new(*ray), stats)
    }
    fn occluded_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        self.0.occluded_counted(&SceneRay::new(*ray), stats)
    }
    fn caches(&self) -> SceneCaches<'_> {
        SceneCaches {
            last: SceneLastHitCache::new(self.0),
            shadow: SceneShadowCache::new(self.0),
        }
    }
}

impl CachedQueries for SceneCaches<'_> {
    type Hit = SceneHit;

    fn closest(&mut self, ray: &Ray) -> Option<SceneHit> {
        self.last.intersect(&SceneRay::new(*ray))
    }
    fn occluded(&mut self, ray: &Ray) -> bool {
        self.shadow.occluded(&SceneRay::new(*ray))
    }
    fn closest_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> Option<SceneHit> {
        self.last.intersect_counted(&SceneRay::new(*ray), stats)
    }
    fn occluded_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        self.shadow.occluded_counted(&SceneRay::new(*ray), stats)
    }
    fn stats(&self, query: Query) -> CacheStats {
        match query {
            Query::Closest => self.last.stats(),
            Query::Occluded => self.shadow.stats(),
        }
    }
}

pub fn print_scene_table(r: &SceneReport) {
    let [rx, ry, rz] = r.grid_resolution;
    println!(
        "scene     {}: {} meshes, {} instances; {} triangles stored, {} seen",
        r.scene, r.meshes, r.instances, r.triangles_stored, r.triangles_seen
    );
    println!(
        "build     two-level {:.3} s; flat-wide8 (binned SAH) {:.3} s; grid {rx} × {ry} × {rz} cells, {:.1} MiB, {:.3} s",
        r.scene_build_seconds,
        r.flat_bvh_build_seconds,
        r.grid_memory_bytes as f64 / (1 << 20) as f64,
        r.grid_build_seconds
    );
    println!(
        "rays      {} × {} camera; secondary sets at its hits; 1 thread, median of {} interleaved rounds",
        r.camera[0], r.camera[1], r.repeat
    );
    let rows: Vec<&Row> = r.rows.iter().map(|s| &s.row).collect();
    let differs: Vec<usize> = r.rows.iter().map(|s| s.differs_from_two_level).collect();
    print_rows(&rows, Some(("vs 2-level", &differs)));
    println!();
}
