//! `hbv info`: the mesh, the tree built over it, and the tree's cost.

use std::path::PathBuf;

use clap::Args;
use hbv::bvh::{expected_tests, sah_cost, SahWeights};
use serde_json::json;

use super::build_args::{load_input, BuildArgs, SceneSource};
use super::scene_info;

#[derive(Args)]
pub struct InfoArgs {
    /// Mesh file (.obj, .ply), scene file (.gltf, .glb: meshes, instances, the top level's and
    /// each mesh's E[X]) or a .hbv file from `hbv build` (a saved tree, or a saved scene); the
    /// built-in scene when omitted.
    pub mesh: Option<PathBuf>,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    if let Some(path) = args.mesh.as_deref() {
        if let Some(source) = SceneSource::of(path) {
            return scene_info::run(path, source, args);
        }
    }
    let scene = load_input(args.mesh.as_deref())?;
    scene.check_build_options(&args.build)?;
    let (name, load_seconds, saved) = (
        scene.name.clone(),
        scene.load_seconds,
        scene.saved.is_some(),
    );
    let (mesh, built, builder_options) = scene.tree(&args.build);
    let builder_name = if saved {
        "saved"
    } else {
        args.build.builder().name()
    };
    let (tree, build_seconds, evaluated) = (
        built.tree,
        built.build_seconds,
        built.search_nodes_per_insertion,
    );
    let optimize_seconds = built.optimize_seconds;
    let shape = tree.shape();
    let weights = SahWeights::default();
    let e = expected_tests(&tree);
    let sah = sah_cost(&tree, weights);
    let open_edges = mesh.open_edge_count();
    let bounds = mesh.bounds();
    let (lo, hi) = if bounds.is_empty() {
        ([0.0; 3], [0.0; 3])
    } else {
        (bounds.min.to_array(), bounds.max.to_array())
    };

    if args.json {
        let out = json!({
            "mesh": name,
            "triangles": mesh.triangle_count(),
            "degenerate": mesh.degenerate_count(),
            "vertices": mesh.positions().len(),
            "open_edges": open_edges,
            "bounds": { "min": lo, "max": hi },
            "builder": builder_name,
            "builder_options": builder_options,
            "load_seconds": load_seconds,
            "build_seconds": build_seconds,
            "optimize": args.build.builder_options().optimize,
            "optimize_seconds": optimize_seconds,
            "search_nodes_per_insertion": evaluated,
            "nodes": shape.nodes,
            "leaves": shape.leaves,
            "depth_max": shape.depth_max,
            "depth_mean": shape.depth_mean,
            "arity_histogram": shape.arity_histogram,
            "expected_tests": e,
            "sah_cost": sah,
            "sah_weights": { "traversal": weights.traversal, "intersection": weights.intersection },
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }

    let arity: Vec<String> = shape
        .arity_histogram
        .iter()
        .enumerate()
        .filter(|(_, &n)| n > 0)
        .map(|(k, n)| format!("{k}: {n}"))
        .collect();
    println!("mesh        {name}");
    println!(
        "triangles   {} ({} degenerate, left out of the tree), {} vertices",
        mesh.triangle_count(),
        mesh.degenerate_count(),
        mesh.positions().len()
    );
    if open_edges == 0 {
        println!("closed      yes (every edge shared by an even number of triangles)");
    } else {
        println!(
            "closed      no ({open_edges} open edges: inside tests are not defined near them)"
        );
    }
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    println!("builder     {builder_options}");
    println!("load        {load_seconds:.3} s");
    if evaluated > 0.0 {
        println!("build       {build_seconds:.3} s ({evaluated:.1} nodes evaluated per insertion)");
    } else {
        println!("build       {build_seconds:.3} s");
    }
    if args.build.builder_options().optimize {
        println!("optimize    {optimize_seconds:.3} s");
    }
    println!(
        "nodes       {} ({} leaves, {} internal)",
        shape.nodes,
        shape.leaves,
        shape.nodes - shape.leaves
    );
    println!(
        "depth       max {}, mean {:.2} (leaves)",
        shape.depth_max, shape.depth_mean
    );
    println!(
        "arity       {} (children: internal nodes)",
        arity.join(", ")
    );
    println!("E[X]        {e:.3} tests per line through the root (Σ a_n SA(n) / SA(root))");
    println!(
        "SAH cost    {sah:.3} (C_t = {}, C_i = {})",
        weights.traversal, weights.intersection
    );
    Ok(())
}
