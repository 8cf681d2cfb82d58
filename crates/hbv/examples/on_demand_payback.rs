//! Where walking the builder's tree for nearest points stops paying: for each mesh, the time to
//! make the nearest-point search tree, and the cost per point of a walk of the binned SAH tree
//! (`BuildTreeSearch`) and of a search of that tree, both on all threads, for the points of
//! `bench/python_compare.py` (uniform in the mesh's box grown 10 % on each side); then the
//! break-even count of points (the search tree's making over the difference per point) against
//! `ClosestPointsOnDemand::payback`.
//!
//! ```text
//! cargo run --release -p hbv --example on_demand_payback -- MESH... [--points N] [--runs N]
//! ```
//!
//! Medians of `--runs` rounds (default 5); the search's cost per point is taken on a batch of
//! `--points` (default 65,536) after the tree is made, the walk's on the same batch.

use std::sync::Arc;
use std::time::Instant;

use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::proximity::{ClosestPointTree, ClosestPointsOnDemand, NearestPointSearch};
use hbv::TriangleMesh;
mod support;

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut paths, mut n, mut runs) = (Vec::new(), 65_536usize, 5usize);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--points" => n = args.next().ok_or("--points needs a number")?.parse()?,
            "--runs" => runs = args.next().ok_or("--runs needs a number")?.parse()?,
            _ => paths.push(arg),
        }
    }
    println!("| mesh | triangles | search tree ms | walk µs/point | search µs/point | break-even points | payback |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: |");
    for path in paths {
        let mesh = Arc::new(TriangleMesh::load(&path)?);
        let tree = Arc::new(BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh));
        let points = support::points_around(&mesh, n, 7);
        let (mut make, mut walk, mut search) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..runs {
            let start = Instant::now();
            let searched = ClosestPointTree::new(&tree, &mesh);
            make.push(start.elapsed().as_secs_f64());
            let start = Instant::now();
            let found = searched.closest_points(&points);
            search.push(start.elapsed().as_secs_f64() / n as f64);
            // Walks only: a limit no batch reaches.
            let walker =
                ClosestPointsOnDemand::with_walk_limit(tree.clone(), mesh.clone(), usize::MAX);
            let start = Instant::now();
            let walked = walker.closest_points(&points);
            walk.push(start.elapsed().as_secs_f64() / n as f64);
            assert!(walker.search_tree().is_none());
            assert_eq!(walked, found, "{path}: walks and searches disagree");
        }
        let (make, walk, search) = (median(make), median(walk), median(search));
        let name = std::path::Path::new(&path)
            .file_stem()
            .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        let break_even = if walk > search {
            format!("{:.0}", make / (walk - search))
        } else {
            "never (walks are faster)".to_string()
        };
        println!(
            "| {name} | {} | {:.1} | {:.2} | {:.2} | {break_even} | {} |",
            mesh.triangle_count(),
            make * 1e3,
            walk * 1e6,
            search * 1e6,
            ClosestPointsOnDemand::payback(mesh.triangle_count())
        );
    }
    Ok(())
}
