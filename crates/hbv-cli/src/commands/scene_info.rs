//! `hbv info SCENE.glb` (or a saved scene, `SCENE.hbv`): a scene's meshes and instances, its triangles as stored and as seen,
//! the E[X] of its top level and of each mesh's tree, and the memory it holds.

use std::path::Path;

use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::scene::SceneSummary;
use serde_json::json;

use super::build_args::{load_scene_file, SceneSource};
use super::info::InfoArgs;

/// Above this many meshes, their E[X] is summarized (least, median, most, mean over the
/// triangles seen) instead of listed one line each.
const MESHES_LISTED: usize = 16;

/// Loads the scene at `path`: a glTF scene with its meshes built as `args` says (insertion
/// unless told, as for a mesh) and laid out in wide-8 nodes, a saved scene as its file says;
/// and prints what [`hbv::Scene::summary`] reports.
pub fn run(path: &Path, source: SceneSource, args: &InfoArgs) -> anyhow::Result<()> {
    source.check_options(path, &args.build, &[])?;
    let builder = args.build.builder_name();
    let structure =
        args.build
            .scene_structure(builder, LayoutKind::Wide8, LayoutOptions::default());
    let (scene, load_seconds) = load_scene_file(path, source, structure)?;
    let summary = scene.summary();
    let mesh_costs = scene.mesh_expected_tests();
    let bounds = scene.bounds();
    let (lo, hi) = if bounds.is_empty() {
        ([0.0; 3], [0.0; 3])
    } else {
        (bounds.min.to_array(), bounds.max.to_array())
    };
    let described = source.describe(&args.build, LayoutKind::Wide8);
    let tree_name = match source {
        SceneSource::Gltf => builder.to_string(),
        SceneSource::Saved => "saved".to_string(),
    };

    if args.json {
        let meshes: Vec<_> = summary
            .meshes
            .iter()
            .zip(&mesh_costs)
            .map(|(m, e)| {
                json!({
                    "triangles": m.triangles,
                    "vertices": m.vertices,
                    "instances": m.instances,
                    "expected_tests": e,
                    "mesh_bytes": m.mesh_bytes,
                    "layout_bytes": m.layout_bytes,
                })
            })
            .collect();
        let out = json!({
            "scene": path.display().to_string(),
            "meshes": meshes,
            "instances": summary.live_instances,
            "instance_ids": summary.instance_ids,
            "triangles_stored": summary.triangles_stored,
            "triangles_seen": summary.triangles_seen,
            "bounds": { "min": lo, "max": hi },
            "builder": described,
            "load_seconds": load_seconds,
            "top_level_expected_tests": summary.top_level_expected_tests,
            "memory_bytes": summary.memory_bytes(),
            "mesh_bytes": summary.mesh_bytes,
            "layout_bytes": summary.layout_bytes,
            "instance_bytes": summary.instance_bytes,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }

    println!("scene       {}", path.display());
    println!(
        "meshes      {} ({} triangles stored)",
        summary.meshes.len(),
        summary.triangles_stored
    );
    println!(
        "instances   {} ({} triangles seen, instanced)",
        summary.live_instances, summary.triangles_seen
    );
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    println!("builder     {described}");
    println!("load        {load_seconds:.3} s (reading, and building each mesh and the top level)");
    println!(
        "E[X] top    {:.3} boxes per line through the root (Σ SA(n) / SA(root) over its nodes)",
        summary.top_level_expected_tests
    );
    print_mesh_costs(&summary, &mesh_costs, &tree_name);
    println!(
        "memory      {:.2} MiB: meshes {:.2}, their BVHs {:.2}, instances {:.3} (top level not counted)",
        mib(summary.memory_bytes()),
        mib(summary.mesh_bytes),
        mib(summary.layout_bytes),
        mib(summary.instance_bytes)
    );
    Ok(())
}

/// One line per mesh, or a summary of their E[X] when there are more than [`MESHES_LISTED`].
fn print_mesh_costs(summary: &SceneSummary, costs: &[f64], builder: &str) {
    let formula = "Σ a_n SA(n) / SA(root)";
    if summary.meshes.len() <= MESHES_LISTED {
        for (id, (m, e)) in summary.meshes.iter().zip(costs).enumerate() {
            println!(
                "E[X] mesh {id:<2} {e:.3} tests per line ({} triangles, {} instances, BVH {:.2} MiB)",
                m.triangles,
                m.instances,
                mib(m.layout_bytes)
            );
        }
        println!("            ({formula} of each mesh's {builder} tree)");
        return;
    }
    let mut sorted = costs.to_vec();
    sorted.sort_by(f64::total_cmp);
    let seen: f64 = summary
        .meshes
        .iter()
        .map(|m| (m.triangles * m.instances) as f64)
        .sum();
    let weighted: f64 = summary
        .meshes
        .iter()
        .zip(costs)
        .map(|(m, e)| e * (m.triangles * m.instances) as f64)
        .sum::<f64>()
        / seen.max(1.0);
    println!(
        "E[X] meshes least {:.3}, median {:.3}, most {:.3}; {weighted:.3} over the triangles seen",
        sorted[0],
        sorted[sorted.len() / 2],
        sorted[sorted.len() - 1]
    );
    println!("            ({formula} of each mesh's {builder} tree; --json lists every mesh)");
}

fn mib(bytes: usize) -> f64 {
    bytes as f64 / (1 << 20) as f64
}
