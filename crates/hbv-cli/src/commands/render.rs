//! `hbv render`: a scene (or the built-in Cornell box) to PNG and OpenEXR images, with extra
//! passes and cost heatmaps, and a report of the rays cast by kind.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use hbv::Accelerator;
use hbv_cli::atomic_write::write_atomically;
use hbv_render::image_output::{pass_image, to_exr};
use hbv_render::{render, Frame, Pass, RayKind, RenderConfig, Scene, SceneTracer};
use serde_json::json;

use super::build_args::{thread_pool, BuildArgs, BuilderName, LayoutName};

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
    #[arg(long, value_enum, default_value_t = LayoutName::Wide8)]
    pub layout: LayoutName,
    #[command(flatten)]
    pub build: BuildArgs,
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
    if !args.force {
        if let Some((path, _)) = outputs.iter().find(|(p, _)| p.exists()) {
            bail!(
                "{} already exists (use --force to replace it)",
                path.display()
            );
        }
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

    let build = args.build.or_builder(BuilderName::BinnedSah);
    let (tree, build_seconds) = pool.install(|| build.build(&scene.mesh));
    let accelerator: Arc<dyn Accelerator> = Arc::from(args.layout.lay_out(&tree, &scene.mesh));
    let tracer = SceneTracer::new(accelerator.clone(), accelerator);

    let config = RenderConfig {
        count_work: !args.no_work_count,
        time_queries: args.time_rays,
        quiet: args.quiet || args.json,
        ..RenderConfig::default()
    };
    let frame = pool.install(|| render(&scene, &tracer, &config));

    for (path, pass) in &outputs {
        let bytes = match pass {
            Some(pass) => pass_image(&frame.film, *pass).to_png()?,
            None => to_exr(&frame.film)?,
        };
        write_atomically(path, |f| f.write_all(&bytes))?;
    }

    let report = Report {
        scene_name: &scene_name,
        scene: &scene,
        frame: &frame,
        structure: format!("{:?} over {}", args.layout, build.describe()).to_lowercase(),
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
                    "nodes_per_ray": counted.then(|| ratio(st.work[k].nodes_visited, st.work[k].rays)),
                    "query_seconds": (timed > 0).then(|| st.query_nanos[k] as f64 * 1e-9),
                    "time_share": (timed > 0).then(|| st.query_nanos[k] as f64 / timed as f64),
                }),
            );
        }
        let s = &self.scene.settings;
        json!({
            "scene": self.scene_name,
            "triangles": self.scene.mesh.triangle_count(),
            "lights": self.scene.lights.len(),
            "width": s.width,
            "height": s.height,
            "spp": s.spp,
            "max_depth": s.max_depth,
            "structure": self.structure,
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
            "scene      {} ({} triangles, {} lights)",
            self.scene_name,
            self.scene.mesh.triangle_count(),
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
        for p in &self.outputs {
            println!("wrote      {}", p.display());
        }
    }
}

fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}
