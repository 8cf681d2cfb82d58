//! What the command-line tests share: running the `hbv` binary and writing meshes for it.
//! Each test file includes it (`mod common;`) and uses what it needs.

#![allow(dead_code)]

pub mod scenes;

use std::path::Path;
use std::process::{Command, Output};

use hbv::glam::Vec3;
use hbv::TriangleMesh;
use rand::RngExt;
use rand_pcg::Pcg64Mcg;

/// Runs the `hbv` binary built for these tests with `args`.
pub fn hbv(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hbv"))
        .args(args)
        .output()
        .expect("the hbv binary runs")
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Writes `mesh` as an OBJ file.
pub fn write_obj(mesh: &TriangleMesh, path: &Path) {
    let mut s = String::new();
    for p in mesh.positions() {
        s += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for [a, b, c] in mesh.indices() {
        s += &format!("f {} {} {}\n", a + 1, b + 1, c + 1);
    }
    std::fs::write(path, s).unwrap();
}

/// A point drawn uniformly from the box of corner `lo` and size `extent`.
pub fn point_in_box(rng: &mut Pcg64Mcg, lo: Vec3, extent: Vec3) -> Vec3 {
    lo + extent * Vec3::new(rng.random(), rng.random(), rng.random())
}

/// A direction drawn from the cube `[-1/2, 1/2]³`, normalized (`+x` if it is too short).
pub fn random_direction(rng: &mut Pcg64Mcg) -> Vec3 {
    (point_in_box(rng, Vec3::ZERO, Vec3::ONE) - 0.5).normalize_or(Vec3::X)
}

/// `hbv bench INPUT --json` on 1,500 rays per set, one timed run on one thread, with `flags`;
/// asserts success and returns the report.
pub fn small_bench(input: &Path, flags: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "bench",
        input.to_str().unwrap(),
        "--rays",
        "1500",
        "--repeat",
        "1",
        "--threads",
        "1",
        "--json",
    ];
    args.extend(flags);
    let out = hbv(&args);
    assert!(out.status.success(), "hbv {args:?}: {}", stderr(&out));
    serde_json::from_str(&stdout(&out)).unwrap()
}
