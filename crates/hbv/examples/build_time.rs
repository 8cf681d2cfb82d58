//! Build time and tree quality of the top-down builders on one or more meshes.
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p hbv --example build_time -- MESH... [--runs N] [--builder NAME] [--bins N] [--structures | --direct]
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
//!
//! With `--direct`, instead: from the mesh to a traceable wide-8 layout, the binned SAH build
//! then the layout ([`Wide8Layout::new`]) against the direct build ([`Wide8Layout::build_direct`]),
//! alternated round by round (medians of `N`); then closest hits of 200,000 random rays
//! (origins around the mesh, aimed at points in its box) on one thread, the two layouts
//! alternated over `N` rounds (median Mrays/s of each).

use std::time::Instant;

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, LbvhBuilder, MedianBuilder, PlocBuilder,
    SweepSahBuilder,
};
use hbv::bvh::layout::Wide8Layout;
use hbv::bvh::{expected_tests, sah_cost, SahWeights};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::proximity::ClosestPointTree;
use hbv::{Accelerator, TriangleMesh};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut paths = Vec::new();
    let mut runs = 5usize;
    let mut only: Option<String> = None;
    let mut binned = BinnedSahConfig::default();
    let mut structures = false;
    let mut direct = false;
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
        } else if arg == "--direct" {
            direct = true;
        } else if arg == "--builder" {
            only = Some(args.next().ok_or("--builder needs a name")?);
        } else {
            paths.push(arg);
        }
    }
    if paths.is_empty() {
        return Err(
            "usage: build_time MESH... [--runs N] [--builder NAME] [--bins N] [--structures | --direct]"
                .into(),
        );
    }
    if direct {
        return direct_times(&paths, runs, binned);
    }
    if structures {
        return structure_times(&paths, runs, BinnedSahBuilder::new(binned));
    }
    let builders: [Box<dyn Builder>; 5] = [
        Box::new(BinnedSahBuilder::new(binned)),
        Box::new(SweepSahBuilder::default()),
        Box::new(MedianBuilder::default()),
        Box::new(LbvhBuilder::default()),
        Box::new(PlocBuilder::default()),
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

/// The `--direct` table: per mesh, the binned SAH build and wide-8 layout against the direct
/// build, alternated, then the ray speed of the two layouts, alternated, on one thread.
fn direct_times(
    paths: &[String],
    runs: usize,
    config: BinnedSahConfig,
) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "threads: {}, runs: {runs}\n| mesh | triangles | build + layout ms | direct ms | ratio | build + layout Mrays/s | direct Mrays/s | ratio |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        rayon::current_num_threads()
    );
    let builder = BinnedSahBuilder::new(config);
    let median = |mut t: Vec<f64>| {
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    for path in paths {
        let mesh = TriangleMesh::load(path)?;
        let (mut two_step, mut direct) = (Vec::new(), Vec::new());
        let mut layouts = None;
        for round in 0..=runs {
            drop(layouts.take()); // Freeing a layout is not building one.
            let start = Instant::now();
            let tree = builder.build(&mesh);
            let old = Wide8Layout::new(&tree, &mesh);
            let built = Instant::now();
            drop(tree);
            let between = Instant::now();
            let new = Wide8Layout::build_direct(&mesh, &config);
            let done = Instant::now();
            if round > 0 {
                two_step.push((built - start).as_secs_f64() * 1e3);
                direct.push((done - between).as_secs_f64() * 1e3);
            }
            layouts = Some((old, new));
        }
        let (old, new) = layouts.expect("one round at least");
        let rays = random_rays(&mesh, 200_000);
        let (mut old_speed, mut new_speed) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            old_speed.push(mrays_per_second(&old, &rays));
            new_speed.push(mrays_per_second(&new, &rays));
        }
        let (two_step, direct) = (median(two_step), median(direct));
        let (old_speed, new_speed) = (median(old_speed), median(new_speed));
        println!(
            "| {} | {} | {two_step:.1} | {direct:.1} | {:.2} | {old_speed:.3} | {new_speed:.3} | {:.3} |",
            mesh_name(path),
            mesh.triangle_count(),
            direct / two_step,
            new_speed / old_speed,
        );
    }
    Ok(())
}

/// `count` rays from points on a sphere around `mesh` (twice its box's half diagonal from the
/// centre) to points in its box, from a fixed xorshift sequence.
fn random_rays(mesh: &TriangleMesh, count: usize) -> Vec<Ray> {
    let bounds = mesh.bounds();
    let (centre, extent) = (bounds.center(), bounds.extent());
    let radius = extent.length();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..count)
        .map(|_| {
            let (z, a) = (2.0 * uniform() - 1.0, std::f32::consts::TAU * uniform());
            let r = (1.0 - z * z).sqrt();
            let origin = centre + radius * Vec3::new(r * a.cos(), r * a.sin(), z);
            let target = bounds.min + extent * Vec3::new(uniform(), uniform(), uniform());
            Ray::new(origin, target - origin)
        })
        .collect()
}

/// Closest hits of `rays` on this thread, one ray a call, in millions of rays per second.
fn mrays_per_second(layout: &Wide8Layout, rays: &[Ray]) -> f64 {
    let start = Instant::now();
    let hits = rays
        .iter()
        .filter(|r| layout.intersect(r).is_some())
        .count();
    std::hint::black_box(hits);
    rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6
}

/// The file name of `path` without its extension.
fn mesh_name(path: &str) -> String {
    std::path::Path::new(path)
        .file_stem()
        .map_or(path.to_owned(), |s| s.to_string_lossy().into_owned())
}
