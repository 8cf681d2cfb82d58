//! `hbv build` and `.hbv` files as input of `info` and `trace`.

use std::path::Path;

mod common;
use common::{hbv, stderr, write_obj};

use glam::Vec3;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce};
use hbv_cli::{hit_file, ray_file};

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn a_saved_tree_traces_like_brute_force_and_info_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.6, 20, 10);
    let obj = dir.path().join("torus.obj");
    write_obj(&mesh, &obj);
    // Saved under a name that does not say .hbv: the magic number decides.
    let saved = dir.path().join("torus.tree");
    let out = hbv(&[
        "build",
        p(&obj),
        "-o",
        p(&saved),
        "--builder",
        "insertion",
        "--optimize",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        report["bytes"].as_u64().unwrap(),
        std::fs::metadata(&saved).unwrap().len()
    );

    let out = hbv(&["info", p(&saved), "--builder", "lbvh"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("holds a saved tree: --builder"),
        "{}",
        stderr(&out)
    );
    let out = hbv(&["info", p(&saved), "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(info["builder"], "saved");
    assert!(info["builder_options"]
        .as_str()
        .unwrap()
        .contains("insertion (order shuffle"));
    assert_eq!(info["expected_tests"], report["expected_tests"]);
    assert_eq!(info["triangles"], mesh.triangle_count());

    let rays: Vec<Ray> = (0..400)
        .map(|i| {
            let a = i as f32 * 0.37;
            Ray::new(
                Vec3::new(a.cos() * 5.0, (a * 0.3).sin(), a.sin() * 5.0),
                -Vec3::new(a.cos(), 0.1, a.sin()),
            )
        })
        .collect();
    let rays_path = dir.path().join("rays.npz");
    ray_file::write_rays(&rays_path, &rays, hbv::atomic_file::Replace::Always).unwrap();
    let hits_path = dir.path().join("hits.npz");
    let out = hbv(&[
        "trace",
        p(&saved),
        "--rays",
        p(&rays_path),
        "--out",
        p(&hits_path),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let got = hit_file::read_hits(&hits_path).unwrap();
    let want = BruteForce::new(&mesh).intersect_batch(&rays);
    assert_eq!(
        got.iter().filter(|h| h.is_some()).count(),
        want.iter().filter(|h| h.is_some()).count()
    );
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.map(|h| (h.t, h.prim)), w.map(|h| (h.t, h.prim)));
    }
}

#[test]
fn build_never_replaces_a_file_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("scene.hbv");
    std::fs::write(&out_path, "keep me").unwrap();
    let obj = dir.path().join("t.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.6, 8, 4), &obj);
    let out = hbv(&["build", p(&obj), "-o", p(&out_path)]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("exists: pass --force to replace it"),
        "{}",
        stderr(&out)
    );
    assert_eq!(std::fs::read_to_string(&out_path).unwrap(), "keep me");
    let out = hbv(&["build", p(&obj), "-o", p(&out_path), "--force"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(hbv::bvh::file::is_bvh_file(&out_path));
    // An output folder that does not exist: one line, nothing written.
    let out = hbv(&[
        "build",
        p(&obj),
        "-o",
        p(&dir.path().join("no/such/dir/x.hbv")),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("does not exist"), "{}", stderr(&out));
}

#[test]
fn a_damaged_tree_file_is_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("t.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.6, 8, 4), &obj);
    let saved = dir.path().join("t.hbv");
    assert!(hbv(&["build", p(&obj), "-o", p(&saved)]).status.success());
    let bytes = std::fs::read(&saved).unwrap();
    let cut = dir.path().join("cut.hbv");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = hbv(&["info", p(&cut)]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("hbv: error: cannot load tree: "), "{err}");
    assert!(err.contains("cut.hbv: the file is truncated"), "{err}");
    // An empty or foreign file named .hbv is not mistaken for a mesh of unknown format.
    for (name, bytes) in [("empty.hbv", &b""[..]), ("text.hbv", &b"v 0 0 0\n"[..])] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = stderr(&hbv(&["info", p(&path)]));
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains(&format!("{name}: not an hbv BVH file")),
            "{err}"
        );
    }
}

#[test]
fn the_dynamic_experiment_reports_every_fraction_against_a_fresh_build() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("t.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.6, 24, 12), &obj);
    let out = hbv(&["experiment", "dynamic", p(&obj), "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 9);
    for row in rows {
        for key in [
            "after",
            "after_optimize",
            "fresh_insertion",
            "fresh_binned_sah",
        ] {
            assert!(row[key]["expected_tests"].as_f64().unwrap() >= 1.0, "{row}");
            assert!(row[key]["sah"].as_f64().unwrap() > 0.0, "{row}");
        }
        // A reinsertion pass never makes the tree worse.
        assert!(
            row["after_optimize"]["expected_tests"].as_f64().unwrap()
                <= row["after"]["expected_tests"].as_f64().unwrap() + 1e-9
        );
    }
    assert_eq!(rows[7]["change"], "move");
    assert_eq!(rows[8]["change"], "move+ins");
    assert_eq!(rows[8]["triangles_changed"], 24 * 12 * 2);
}
