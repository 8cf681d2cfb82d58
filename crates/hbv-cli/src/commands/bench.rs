//! `hbv bench`: rays per second of every layout on camera, diffuse and shadow rays, on one thread
//! and on all, with the tests per ray that explain them.
//!
//! The tree is built once; each layout is laid out from it, so layouts are compared on the same
//! tree. Each measurement is the median of `--repeat` timed batches after one untimed warm-up
//! batch (which faults in the result buffer and warms the caches and the thread pool).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use hbv::atomic_file::Replace;
use hbv::bvh::BuildTree;
use hbv::geometry::Ray;
use hbv::{Accelerator, TraversalStats, TriangleMesh};
use hbv_cli::output_check::{check_output_folder, replace_policy};
use hbv_cli::ray_file;
use hbv_cli::ray_sets::{camera_image_size, RaySet, Stage};
use rayon::ThreadPool;
use serde::Serialize;

use hbv::grid::{GridConfig, UniformGrid};

use super::build_args::{load_mesh, thread_pool, AccelName, BuildArgs, SceneSource};
use super::flag_values::ray_count;
use super::median::median;
use super::name_values::layout_kind;
use super::scene_bench;
use hbv::bvh::build::BuilderKind;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};

#[derive(Args)]
pub struct BenchArgs {
    /// Mesh file (.obj, .ply), scene file (.gltf, .glb: its instances traced through the top
    /// level, the rays made on its flattened triangles) or a .hbv file from `hbv build` (a
    /// saved tree's mesh, built again; a saved scene, measured as saved); the built-in scene
    /// when omitted.
    pub mesh: Option<PathBuf>,
    /// Layout to measure; repeat for several. Default: every layout (a saved scene: the one its
    /// file records).
    #[arg(long = "layout", value_name = "LAYOUT", value_parser = layout_kind())]
    pub layouts: Vec<LayoutKind>,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Acceleration structure: the BVH in every --layout, or the uniform grid (with mailboxes).
    #[arg(long, value_enum, default_value_t = AccelName::Bvh)]
    pub accel: AccelName,
    /// Threads of the parallel measurement (every layout is also measured on 1 thread); 0 uses
    /// every core.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Rays per set (the camera set is the first N pixels of a ⌈√N⌉-wide image: 512 × 512 by
    /// default).
    #[arg(long, default_value_t = 1 << 18, value_parser = ray_count)]
    pub rays: usize,
    /// Timed runs per measurement, after one warm-up run; the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Seed of the diffuse and shadow rays (the camera rays take none).
    #[arg(long = "ray-seed", default_value_t = 1)]
    pub ray_seed: u64,
    /// Rays of each set, spread evenly over it, on which the work per ray is counted: nodes
    /// visited, boxes and triangles tested. On a scene, the work inside its meshes' trees, each
    /// instance entered counted as one node visited; the top level's boxes are not counted.
    #[arg(long = "counted-rays", default_value_t = 10_000)]
    pub counted_rays: usize,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write the ray sets to DIR as primary.npz, diffuse.npz and shadow.npz (ray files of
    /// docs/RAYS.md) and stop, without building or tracing.
    #[arg(long = "write-rays", value_name = "DIR")]
    pub write_rays: Option<PathBuf>,
    /// With --write-rays: replace ray files that exist (without this, an existing file is an
    /// error and nothing is written).
    #[arg(long, requires = "write_rays")]
    pub force: bool,
}

/// The queries of [`hbv::Accelerator`], named as in `hbv trace --json`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Query {
    Closest,
    Occluded,
}

impl Query {
    pub(super) fn name(self) -> &'static str {
        match self {
            Query::Closest => "closest",
            Query::Occluded => "occluded",
        }
    }
}

/// What is measured on each set: camera and bounce rays want the closest hit; shadow rays, and
/// bounce rays used as ambient-occlusion probes, only whether anything is hit.
pub(super) const CASES: [(RaySet, Query); 4] = [
    (RaySet::Primary, Query::Closest),
    (RaySet::Diffuse, Query::Closest),
    (RaySet::Diffuse, Query::Occluded),
    (RaySet::Shadow, Query::Occluded),
];

/// One layout as laid out for the benchmark.
#[derive(Serialize)]
pub(super) struct LayoutReport {
    pub(super) layout: String,
    /// Bytes of node and triangle data.
    pub(super) memory_bytes: usize,
    pub(super) layout_seconds: f64,
}

/// One measurement: a layout, a set, a query, a thread count.
#[derive(Serialize)]
pub(super) struct Measurement {
    pub(super) layout: String,
    pub(super) ray_set: &'static str,
    pub(super) query: &'static str,
    pub(super) threads: usize,
    pub(super) rays: usize,
    /// Median of `runs`.
    pub(super) mrays_per_second: f64,
    /// Every timed run, in Mrays/s, in the order run.
    pub(super) runs: Vec<f64>,
    /// Fraction of the rays that hit (closest) or are occluded.
    pub(super) hit_fraction: f64,
    pub(super) memory_bytes: usize,
    /// Mean work per ray on the counted subsample (the same on any thread count; what is
    /// counted: `--counted-rays`).
    pub(super) nodes_per_ray: f64,
    pub(super) boxes_per_ray: f64,
    pub(super) triangles_per_ray: f64,
    pub(super) counted_rays: u64,
}

/// A scene's counts, beside `Report::triangles` (its triangles as stored).
#[derive(Serialize)]
pub(super) struct SceneFacts {
    pub(super) meshes: usize,
    pub(super) instances: usize,
    pub(super) triangles_seen: usize,
}

#[derive(Serialize)]
pub(super) struct Report {
    pub(super) mesh: String,
    pub(super) triangles: usize,
    pub(super) builder: String,
    pub(super) load_seconds: f64,
    /// `None` for a scene, whose meshes are built as it is loaded (each layout's
    /// `layout_seconds`).
    pub(super) build_seconds: Option<f64>,
    /// What a scene holds; absent for a mesh.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) scene: Option<SceneFacts>,
    pub(super) rays_per_set: usize,
    pub(super) ray_seed: u64,
    pub(super) camera: [u32; 2],
    pub(super) light: [f32; 3],
    pub(super) repeat: u32,
    pub(super) thread_counts: Vec<usize>,
    pub(super) layouts: Vec<LayoutReport>,
    pub(super) results: Vec<Measurement>,
}

/// Runs `hbv bench`: writes the ray sets, or measures every requested layout on them.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    if let Some(dir) = &args.write_rays {
        check_ray_set_outputs(dir, args.force)?;
    }
    if let Some(path) = args.mesh.as_deref() {
        if let Some(source) = SceneSource::of(path) {
            return scene_bench::run(path, source, args);
        }
    }
    let (mesh, name, load_seconds) = load_mesh(args.mesh.as_deref())?;
    if mesh.triangle_count() == mesh.degenerate_count() {
        bail!("{name} has no triangle of non-zero area: there is no surface to shoot rays from");
    }
    let sets: Vec<(RaySet, Vec<Ray>)> = RaySet::ALL
        .iter()
        .map(|&set| (set, set.generate(&mesh, args.rays, args.ray_seed)))
        .collect();
    if let Some(dir) = &args.write_rays {
        return write_ray_sets(dir, &sets, replace_policy(args.force));
    }

    let pools = thread_pools(args.threads)?;
    let all_threads = pools.last().expect("at least one pool");
    let mut layouts = Vec::new();
    let mut results = Vec::new();
    let (described, build_seconds) = match args.accel {
        AccelName::Bvh => {
            let build = args.build.or_builder(BuilderKind::BinnedSah);
            let (tree, build_seconds) = all_threads.install(|| build.build(&mesh));
            for layout in requested_layouts(&args.layouts) {
                let (report, measurements) =
                    measure_layout(layout, &tree, &mesh, &sets, &pools, args);
                layouts.push(report);
                results.extend(measurements);
            }
            (build.describe(), build_seconds)
        }
        AccelName::Grid => {
            let start = Instant::now();
            let grid = all_threads.install(|| UniformGrid::new(&mesh, GridConfig::default()));
            let build_seconds = start.elapsed().as_secs_f64();
            let memory_bytes = grid.memory_bytes();
            let report = LayoutReport {
                layout: "grid".into(),
                memory_bytes,
                layout_seconds: 0.0,
            };
            results.extend(measure(
                &grid as &dyn Accelerator,
                &report,
                &sets,
                &pools,
                args,
            ));
            layouts.push(report);
            let r = grid.shape().map_or([0; 3], |s| s.resolution);
            let described = format!(
                "uniform grid {} × {} × {} (λ = {}, mailboxes)",
                r[0],
                r[1],
                r[2],
                grid.config().lambda
            );
            (described, build_seconds)
        }
    };

    let report = Report {
        mesh: name,
        triangles: mesh.triangle_count(),
        builder: described,
        load_seconds,
        build_seconds: Some(build_seconds),
        scene: None,
        rays_per_set: args.rays,
        ray_seed: args.ray_seed,
        camera: camera_image_size(args.rays).into(),
        light: Stage::new(&mesh.bounds()).light.to_array(),
        repeat: args.repeat,
        thread_counts: pools.iter().map(|p| p.current_num_threads()).collect(),
        layouts,
        results,
    };
    report.print(args.json)
}

/// Lays the tree out as `layout` and measures it on every (set, query) case and every pool.
fn measure_layout(
    layout: LayoutKind,
    tree: &BuildTree,
    mesh: &TriangleMesh,
    sets: &[(RaySet, Vec<Ray>)],
    pools: &[ThreadPool],
    args: &BenchArgs,
) -> (LayoutReport, Vec<Measurement>) {
    let start = Instant::now();
    let accel = layout.lay_out(tree, mesh, &LayoutOptions::default());
    let report = LayoutReport {
        layout: layout.to_string(),
        memory_bytes: accel.memory_bytes(),
        layout_seconds: start.elapsed().as_secs_f64(),
    };
    let results = measure(&accel as &dyn Accelerator, &report, sets, pools, args);
    (report, results)
}

/// What `hbv bench` measures: a mesh's acceleration structure or a scene, answering batches of
/// its own kind of ray.
pub(super) trait Measured: Sync {
    type Ray: Sync;

    /// Answers `query` on every ray as one batch, on the current pool; returns the seconds of
    /// the batch call alone (collecting the answers, not counting or freeing them) and how many
    /// rays hit (or are occluded).
    fn answer(&self, rays: &[Self::Ray], query: Query) -> (f64, usize);

    /// The work of `query` counted on at most `count` of `rays` ([`count_sampled`]).
    fn count_tests(&self, rays: &[Self::Ray], query: Query, count: usize) -> TraversalStats;
}

impl Measured for dyn Accelerator + '_ {
    type Ray = Ray;

    fn answer(&self, rays: &[Ray], query: Query) -> (f64, usize) {
        match query {
            Query::Closest => timed_hits(|| self.intersect_batch(rays)),
            Query::Occluded => timed_occlusion(|| self.occluded_batch(rays)),
        }
    }

    fn count_tests(&self, rays: &[Ray], query: Query, count: usize) -> TraversalStats {
        count_sampled(rays, count, |ray, stats| match query {
            Query::Closest => {
                self.intersect_counted(ray, stats);
            }
            Query::Occluded => {
                self.occluded_counted(ray, stats);
            }
        })
    }
}

/// Measures `measured` (named and sized by `report`) on every (set, query) case and every pool.
pub(super) fn measure<M: Measured + ?Sized>(
    measured: &M,
    report: &LayoutReport,
    sets: &[(RaySet, Vec<M::Ray>)],
    pools: &[ThreadPool],
    args: &BenchArgs,
) -> Vec<Measurement> {
    let memory_bytes = report.memory_bytes;
    let mut results = Vec::new();
    for (set, query) in CASES {
        let rays = &sets.iter().find(|(s, _)| *s == set).expect("every set").1;
        let stats = measured.count_tests(rays, query, args.counted_rays);
        for pool in pools {
            let (runs, hits) = time_runs(measured, rays, query, pool, args.repeat);
            results.push(Measurement {
                layout: report.layout.clone(),
                ray_set: set.name(),
                query: query.name(),
                threads: pool.current_num_threads(),
                rays: rays.len(),
                mrays_per_second: median(&runs),
                runs,
                hit_fraction: hits as f64 / rays.len().max(1) as f64,
                memory_bytes,
                nodes_per_ray: stats.nodes_per_ray(),
                boxes_per_ray: stats.boxes_per_ray(),
                triangles_per_ray: stats.triangles_per_ray(),
                counted_rays: stats.rays,
            });
        }
    }
    results
}

/// `DIR/NAME.npz`, the file of ray set `set` written by `--write-rays DIR`.
pub(super) fn ray_set_path(dir: &std::path::Path, set: RaySet) -> PathBuf {
    dir.join(format!("{}.npz", set.name()))
}

/// Checks `--write-rays DIR` before the mesh is loaded and the rays made: unless `force`, a
/// file that exists already is an error; `DIR` must be a folder, or one that can be made.
fn check_ray_set_outputs(dir: &std::path::Path, force: bool) -> anyhow::Result<()> {
    if !force {
        if let Some(existing) = RaySet::ALL
            .iter()
            .map(|&set| ray_set_path(dir, set))
            .find(|p| hbv::atomic_file::would_replace(p))
        {
            anyhow::bail!(
                "{}: the output file exists; pass --force to replace it",
                existing.display()
            );
        }
    }
    check_output_folder(dir)?;
    Ok(())
}

/// Writes each set as `DIR/NAME.npz`, creating `DIR` if needed ([`check_ray_set_outputs`]
/// has checked the paths).
pub(super) fn write_ray_sets(
    dir: &std::path::Path,
    sets: &[(RaySet, Vec<Ray>)],
    replace: Replace,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (set, rays) in sets {
        let path = ray_set_path(dir, *set);
        ray_file::write_rays(&path, rays, replace)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {} ({} rays)", path.display(), rays.len());
    }
    Ok(())
}

/// A pool of one thread, and one of `threads` (0: every core) unless that is also one.
pub(super) fn thread_pools(threads: usize) -> anyhow::Result<Vec<ThreadPool>> {
    let mut pools = vec![thread_pool(1)?];
    let all = thread_pool(threads)?;
    if all.current_num_threads() > 1 {
        pools.push(all);
    }
    Ok(pools)
}

/// The layouts asked for, each once in the order given; every layout when none is.
pub(super) fn requested_layouts(asked: &[LayoutKind]) -> Vec<LayoutKind> {
    if asked.is_empty() {
        return LayoutKind::ALL.to_vec();
    }
    let mut layouts = Vec::new();
    for &l in asked {
        if !layouts.contains(&l) {
            layouts.push(l);
        }
    }
    layouts
}

/// Traces `rays` once untimed, then `repeat` times timed, on `pool`; returns each timed run's
/// Mrays/s and the number of hits (or occluded rays). The timed span is the batch call alone,
/// as in `hbv trace`: it includes collecting the answers, not freeing them.
fn time_runs<M: Measured + ?Sized>(
    measured: &M,
    rays: &[M::Ray],
    query: Query,
    pool: &ThreadPool,
    repeat: u32,
) -> (Vec<f64>, usize) {
    pool.install(|| {
        let (_, hits) = measured.answer(rays, query);
        let runs = (0..repeat)
            .map(|_| {
                let (seconds, _) = measured.answer(rays, query);
                rays.len() as f64 / seconds.max(1e-9) / 1e6
            })
            .collect();
        (runs, hits)
    })
}

/// The seconds `batch` takes, and how many of its answers are hits.
pub(super) fn timed_hits<H>(batch: impl FnOnce() -> Vec<Option<H>>) -> (f64, usize) {
    let start = Instant::now();
    let hits = batch();
    let seconds = start.elapsed().as_secs_f64();
    (seconds, hits.iter().flatten().count())
}

/// The seconds `batch` takes, and how many of its answers say occluded.
pub(super) fn timed_occlusion(batch: impl FnOnce() -> Vec<bool>) -> (f64, usize) {
    let start = Instant::now();
    let occluded = batch();
    let seconds = start.elapsed().as_secs_f64();
    (seconds, occluded.iter().filter(|&&o| o).count())
}

/// The work `count_one` adds up on at most `count` rays spread evenly over `rays` (every k-th),
/// so that a camera subsample covers the whole image and not its top rows. (Counted ray by ray:
/// what the wide-8 layout's packets of coherent rays share is not counted.)
pub(super) fn count_sampled<R>(
    rays: &[R],
    count: usize,
    mut count_one: impl FnMut(&R, &mut TraversalStats),
) -> TraversalStats {
    let mut stats = TraversalStats::default();
    if count == 0 {
        return stats;
    }
    let stride = rays.len().div_ceil(count).max(1);
    for ray in rays.iter().step_by(stride) {
        count_one(ray, &mut stats);
    }
    stats
}

impl Report {
    /// Prints the report as one JSON object, or as tables.
    pub(super) fn print(&self, json: bool) -> anyhow::Result<()> {
        if json {
            println!("{}", serde_json::to_string_pretty(self)?);
        } else {
            print_tables(self);
        }
        Ok(())
    }
}

fn print_tables(report: &Report) {
    let [w, h] = report.camera;
    let threads: Vec<String> = report.thread_counts.iter().map(|t| t.to_string()).collect();
    match &report.scene {
        None => println!("mesh      {}: {} triangles", report.mesh, report.triangles),
        Some(s) => println!(
            "scene     {}: {} meshes, {} instances; {} triangles stored, {} seen",
            report.mesh, s.meshes, s.instances, report.triangles, s.triangles_seen
        ),
    }
    println!("load      {:.3} s", report.load_seconds);
    match report.build_seconds {
        Some(seconds) => println!("build     {seconds:.3} s, {}", report.builder),
        None => println!(
            "build     as loaded, {} (each layout's time: \"lay out\")",
            report.builder
        ),
    }
    println!(
        "rays      {} per set, seed {}: primary = {w} × {h} camera, diffuse, shadow (light at [{:.4}, {:.4}, {:.4}])",
        report.rays_per_set, report.ray_seed, report.light[0], report.light[1], report.light[2]
    );
    println!(
        "timing    Mrays/s on {} thread(s), median of {} runs after a warm-up",
        threads.join(" and "),
        report.repeat
    );
    println!();
    println!("{:<10} {:>10} {:>9}", "layout", "memory", "lay out");
    for l in &report.layouts {
        println!(
            "{:<10} {:>6.1} MiB {:>7.3} s",
            l.layout,
            l.memory_bytes as f64 / (1 << 20) as f64,
            l.layout_seconds
        );
    }
    println!();

    let mut header = format!(
        "{:<10} {:<8} {:<9} {:>6}",
        "layout", "set", "query", "hit %"
    );
    for t in &report.thread_counts {
        header += &format!(" {:>9}", format!("{t} thr"));
    }
    header += &format!(" {:>9} {:>9} {:>9}", "nodes/ray", "boxes/ray", "tris/ray");
    println!("{header}");
    // Measurements come grouped by (layout, set, query), one per thread count, in pool order.
    for row in report.results.chunks(report.thread_counts.len()) {
        let m = &row[0];
        let mut line = format!(
            "{:<10} {:<8} {:<9} {:>6.1}",
            m.layout,
            m.ray_set,
            m.query,
            100.0 * m.hit_fraction
        );
        for r in row {
            line += &format!(" {:>9.3}", r.mrays_per_second);
        }
        for per_ray in [m.nodes_per_ray, m.boxes_per_ray, m.triangles_per_ray] {
            line += &format!(" {per_ray:>9.1}");
        }
        println!("{line}");
    }
    if report.scene.is_some() {
        println!();
        println!(
            "per ray   counted inside the meshes' trees, each instance entered as one node; \
             the top level's boxes are not counted"
        );
    }
}
