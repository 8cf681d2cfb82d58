//! Memory and time of building, laying out, saving and tracing a large generated scene: bytes
//! per triangle of each builder's tree and of each layout, and the process's peak memory.
//!
//! ```text
//! cargo run --release -p hbv --example large_scene -- [--detail D] [--builder NAME] [--rays N] [--save FILE.hbv]
//! ```
//!
//! The scene is the built-in one (`mesh::procedural::default_scene`) at detail `D` (about
//! `1,152 · D²` triangles beyond a few hundred thousand; 92 gives 10.3M). One builder per run (`insertion`, `binned-sah`,
//! `sweep-sah`, `median`, `lbvh`; default `binned-sah`), so that the peak resident memory after
//! building (Linux `VmHWM`) is that builder's. Then each layout in turn is made, measured, used to
//! trace `N` rays (default 1M, from random points of the scene's box in random directions) and
//! dropped. With `--save`, the tree is also written as a `.hbv` file and loaded back.

use std::time::Instant;

use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::bvh::file::BvhFile;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::bvh::BuildTree;
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::mesh::procedural::default_scene;
use hbv::Accelerator;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// A field of `/proc/self/status` in bytes (Linux), 0 elsewhere.
fn proc_status_bytes(field: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(field))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// Bytes held by a `BuildTree`: its nodes, and their child and triangle lists.
fn tree_bytes(tree: &BuildTree) -> usize {
    std::mem::size_of_val(tree.nodes()) + tree.nodes().iter().map(|n| 4 * n.arity()).sum::<usize>()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut detail, mut builder_name, mut ray_count, mut save) =
        (92u32, BuilderKind::BinnedSah, 1_000_000usize, None);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--detail" => detail = value()?.parse()?,
            "--builder" => builder_name = value()?.parse()?,
            "--rays" => ray_count = value()?.parse()?,
            "--save" => save = Some(value()?),
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }

    let start = Instant::now();
    let mesh = default_scene(detail);
    let n = mesh.triangle_count();
    let per = |bytes: usize| bytes as f64 / n as f64;
    let mesh_bytes = 12 * mesh.positions().len() + 12 * n;
    println!(
        "scene     detail {detail}: {n} triangles, {} vertices, {:.1} B/triangle, made in {:.1} s, RSS {:.2} GiB",
        mesh.positions().len(),
        per(mesh_bytes),
        start.elapsed().as_secs_f64(),
        proc_status_bytes("VmRSS:") as f64 / (1u64 << 30) as f64
    );

    let start = Instant::now();
    let tree = builder_name.build(&mesh, &BuilderOptions::default());
    let build_seconds = start.elapsed().as_secs_f64();
    let peak = proc_status_bytes("VmHWM:");
    println!(
        "build     {builder_name}: {build_seconds:.1} s, tree {:.1} B/triangle ({} nodes), peak RSS so far {:.2} GiB ({:.0} B/triangle)",
        per(tree_bytes(&tree)),
        tree.nodes().len(),
        peak as f64 / (1u64 << 30) as f64,
        peak as f64 / n as f64
    );

    if let Some(path) = save {
        let file = BvhFile {
            mesh: mesh.clone(),
            tree: tree.clone(),
            settings: format!("{builder_name} (large_scene example, detail {detail})"),
        };
        let start = Instant::now();
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        file.write_to(&mut out)?;
        drop(out);
        let write_seconds = start.elapsed().as_secs_f64();
        drop(file);
        let bytes = std::fs::metadata(&path)?.len();
        let start = Instant::now();
        let loaded = BvhFile::load(&path)?;
        let load_seconds = start.elapsed().as_secs_f64();
        assert_eq!(loaded.tree.nodes().len(), tree.nodes().len());
        println!(
            "file      {path}: {:.1} B/triangle, written in {write_seconds:.1} s, read back and checked in {load_seconds:.1} s",
            bytes as f64 / n as f64
        );
    }

    let mut rng = Pcg64Mcg::seed_from_u64(7);
    let b = mesh.bounds();
    let rays: Vec<Ray> = (0..ray_count)
        .map(|_| {
            let mut unit = || Vec3::new(rng.random(), rng.random(), rng.random());
            let origin = b.min + b.extent() * unit();
            Ray::new(origin, (unit() - 0.5).normalize_or(Vec3::X))
        })
        .collect();
    for name in LayoutKind::ALL {
        let start = Instant::now();
        let accel = name.lay_out(&tree, &mesh, &LayoutOptions::default());
        let bytes = accel.memory_bytes();
        let layout_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let hits = accel
            .intersect_batch(&rays)
            .iter()
            .filter(|h| h.is_some())
            .count();
        let trace_seconds = start.elapsed().as_secs_f64();
        println!(
            "layout    {name:<9}: {:.1} B/triangle, made in {layout_seconds:.1} s; {ray_count} rays in {trace_seconds:.2} s ({:.2} Mrays/s, {hits} hits); peak RSS so far {:.2} GiB",
            per(bytes),
            ray_count as f64 / trace_seconds / 1e6,
            proc_status_bytes("VmHWM:") as f64 / (1u64 << 30) as f64
        );
    }
    Ok(())
}
