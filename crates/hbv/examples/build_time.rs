//! Build time and tree quality of the top-down builders on one or more meshes.
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p hbv --example build_time -- MESH... [--runs N] [--builder NAME] [--bins N]
//! ```
//!
//! For each mesh and builder (all four, or the one named by `--builder`, with default options but
//! for the binned SAH builder's bin count, `--bins`): the median wall time of `N` builds
//! (default 5, after one warm-up), conversion to `BuildTree` included and mesh loading excluded;
//! then the tree's SAH cost (`C_t = C_i = 1`), E\[X\], node count and depth.

use std::time::Instant;

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, LbvhBuilder, MedianBuilder, SweepSahBuilder,
};
use hbv::bvh::{expected_tests, sah_cost, SahWeights};
use hbv::TriangleMesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut paths = Vec::new();
    let mut runs = 5usize;
    let mut only: Option<String> = None;
    let mut binned = BinnedSahConfig::default();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        if arg == "--runs" {
            runs = args
                .next()
                .ok_or("--runs needs a number")?
                .parse::<usize>()?
                .max(1);
        } else if arg == "--bins" {
            binned.bins = args.next().ok_or("--bins needs a number")?.parse()?;
        } else if arg == "--builder" {
            only = Some(args.next().ok_or("--builder needs a name")?);
        } else {
            paths.push(arg);
        }
    }
    if paths.is_empty() {
        return Err("usage: build_time MESH... [--runs N] [--builder NAME] [--bins N]".into());
    }
    let builders: [Box<dyn Builder>; 4] = [
        Box::new(BinnedSahBuilder::new(binned)),
        Box::new(SweepSahBuilder::default()),
        Box::new(MedianBuilder::default()),
        Box::new(LbvhBuilder::default()),
    ];
    println!(
        "threads: {}, runs: {runs}\n| mesh | triangles | builder | build s | SAH | E[X] | nodes | depth mean | depth max |\n| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
        rayon::current_num_threads()
    );
    for path in &paths {
        let mesh = TriangleMesh::load(path)?;
        let name = std::path::Path::new(path)
            .file_stem()
            .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        for builder in &builders {
            if only.as_deref().is_some_and(|name| name != builder.name()) {
                continue;
            }
            let mut tree = builder.build(&mesh);
            let mut seconds = Vec::with_capacity(runs);
            for _ in 0..runs {
                drop(tree); // Outside the timed part: freeing a tree is not building one.
                let start = Instant::now();
                tree = builder.build(&mesh);
                seconds.push(start.elapsed().as_secs_f64());
            }
            seconds.sort_by(f64::total_cmp);
            let shape = tree.shape();
            println!(
                "| {name} | {} | {} | {:.4} | {:.3} | {:.2} | {} | {:.1} | {} |",
                mesh.triangle_count(),
                builder.name(),
                seconds[seconds.len() / 2],
                sah_cost(&tree, SahWeights::default()),
                expected_tests(&tree),
                shape.nodes,
                shape.depth_mean,
                shape.depth_max,
            );
        }
    }
    Ok(())
}
