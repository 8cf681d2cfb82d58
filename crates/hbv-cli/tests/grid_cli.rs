//! `--accel grid` of `hbv trace` and `hbv bench`, and `hbv experiment seed-claims`, from the
//! outside.

use std::process::Output;

mod common;
use common::{hbv, write_obj};

use glam::Vec3;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce, TriangleMesh};
use hbv_cli::{hit_file, ray_file};
use serde_json::Value;

fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Rays through the torus's box from a ring around it and from inside, some axis-aligned.
fn rays(mesh: &TriangleMesh) -> Vec<Ray> {
    let b = mesh.bounds();
    (0..1500)
        .map(|i| {
            let f = i as f32 / 1500.0;
            let target = b.min + b.extent() * Vec3::new(f, (7.0 * f).fract(), (3.0 * f).fract());
            match i % 3 {
                0 => {
                    let o = b.center() + 3.0 * Vec3::new((9.0 * f).cos(), 0.5, (9.0 * f).sin());
                    Ray::new(o, target - o)
                }
                1 => Ray::new(target, Vec3::new(0.3, -1.0, 0.2)),
                _ => Ray::new(target, Vec3::Z),
            }
        })
        .collect()
}

#[test]
fn trace_with_the_grid_equals_brute_force_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::new(0.5, -1.0, 2.0), 2.0, 0.7, 32, 16);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let mesh = TriangleMesh::load(&path).unwrap();
    let rays = rays(&mesh);
    let (rays_path, hits, occ) = (
        dir.path().join("rays.npz"),
        dir.path().join("hits.npz"),
        dir.path().join("occ.npz"),
    );
    ray_file::write_rays(&rays_path, &rays, hbv::atomic_file::Replace::Always).unwrap();
    let common = [
        "trace",
        path.to_str().unwrap(),
        "--rays",
        rays_path.to_str().unwrap(),
        "--accel",
        "grid",
    ];
    let out = ok(hbv(&[
        &common[..],
        &["--out", hits.to_str().unwrap(), "--json"],
    ]
    .concat()));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(report["accel"].as_str().unwrap().contains("grid"));
    ok(hbv(&[
        &common[..],
        &["--out", occ.to_str().unwrap(), "--occluded"],
    ]
    .concat()));

    let brute = BruteForce::new(&mesh);
    assert_eq!(
        hit_file::read_hits(&hits).unwrap(),
        brute.intersect_batch(&rays)
    );
    assert_eq!(
        hit_file::read_occlusion(&occ).unwrap(),
        brute.occluded_batch(&rays)
    );
}

#[test]
fn bench_measures_the_grid() {
    let out = ok(hbv(&[
        "bench", "--accel", "grid", "--rays", "2000", "--repeat", "1", "--json",
    ]));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    let layouts = report["layouts"].as_array().unwrap();
    assert_eq!(layouts.len(), 1);
    assert_eq!(layouts[0]["layout"], "grid");
    assert!(report["builder"].as_str().unwrap().contains("grid"));
    for m in report["results"].as_array().unwrap() {
        assert!(m["mrays_per_second"].as_f64().unwrap() > 0.0);
        assert!(m["triangles_per_ray"].as_f64().unwrap() > 0.0);
    }
}

#[test]
fn seed_claims_json_covers_every_structure_and_set_and_caches_agree() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("torus.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.7, 24, 12), &path);
    let out = ok(hbv(&[
        "experiment",
        "seed-claims",
        path.to_str().unwrap(),
        "--rays",
        "900",
        "--repeat",
        "1",
        "--json",
    ]));
    let reports: Value = serde_json::from_slice(&out.stdout).expect("--json prints JSON");
    let reports = reports.as_array().unwrap();
    assert_eq!(reports.len(), 1);
    let rows = reports[0]["rows"].as_array().unwrap();
    let structures = [
        "grid",
        "grid-no-mailbox",
        "recursive",
        "skip",
        "ordered",
        "wide4",
        "wide8",
    ];
    let sets = [
        "primary",
        "reflection",
        "diffuse",
        "shadow",
        "shadow-random",
    ];
    assert_eq!(rows.len(), structures.len() * sets.len());
    for set in sets {
        for s in structures {
            let row = rows
                .iter()
                .find(|r| r["set"] == set && r["structure"] == s)
                .unwrap_or_else(|| panic!("no row {set} {s}"));
            assert_eq!(row["mismatches"], 0, "{row}");
            assert!(row["mrays_per_second"].as_f64().unwrap() > 0.0);
        }
    }
    let grid = |set: &str, s: &str| {
        rows.iter()
            .find(|r| r["set"] == set && r["structure"] == s)
            .unwrap()
            .clone()
    };
    // Mailboxes save tests and change nothing else.
    let (with, without) = (grid("primary", "grid"), grid("primary", "grid-no-mailbox"));
    assert!(with["mailbox_skips_per_ray"].as_f64().unwrap() > 0.0);
    assert!(with["tests_per_ray"].as_f64() < without["tests_per_ray"].as_f64());
    assert_eq!(with["hit_fraction"], without["hit_fraction"]);
}

#[test]
fn seed_claims_on_a_missing_mesh_is_one_clear_line() {
    let out = hbv(&["experiment", "seed-claims", "no/such/mesh.ply"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("mesh.ply"), "{err}");
}
