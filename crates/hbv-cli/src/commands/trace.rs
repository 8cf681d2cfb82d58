//! `hbv trace`: a ray file in, a hit file out (formats of `docs/RAYS.md`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use hbv_cli::output_check::replace_policy;
use hbv_cli::{hit_file, ray_file};
use serde_json::json;

use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::Accelerator;

use super::build_args::{load_scene, thread_pool, AccelName, BuildArgs};
use super::median::median;
use super::name_values::layout_kind;
use hbv::bvh::build::BuilderKind;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};

#[derive(Args)]
pub struct TraceArgs {
    /// Mesh file (.obj, .ply, .gltf, .glb) or saved tree (.hbv, from `hbv build`).
    pub mesh: PathBuf,
    /// Ray file (.npz with origins, directions, optional tmin, tmax).
    #[arg(long)]
    pub rays: PathBuf,
    /// Output file (.npz); written atomically (temporary file, then rename).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the output file if it exists (without this, an existing file is an error).
    #[arg(long)]
    pub force: bool,
    /// Any-hit query: write `occluded` instead of closest hits.
    #[arg(long)]
    pub occluded: bool,
    /// Trace every ray of the batch alone (interleaved), without the wide-8 layout's packets of
    /// coherent rays (runs of eight consecutive rays in a narrow beam, such as camera rays in
    /// pixel order, traced together). Same answers; for comparing the two.
    #[arg(long)]
    pub no_packets: bool,
    /// Trace each ray on its own (`Accelerator::intersect` / `occluded`, one call per ray) instead
    /// of the interleaved batch: the speed of single-ray calls, as a renderer makes them.
    #[arg(long, conflicts_with = "no_packets")]
    pub one_by_one: bool,
    /// Worker threads; 0 uses every core.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    #[command(flatten)]
    pub build: BuildArgs,
    /// How the tree is laid out for traversal.
    #[arg(long, value_parser = layout_kind(), default_value_t = LayoutKind::Wide8)]
    pub layout: LayoutKind,
    /// Acceleration structure: a BVH (--builder, --layout) or a uniform grid.
    #[arg(long, value_enum, default_value_t = AccelName::Bvh)]
    pub accel: AccelName,
    /// Trace the rays this many times and report the median time (the answers are the same
    /// every time; the file holds one copy). The first run pays for cold caches and for the
    /// first touch of the answers' pages, which later runs, like a peer's warmed-up calls in a
    /// benchmark, do not.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Print one JSON object of timings instead of text.
    #[arg(long)]
    pub json: bool,
}

/// One trace's answers.
enum Answers {
    Occluded(Vec<bool>),
    Hits(Vec<Option<hbv::Hit>>),
}

pub fn run(args: &TraceArgs) -> anyhow::Result<()> {
    // Checked first, so that a run that would be refused costs nothing (a dangling link is in
    // the way too; a device such as /dev/null is not).
    if !args.force && hbv::atomic_file::would_replace(&args.out) {
        anyhow::bail!(
            "{}: the output file exists; pass --force to replace it",
            args.out.display()
        );
    }
    // A missing folder is refused before the tracing, with the message the write would give.
    hbv::atomic_file::check_writable(&args.out).context("cannot write hits")?;
    let pool = thread_pool(args.threads)?;
    let scene = load_scene(Some(&args.mesh))?;
    scene.check_build_options(&args.build)?;
    let load_seconds = scene.load_seconds;
    let rays = ray_file::read_rays(&args.rays).context("cannot read rays")?;
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let (mesh, accel, build_seconds, built): (_, Box<dyn Accelerator>, f64, String) =
        match args.accel {
            AccelName::Bvh => {
                let (mesh, built, builder_options) = pool.install(|| scene.tree(&build));
                let build_seconds = built.build_seconds + built.optimize_seconds;
                let options = LayoutOptions {
                    ray_packets: !args.no_packets,
                };
                let accel = Box::new(args.layout.lay_out(&built.tree, &mesh, &options));
                (mesh, accel, build_seconds, builder_options)
            }
            AccelName::Grid => {
                let mesh = scene.mesh;
                let start = Instant::now();
                let grid = pool.install(|| UniformGrid::new(&mesh, GridConfig::default()));
                let resolution = grid.shape().map_or([0; 3], |s| s.resolution);
                let described = format!(
                    "uniform grid {} × {} × {} (λ = {}, mailboxes)",
                    resolution[0],
                    resolution[1],
                    resolution[2],
                    grid.config().lambda
                );
                (
                    mesh,
                    Box::new(grid),
                    start.elapsed().as_secs_f64(),
                    described,
                )
            }
        };

    let trace = || {
        let start = Instant::now();
        let answers = if args.occluded {
            Answers::Occluded(if args.one_by_one {
                pool.install(|| one_by_one(&rays, |r| accel.occluded(r)))
            } else {
                pool.install(|| accel.occluded_batch(&rays))
            })
        } else {
            Answers::Hits(if args.one_by_one {
                pool.install(|| one_by_one(&rays, |r| accel.intersect(r)))
            } else {
                pool.install(|| accel.intersect_batch(&rays))
            })
        };
        (answers, start.elapsed().as_secs_f64())
    };
    let (answers, first_seconds) = trace();
    let mut run_seconds = vec![first_seconds];
    for _ in 1..args.repeat {
        // The same answers each time: only the time is kept.
        run_seconds.push(trace().1);
    }
    let trace_seconds = median(&run_seconds);
    let hit_count = match &answers {
        Answers::Occluded(occluded) => {
            hit_file::write_occlusion(&args.out, occluded, replace_policy(args.force))
                .context("cannot write hits")?;
            occluded.iter().filter(|&&o| o).count()
        }
        Answers::Hits(hits) => {
            hit_file::write_hits(&args.out, hits, replace_policy(args.force))
                .context("cannot write hits")?;
            hits.iter().filter(|h| h.is_some()).count()
        }
    };
    let rays_per_second = if trace_seconds > 0.0 {
        rays.len() as f64 / trace_seconds
    } else {
        0.0
    };

    if args.json {
        let out = json!({
            "mesh": args.mesh.display().to_string(),
            "triangles": mesh.triangle_count(),
            "query": if args.occluded { "occluded" } else { "closest" },
            "accel": built,
            "threads": pool.current_num_threads(),
            "rays": rays.len(),
            "hits": hit_count,
            "load_seconds": load_seconds,
            "build_seconds": build_seconds,
            "trace_seconds": trace_seconds,
            "trace_seconds_each": run_seconds,
            "rays_per_second": rays_per_second,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let query = if args.occluded {
            "occluded"
        } else {
            "closest hit"
        };
        println!(
            "mesh      {} ({} triangles)",
            args.mesh.display(),
            mesh.triangle_count()
        );
        println!("load      {load_seconds:.3} s");
        println!("build     {build_seconds:.3} s ({built})");
        let runs = if args.repeat > 1 {
            format!(" (median of {} runs)", args.repeat)
        } else {
            String::new()
        };
        println!("trace     {trace_seconds:.3} s{runs}, {} rays ({query}), {hit_count} hit, {:.3} Mrays/s on {} threads", rays.len(), rays_per_second / 1e6, pool.current_num_threads());
        println!("wrote     {}", args.out.display());
    }
    Ok(())
}

/// `query` on each ray, one call per ray, in parallel on the current pool.
fn one_by_one<T: Send>(rays: &[Ray], query: impl Fn(&Ray) -> T + Sync + Send) -> Vec<T> {
    use rayon::prelude::*;
    rays.par_iter().with_min_len(256).map(query).collect()
}
