//! `hbv build`: build a tree over a mesh once and save it, with the mesh, as a `.hbv` file that
//! `info` and `trace` load instead of building again. A glTF file (`.gltf`, `.glb`) is a scene:
//! each of its meshes is built once and saved with the instances placing them, as a `.hbv`
//! scene file (`Scene::save`); `--flatten` saves its world-space triangles as one mesh instead.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use hbv::atomic_file::would_replace;
use hbv::bvh::expected_tests;
use hbv::bvh::file::BvhFile;
use hbv::mesh::MeshFormat;
use hbv::scene::{MeshId, Scene, SceneStructure};
use hbv_cli::output_check::replace_policy;
use serde_json::json;

use super::build_args::{load_mesh, BuildArgs};
use hbv::bvh::build::BuilderKind;

#[derive(Args)]
pub struct BuildCommandArgs {
    /// Mesh file (.obj, .ply), or scene file (.gltf, .glb: saved as a scene of instances); the
    /// built-in scene when omitted.
    pub mesh: Option<PathBuf>,
    /// Save a glTF file's triangles, placed in world space, as one mesh instead of a scene.
    #[arg(long)]
    pub flatten: bool,
    /// Output file (.hbv), written atomically (temporary file, then rename or link).
    #[arg(short = 'o', long)]
    pub out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &BuildCommandArgs) -> anyhow::Result<()> {
    if !args.force && would_replace(&args.out) {
        bail!("{} exists: pass --force to replace it", args.out.display());
    }
    // A missing folder is refused before the build, with the message the write would give.
    hbv::atomic_file::check_writable(&args.out).context("cannot save the tree")?;
    match args.mesh.as_deref() {
        Some(path) if !args.flatten && MeshFormat::from_path(path) == Some(MeshFormat::Gltf) => {
            build_scene(args, path)
        }
        _ => build_mesh(args),
    }
}

/// Builds every mesh of the glTF scene at `path` once and saves the scene.
fn build_scene(args: &BuildCommandArgs, path: &Path) -> anyhow::Result<()> {
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let structure = SceneStructure {
        builder: build.builder_name(),
        builder_options: build.builder_options(),
        ..SceneStructure::default()
    };
    let start = Instant::now();
    let scene = Scene::load_with_structure(path, structure).context("cannot load scene")?;
    let seconds = start.elapsed().as_secs_f64();
    let bytes = scene
        .save(&args.out, replace_policy(args.force))
        .context("cannot save the scene")?;
    let triangles: usize = (0..scene.mesh_count() as u32)
        .filter_map(|m| scene.mesh(MeshId(m)))
        .map(|mesh| mesh.triangle_count())
        .sum();
    let name = path.display().to_string();
    if args.json {
        let out = json!({
            "scene": name,
            "out": args.out.display().to_string(),
            "meshes": scene.mesh_count(),
            "instances": scene.instance_count(),
            "triangles": triangles,
            "builder_options": build.describe(),
            "load_and_build_seconds": seconds,
            "bytes": bytes,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "scene     {name} ({} meshes, {} instances, {triangles} triangles in the meshes)",
            scene.mesh_count(),
            scene.instance_count()
        );
        println!(
            "build     {seconds:.3} s, loading included ({})",
            build.describe()
        );
        println!("wrote     {} ({bytes} bytes)", args.out.display());
    }
    Ok(())
}

/// Builds the tree over one mesh and saves both.
fn build_mesh(args: &BuildCommandArgs) -> anyhow::Result<()> {
    let (mesh, name, load_seconds) = load_mesh(args.mesh.as_deref())?;
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let built = build.build_with_report(&mesh);
    let cost = expected_tests(&built.tree);
    let file = BvhFile {
        mesh,
        tree: built.tree,
        settings: build.describe(),
    };
    // The same save as Python's `BVH.save`; without --force a file that appeared during the
    // build is refused too.
    let bytes = file
        .save(&args.out, replace_policy(args.force))
        .context("cannot save the tree")?;
    let build_seconds = built.build_seconds + built.optimize_seconds;
    if args.json {
        let out = json!({
            "mesh": name,
            "out": args.out.display().to_string(),
            "triangles": file.mesh.triangle_count(),
            "nodes": file.tree.nodes().len() - file.tree.released_count(),
            "builder_options": file.settings,
            "load_seconds": load_seconds,
            "build_seconds": build_seconds,
            "expected_tests": cost,
            "bytes": bytes,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "mesh      {name} ({} triangles)",
            file.mesh.triangle_count()
        );
        println!(
            "build     {build_seconds:.3} s ({}), E[X] {cost:.3}",
            file.settings
        );
        println!("wrote     {} ({bytes} bytes)", args.out.display());
    }
    Ok(())
}
