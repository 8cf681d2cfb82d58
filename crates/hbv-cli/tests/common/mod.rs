//! What the command-line tests share: running the `hbv` binary and writing meshes for it.
//! Each test file includes it (`mod common;`) and uses what it needs.

#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use hbv::TriangleMesh;

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
