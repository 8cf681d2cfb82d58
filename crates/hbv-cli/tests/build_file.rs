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

/// A glTF scene is saved as a `.hbv` scene file that answers as the glTF file loaded; with
/// `--flatten`, as one mesh of its world-space triangles.
#[test]
fn a_gltf_scene_is_saved_as_a_scene_file() {
    use glam::{DAffine3, DQuat, DVec3};
    use hbv::atomic_file::Replace;
    use hbv::bvh::file::BvhFileKind;
    use hbv::mesh::procedural::icosphere;
    use hbv::scene::{AnyBvhFile, InstanceTransform, Scene, SceneRay};

    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::new();
    let ring = scene.add_mesh(torus(Vec3::ZERO, 1.0, 0.3, 12, 6));
    let ball = scene.add_mesh(icosphere(Vec3::ZERO, 0.8, 2));
    for k in 0..5 {
        let f = k as f64;
        let placed = DAffine3::from_scale_rotation_translation(
            DVec3::new(if k % 2 == 0 { -1.0 } else { 1.0 }, 1.0 + 0.1 * f, 1.0),
            DQuat::from_rotation_y(0.4 * f),
            DVec3::new(3.0 * f - 6.0, 0.0, 0.0),
        );
        let mesh = if k % 3 == 0 { ball } else { ring };
        let t = InstanceTransform::new(placed).unwrap();
        scene.add_instance(mesh, t, u32::MAX).unwrap();
    }
    let glb = dir.path().join("field.glb");
    scene.write_gltf(&glb, Replace::Never).unwrap();
    let saved = dir.path().join("field.hbv");
    let out = hbv(&[
        "build",
        p(&glb),
        "-o",
        p(&saved),
        "--builder",
        "sweep-sah",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["meshes"], 2);
    assert_eq!(report["instances"], 5);
    assert_eq!(
        report["bytes"].as_u64().unwrap(),
        std::fs::metadata(&saved).unwrap().len()
    );
    assert!(report["builder_options"]
        .as_str()
        .unwrap()
        .starts_with("sweep-sah"));
    let AnyBvhFile::Scene(opened) = AnyBvhFile::load(&saved).unwrap() else {
        panic!("a scene file was expected");
    };
    opened.validate().unwrap();
    let loaded = Scene::load(&glb).unwrap();
    let mut hits = 0;
    for i in 0..300 {
        let a = i as f32 * 0.21;
        let origin = Vec3::new(a.sin() * 9.0, 4.0 * a.cos(), 5.0);
        let target = Vec3::new((i % 13) as f32 - 6.0, 0.2 * (a * 3.0).sin(), 0.0);
        let ray = SceneRay::new(Ray::new(origin, target - origin));
        assert_eq!(opened.intersect(&ray), loaded.intersect(&ray), "{ray:?}");
        hits += usize::from(opened.intersect(&ray).is_some());
    }
    assert!(hits > 30, "{hits}");

    // Flattened: one mesh file, every instance's triangles.
    let flat = dir.path().join("flat.hbv");
    let out = hbv(&["build", p(&glb), "-o", p(&flat), "--flatten"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let file = AnyBvhFile::load(&flat).unwrap();
    assert_eq!(file.kind(), BvhFileKind::Mesh);
    let AnyBvhFile::Mesh(mesh) = file else {
        unreachable!()
    };
    assert_eq!(
        mesh.mesh.triangle_count(),
        loaded.flattened().unwrap().mesh.triangle_count()
    );
    // And without --force it is never replaced.
    let out = hbv(&["build", p(&glb), "-o", p(&saved)]);
    assert!(
        stderr(&out).contains("exists: pass --force"),
        "{}",
        stderr(&out)
    );
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
