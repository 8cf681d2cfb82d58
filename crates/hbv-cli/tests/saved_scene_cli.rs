//! `hbv trace`, `info` and `bench` on saved scenes (`.hbv` scene files, `docs/BVH_FILE.md`): a
//! scene saved by `hbv build SCENE.glb` answers exactly as the glTF scene it was built from,
//! its removed instances stay holes, and options a saved scene cannot honour are refused.

use std::path::{Path, PathBuf};

mod common;
use common::scenes::{instanced_scene, rays_at};
use common::{hbv, small_bench, stderr, stdout};

use hbv::atomic_file::Replace;
use hbv::scene::{InstanceId, Scene, SceneRay};
use hbv_cli::{hit_file, ray_file};

/// Runs `hbv` with `args`, asserting success; returns stdout.
fn run(args: &[&str]) -> String {
    let out = hbv(args);
    assert!(out.status.success(), "hbv {args:?}: {}", stderr(&out));
    stdout(&out)
}

/// Runs `hbv` with `args`, asserting failure in one line; returns that line.
fn refused(args: &[&str]) -> String {
    let out = hbv(args);
    assert!(!out.status.success(), "hbv {args:?} succeeded");
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("hbv: error: "), "{err}");
    err
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The glTF scene and rays at it, written into `dir`: `(scene.glb, rays.npz)`.
fn inputs(dir: &Path) -> (PathBuf, PathBuf) {
    let scene = instanced_scene();
    let glb = dir.join("scene.glb");
    scene.write_gltf(&glb, Replace::Always).unwrap();
    let rays = dir.join("rays.npz");
    ray_file::write_rays(&rays, &rays_at(&scene, 2000, 11), Replace::Always).unwrap();
    (glb, rays)
}

/// `hbv trace INPUT` with `flags`, writing `out`; returns the bytes of the hit file.
fn trace_bytes(input: &Path, rays: &Path, out: &Path, flags: &[&str]) -> Vec<u8> {
    let mut args = vec![
        "trace",
        s(input),
        "--rays",
        s(rays),
        "--out",
        s(out),
        "--force",
    ];
    args.extend(flags);
    run(&args);
    std::fs::read(out).unwrap()
}

#[test]
fn a_saved_scene_traces_bit_for_bit_as_its_gltf_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, rays) = inputs(dir.path());
    let out = dir.path().join("hits.npz");
    for builder in [None, Some("sweep-sah"), Some("insertion")] {
        let saved = dir.path().join("scene.hbv");
        let mut build = vec!["build", s(&glb), "-o", s(&saved), "--force"];
        let builder_flags: Vec<&str> = builder.map_or(vec![], |b| vec!["--builder", b]);
        build.extend(&builder_flags);
        run(&build);
        for query in [
            &[][..],
            &["--occluded"],
            &["--one-by-one", "--threads", "1"],
        ] {
            let mut gltf_flags = builder_flags.clone();
            gltf_flags.extend(query);
            let want = trace_bytes(&glb, &rays, &out, &gltf_flags);
            let got = trace_bytes(&saved, &rays, &out, query);
            assert!(got == want, "{builder:?} {query:?}: the hit files differ");
        }
    }
    // A saved scene is told by its content, whatever its name.
    let saved = dir.path().join("scene.hbv");
    let renamed = dir.path().join("scene.bin");
    std::fs::copy(&saved, &renamed).unwrap();
    let want = trace_bytes(&saved, &rays, &out, &[]);
    assert!(trace_bytes(&renamed, &rays, &out, &[]) == want);
    let json: serde_json::Value = serde_json::from_str(&run(&[
        "trace",
        s(&renamed),
        "--rays",
        s(&rays),
        "--out",
        s(&out),
        "--force",
        "--json",
    ]))
    .unwrap();
    assert_eq!(json["instances"], 6, "{json}");
    assert!(json["accel"].as_str().unwrap().contains("saved"), "{json}");
}

#[test]
fn removed_instances_of_a_saved_scene_stay_holes() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = instanced_scene();
    scene.remove_instance(InstanceId(0)).unwrap();
    scene.remove_instance(InstanceId(3)).unwrap();
    scene.set_mask(InstanceId(1), 0b10).unwrap();
    let saved = dir.path().join("holes.hbv");
    scene.save(&saved, Replace::Never).unwrap();
    let rays = rays_at(&instanced_scene(), 2000, 12);
    let rays_path = dir.path().join("rays.npz");
    ray_file::write_rays(&rays_path, &rays, Replace::Always).unwrap();
    let out = dir.path().join("hits.npz");
    trace_bytes(&saved, &rays_path, &out, &[]);
    let got = hit_file::read_scene_hits(&out).unwrap();
    let scene_rays: Vec<SceneRay> = rays.iter().map(|&r| SceneRay::from(r)).collect();
    assert_eq!(got, scene.intersect_batch(&scene_rays));
    let seen: Vec<u32> = got.iter().flatten().map(|h| h.instance).collect();
    assert!(!seen.contains(&0) && !seen.contains(&3));
    assert!(seen.contains(&5), "the ids after a hole keep their meaning");
    trace_bytes(&saved, &rays_path, &out, &["--occluded"]);
    assert_eq!(
        hit_file::read_occlusion(&out).unwrap(),
        scene.occluded_batch(&scene_rays)
    );
    // The opened scene reports what the saved one held.
    let info: serde_json::Value =
        serde_json::from_str(&run(&["info", s(&saved), "--json"])).unwrap();
    assert_eq!(info["instances"], 4, "{info}");
    assert_eq!(info["instance_ids"], 6, "{info}");
}

#[test]
fn info_and_bench_report_a_saved_scene_as_its_gltf_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, _) = inputs(dir.path());
    let saved = dir.path().join("scene.hbv");
    run(&["build", s(&glb), "-o", s(&saved)]);
    let info = |args: &[&str]| -> serde_json::Value {
        serde_json::from_str(&run(&[&["info"], args, &["--json"]].concat())).unwrap()
    };
    let want = info(&[s(&glb), "--builder", "binned-sah"]);
    let got = info(&[s(&saved)]);
    for key in [
        "meshes",
        "instances",
        "instance_ids",
        "triangles_stored",
        "triangles_seen",
        "bounds",
        "top_level_expected_tests",
        "memory_bytes",
    ] {
        assert_eq!(got[key], want[key], "{key}");
    }
    assert!(run(&["info", s(&saved)]).contains("saved tree"));

    let want = small_bench(&glb, &["--layout", "wide8"]);
    let got = small_bench(&saved, &[]);
    assert_eq!(got["scene"], want["scene"]);
    assert_eq!(got["layouts"].as_array().unwrap().len(), 1);
    assert_eq!(got["layouts"][0]["layout"], "saved");
    let (got, want) = (
        got["results"].as_array().unwrap(),
        want["results"].as_array().unwrap(),
    );
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        // The same rays, the same trees: the same answers and the same work counted.
        for key in [
            "ray_set",
            "query",
            "hit_fraction",
            "nodes_per_ray",
            "boxes_per_ray",
            "triangles_per_ray",
            "counted_rays",
        ] {
            assert_eq!(g[key], w[key], "{key}: {g} vs {w}");
        }
        assert!(g["triangles_per_ray"].as_f64().unwrap() > 0.0, "{g}");
    }
}

#[test]
fn options_a_saved_scene_cannot_honour_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, rays) = inputs(dir.path());
    let saved = dir.path().join("scene.hbv");
    run(&["build", s(&glb), "-o", s(&saved)]);
    let out = dir.path().join("hits.npz");
    let trace = ["trace", s(&saved), "--rays", s(&rays), "--out", s(&out)];
    for (flags, named) in [
        (&["--layout", "skip"][..], "--layout"),
        (&["--no-packets"], "--no-packets"),
        (&["--builder", "sweep-sah"], "--builder"),
        (&["--leaf-size", "2"], "--leaf-size"),
        (&["--accel", "grid"], "--accel grid"),
    ] {
        let err = refused(&[&trace[..], flags].concat());
        assert!(err.contains(s(&saved)) && err.contains(named), "{err}");
    }
    assert!(!out.exists());
    let err = refused(&["bench", s(&saved), "--layout", "wide8"]);
    assert!(err.contains(s(&saved)) && err.contains("--layout"), "{err}");
    let err = refused(&["info", s(&saved), "--optimize"]);
    assert!(err.contains("holds a saved scene"), "{err}");

    // A damaged scene file: one line naming the file and what is wrong.
    let bytes = std::fs::read(&saved).unwrap();
    let damaged = dir.path().join("damaged.hbv");
    std::fs::write(&damaged, &bytes[..bytes.len() - 9]).unwrap();
    for command in [&trace[..1], &["info"], &["bench"]] {
        let mut args = command.to_vec();
        args.push(s(&damaged));
        if command[0] == "trace" {
            args.extend(["--rays", s(&rays), "--out", s(&out)]);
        }
        let err = refused(&args);
        assert!(
            err.contains(s(&damaged)) && err.contains("truncated"),
            "{err}"
        );
    }
}

#[test]
fn commands_that_take_a_mesh_take_a_saved_scene_flattened() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, _) = inputs(dir.path());
    let saved = dir.path().join("scene.hbv");
    run(&["build", s(&glb), "-o", s(&saved)]);
    let flat = dir.path().join("flat.hbv");
    run(&["build", s(&saved), "-o", s(&flat)]);
    let info: serde_json::Value =
        serde_json::from_str(&run(&["info", s(&flat), "--json"])).unwrap();
    let scene = Scene::load(&glb).unwrap();
    assert_eq!(info["triangles"], scene.summary().triangles_seen);
}
