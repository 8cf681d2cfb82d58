//! `hbv experiment dynamic`: what keeping a tree live costs, and what it does to the tree.
//!
//! Starting from the insertion builder's tree (shuffled order, leaf size 1), a fraction of the
//! triangles is either removed and reinserted (`reinsert`), or displaced by a random offset and
//! refitted (`move`); the tree's E\[X\] and SAH cost are then compared with a fresh build over
//! the same triangles, before and after a reinsertion pass (Bittner et al. 2013).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use hbv::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder};
use hbv::bvh::dynamic::{DynamicBvh, DynamicConfig};
use hbv::bvh::optimize::ReinsertionConfig;
use hbv::bvh::{expected_tests, sah_cost, BuildTree, SahWeights};
use hbv::glam::Vec3;
use hbv::TriangleMesh;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use crate::commands::build_args::load_mesh;
use crate::commands::flag_values::{displacement, seed};

#[derive(Args)]
pub struct DynamicArgs {
    /// Mesh file (.obj, .ply, .gltf, .glb, .hbv); the built-in scene when omitted.
    pub mesh: Option<PathBuf>,
    /// Largest displacement of a moved triangle, as a fraction of the scene's diagonal (0 to 10).
    #[arg(long, default_value_t = 0.05, value_parser = displacement)]
    pub displacement: f32,
    /// Seed of the choice of triangles and of their displacements.
    #[arg(long, default_value_t = 0x5eed, value_parser = seed)]
    pub seed: u64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Cost E[X] and SAH of a tree.
#[derive(Clone, Copy, Serialize)]
struct Quality {
    expected_tests: f64,
    sah: f64,
}

impl Quality {
    fn of(tree: &BuildTree) -> Self {
        Self {
            expected_tests: expected_tests(tree),
            sah: sah_cost(tree, SahWeights::default()),
        }
    }
}

/// One row: a change to a fraction of the triangles, its cost and the tree after it.
#[derive(Serialize)]
struct Row {
    /// `reinsert` (removed, inserted again), `move` (displaced, refitted) or `move+ins`
    /// (displaced, each taken out and inserted again: `DynamicBvh::reinsert_moved`).
    change: &'static str,
    fraction: f64,
    triangles_changed: usize,
    /// Microseconds per triangle of remove, insert, and move + refit or move + reinsert (0
    /// where not done).
    remove_us: f64,
    insert_us: f64,
    update_us: f64,
    after: Quality,
    optimize_seconds: f64,
    after_optimize: Quality,
    fresh_insertion: Quality,
    fresh_binned_sah: Quality,
}

pub fn run(args: &DynamicArgs) -> anyhow::Result<()> {
    let (mesh, name, _) = load_mesh(args.mesh.as_deref())?;
    let start = Instant::now();
    let initial = InsertionBuilder::default().build(&mesh);
    let build_seconds = start.elapsed().as_secs_f64();
    let initial_quality = Quality::of(&initial);
    let fresh_binned = Quality::of(&BinnedSahBuilder::default().build(&mesh));
    let live: Vec<u32> = (0..mesh.triangle_count() as u32)
        .filter(|&p| !mesh.triangle(p as usize).is_degenerate())
        .collect();
    let diagonal = mesh.bounds().extent().length();

    let mut rows = Vec::new();
    for fraction in [0.1, 0.5, 1.0] {
        let mut rng = Pcg64Mcg::seed_from_u64(args.seed);
        let mut chosen = live.clone();
        chosen.shuffle(&mut rng);
        chosen.truncate((fraction * live.len() as f64).round() as usize);

        rows.push(reinsert(
            &mesh,
            &initial,
            &chosen,
            fraction,
            initial_quality,
            fresh_binned,
        )?);
        for update in [Update::Refit, Update::Reinsert] {
            let mut rng = Pcg64Mcg::seed_from_u64(args.seed ^ 1);
            let reach = args.displacement * diagonal;
            rows.push(displace(
                &mesh, &initial, &chosen, fraction, reach, update, &mut rng,
            )?);
        }
    }

    if args.json {
        let out = serde_json::json!({
            "mesh": name,
            "triangles": mesh.triangle_count(),
            "build_seconds": build_seconds,
            "initial": initial_quality,
            "displacement": args.displacement,
            "rows": rows,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("mesh     {name} ({} triangles)", mesh.triangle_count());
    println!(
        "start    insertion builder (shuffled), {build_seconds:.2} s: E[X] {:.2}, SAH {:.2}",
        initial_quality.expected_tests, initial_quality.sah
    );
    println!(
        "{:<9} {:>5} {:>9} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8}",
        "change",
        "%",
        "remove µs",
        "insert µs",
        "update µs",
        "E[X]",
        "SAH",
        "E[X] opt",
        "SAH opt",
        "opt s",
        "fresh EX",
        "fresh SAH"
    );
    for r in &rows {
        println!(
            "{:<9} {:>5.0} {:>9.2} {:>9.2} {:>9.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>7.2} {:>8.2} {:>8.2}",
            r.change,
            r.fraction * 100.0,
            r.remove_us,
            r.insert_us,
            r.update_us,
            r.after.expected_tests,
            r.after.sah,
            r.after_optimize.expected_tests,
            r.after_optimize.sah,
            r.optimize_seconds,
            r.fresh_insertion.expected_tests,
            r.fresh_insertion.sah,
        );
    }
    println!(
        "(µs per triangle changed; opt: after a reinsertion pass; fresh: the insertion builder \
         over the same triangles; --json adds the binned SAH builder's)"
    );
    Ok(())
}

fn micros_per(seconds: f64, count: usize) -> f64 {
    seconds * 1e6 / count.max(1) as f64
}

/// Runs a reinsertion pass on `bvh`: its time and the quality after.
fn optimized(bvh: &mut DynamicBvh) -> (f64, Quality) {
    let start = Instant::now();
    bvh.optimize(ReinsertionConfig::default());
    (start.elapsed().as_secs_f64(), Quality::of(bvh.tree()))
}

/// Removes `chosen`, then inserts the same triangles back in the same (random) order: they get
/// the freed ids, smallest first.
fn reinsert(
    mesh: &TriangleMesh,
    initial: &BuildTree,
    chosen: &[u32],
    fraction: f64,
    fresh_insertion: Quality,
    fresh_binned_sah: Quality,
) -> anyhow::Result<Row> {
    let mut bvh = DynamicBvh::from_tree(mesh, initial.clone(), DynamicConfig::default());
    let triangles: Vec<[Vec3; 3]> = chosen
        .iter()
        .map(|&p| {
            let t = mesh.triangle(p as usize);
            [t.p0, t.p1, t.p2]
        })
        .collect();
    let start = Instant::now();
    bvh.remove(chosen)?;
    let remove = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let ids = bvh.insert(&triangles)?;
    let insert = start.elapsed().as_secs_f64();
    debug_assert_eq!(ids.len(), chosen.len());
    let after = Quality::of(bvh.tree());
    let (optimize_seconds, after_optimize) = optimized(&mut bvh);
    Ok(Row {
        change: "reinsert",
        fraction,
        triangles_changed: chosen.len(),
        remove_us: micros_per(remove, chosen.len()),
        insert_us: micros_per(insert, chosen.len()),
        update_us: 0.0,
        after,
        optimize_seconds,
        after_optimize,
        fresh_insertion,
        fresh_binned_sah,
    })
}

/// How a move reaches the tree.
#[derive(Clone, Copy)]
enum Update {
    /// `DynamicBvh::refit`: the topology is kept, the boxes follow.
    Refit,
    /// `DynamicBvh::reinsert_moved`: each moved triangle is placed again.
    Reinsert,
}

/// Moves each of `chosen` by a random offset of length up to `reach`, then updates the tree.
fn displace(
    mesh: &TriangleMesh,
    initial: &BuildTree,
    chosen: &[u32],
    fraction: f64,
    reach: f32,
    update: Update,
    rng: &mut Pcg64Mcg,
) -> anyhow::Result<Row> {
    let mut bvh = DynamicBvh::from_tree(mesh, initial.clone(), DynamicConfig::default());
    let moves: Vec<(u32, [Vec3; 3])> = chosen
        .iter()
        .map(|&p| {
            let dir = Vec3::new(
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
            )
            .normalize_or(Vec3::X);
            let offset = dir * reach * rng.random::<f32>();
            let t = mesh.triangle(p as usize);
            (p, [t.p0 + offset, t.p1 + offset, t.p2 + offset])
        })
        .collect();
    let start = Instant::now();
    for &(p, t) in &moves {
        // A mesh near the limits of f32 can leave them when moved: say so, rather than blame
        // the mesh's triangle alone.
        bvh.set_triangle(p, t).with_context(|| {
            format!("moving triangle {p} by up to {reach} (--displacement) leaves f32's range")
        })?;
    }
    match update {
        Update::Refit => bvh.refit(),
        Update::Reinsert => bvh.reinsert_moved(),
    }
    let refit = start.elapsed().as_secs_f64();
    let after = Quality::of(bvh.tree());
    let (optimize_seconds, after_optimize) = optimized(&mut bvh);
    let moved = bvh.mesh();
    Ok(Row {
        change: match update {
            Update::Refit => "move",
            Update::Reinsert => "move+ins",
        },
        fraction,
        triangles_changed: chosen.len(),
        remove_us: 0.0,
        insert_us: 0.0,
        update_us: micros_per(refit, chosen.len()),
        after,
        optimize_seconds,
        after_optimize,
        fresh_insertion: Quality::of(&InsertionBuilder::default().build(&moved)),
        fresh_binned_sah: Quality::of(&BinnedSahBuilder::default().build(&moved)),
    })
}
