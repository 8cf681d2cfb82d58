//! `hbv experiment seed-claims`: do the seed's statements hold on real meshes?
//!
//! The seed says that (1) "grids are faster for intersection rays, HBV faster for shadow rays",
//! (2) mailboxes save work in grids, and (3) "reflected and transmitted rays bypass the caches,
//! since they are spatially incoherent". For each mesh this traces, on one thread and in the
//! order a renderer makes them:
//!
//! | set | rays | query | cache |
//! | --- | --- | --- | --- |
//! | `primary` | camera, scanline order | closest | [`LastHitCache`] |
//! | `reflection` | mirror reflections at the camera hits, in pixel order | closest | [`LastHitCache`] |
//! | `diffuse` | cosine bounces at the camera hits, in pixel order | closest | [`LastHitCache`] |
//! | `shadow` | camera hits to the light, in pixel order | any hit | [`ShadowCache`] |
//! | `shadow-random` | random surface points to the light (no order) | any hit | [`ShadowCache`] |
//!
//! through the grid (with and without mailboxes) and every BVH layout (binned-SAH tree), each
//! plain and under its cache. Timings are interleaved (every structure once per round, rounds
//! repeated, the first discarded) and the median reported; tests per ray are counted on every
//! ray. Cached answers are compared with plain ones (`mismatches`, always 0).

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::bail;
use clap::Args;
use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::cache::{CacheStats, LastHitCache, ShadowCache};
use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::{Accelerator, Hit, TraversalStats, TriangleMesh};
use hbv_cli::ray_sets::{camera_image_size, primary_rays, secondary_rays, RaySet, Stage};
use serde::Serialize;

use crate::commands::build_args::load_mesh;
use crate::commands::flag_values::{grid_density, ray_count, seed};
use crate::commands::median::median;

#[derive(Args)]
pub struct SeedClaimsArgs {
    /// Meshes (.obj, .ply, .gltf, .glb). Default: the built-in scene, then every
    /// ../shared/scenes/*.ply when that folder exists.
    pub meshes: Vec<PathBuf>,
    /// Camera rays (a ⌈√N⌉-wide image); the secondary sets have one ray per camera hit.
    #[arg(long, default_value_t = 1 << 18, value_parser = ray_count)]
    pub rays: usize,
    /// Timed rounds after one warm-up round; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Seed of the diffuse bounces and the random shadow rays.
    #[arg(long = "ray-seed", default_value_t = 1, value_parser = seed)]
    pub ray_seed: u64,
    /// Grid density λ (λ · N^(1/3) cells along the longest axis; 0.001 to 1024).
    #[arg(long, default_value_t = GridConfig::default().lambda, value_parser = grid_density)]
    pub lambda: f64,
    /// Print one JSON array (one object per mesh) instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// The query of a ray set and the cache that goes with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Query {
    /// Closest hit; cache: [`LastHitCache`].
    Closest,
    /// Any hit; cache: [`ShadowCache`].
    Occluded,
}

/// One structure on one set: plain and cached.
#[derive(Serialize)]
struct Row {
    set: &'static str,
    structure: String,
    rays: usize,
    hit_fraction: f64,
    /// Median Mrays/s on one thread, without and with the cache.
    mrays_per_second: f64,
    cached_mrays_per_second: f64,
    /// Boxes plus triangles tested per ray (grid: triangles; its cells are in `nodes_per_ray`).
    tests_per_ray: f64,
    cached_tests_per_ray: f64,
    /// Nodes (BVH) or cells (grid) visited per ray.
    nodes_per_ray: f64,
    /// Triangle tests per ray saved by the grid's mailboxes.
    mailbox_skips_per_ray: f64,
    /// Fraction of queries where the cached triangle was hit.
    cache_hit_rate: f64,
    /// The same among the rays that hit something (or are occluded): how often the answer's
    /// triangle, or one blocking as well, was the cached one.
    cache_hit_rate_of_hits: f64,
    /// Rays whose cached answer differs from the plain one (must be 0).
    mismatches: usize,
    runs: Vec<f64>,
    cached_runs: Vec<f64>,
}

#[derive(Serialize)]
struct MeshReport {
    mesh: String,
    triangles: usize,
    bvh_build_seconds: f64,
    grid_build_seconds: f64,
    grid_resolution: [u32; 3],
    grid_listed_per_triangle: f64,
    grid_memory_bytes: usize,
    camera: [u32; 2],
    repeat: u32,
    rows: Vec<Row>,
}

/// Runs the experiment on every mesh.
pub fn run(args: &SeedClaimsArgs) -> anyhow::Result<()> {
    let meshes = mesh_list(&args.meshes)?;
    let mut reports = Vec::new();
    for path in &meshes {
        let report = measure_mesh(path.as_deref(), args)?;
        if !args.json {
            print_table(&report);
        }
        reports.push(report);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&reports)?);
    }
    Ok(())
}

/// The meshes named, or the built-in scene (`None`) and `../shared/scenes/*.ply`.
fn mesh_list(named: &[PathBuf]) -> anyhow::Result<Vec<Option<PathBuf>>> {
    if !named.is_empty() {
        return Ok(named.iter().cloned().map(Some).collect());
    }
    let mut list = vec![None];
    let shared = Path::new("../shared/scenes");
    if let Ok(entries) = std::fs::read_dir(shared) {
        let mut plys: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "ply"))
            .collect();
        plys.sort();
        list.extend(plys.into_iter().map(Some));
    }
    Ok(list)
}

/// Every structure on every set of one mesh.
fn measure_mesh(path: Option<&Path>, args: &SeedClaimsArgs) -> anyhow::Result<MeshReport> {
    let (mesh, name, _) = load_mesh(path)?;
    if mesh.triangle_count() == mesh.degenerate_count() {
        bail!("{name} has no triangle of non-zero area: there is nothing to trace");
    }
    let start = Instant::now();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let bvh_build_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let grid_config = GridConfig {
        lambda: args.lambda,
        mailbox: true,
    };
    let grid = UniformGrid::new(&mesh, grid_config);
    let grid_build_seconds = start.elapsed().as_secs_f64();
    let grid_resolution = grid.shape().map_or([0; 3], |s| s.resolution);
    let grid_listed_per_triangle = grid.listed() as f64 / mesh.triangle_count() as f64;
    let grid_memory_bytes = grid.memory_bytes();
    let no_mailbox = UniformGrid::new(
        &mesh,
        GridConfig {
            mailbox: false,
            ..grid_config
        },
    );
    let mut structures: Vec<(&str, Box<dyn Accelerator>)> = vec![
        ("grid", Box::new(grid)),
        ("grid-no-mailbox", Box::new(no_mailbox)),
    ];
    for kind in LayoutKind::ALL {
        let layout = kind.lay_out(&tree, &mesh, &LayoutOptions::default());
        structures.push((kind.name(), Box::new(layout)));
    }

    let stage = Stage::new(&mesh.bounds());
    let (width, height) = camera_image_size(args.rays);
    let mut primary = primary_rays(&stage, width, height);
    primary.truncate(args.rays);
    let primary_hits = structures[0].1.intersect_batch(&primary);
    let secondary = secondary_rays(&mesh, &stage, &primary, &primary_hits, args.ray_seed);
    let random_shadow = RaySet::Shadow.generate(&mesh, secondary.shadow.len(), args.ray_seed);
    let sets: Vec<(&'static str, Query, Vec<Ray>)> = vec![
        ("primary", Query::Closest, primary),
        ("reflection", Query::Closest, secondary.reflection),
        ("diffuse", Query::Closest, secondary.diffuse),
        ("shadow", Query::Occluded, secondary.shadow),
        ("shadow-random", Query::Occluded, random_shadow),
    ];

    // Work counted on every ray, answers compared, then interleaved timing rounds.
    let mut rows = Vec::new();
    for (set, query, rays) in &sets {
        for (structure, accel) in &structures {
            rows.push(count_row(
                set,
                *query,
                rays,
                structure,
                accel.as_ref(),
                &mesh,
            ));
        }
    }
    for round in 0..=args.repeat {
        let mut k = 0;
        for (_, query, rays) in &sets {
            for (_, accel) in &structures {
                let plain = time_plain(*query, rays, accel.as_ref());
                let cached = time_cached(*query, rays, accel.as_ref(), &mesh);
                if round > 0 {
                    rows[k].runs.push(plain);
                    rows[k].cached_runs.push(cached);
                }
                k += 1;
            }
        }
    }
    for row in &mut rows {
        row.mrays_per_second = median(&row.runs);
        row.cached_mrays_per_second = median(&row.cached_runs);
    }
    Ok(MeshReport {
        mesh: name,
        triangles: mesh.triangle_count(),
        bvh_build_seconds,
        grid_build_seconds,
        grid_resolution,
        grid_listed_per_triangle,
        grid_memory_bytes,
        camera: [width, height],
        repeat: args.repeat,
        rows,
    })
}

/// Counts the work of one structure on one set, plain and cached, and checks that the cache
/// changes no answer.
fn count_row(
    set: &'static str,
    query: Query,
    rays: &[Ray],
    structure: &str,
    accel: &dyn Accelerator,
    mesh: &TriangleMesh,
) -> Row {
    let mut plain = TraversalStats::default();
    let mut cached = TraversalStats::default();
    let mut hits = 0usize;
    let mut mismatches = 0usize;
    let cache_stats: CacheStats = match query {
        Query::Closest => {
            let mut cache = LastHitCache::new(accel, mesh);
            for ray in rays {
                let a: Option<Hit> = accel.intersect_counted(ray, &mut plain);
                let b = cache.intersect_counted(ray, &mut cached);
                hits += a.is_some() as usize;
                mismatches += (a != b) as usize;
            }
            cache.stats()
        }
        Query::Occluded => {
            let mut cache = ShadowCache::new(accel, mesh);
            for ray in rays {
                let a = accel.occluded_counted(ray, &mut plain);
                let b = cache.occluded_counted(ray, &mut cached);
                hits += a as usize;
                mismatches += (a != b) as usize;
            }
            cache.stats()
        }
    };
    Row {
        set,
        structure: structure.to_string(),
        rays: rays.len(),
        hit_fraction: hits as f64 / rays.len().max(1) as f64,
        mrays_per_second: 0.0,
        cached_mrays_per_second: 0.0,
        tests_per_ray: plain.tests_per_ray(),
        cached_tests_per_ray: cached.tests_per_ray(),
        nodes_per_ray: plain.nodes_per_ray(),
        mailbox_skips_per_ray: plain.mailbox_skips_per_ray(),
        cache_hit_rate: cache_stats.hit_rate(),
        cache_hit_rate_of_hits: cache_stats.hits as f64 / hits.max(1) as f64,
        mismatches,
        runs: Vec::new(),
        cached_runs: Vec::new(),
    }
}

/// Mrays/s of the plain queries, one thread, in the set's order; the set is traced again until
/// [`MIN_SECONDS`] have passed, so that small sets are timed over more than a scheduler tick.
fn time_plain(query: Query, rays: &[Ray], accel: &dyn Accelerator) -> f64 {
    let start = Instant::now();
    let mut traced = 0usize;
    let mut found = 0usize;
    while traced == 0 || start.elapsed().as_secs_f64() < MIN_SECONDS {
        for ray in rays {
            found += match query {
                Query::Closest => accel.intersect(black_box(ray)).is_some(),
                Query::Occluded => accel.occluded(black_box(ray)),
            } as usize;
        }
        traced += rays.len().max(1);
    }
    black_box(found);
    mrays(traced, start)
}

/// Mrays/s of the cached queries (a fresh cache each pass), timed as [`time_plain`].
fn time_cached(query: Query, rays: &[Ray], accel: &dyn Accelerator, mesh: &TriangleMesh) -> f64 {
    let start = Instant::now();
    let mut traced = 0usize;
    let mut found = 0usize;
    while traced == 0 || start.elapsed().as_secs_f64() < MIN_SECONDS {
        match query {
            Query::Closest => {
                let mut cache = LastHitCache::new(accel, mesh);
                for ray in rays {
                    found += cache.intersect(black_box(ray)).is_some() as usize;
                }
            }
            Query::Occluded => {
                let mut cache = ShadowCache::new(accel, mesh);
                for ray in rays {
                    found += cache.occluded(black_box(ray)) as usize;
                }
            }
        }
        traced += rays.len().max(1);
    }
    black_box(found);
    mrays(traced, start)
}

/// Shortest time of one measurement.
const MIN_SECONDS: f64 = 0.05;

fn mrays(count: usize, start: Instant) -> f64 {
    count as f64 / start.elapsed().as_secs_f64().max(1e-9) / 1e6
}

fn print_table(r: &MeshReport) {
    let [rx, ry, rz] = r.grid_resolution;
    println!("mesh      {}: {} triangles", r.mesh, r.triangles);
    println!(
        "grid      {rx} × {ry} × {rz} cells, {:.2} cell entries per triangle, {:.1} MiB, built in {:.3} s; BVH (binned SAH) built in {:.3} s",
        r.grid_listed_per_triangle,
        r.grid_memory_bytes as f64 / (1 << 20) as f64,
        r.grid_build_seconds,
        r.bvh_build_seconds
    );
    println!(
        "rays      {} × {} camera; secondary sets at its hits; 1 thread, median of {} interleaved rounds",
        r.camera[0], r.camera[1], r.repeat
    );
    println!(
        "{:<14} {:<16} {:>7} {:>6} {:>8} {:>9} {:>9} {:>8} {:>9} {:>9} {:>6} {:>6} {:>8}",
        "set",
        "structure",
        "rays",
        "hit %",
        "Mrays/s",
        "tests/ray",
        "nodes/ray",
        "mb skips",
        "cached",
        "c tests",
        "c hit%",
        "of hit",
        "mismatch"
    );
    for row in &r.rows {
        println!(
            "{:<14} {:<16} {:>7} {:>6.1} {:>8.3} {:>9.1} {:>9.1} {:>8.1} {:>9.3} {:>9.1} {:>6.1} {:>6.1} {:>8}",
            row.set,
            row.structure,
            row.rays,
            100.0 * row.hit_fraction,
            row.mrays_per_second,
            row.tests_per_ray,
            row.nodes_per_ray,
            row.mailbox_skips_per_ray,
            row.cached_mrays_per_second,
            row.cached_tests_per_ray,
            100.0 * row.cache_hit_rate,
            100.0 * row.cache_hit_rate_of_hits,
            row.mismatches
        );
    }
    println!();
}
