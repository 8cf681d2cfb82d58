//! Times `ClosestPointTree::closest_points` on a mesh file, one thread, the points of
//! `bench/python_compare.py` (uniform in the mesh's box grown 10 % on each side):
//! `cargo run --release -p hbv --example closest_point_timing -- MESH [POINTS] [ROUNDS] [LEAF_TRIANGLES] [aligned] [cells=N] [candidates=K] [margin=F] [listing=F] [payback=F]`
//! (`cells=0`: no candidate grid, batches sorted in Morton order as before it; the grid is made
//! with the tree, inside the build time printed, unless `payback=F` says after how many points
//! per cell).
//! Prints the build time of the search tree and the median and best M queries/s. With `tally`,
//! also the search's nodes, packets and exact tests per query by distance band (share of the
//! mesh's box diagonal) and side (the nearest face's normal: outside or inside).

use std::time::Instant;

use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::glam::DVec3;
use hbv::proximity::{
    CandidateGridConfig, ClosestPointTree, NearestPointSearch, SearchTally, SearchTreeConfig,
};
use hbv::TriangleMesh;
mod support;

fn main() {
    let mut grid = CandidateGridConfig {
        payback: 0.0,
        ..CandidateGridConfig::default()
    };
    let mut all: Vec<String> = std::env::args().skip(1).collect();
    let tally = all.iter().any(|a| a == "tally");
    all.retain(|a| a != "tally");
    for arg in &all {
        match arg.split_once('=') {
            Some(("cells", n)) => grid.cells = n.parse().unwrap(),
            Some(("candidates", n)) => grid.max_candidates = n.parse().unwrap(),
            Some(("margin", f)) => grid.margin = f.parse().unwrap(),
            Some(("listing", f)) => grid.min_listing = f.parse().unwrap(),
            Some(("payback", f)) => grid.payback = f.parse().unwrap(),
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
    let points = support::points_around(&mesh, n, 7);
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
    if tally {
        print_tally(&search, &mesh, &points);
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

/// Nodes, packets and exact tests per query of the seeded batch search, by distance band and
/// side.
fn print_tally(search: &ClosestPointTree, mesh: &TriangleMesh, points: &[DVec3]) {
    let b = mesh.bounds();
    let diagonal = (b.max - b.min).length() as f64;
    let bands = [0.0, 0.005, 0.02, 0.05, 0.1, f64::INFINITY];
    // [band][side]: queries, nodes, packets, exact tests.
    let mut sums = vec![[[0u64; 4]; 2]; bands.len() - 1];
    let mut total = SearchTally::default();
    for (p, (found, t)) in points.iter().zip(search.closest_points_tallied(points)) {
        let Some(c) = found else { continue };
        let tri = mesh.triangle(c.prim as usize);
        let normal = (tri.p1 - tri.p0).cross(tri.p2 - tri.p0).as_dvec3();
        let side = ((*p - c.point).dot(normal) < 0.0) as usize;
        let share = c.distance / diagonal;
        let band = bands.windows(2).position(|w| share < w[1]).unwrap();
        let s = &mut sums[band][side];
        s[0] += 1;
        s[1] += t.nodes;
        s[2] += t.packets;
        s[3] += t.exact;
        total.nodes += t.nodes;
        total.packets += t.packets;
        total.exact += t.exact;
    }
    let n = points.len() as f64;
    println!(
        "per query: {:.1} nodes, {:.1} packets, {:.1} exact tests",
        total.nodes as f64 / n,
        total.packets as f64 / n,
        total.exact as f64 / n
    );
    // The floor of exact tests for a conservative search: triangles as near as the answer
    // (shared vertices and edges tie), on a sample.
    let sample = &points[..points.len().min(2048)];
    let mut tied = 0usize;
    for p in sample {
        let Some(best) = search.closest_point(*p) else {
            continue;
        };
        let d2 = best.distance * best.distance;
        tied += mesh
            .triangles()
            .filter(|t| !t.is_degenerate())
            .filter(|t| {
                let q = hbv::proximity::closest_point_on_triangle(
                    *p,
                    t.p0.as_dvec3(),
                    t.p1.as_dvec3(),
                    t.p2.as_dvec3(),
                );
                (*p - q.point).length_squared() <= d2 * (1.0 + 1e-9)
            })
            .count();
    }
    println!(
        "triangles as near as the answer (floor of exact tests): {:.2} per query",
        tied as f64 / sample.len() as f64
    );
    println!("band (distance / diagonal) | side | share of queries | nodes | packets | exact");
    for (band, by_side) in sums.iter().enumerate() {
        for (side, s) in by_side.iter().enumerate() {
            let q = s[0].max(1) as f64;
            println!(
                "[{:.3}, {:.3}) | {} | {:.1} % | {:.1} | {:.1} | {:.1}",
                bands[band],
                bands[band + 1],
                ["out", "in"][side],
                100.0 * s[0] as f64 / n,
                s[1] as f64 / q,
                s[2] as f64 / q,
                s[3] as f64 / q
            );
        }
    }
}
