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

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::bail;
use clap::Args;
use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::cache::{CacheStats, LastHitCache, ShadowCache};
use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::mesh::MeshFormat;
use hbv::{Accelerator, Hit, TraversalStats, TriangleMesh};
use hbv_cli::ray_sets::{camera_image_size, primary_rays, secondary_rays, RaySet, Stage};
use serde::Serialize;

use super::instanced_field::DEFAULT_FIELD_INSTANCES;
use super::seed_claims_scene::{measure_scene, print_scene_table, SceneReport, SceneSource};
use super::traced::{
    count_row, print_rows, time_cached, time_plain, CachedQueries, Query, Row, Traced,
};

use crate::commands::build_args::load_mesh;
use crate::commands::flag_values::{grid_density, ray_count, seed};
use crate::commands::median::median;

#[derive(Args)]
pub struct SeedClaimsArgs {
    /// Meshes (.obj, .ply) and scenes (.gltf, .glb: their nodes are instances, measured by the
    /// scene form). Default: the built-in scene, then every ../shared/scenes/*.ply when that
    /// folder exists (or only the built-in field, with --scene-default).
    pub meshes: Vec<PathBuf>,
    /// Also measure the built-in scene of many instances sharing meshes (see --instances): the
    /// two-level scene and its (instance, prim) caches against a BVH and a grid over its
    /// flattened triangles.
    #[arg(long)]
    pub scene_default: bool,
    /// Instances of the built-in field of --scene-default (1 to 100000).
    #[arg(long, default_value_t = DEFAULT_FIELD_INSTANCES,
          value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub instances: u32,
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

/// One input's report: a mesh's or a scene's (the JSON array holds both, as they come).
#[derive(Serialize)]
#[serde(untagged)]
enum Report {
    Mesh(MeshReport),
    Scene(SceneReport),
}

/// Runs the experiment on every mesh and scene.
pub fn run(args: &SeedClaimsArgs) -> anyhow::Result<()> {
    let mut inputs: Vec<Option<PathBuf>> = if args.meshes.is_empty() && args.scene_default {
        Vec::new()
    } else {
        mesh_list(&args.meshes)?
    };
    if args.scene_default {
        // `None` after the named inputs: the built-in field.
        inputs.push(None);
    }
    let field_at = args.scene_default.then(|| inputs.len() - 1);
    let mut reports = Vec::new();
    for (k, path) in inputs.iter().enumerate() {
        let scene = match path {
            _ if Some(k) == field_at => Some(SceneSource::BuiltIn {
                instances: args.instances,
            }),
            Some(p) if MeshFormat::from_path(p) == Some(MeshFormat::Gltf) => {
                Some(SceneSource::File(p))
            }
            _ => None,
        };
        let report = match scene {
            Some(source) => Report::Scene(measure_scene(source, args)?),
            None => Report::Mesh(measure_mesh(path.as_deref(), args)?),
        };
        if !args.json {
            match &report {
                Report::Mesh(r) => print_table(r),
                Report::Scene(r) => print_scene_table(r),
            }
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

/// A ray set, its query, its rays.
pub type Set = (&'static str, Query, Vec<Ray>);

/// The sets of the experiment on `mesh` (a scene's flattened mesh): `args.rays` camera rays at
/// `stage` in scanline order, the mirror, diffuse and shadow rays at their hits (`closest`
/// gives those, face ids of `mesh`) in pixel order, and as many shadow rays from random surface
/// points. Also returns the camera's image size.
pub fn ray_sets(
    mesh: &TriangleMesh,
    stage: &Stage,
    args: &SeedClaimsArgs,
    closest: impl FnOnce(&[Ray]) -> Vec<Option<Hit>>,
) -> ([u32; 2], Vec<Set>) {
    let (width, height) = camera_image_size(args.rays);
    let mut primary = primary_rays(stage, width, height);
    primary.truncate(args.rays);
    let primary_hits = closest(&primary);
    let secondary = secondary_rays(mesh, stage, &primary, &primary_hits, args.ray_seed);
    let random_shadow = RaySet::Shadow.generate(mesh, secondary.shadow.len(), args.ray_seed);
    let sets = vec![
        ("primary", Query::Closest, primary),
        ("reflection", Query::Closest, secondary.reflection),
        ("diffuse", Query::Closest, secondary.diffuse),
        ("shadow", Query::Occluded, secondary.shadow),
        ("shadow-random", Query::Occluded, random_shadow),
    ];
    ([width, height], sets)
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
    let ([width, height], sets) = ray_sets(&mesh, &stage, args, |primary| {
        structures[0].1.intersect_batch(primary)
    });

    // Work counted on every ray, answers compared, then interleaved timing rounds.
    let mut rows = Vec::new();
    for (set, query, rays) in &sets {
        for (structure, accel) in &structures {
            let traced = MeshTraced {
                accel: accel.as_ref(),
                mesh: &mesh,
            };
            rows.push(count_row(set, *query, rays, structure, &traced));
        }
    }
    for round in 0..=args.repeat {
        let mut k = 0;
        for (_, query, rays) in &sets {
            for (_, accel) in &structures {
                let traced = MeshTraced {
                    accel: accel.as_ref(),
                    mesh: &mesh,
                };
                let plain = time_plain(*query, rays, &traced);
                let cached = time_cached(*query, rays, &traced);
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
    print_rows(&r.rows.iter().collect::<Vec<_>>(), None);
    println!();
}

/// A mesh's structure and the mesh its caches test.
pub struct MeshTraced<'a> {
    pub accel: &'a dyn Accelerator,
    pub mesh: &'a TriangleMesh,
}

/// The mesh caches over one structure.
pub struct MeshCaches<'a> {
    last: LastHitCache<'a, dyn Accelerator + 'a>,
    shadow: ShadowCache<'a, dyn Accelerator + 'a>,
}

impl Traced for MeshTraced<'_> {
    type Hit = Hit;
    type Caches<'b>
        = MeshCaches<'b>
    where
        Self: 'b;

    fn closest(&self, ray: &Ray) -> Option<Hit> {
        self.accel.intersect(ray)
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }
    fn closest_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        self.accel.intersect_counted(ray, stats)
    }
    fn occluded_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        self.accel.occluded_counted(ray, stats)
    }
    fn caches(&self) -> MeshCaches<'_> {
        MeshCaches {
            last: LastHitCache::new(self.accel, self.mesh),
            shadow: ShadowCache::new(self.accel, self.mesh),
        }
    }
}

impl CachedQueries for MeshCaches<'_> {
    type Hit = Hit;

    fn closest(&mut self, ray: &Ray) -> Option<Hit> {
        self.last.intersect(ray)
    }
    fn occluded(&mut self, ray: &Ray) -> bool {
        self.shadow.occluded(ray)
    }
    fn closest_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        self.last.intersect_counted(ray, stats)
    }
    fn occluded_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        self.shadow.occluded_counted(ray, stats)
    }
    fn stats(&self, query: Query) -> CacheStats {
        match query {
            Query::Closest => self.last.stats(),
            Query::Occluded => self.shadow.stats(),
        }
    }
}
