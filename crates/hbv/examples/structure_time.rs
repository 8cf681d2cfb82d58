//! What a first query on a fresh tree waits for, phase by phase: the binned SAH build, the wide-8
//! layout (the ray queries' structure) and the nearest-point tree.
//!
//! ```text
//! cargo run --release -p hbv --example structure_time -- MESH... [--runs N]
//! ```
//!
//! For each mesh, the median wall time of `N` rounds (default 7, after one warm-up) of each
//! phase, on the current rayon pool (`RAYON_NUM_THREADS` to choose), mesh loading excluded. To
//! compare two commits, build this at each and run the two programs in turn: timings of two
//! builds linked into one program differ by a few per cent with code placement alone.

use std::time::Instant;

use hbv::bvh::build::{BinnedSahBuilder, Builder};
use hbv::bvh::layout::Wide8Layout;
use hbv::proximity::ClosestPointTree;
use hbv::TriangleMesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut paths = Vec::new();
    let mut runs = 7usize;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        if arg == "--runs" {
            runs = args
                .next()
                .ok_or("--runs needs a number")?
                .parse::<usize>()?
                .max(1);
        } else {
            paths.push(arg);
        }
    }
    if paths.is_empty() {
        return Err("usage: structure_time MESH... [--runs N]".into());
    }
    println!(
        "threads: {}, runs: {runs}\n| mesh | triangles | binned SAH build ms | wide-8 layout ms | nearest-point tree ms |\n| --- | ---: | ---: | ---: | ---: |",
        rayon::current_num_threads()
    );
    for path in &paths {
        let mesh = TriangleMesh::load(path)?;
        let mut times = [vec![], vec![], vec![]];
        for round in 0..=runs {
            let start = Instant::now();
            let tree = BinnedSahBuilder::default().build(&mesh);
            let built = Instant::now();
            let layout = Wide8Layout::new(&tree, &mesh);
            let laid_out = Instant::now();
            let nearest = ClosestPointTree::new(&tree, &mesh);
            let done = Instant::now();
            std::hint::black_box((&layout, &nearest));
            if round > 0 {
                for (k, (from, to)) in [(start, built), (built, laid_out), (laid_out, done)]
                    .into_iter()
                    .enumerate()
                {
                    times[k].push((to - from).as_secs_f64() * 1e3);
                }
            }
        }
        let [build, layout, nearest] = times.map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        });
        let name = std::path::Path::new(path)
            .file_stem()
            .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        println!(
            "| {name} | {} | {build:.1} | {layout:.1} | {nearest:.1} |",
            mesh.triangle_count()
        );
    }
    Ok(())
}
