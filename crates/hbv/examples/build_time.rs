//! Build time and tree quality of the top-down builders on one or more meshes.
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p hbv --example build_time -- MESH... [--runs N] [--builder NAME] [--bins N] [--structures]
//! ```
//!
//! For each mesh and builder (all four, or the one named by `--builder`, with default options but
//! for the binned SAH builder's bin count, `--bins`): the median wall time of `N` builds
//! (default 5, after one warm-up), conversion to `BuildTree` included and mesh loading excluded;
//! then the tree's SAH cost (`C_t = C_i = 1`), E\[X\], node count and depth.
//!
//! With `--structures`, instead: what a first query on a fresh tree waits for, phase by phase,
//! the median of `N` rounds of each: the binned SAH build, the wide-8 layout (the ray queries'
//! structure) and the nearest-point tree. To compare two commits, build this at each and run the
//! two programs in turn: two builds linked into one program differ by a few per cent with code
//! placement alone.

use std::time::Instant;

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, LbvhBuilder, MedianBuilder, SweepSahBuilder,
};
use hbv::bvh::layout::Wide8Layout;
use hbv::bvh::{expected_tests, sah_cost, SahWeights};
use hbv::proximity::ClosestPointTree;
use hbv::TriangleMesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut paths = Vec::new();
    let mut runs = 5usize;
    let mut only: Option<String> = None;
    let mut binned = BinnedSahConfig::default();
    let mut structures = false;
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
        } else if arg == "--structures" {
            structures = true;
        } else if arg == "--builder" {
            only = Some(args.next().ok_or("--builder needs a name")?);
        } else {
            paths.push(arg);
        }
    }
    if paths.is_empty() {
        return Err(
            "usage: build_time MESH... [--runs N] [--builder NAME] [--bins N] [--structures]"
                .into(),
        );
    }
    if structures {
        return structure_times(&paths, runs, BinnedSahBuilder::new(binned));
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
        let name = mesh_name(path);
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

/// The `--structures` table: per mesh, the median of `runs` rounds (after one warm-up) of the
/// build, the wide-8 layout and the nearest-point tree.
fn structure_times(
    paths: &[String],
    runs: usize,
    builder: BinnedSahBuilder,
) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "threads: {}, runs: {runs}\n| mesh | triangles | binned SAH build ms | wide-8 layout ms | nearest-point tree ms |\n| --- | ---: | ---: | ---: | ---: |",
        rayon::current_num_threads()
    );
    for path in paths {
        let mesh = TriangleMesh::load(path)?;
        let mut times = [vec![], vec![], vec![]];
        for round in 0..=runs {
            let start = Instant::now();
            let tree = builder.build(&mesh);
            let built = Instant::now();
            let layout = Wide8Layout::new(&tree, &mesh);
            let laid_out = Instant::now();
            let nearest = ClosestPointTree::new(&tree, &mesh);
            let done = Instant::now();
            std::hint::black_box((&layout, &nearest));
            if round > 0 {
                let phases = [(start, built), (built, laid_out), (laid_out, done)];
                for (k, (from, to)) in phases.into_iter().enumerate() {
                    times[k].push((to - from).as_secs_f64() * 1e3);
                }
            }
        }
        let [build, layout, nearest] = times.map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        });
        println!(
            "| {} | {} | {build:.1} | {layout:.1} | {nearest:.1} |",
            mesh_name(path),
            mesh.triangle_count()
        );
    }
    Ok(())
}

/// The file name of `path` without its extension.
fn mesh_name(path: &str) -> String {
    std::path::Path::new(path)
        .file_stem()
        .map_or(path.to_owned(), |s| s.to_string_lossy().into_owned())
}
