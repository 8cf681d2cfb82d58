//! Times `ClosestPointTree::closest_points` on a mesh file, one thread, the points of
//! `bench/python_compare.py` (uniform in the mesh's box grown 10 % on each side):
//! `cargo run --release -p hbv --example closest_point_timing -- MESH [POINTS] [ROUNDS] [LEAF_TRIANGLES] [aligned] [cells=N] [candidates=K] [margin=F] [listing=F]`
//! (`cells=0`: no candidate grid, batches sorted in Morton order as before it).
//! Prints the build time of the search tree and the median and best M queries/s.

use std::time::Instant;

use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::glam::DVec3;
use hbv::proximity::{CandidateGridConfig, ClosestPointTree, SearchTreeConfig};
use hbv::TriangleMesh;
use rand::{RngExt, SeedableRng};

fn main() {
    let mut grid = CandidateGridConfig::default();
    let all: Vec<String> = std::env::args().skip(1).collect();
    for arg in &all {
        match arg.split_once('=') {
            Some(("cells", n)) => grid.cells = n.parse().unwrap(),
            Some(("candidates", n)) => grid.max_candidates = n.parse().unwrap(),
            Some(("margin", f)) => grid.margin = f.parse().unwrap(),
            Some(("listing", f)) => grid.min_listing = f.parse().unwrap(),
            _ => {}
        }
    }
    let mut args = all.into_iter().filter(|a| !a.contains('='));
    let path = args
        .next()
        .expect("usage: closest_point_timing MESH [POINTS] [ROUNDS] [LEAF_TRIANGLES] [aligned]");
    let n: usize = args.next().map_or(65_536, |s| s.parse().unwrap());
    let rounds: usize = args.next().map_or(5, |s| s.parse().unwrap());
    let leaf: Option<usize> = args.next().map(|s| s.parse().unwrap());
    let mesh = TriangleMesh::load(&path).unwrap();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let start = Instant::now();
    let config = SearchTreeConfig {
        leaf_triangles: leaf.unwrap_or(SearchTreeConfig::default().leaf_triangles),
        rotated_frames: args.next().is_none_or(|s| s != "aligned"),
    };
    let search = ClosestPointTree::with_grid(&tree, &mesh, config, grid);
    let build = start.elapsed().as_secs_f64();
    let b = mesh.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let pad = 0.1 * (hi - lo);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let points: Vec<DVec3> = (0..n)
        .map(|_| {
            let k = DVec3::new(rng.random(), rng.random(), rng.random());
            (lo - pad + (hi - lo + 2.0 * pad) * k).as_vec3().as_dvec3()
        })
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut times = Vec::new();
    let mut checksum = 0.0;
    for _ in 0..rounds {
        let start = Instant::now();
        let found = pool.install(|| search.closest_points(&points));
        times.push(start.elapsed().as_secs_f64());
        checksum = found.iter().flatten().map(|c| c.distance).sum::<f64>();
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let (cells, listing, listed) = search.grid_summary();
    println!(
        "grid: {cells} cells, {listing} listing candidates ({:.2} each), the rest seeding a search",
        listed as f64 / listing.max(1) as f64
    );
    println!(
        "{path}: {} triangles, search tree {:.1} ms, {:.3} M queries/s (median of {rounds}), best {:.3}, checksum {checksum:.9e}",
        mesh.triangle_count(),
        build * 1e3,
        n as f64 / median / 1e6,
        n as f64 / times[0] / 1e6
    );
}
