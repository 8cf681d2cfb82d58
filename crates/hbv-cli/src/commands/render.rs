//! `hbv render`: a scene (or the built-in Cornell box) to PNG and OpenEXR images, with extra
//! passes and cost heatmaps, and a report of the rays cast by kind.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use hbv::atomic_file::{would_replace, write_all_atomically};
use hbv::grid::{GridConfig, UniformGrid};
use hbv::Accelerator;
use hbv_cli::output_check::{check_output, replace_policy, OutputFormat};
use hbv_render::image_output::{pass_image, to_exr};
use hbv_render::{
    render, Frame, Pass, QueryCacheConfig, RayKind, RenderConfig, Scene, SceneTracer,
};
use serde_json::json;

use super::build_args::{thread_pool, AccelName, BuildArgs};
use super::name_values::layout_kind;
use hbv::bvh::build::BuilderKind;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::scene::SceneStructure;

/// Most pixels of an image (8192 × 8192): the film's passes take 40 bytes a pixel.
const MAX_PIXELS: u64 = 1 << 26;

/// Extra passes, each written beside the image as `OUT.PASS.png`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PassName {
    /// Distance to the first hit (near white, far dark).
    Depth,
    /// Shading normal of the first hit as RGB.
    Normal,
    /// Triangle id of the first hit, one colour per triangle.
    Prim,
    /// Heatmap of nodes visited per pixel (all rays of the pixel), with a legend.
    Nodes,
    /// Heatmap of triangles tested per pixel (all rays of the pixel), with a legend.
    Triangles,
}

impl PassName {
    fn pass(self) -> Pass {
        match self {
            PassName::Depth => Pass::Depth,
            PassName::Normal => Pass::Normal,
            PassName::Prim => Pass::Prim,
            PassName::Nodes => Pass::Nodes,
            PassName::Triangles => Pass::Triangles,
        }
    }
}

/// How the scene's instances are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Instancing {
    /// Two-level when some mesh is placed more than once, flat otherwise, and flat whenever the
    /// run asks for the uniform grid (--primary/--shadow grid), which only the flat scene has.
    Auto,
    /// hbv's two-level scene: each mesh's BVH built once (--builder, --layout), a top level
    /// over the instances, with its object caches (keyed by instance and triangle) and counted
    /// work (tests per ray, heatmaps).
    TwoLevel,
    /// Every instance's triangles copied into one world-space mesh, traced by --primary and
    /// --shadow with the object caches and the counted queries.
    Flat,
}

#[derive(Args)]
pub struct RenderArgs {
    /// Scene file (TOML; see docs/SCENES.md). Without one: the built-in Cornell box.
    pub scene: Option<PathBuf>,
    /// Output image (PNG, 8-bit sRGB); written atomically.
    #[arg(short = 'o', long = "out", default_value = "render.png")]
    pub out: PathBuf,
    /// Replace output files that already exist.
    #[arg(long)]
    pub force: bool,
    /// Image width in pixels [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=32768))]
    pub width: Option<u32>,
    /// Image height in pixels [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=32768))]
    pub height: Option<u32>,
    /// Samples per pixel [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: Option<u32>,
    /// Most reflection/refraction bounces [default: the scene's].
    #[arg(long = "max-depth", value_parser = clap::value_parser!(u32).range(0..=64))]
    pub max_depth: Option<u32>,
    /// Also write the linear image (and depth) as OpenEXR float channels R, G, B, Z.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Extra pass to write as OUT.PASS.png (repeatable).
    #[arg(long = "pass", value_enum)]
    pub passes: Vec<PassName>,
    /// How the tree is laid out for traversal.
    #[arg(long, value_parser = layout_kind(), default_value_t = LayoutKind::Wide8)]
    pub layout: LayoutKind,
    #[command(flatten)]
    pub build: BuildArgs,
    /// How the scene's instances are traced.
    #[arg(long, value_enum, default_value_t = Instancing::Auto)]
    pub instancing: Instancing,
    /// Structure for intersection rays (primary, reflected, transmitted) of a flat scene.
    #[arg(long, value_enum, default_value_t = AccelName::Bvh)]
    pub primary: AccelName,
    /// Structure for shadow rays of a flat scene.
    #[arg(long, value_enum, default_value_t = AccelName::Bvh)]
    pub shadow: AccelName,
    /// No object caches (by default: a shadow cache per light and tile, a last-hit cache for
    /// primary rays). The image is the same either way.
    #[arg(long = "no-cache")]
    pub no_cache: bool,
    /// Diagnostic: also give reflected and transmitted rays a last-hit cache each, to measure
    /// what caching secondary rays would give.
    #[arg(long = "cache-secondary", conflicts_with = "no_cache")]
    pub cache_secondary: bool,
    /// Diagnostic: one shadow cache per light sample instead of per light.
    #[arg(long = "shadow-cache-per-sample", conflicts_with = "no_cache")]
    pub shadow_cache_per_sample: bool,
    /// Worker threads; 0 uses every core.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// No progress bar (there is none anyway when stderr is not a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// Time every query to report the share of time of each ray kind (adds two clock reads a
    /// ray).
    #[arg(long = "time-rays")]
    pub time_rays: bool,
    /// Use the uncounted queries (faster; no tests per ray). Not with --pass nodes|triangles.
    #[arg(long = "no-work-count")]
    pub no_work_count: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let passes: Vec<Pass> = args.passes.iter().map(|p| p.pass()).collect();
    if args.no_work_count && passes.iter().any(|p| p.needs_work_counted()) {
        bail!("--no-work-count cannot make the nodes and triangles heatmaps");
    }
    let outputs = output_files(args, &passes);
    for (i, (path, _)) in outputs.iter().enumerate() {
        if outputs[..i]
            .iter()
            .any(|(earlier, _)| same_file(earlier, path))
        {
            bail!(
                "{} is named twice among the outputs (the image, its passes and --exr)",
                path.display()
            );
        }
    }
    if !args.force {
        if let Some((path, _)) = outputs.iter().find(|(p, _)| would_replace(p)) {
            bail!(
                "{} already exists (use --force to replace it)",
                path.display()
            );
        }
    }
    // A missing folder or a name of another format is refused now, not after rendering.
    for (path, pass) in &outputs {
        let format = match pass {
            Some(_) => OutputFormat::Png,
            None => OutputFormat::OpenExr,
        };
        check_output(path, Some(format))?;
    }
    let pool = thread_pool(args.threads)?;

    let start = Instant::now();
    let (mut scene, scene_name) = match &args.scene {
        Some(path) => (
            hbv_render::scene::load_scene(path).context("cannot load scene")?,
            path.display().to_string(),
        ),
        None => (Scene::cornell_box(), "built-in Cornell box".to_string()),
    };
    let s = &mut scene.settings;
    s.width = args.width.unwrap_or(s.width);
    s.height = args.height.unwrap_or(s.height);
    s.spp = args.spp.unwrap_or(s.spp);
    s.max_depth = args.max_depth.unwrap_or(s.max_depth);
    if s.width as u64 * s.height as u64 > MAX_PIXELS {
        bail!(
            "{}×{} is too large: at most {MAX_PIXELS} pixels (the film holds 40 bytes a pixel)",
            s.width,
            s.height
        );
    }
    let load_seconds = start.elapsed().as_secs_f64();

    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let grid = args.primary == AccelName::Grid || args.shadow == AccelName::Grid;
    let two_level = match args.instancing {
        Instancing::Flat => false,
        Instancing::TwoLevel => {
            if grid {
                bail!("the uniform grid (--primary/--shadow grid) needs --instancing flat: there is no grid over instances");
            }
            true
        }
        Instancing::Auto => !grid && scene.shares_meshes(),
    };
    let caches = if args.no_cache {
        QueryCacheConfig::none()
    } else {
        QueryCacheConfig {
            secondary: args.cache_secondary,
            shadow_per_sample: args.shadow_cache_per_sample,
            ..QueryCacheConfig::default()
        }
    };
    let mut build_seconds = 0.0;
    let (tracer, structure) = if two_level {
        let start = Instant::now();
        let structure = SceneStructure {
            builder: build.builder_name(),
            builder_options: build.builder_options(),
            layout: args.layout,
            layout_options: LayoutOptions::default(),
        };
        let instanced = pool.install(|| scene.two_level(structure));
        build_seconds += start.elapsed().as_secs_f64();
        let described = format!(
            "two-level scene: {} meshes ({:?} over {}), {} instances under a top-level bvh",
            scene.meshes.len(),
            args.layout,
            build.describe(),
            scene.instances.len()
        )
        .to_lowercase();
        let tracer = SceneTracer::two_level(Arc::new(instanced)).with_caches(caches);
        (tracer, described)
    } else {
        let start = Instant::now();
        let mesh = &pool
            .install(|| scene.flat())
            .map_err(|e| anyhow::anyhow!(e))?
            .mesh;
        build_seconds += start.elapsed().as_secs_f64();
        let uses = |accel| args.primary == accel || args.shadow == accel;
        let bvh = uses(AccelName::Bvh).then(|| {
            let (tree, seconds) = pool.install(|| build.build(mesh));
            let start = Instant::now();
            let laid_out: Arc<dyn Accelerator> =
                Arc::new(args.layout.lay_out(&tree, mesh, &LayoutOptions::default()));
            build_seconds += seconds + start.elapsed().as_secs_f64();
            let described = format!("{:?} over {}", args.layout, build.describe()).to_lowercase();
            (laid_out, described)
        });
        let grid = uses(AccelName::Grid).then(|| {
            let start = Instant::now();
            let grid = pool.install(|| UniformGrid::new(mesh, GridConfig::default()));
            build_seconds += start.elapsed().as_secs_f64();
            let r = grid.shape().map_or([0; 3], |s| s.resolution);
            let described = format!(
                "uniform grid {}×{}×{} (λ = {}, mailboxes)",
                r[0],
                r[1],
                r[2],
                grid.config().lambda
            );
            (Arc::new(grid) as Arc<dyn Accelerator>, described)
        });
        let chosen = |accel| match accel {
            AccelName::Bvh => bvh.clone(),
            AccelName::Grid => grid.clone(),
        };
        let (primary, primary_name) = chosen(args.primary).expect("built above");
        let (shadow, shadow_name) = chosen(args.shadow).expect("built above");
        let tracer = SceneTracer::new(primary, shadow).with_caches(caches);
        let structure = if args.primary == args.shadow {
            primary_name
        } else {
            format!("{primary_name} for intersection rays, {shadow_name} for shadow rays")
        };
        (tracer, structure)
    };

    let config = RenderConfig {
        count_work: !args.no_work_count,
        time_queries: args.time_rays,
        quiet: args.quiet || args.json,
        ..RenderConfig::default()
    };
    let frame = pool.install(|| render(&scene, &tracer, &config));

    // Every image encoded first, then all written or none: a failing last output (a missing
    // folder, a full disk) no longer leaves the first ones behind.
    let encoded = outputs
        .iter()
        .map(|(path, pass)| {
            let bytes = match pass {
                Some(pass) => pass_image(&frame.film, *pass).to_png()?,
                None => to_exr(&frame.film)?,
            };
            Ok((path.as_path(), bytes))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let files: Vec<(&Path, &[u8])> = encoded.iter().map(|(p, b)| (*p, b.as_slice())).collect();
    write_all_atomically(&files, replace_policy(args.force))?;

    let report = Report {
        scene_name: &scene_name,
        scene: &scene,
        frame: &frame,
        structure,
        primary: args.primary,
        shadow: args.shadow,
        caches,
        threads: pool.current_num_threads(),
        load_seconds,
        build_seconds,
        outputs: outputs.iter().map(|(p, _)| p.as_path()).collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.json())?);
    } else {
        report.print();
    }
    Ok(())
}

/// Every file this run writes, with the pass it holds (`None`: the OpenEXR file).
fn output_files(args: &RenderArgs, passes: &[Pass]) -> Vec<(PathBuf, Option<Pass>)> {
    let mut files = vec![(args.out.clone(), Some(Pass::Beauty))];
    for &pass in passes {
        files.push((pass_path(&args.out, pass), Some(pass)));
    }
    if let Some(exr) = &args.exr {
        files.push((exr.clone(), None));
    }
    files
}

/// Whether two output paths name the same file: equal as written, or the same existing file
/// (through links or `..`).
fn same_file(a: &Path, b: &Path) -> bool {
    a == b
        || match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        }
}

/// `dir/name.png` → `dir/name.PASS.png`.
fn pass_path(out: &Path, pass: Pass) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    out.with_file_name(format!("{stem}.{}.png", pass.name()))
}

struct Report<'a> {
    scene_name: &'a str,
    scene: &'a Scene,
    frame: &'a Frame,
    structure: String,
    primary: AccelName,
    shadow: AccelName,
    caches: QueryCacheConfig,
    threads: usize,
    load_seconds: f64,
    build_seconds: f64,
    outputs: Vec<&'a Path>,
}

impl Report<'_> {
    fn mrays_per_second(&self) -> f64 {
        self.frame.stats.total_rays() as f64 / self.frame.seconds.max(1e-9) / 1e6
    }

    fn json(&self) -> serde_json::Value {
        let st = &self.frame.stats;
        let counted = st.total_work().rays > 0;
        let timed: u64 = st.query_nanos.iter().sum();
        let mut kinds = serde_json::Map::new();
        for (k, name) in RayKind::NAMES.iter().enumerate() {
            kinds.insert(
                name.to_string(),
                json!({
                    "rays": st.rays[k],
                    "tests_per_ray": counted.then(|| st.work[k].tests_per_ray()),
                    "nodes_per_ray": counted.then(|| st.work[k].nodes_per_ray()),
                    "query_seconds": (timed > 0).then(|| st.query_nanos[k] as f64 * 1e-9),
                    "time_share": (timed > 0).then(|| st.query_nanos[k] as f64 / timed as f64),
                    "cache": cache_json(st.cache[k]),
                    "blocked": (k == 3).then_some(st.shadow_blocked),
                    "mailbox_skips": counted.then_some(st.work[k].mailbox_skips),
                }),
            );
        }
        let s = &self.scene.settings;
        json!({
            "scene": self.scene_name,
            "triangles": self.scene.triangle_count(),
            "triangles_stored": self.scene.stored_triangle_count(),
            "meshes": self.scene.meshes.len(),
            "instances": self.scene.instances.len(),
            "lights": self.scene.lights.len(),
            "width": s.width,
            "height": s.height,
            "spp": s.spp,
            "max_depth": s.max_depth,
            "structure": self.structure,
            "primary": accel_name(self.primary),
            "shadow": accel_name(self.shadow),
            "caches": {
                "primary": self.caches.primary,
                "shadow": self.caches.shadow,
                "secondary": self.caches.secondary,
                "shadow_per_sample": self.caches.shadow_per_sample,
            },
            "threads": self.threads,
            "load_seconds": self.load_seconds,
            "build_seconds": self.build_seconds,
            "render_seconds": self.frame.seconds,
            "rays": st.total_rays(),
            "mrays_per_second": self.mrays_per_second(),
            "tests_per_ray": counted.then(|| st.total_work().tests_per_ray()),
            "by_kind": kinds,
            "files": self.outputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        })
    }

    fn print(&self) {
        let st = &self.frame.stats;
        let s = &self.scene.settings;
        println!(
            "scene      {} ({} triangles in {} instances of {} meshes, {} lights)",
            self.scene_name,
            self.scene.triangle_count(),
            self.scene.instances.len(),
            self.scene.meshes.len(),
            self.scene.lights.len()
        );
        println!(
            "structure  {} (built in {:.3} s)",
            self.structure, self.build_seconds
        );
        println!(
            "rendered   {}×{}, {} spp, depth {} in {:.3} s on {} threads: {} rays, {:.2} Mrays/s",
            s.width,
            s.height,
            s.spp,
            s.max_depth,
            self.frame.seconds,
            self.threads,
            st.total_rays(),
            self.mrays_per_second()
        );
        let counted = st.total_work().rays > 0;
        let timed: u64 = st.query_nanos.iter().sum();
        println!(
            "{:<12} {:>12} {:>14} {:>12}",
            "ray kind", "rays", "tests/ray", "time share"
        );
        for (k, name) in RayKind::NAMES.iter().enumerate() {
            let tests = if counted {
                format!("{:.1}", st.work[k].tests_per_ray())
            } else {
                "-".into()
            };
            let share = if timed > 0 {
                format!("{:.1}%", 100.0 * st.query_nanos[k] as f64 / timed as f64)
            } else {
                "-".into()
            };
            println!("{name:<12} {:>12} {tests:>14} {share:>12}", st.rays[k]);
        }
        if counted {
            println!(
                "{:<12} {:>12} {:>14.1}",
                "all",
                st.total_rays(),
                st.total_work().tests_per_ray()
            );
        }
        self.print_caches_and_mailboxes();
        for p in &self.outputs {
            println!("wrote      {}", p.display());
        }
    }
}

impl Report<'_> {
    /// Cache hit rates per cached ray kind, and the tests the grid's mailboxes saved.
    fn print_caches_and_mailboxes(&self) {
        let st = &self.frame.stats;
        let cached: Vec<usize> = (0..4)
            .filter(|&k| st.cache[k].hits + st.cache[k].misses > 0)
            .collect();
        if cached.is_empty() {
            println!("caches     none");
        } else {
            println!(
                "{:<12} {:>12} {:>14} {:>12}",
                "cache", "hits", "lookups", "hit rate"
            );
            for k in cached {
                let c = st.cache[k];
                let of_blocked = if k == 3 {
                    format!(
                        " ({:.1}% of the {} blocked rays)",
                        100.0 * ratio(c.hits, st.shadow_blocked),
                        st.shadow_blocked
                    )
                } else {
                    String::new()
                };
                println!(
                    "{:<12} {:>12} {:>14} {:>11.1}%{of_blocked}",
                    RayKind::NAMES[k],
                    c.hits,
                    c.hits + c.misses,
                    100.0 * c.hit_rate()
                );
            }
        }
        let skips: Vec<usize> = (0..4).filter(|&k| st.work[k].mailbox_skips > 0).collect();
        for k in skips {
            let w = st.work[k];
            println!(
                "mailboxes  {}: {} repeated tests saved ({:.1} per ray, {:.1}% of the tests)",
                RayKind::NAMES[k],
                w.mailbox_skips,
                w.mailbox_skips_per_ray(),
                100.0 * ratio(w.mailbox_skips, w.mailbox_skips + w.triangles_tested)
            );
        }
    }
}

/// `{hits, lookups, hit_rate}`, or null for a kind that bypasses the caches.
fn cache_json(c: hbv::cache::CacheStats) -> serde_json::Value {
    let lookups = c.hits + c.misses;
    if lookups == 0 {
        serde_json::Value::Null
    } else {
        json!({"hits": c.hits, "lookups": lookups, "hit_rate": c.hit_rate()})
    }
}

fn accel_name(accel: AccelName) -> &'static str {
    match accel {
        AccelName::Bvh => "bvh",
        AccelName::Grid => "grid",
    }
}

fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}
