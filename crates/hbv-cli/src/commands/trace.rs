//! `hbv trace`: a ray file in, a hit file out (formats of `docs/RAYS.md`).

use std::io;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use hbv::atomic_file::write_atomically;
use hbv_cli::hit_file;
use hbv_cli::hit_file_writer::{write_hit_file, HitFileKind, HitFileWriter};
use hbv_cli::output_check::replace_policy;
use hbv_cli::ray_stream::RayChunks;
use serde_json::json;

use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::scene::{SceneHit, SceneRay};
use hbv::{Accelerator, Hit, TriangleMesh};
use rayon::prelude::*;
use rayon::ThreadPool;

use super::build_args::{
    load_input, load_scene_file, thread_pool, AccelName, BuildArgs, SceneSource,
};
use super::median::median;
use super::name_values::layout_kind;
use super::trace_progress::TraceProgress;
use hbv::bvh::build::BuilderKind;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};

#[derive(Args)]
pub struct TraceArgs {
    /// Mesh file (.obj, .ply), scene file (.gltf, .glb: its nodes are instances of its meshes)
    /// or a .hbv file from `hbv build` (a saved tree, or a saved scene, which answers as the
    /// glTF scene it was built from).
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
    /// How the tree is laid out for traversal [default: wide8]; a saved scene is laid out as
    /// its file says.
    #[arg(long, value_parser = layout_kind())]
    pub layout: Option<LayoutKind>,
    /// Acceleration structure: a BVH (--builder, --layout) or a uniform grid.
    #[arg(long, value_enum, default_value_t = AccelName::Bvh)]
    pub accel: AccelName,
    /// Trace each chunk of rays this many times and report the median of the runs' total
    /// times (the answers are the same every time; the file holds one copy). The first run
    /// pays for cold caches and for the first touch of the answers' pages, which later runs,
    /// like a peer's warmed-up calls in a benchmark, do not.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Rays read, traced and written at a time: memory holds about 200 bytes per ray of a
    /// chunk, whatever the size of the ray file (a larger chunk gives the threads longer runs).
    #[arg(long, default_value_t = DEFAULT_CHUNK_RAYS, value_parser = clap::value_parser!(u64).range(1..))]
    pub chunk_rays: u64,
    /// Print one JSON object of timings instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Rays per chunk unless `--chunk-rays` says otherwise: about 200 MB of rays and answers.
const DEFAULT_CHUNK_RAYS: u64 = 1 << 20;

/// What is traced: a mesh's acceleration structure, or a scene of instances.
enum Target {
    Mesh {
        mesh: TriangleMesh,
        accel: Box<dyn Accelerator>,
    },
    Scene(hbv::Scene),
}

/// The facts printed about what was traced.
struct Traced {
    /// Triangles as stored: of the mesh, or summed over the scene's meshes.
    triangles: usize,
    /// Triangles as seen: summed over the instances (the mesh's own for a mesh).
    triangles_seen: usize,
    meshes: usize,
    /// Live instances (1 for a mesh, a scene of one instance).
    instances: usize,
    /// How the structure was made.
    built: String,
    load_seconds: f64,
    /// `None` for a scene, whose meshes are built as they are loaded (in `load_seconds`).
    build_seconds: Option<f64>,
}

/// One trace's answers.
enum Answers {
    Occluded(Vec<bool>),
    MeshHits(Vec<Option<Hit>>),
    SceneHits(Vec<Option<SceneHit>>),
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
    let (target, traced) = match SceneSource::of(&args.mesh) {
        Some(source) => load_scene_target(args, source, &pool)?,
        None => build_mesh_target(args, &pool)?,
    };
    let ray_chunks = RayChunks::open(&args.rays).context("cannot read rays")?;
    let ray_count = ray_chunks.len();
    let Tally {
        run_seconds,
        hit_count,
    } = trace_in_chunks(args, &target, &pool, ray_chunks)?;
    let trace_seconds = median(&run_seconds);
    let rays_per_second = if trace_seconds > 0.0 {
        ray_count as f64 / trace_seconds
    } else {
        0.0
    };

    if args.json {
        let out = json!({
            "mesh": args.mesh.display().to_string(),
            "triangles": traced.triangles,
            "triangles_seen": traced.triangles_seen,
            "meshes": traced.meshes,
            "instances": traced.instances,
            "query": if args.occluded { "occluded" } else { "closest" },
            "accel": traced.built,
            "threads": pool.current_num_threads(),
            "rays": ray_count,
            "chunk_rays": args.chunk_rays,
            "hits": hit_count,
            "load_seconds": traced.load_seconds,
            "build_seconds": traced.build_seconds,
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
        match &target {
            Target::Mesh { .. } => println!(
                "mesh      {} ({} triangles)",
                args.mesh.display(),
                traced.triangles
            ),
            Target::Scene(_) => println!(
                "scene     {} ({} meshes, {} instances; {} triangles stored, {} seen)",
                args.mesh.display(),
                traced.meshes,
                traced.instances,
                traced.triangles,
                traced.triangles_seen
            ),
        }
        match traced.build_seconds {
            Some(build_seconds) => {
                println!("load      {:.3} s", traced.load_seconds);
                println!("build     {build_seconds:.3} s ({})", traced.built);
            }
            None => println!(
                "load      {:.3} s, building as loaded ({})",
                traced.load_seconds, traced.built
            ),
        }
        let runs = if args.repeat > 1 {
            format!(" (median of {} runs)", args.repeat)
        } else {
            String::new()
        };
        println!("trace     {trace_seconds:.3} s{runs}, {} rays ({query}), {hit_count} hit, {:.3} Mrays/s on {} threads", ray_count, rays_per_second / 1e6, pool.current_num_threads());
        println!("wrote     {}", args.out.display());
    }
    Ok(())
}

/// What a traced ray file came to.
struct Tally {
    /// Each repetition's time (`--repeat`), summed over the chunks.
    run_seconds: Vec<f64>,
    /// Rays that hit (or are occluded).
    hit_count: usize,
}

/// Traces the rays of `ray_chunks` on `target` a chunk at a time (`--chunk-rays`) and writes
/// the answers to `--out` as they come.
///
/// The hit file is laid out for every ray up front and filled chunk by chunk, through an
/// atomic write: an error (a ray file that cannot be read on, a full disk) leaves no output,
/// as the write removes its temporary file.
fn trace_in_chunks(
    args: &TraceArgs,
    target: &Target,
    pool: &ThreadPool,
    mut ray_chunks: RayChunks,
) -> anyhow::Result<Tally> {
    let ray_count = ray_chunks.len();
    let chunk_rays = usize::try_from(args.chunk_rays).unwrap_or(usize::MAX);
    let kind = if args.occluded {
        HitFileKind::Occlusion
    } else {
        HitFileKind::Closest
    };
    let progress = TraceProgress::new(ray_count as u64);
    let mut tally = Tally {
        run_seconds: vec![0.0; args.repeat as usize],
        hit_count: 0,
    };
    let mut read_failure = None;
    let written = write_atomically(&args.out, replace_policy(args.force), |file| {
        write_hit_file(file, kind, ray_count, |writer| {
            let mut rays = Vec::with_capacity(chunk_rays.min(ray_count));
            loop {
                match ray_chunks.read_next(chunk_rays, &mut rays) {
                    Ok(0) => return Ok(()),
                    Ok(_) => {}
                    Err(e) => {
                        read_failure = Some(e);
                        return Err(io::Error::other("the rays could not be read"));
                    }
                }
                let answers = target.trace_timed(&rays, args, pool, &mut tally.run_seconds);
                tally.hit_count += answers.write(writer, target, pool)?;
                progress.advance(rays.len() as u64, &tally.run_seconds);
            }
        })
    });
    progress.finish();
    if let Some(e) = read_failure {
        return Err(anyhow::Error::new(e).context("cannot read rays"));
    }
    written.context("cannot write hits")?;
    Ok(tally)
}

/// Loads the mesh (or saved tree) of `--mesh` and builds the structure `--accel` names over it.
fn build_mesh_target(args: &TraceArgs, pool: &ThreadPool) -> anyhow::Result<(Target, Traced)> {
    let input = load_input(Some(&args.mesh))?;
    input.check_build_options(&args.build)?;
    let load_seconds = input.load_seconds;
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let (mesh, accel, build_seconds, built): (_, Box<dyn Accelerator>, f64, String) =
        match args.accel {
            AccelName::Bvh => {
                let options = LayoutOptions {
                    ray_packets: !args.no_packets,
                };
                let layout = args.layout.unwrap_or(DEFAULT_LAYOUT);
                match pool.install(|| input.direct_layout(&build, layout, &options)) {
                    Some((accel, seconds, described)) => {
                        (input.mesh, Box::new(accel), seconds, described)
                    }
                    None => {
                        let (mesh, built, described) = pool.install(|| input.tree(&build));
                        let build_seconds = built.build_seconds + built.optimize_seconds;
                        let accel = Box::new(layout.lay_out(&built.tree, &mesh, &options));
                        (mesh, accel, build_seconds, described)
                    }
                }
            }
            AccelName::Grid => {
                let mesh = input.mesh;
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
    let traced = Traced {
        triangles: mesh.triangle_count(),
        triangles_seen: mesh.triangle_count(),
        meshes: 1,
        instances: 1,
        built,
        load_seconds,
        build_seconds: Some(build_seconds),
    };
    Ok((Target::Mesh { mesh, accel }, traced))
}

/// The layout of `--layout` when none is named.
const DEFAULT_LAYOUT: LayoutKind = LayoutKind::Wide8;

/// Loads the scene file `--mesh`: a glTF scene with each mesh built by `--builder` and laid out
/// by `--layout`, a saved scene as its file says.
fn load_scene_target(
    args: &TraceArgs,
    source: SceneSource,
    pool: &ThreadPool,
) -> anyhow::Result<(Target, Traced)> {
    if args.accel == AccelName::Grid {
        anyhow::bail!(
            "{}: --accel grid takes a mesh; a scene is traced by its two-level BVH \
             (--accel bvh)",
            args.mesh.display()
        );
    }
    let layout_flags: Vec<&str> = [
        (args.layout.is_some(), "--layout"),
        (args.no_packets, "--no-packets"),
    ]
    .into_iter()
    .filter_map(|(given, flag)| given.then_some(flag))
    .collect();
    source.check_options(&args.mesh, &args.build, &layout_flags)?;
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let options = LayoutOptions {
        ray_packets: !args.no_packets,
    };
    let layout = args.layout.unwrap_or(DEFAULT_LAYOUT);
    let structure = build.scene_structure(BuilderKind::BinnedSah, layout, options);
    let (scene, load_seconds) = pool.install(|| load_scene_file(&args.mesh, source, structure))?;
    let summary = scene.summary();
    let traced = Traced {
        triangles: summary.triangles_stored,
        triangles_seen: summary.triangles_seen,
        meshes: summary.meshes.len(),
        instances: summary.live_instances,
        built: source.describe(&build, layout),
        load_seconds,
        build_seconds: None,
    };
    Ok((Target::Scene(scene), traced))
}

/// Rays handed to one rayon task at least by `--one-by-one`, as in the library's batches.
const RAYS_PER_TASK: usize = 256;

impl Target {
    /// The answers of the query `args` asks (closest or any hit; batch or one call per ray) on
    /// `rays` (`scene_rays`, the same rays with their masks, for a scene), on the current pool.
    fn trace(&self, rays: &[Ray], scene_rays: &[SceneRay], args: &TraceArgs) -> Answers {
        match self {
            Target::Mesh { accel, .. } => match (args.occluded, args.one_by_one) {
                (true, true) => Answers::Occluded(one_by_one(rays, |r| accel.occluded(r))),
                (true, false) => Answers::Occluded(accel.occluded_batch(rays)),
                (false, true) => Answers::MeshHits(one_by_one(rays, |r| accel.intersect(r))),
                (false, false) => Answers::MeshHits(accel.intersect_batch(rays)),
            },
            Target::Scene(scene) => match (args.occluded, args.one_by_one) {
                (true, true) => Answers::Occluded(one_by_one(scene_rays, |r| scene.occluded(r))),
                (true, false) => Answers::Occluded(scene.occluded_batch(scene_rays)),
                (false, true) => Answers::SceneHits(one_by_one(scene_rays, |r| scene.intersect(r))),
                (false, false) => Answers::SceneHits(scene.intersect_batch(scene_rays)),
            },
        }
    }
}

impl Target {
    /// The answers for one chunk of `rays`, traced `run_seconds.len()` times (`--repeat`),
    /// each time added to its entry of `run_seconds`; the first run's answers are kept.
    fn trace_timed(
        &self,
        rays: &[Ray],
        args: &TraceArgs,
        pool: &ThreadPool,
        run_seconds: &mut [f64],
    ) -> Answers {
        // Scenes take rays with masks; ray files have none, so every ray sees every instance.
        let scene_rays: Vec<SceneRay> = match self {
            Target::Scene(_) => rays.iter().map(|&r| SceneRay::from(r)).collect(),
            Target::Mesh { .. } => Vec::new(),
        };
        let mut kept = None;
        for seconds in run_seconds.iter_mut() {
            let start = Instant::now();
            let answers = pool.install(|| self.trace(rays, &scene_rays, args));
            *seconds += start.elapsed().as_secs_f64();
            kept.get_or_insert(answers);
        }
        kept.expect("--repeat is at least 1")
    }
}

impl Answers {
    /// Writes the answers of one chunk to the hit file; returns how many rays hit.
    fn write(
        self,
        writer: &mut HitFileWriter,
        target: &Target,
        pool: &ThreadPool,
    ) -> io::Result<usize> {
        match self {
            Answers::Occluded(occluded) => {
                writer.write_occluded(&occluded)?;
                Ok(occluded.iter().filter(|&&o| o).count())
            }
            Answers::MeshHits(hits) => {
                let Target::Mesh { mesh, .. } = target else {
                    unreachable!("mesh hits come from a mesh");
                };
                let hits: Vec<Option<SceneHit>> = pool.install(|| {
                    hits.par_iter()
                        .with_min_len(RAYS_PER_TASK)
                        .map(|h| h.as_ref().map(|h| hit_file::mesh_hit(mesh, h)))
                        .collect()
                });
                Answers::SceneHits(hits).write(writer, target, pool)
            }
            Answers::SceneHits(hits) => {
                writer.write_hits(&hits)?;
                Ok(hits.iter().filter(|h| h.is_some()).count())
            }
        }
    }
}

/// `query` on each ray, one call per ray, in parallel on the current pool.
fn one_by_one<R: Sync, T: Send>(rays: &[R], query: impl Fn(&R) -> T + Sync + Send) -> Vec<T> {
    rays.par_iter()
        .with_min_len(RAYS_PER_TASK)
        .map(query)
        .collect()
}
