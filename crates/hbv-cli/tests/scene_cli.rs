//! `hbv trace` and `hbv info` on glTF scenes (docs/RAYS.md, "Scenes (glTF)"): answers equal to
//! `Scene::intersect` ray by ray and to a brute force over the flattened scene; bad scene files
//! refused in one line; mesh hit files carrying `instance` and `normal` too.

use std::path::Path;

mod common;
use common::scenes::{instanced_scene, rays_at};
use common::{hbv, small_bench, stderr, stdout, write_obj};

use glam::{DVec3, Vec3};
use hbv::atomic_file::Replace;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::scene::{InstanceTransform, Scene, SceneHit, SceneRay};
use hbv_cli::{hit_file, ray_file};

/// Runs `hbv` with `args`, asserting success; returns stdout.
fn run(args: &[&str]) -> String {
    let out = hbv(args);
    assert!(out.status.success(), "hbv {args:?}: {}", stderr(&out));
    stdout(&out)
}

/// Writes `scene` as `NAME.glb` and `rays` as `rays.npz` into `dir`; returns both paths.
fn write_inputs(dir: &Path, scene: &Scene, rays: &[Ray]) -> (String, String) {
    let scene_path = dir.join("scene.glb");
    scene.write_gltf(&scene_path, Replace::Always).unwrap();
    let rays_path = dir.join("rays.npz");
    ray_file::write_rays(&rays_path, rays, Replace::Always).unwrap();
    (
        scene_path.to_str().unwrap().to_owned(),
        rays_path.to_str().unwrap().to_owned(),
    )
}

#[test]
fn trace_answers_as_the_scene_and_the_flattened_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let rays = rays_at(&instanced_scene(), 3000, 7);
    let (scene_path, rays_path) = write_inputs(dir.path(), &instanced_scene(), &rays);
    // The scene as the file gives it (its transforms as glTF holds them), built as `hbv trace`
    // builds it by default: binned SAH, wide-8 nodes.
    let scene = Scene::load(&scene_path).unwrap();
    let scene_rays: Vec<SceneRay> = rays.iter().map(|&r| SceneRay::from(r)).collect();
    let want = scene.intersect_batch(&scene_rays);
    let hits_path = dir.path().join("hits.npz");
    let hits = hits_path.to_str().unwrap();
    run(&["trace", &scene_path, "--rays", &rays_path, "--out", hits]);
    let got = hit_file::read_scene_hits(&hits_path).unwrap();
    assert_eq!(got, want, "hbv trace and Scene::intersect, ray by ray");
    let hit_count = got.iter().flatten().count();
    assert!(hit_count > rays.len() / 3, "{hit_count} hits");
    // Every instance answers, mirrored and scaled ones included.
    for instance in 0..scene.instance_count() as u32 {
        assert!(got.iter().flatten().any(|h| h.instance == instance));
    }

    // The brute force over the flattened world triangles agrees within the transforms'
    // rounding: the same triangle (or a tie at the same t), t and the normal to f32 precision.
    let flat = scene.flattened().unwrap();
    for (i, (g, ray)) in got.iter().zip(&scene_rays).enumerate() {
        let w = flat.intersect(ray);
        match (g, &w) {
            (None, None) => {}
            (Some(g), Some(w)) => {
                assert!(
                    (g.t - w.t).abs() <= 1e-5 * w.t.abs().max(1.0),
                    "ray {i}: t {} vs {}",
                    g.t,
                    w.t
                );
                if (g.instance, g.prim) == (w.instance, w.prim) {
                    assert!(
                        (g.normal - w.normal).length() < 1e-5,
                        "ray {i}: normal {} vs {}",
                        g.normal,
                        w.normal
                    );
                }
                assert!((g.normal.length() - 1.0).abs() < 1e-6, "ray {i}");
            }
            _ => panic!("ray {i} {ray:?}: hbv trace {g:?}, brute force {w:?}"),
        }
    }

    // Any hit: as the scene's, and as the brute force's.
    let occ_path = dir.path().join("occluded.npz");
    let occ = occ_path.to_str().unwrap();
    run(&[
        "trace",
        &scene_path,
        "--rays",
        &rays_path,
        "--out",
        occ,
        "--occluded",
    ]);
    let occluded = hit_file::read_occlusion(&occ_path).unwrap();
    assert_eq!(occluded, scene.occluded_batch(&scene_rays));
    let brute: Vec<bool> = scene_rays.iter().map(|r| flat.occluded(r)).collect();
    assert_eq!(occluded, brute);

    // One thread, one call per ray, no packets: the same answers.
    let other_path = dir.path().join("other.npz");
    let other = other_path.to_str().unwrap();
    for flags in [
        &["--threads", "1"][..],
        &["--one-by-one"],
        &["--no-packets", "--threads", "3"],
    ] {
        let mut args = vec!["trace", &scene_path, "--rays", &rays_path, "--out", other];
        args.extend(flags);
        args.push("--force");
        run(&args);
        assert_eq!(
            hit_file::read_scene_hits(&other_path).unwrap(),
            got,
            "{flags:?}"
        );
        args.push("--occluded");
        run(&args);
        assert_eq!(
            hit_file::read_occlusion(&other_path).unwrap(),
            occluded,
            "{flags:?}"
        );
    }

    // Other builders and layouts: the same hits, up to ties between triangles at equal t.
    for flags in [
        &["--builder", "sweep-sah", "--layout", "skip"][..],
        &[
            "--builder",
            "insertion",
            "--leaf-size",
            "4",
            "--layout",
            "wide4",
        ],
    ] {
        let mut args = vec!["trace", &scene_path, "--rays", &rays_path, "--out", other];
        args.extend(flags);
        args.push("--force");
        run(&args);
        let answers = hit_file::read_scene_hits(&other_path).unwrap();
        for (i, (a, g)) in answers.iter().zip(&got).enumerate() {
            match (a, g) {
                (None, None) => {}
                (Some(a), Some(g)) => assert!(
                    (a.instance, a.prim) == (g.instance, g.prim) || a.t == g.t,
                    "{flags:?} ray {i}: {a:?} vs {g:?}"
                ),
                _ => panic!("{flags:?} ray {i}: {a:?} vs {g:?}"),
            }
        }
    }
}

#[test]
fn trace_json_reports_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = instanced_scene();
    let rays = rays_at(&scene, 300, 3);
    let (scene_path, rays_path) = write_inputs(dir.path(), &scene, &rays);
    let out_path = dir.path().join("hits.npz");
    let text = run(&[
        "trace",
        &scene_path,
        "--rays",
        &rays_path,
        "--out",
        out_path.to_str().unwrap(),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let summary = scene.summary();
    assert_eq!(json["meshes"], 2);
    assert_eq!(json["instances"], summary.live_instances);
    assert_eq!(json["triangles"], summary.triangles_stored);
    assert_eq!(json["triangles_seen"], summary.triangles_seen);
    assert_eq!(json["rays"], rays.len());
}

#[test]
fn info_reports_meshes_instances_triangles_and_costs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = instanced_scene();
    let (scene_path, _) = write_inputs(dir.path(), &scene, &[]);
    let summary = scene.summary();
    let text = run(&["info", &scene_path, "--builder", "binned-sah"]);
    for expected in [
        "meshes      2 ".to_string(),
        format!("{} triangles stored", summary.triangles_stored),
        format!("instances   {} ", summary.live_instances),
        format!("{} triangles seen", summary.triangles_seen),
        "E[X] top".into(),
        "E[X] mesh 0".into(),
        "E[X] mesh 1".into(),
        "memory".into(),
    ] {
        assert!(text.contains(&expected), "{expected:?} in\n{text}");
    }

    let text = run(&["info", &scene_path, "--builder", "binned-sah", "--json"]);
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let loaded = Scene::load(&scene_path).unwrap();
    let costs = loaded.mesh_expected_tests();
    let loaded = loaded.summary();
    assert_eq!(json["instances"], loaded.live_instances);
    assert_eq!(json["triangles_stored"], loaded.triangles_stored);
    assert_eq!(json["triangles_seen"], loaded.triangles_seen);
    assert_eq!(json["memory_bytes"], loaded.memory_bytes());
    assert_eq!(
        json["top_level_expected_tests"].as_f64().unwrap() as f32,
        loaded.top_level_expected_tests
    );
    let meshes = json["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 2);
    for (m, cost) in meshes.iter().zip(costs) {
        assert_eq!(m["expected_tests"].as_f64().unwrap(), cost);
    }
    assert_eq!(meshes[0]["instances"], 4);
    assert_eq!(meshes[1]["instances"], 2);
}

/// The JSON of a `.gltf` file of one triangle (non-indexed, its positions in `tri.bin`, see
/// [`write_triangle_buffer`]) placed by one node whose transform is `node` (JSON members).
fn one_triangle_gltf(node: &str) -> String {
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0 {node}}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "buffers": [{{"byteLength": 36, "uri": "tri.bin"}}],
            "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 1, 0]}}]}}"#
    )
}

/// Writes `tri.bin` into `dir`: the corners (0, 0, 0), (1, 0, 0), (0, 1, 0) as float32.
fn write_triangle_buffer(dir: &Path) {
    let bin: Vec<u8> = [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    std::fs::write(dir.join("tri.bin"), bin).unwrap();
}

#[test]
fn bad_scene_files_are_one_line_naming_the_file_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let rays = [Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)];
    let rays_path = dir.path().join("rays.npz");
    ray_file::write_rays(&rays_path, &rays, Replace::Always).unwrap();
    let good = instanced_scene().to_glb();
    // The one-triangle file is good as it is: the ray hits it.
    write_triangle_buffer(dir.path());
    let plain = dir.path().join("plain.gltf");
    std::fs::write(&plain, one_triangle_gltf("")).unwrap();
    let out = dir.path().join("hits.npz");
    run(&[
        "trace",
        plain.to_str().unwrap(),
        "--rays",
        rays_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let hits = hit_file::read_scene_hits(&out).unwrap();
    assert_eq!(hits[0].map(|h| (h.instance, h.prim)), Some((0, 0)));
    assert_eq!(hits[0].unwrap().normal, Vec3::Z);
    std::fs::remove_file(&out).unwrap();

    let cases: [(&str, Vec<u8>, &[&str]); 5] = [
        (
            "cut.glb",
            good[..good.len() / 2].to_vec(),
            &["cut.glb", "not valid glTF"],
        ),
        ("empty.glb", Vec::new(), &["empty.glb"]),
        (
            "flat.gltf",
            one_triangle_gltf(r#", "scale": [1, 0, 1]"#).into_bytes(),
            &["flat.gltf", "node 0", "singular"],
        ),
        (
            "huge.gltf",
            one_triangle_gltf(r#", "translation": [1e39, 0, 0]"#).into_bytes(),
            &["huge.gltf", "node 0", "not finite"],
        ),
        (
            "no_triangles.gltf",
            br#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{}]}"#.to_vec(),
            &["no_triangles.gltf", "no triangles"],
        ),
    ];
    for (name, bytes, reasons) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let p = path.to_str().unwrap();
        for command in [
            &[
                "trace",
                p,
                "--rays",
                rays_path.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ][..],
            &["info", p],
        ] {
            let result = hbv(command);
            assert!(!result.status.success(), "{name}: {command:?} succeeded");
            let message = stderr(&result);
            assert_eq!(message.lines().count(), 1, "{name}: {message}");
            assert!(
                message.starts_with("hbv: error: cannot load scene: "),
                "{message}"
            );
            for reason in reasons {
                assert!(message.contains(reason), "{name}: {reason:?} in {message}");
            }
            assert!(!message.contains("panicked") && !message.contains("internal error"));
            assert!(!out.exists(), "{name}: a hit file was written");
        }
    }
    // Nothing but the inputs is left behind (no temporary files).
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| !n.ends_with(".glb") && !n.ends_with(".gltf"))
        .filter(|n| n != "rays.npz" && n != "tri.bin")
        .collect();
    assert!(left.is_empty(), "{left:?}");

    // The grid takes meshes only: refused naming the scene, before any output.
    let scene_path = dir.path().join("scene.glb");
    std::fs::write(&scene_path, &good).unwrap();
    let result = hbv(&[
        "trace",
        scene_path.to_str().unwrap(),
        "--rays",
        rays_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--accel",
        "grid",
    ]);
    assert!(!result.status.success());
    assert!(stderr(&result).contains("scene.glb: --accel grid takes a mesh"));
    assert!(!out.exists());
}

/// A PLY or OBJ mesh is a scene of one instance: its hit file has `instance` 0 (-1 on a miss)
/// and the triangle's normal, the bits `Scene` gives on the same file.
#[test]
fn mesh_hit_files_carry_instance_and_normal() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 1.5, 0.4, 24, 12);
    let mesh_path = dir.path().join("ring.obj");
    write_obj(&mesh, &mesh_path);
    let scene = Scene::load(&mesh_path).unwrap();
    let rays = rays_at(&scene, 600, 11);
    let rays_path = dir.path().join("rays.npz");
    ray_file::write_rays(&rays_path, &rays, Replace::Always).unwrap();
    let hits_path = dir.path().join("hits.npz");
    run(&[
        "trace",
        mesh_path.to_str().unwrap(),
        "--rays",
        rays_path.to_str().unwrap(),
        "--out",
        hits_path.to_str().unwrap(),
    ]);
    let got = hit_file::read_scene_hits(&hits_path).unwrap();
    let scene_rays: Vec<SceneRay> = rays.iter().map(|&r| SceneRay::from(r)).collect();
    let want: Vec<Option<SceneHit>> = scene.intersect_batch(&scene_rays);
    assert_eq!(got, want);
    assert!(got.iter().flatten().count() > 100);
    for h in got.iter().flatten() {
        let t = mesh.triangle(h.prim as usize);
        let n = (t.p1 - t.p0).cross(t.p2 - t.p0).normalize();
        assert!((h.normal - n).length() < 1e-6);
    }
    // Both scene members are in the file.
    let raw = std::fs::read(&hits_path).unwrap();
    for name in ["instance.npy", "normal.npy"] {
        assert!(raw.windows(name.len()).any(|w| w == name.as_bytes()));
    }
}

#[test]
fn bench_measures_scenes_with_their_facts() {
    let dir = tempfile::tempdir().unwrap();
    let scene = instanced_scene();
    let (scene_path, _) = write_inputs(dir.path(), &scene, &[]);
    let text = run(&[
        "bench",
        &scene_path,
        "--rays",
        "2000",
        "--repeat",
        "1",
        "--layout",
        "wide8",
        "--layout",
        "ordered",
        "--threads",
        "2",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let summary = scene.summary();
    assert_eq!(json["scene"]["meshes"], 2);
    assert_eq!(json["scene"]["instances"], summary.live_instances);
    assert_eq!(json["scene"]["triangles_seen"], summary.triangles_seen);
    assert_eq!(json["triangles"], summary.triangles_stored);
    assert_eq!(json["thread_counts"], serde_json::json!([1, 2]));
    let results = json["results"].as_array().unwrap();
    // 2 layouts × 4 (set, query) cases × 2 thread counts.
    assert_eq!(results.len(), 16);
    for r in results {
        assert!(r["mrays_per_second"].as_f64().unwrap() > 0.0, "{r}");
        // Counted through the scene's counted queries: work inside the meshes' trees.
        assert!(r["triangles_per_ray"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["nodes_per_ray"].as_f64().unwrap() > 0.0, "{r}");
    }
    // The diffuse rays' closest hits and any hits agree on which rays hit something, and the
    // two layouts on every fraction.
    let fraction = |layout: &str, set: &str, query: &str| {
        results
            .iter()
            .find(|r| r["layout"] == layout && r["ray_set"] == set && r["query"] == query)
            .unwrap()["hit_fraction"]
            .as_f64()
            .unwrap()
    };
    let diffuse = fraction("wide8", "diffuse", "closest");
    assert!(diffuse > 0.0);
    assert_eq!(diffuse, fraction("wide8", "diffuse", "occluded"));
    for (set, query) in [("primary", "closest"), ("shadow", "occluded")] {
        assert_eq!(
            fraction("wide8", set, query),
            fraction("ordered", set, query)
        );
    }

    // The table form names the scene's counts.
    let text = run(&[
        "bench",
        &scene_path,
        "--rays",
        "500",
        "--repeat",
        "1",
        "--layout",
        "wide8",
    ]);
    assert!(
        text.contains(&format!(
            "{} instances; {} triangles stored, {} seen",
            summary.live_instances, summary.triangles_stored, summary.triangles_seen
        )),
        "{text}"
    );
}

/// What `hbv bench` counts per ray on a scene means what it means on a mesh: a scene of one
/// instance of a mesh, placed by the identity, tests the mesh's triangles, its boxes (less those
/// of rays the top level turns away), and visits its nodes plus the instance entered.
#[test]
fn bench_counts_a_scene_of_one_instance_as_its_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 1.5, 0.4, 48, 24);
    let obj = dir.path().join("ring.obj");
    write_obj(&mesh, &obj);
    let mut scene = Scene::new();
    let ring = scene.add_mesh(mesh);
    let identity = InstanceTransform::from_translation(DVec3::ZERO).unwrap();
    scene.add_instance(ring, identity, u32::MAX).unwrap();
    scene.build();
    let glb = dir.path().join("ring.glb");
    scene.write_gltf(&glb, Replace::Always).unwrap();
    let wide8 = ["--layout", "wide8"];
    let (of_mesh, of_scene) = (small_bench(&obj, &wide8), small_bench(&glb, &wide8));
    let (of_mesh, of_scene) = (
        of_mesh["results"].as_array().unwrap(),
        of_scene["results"].as_array().unwrap(),
    );
    assert_eq!(of_mesh.len(), of_scene.len());
    let per_ray = |r: &serde_json::Value, key: &str| r[key].as_f64().unwrap();
    for (m, s) in of_mesh.iter().zip(of_scene) {
        // The same triangles tested: the instance's tree is the mesh's, the ray carried
        // exactly by the identity.
        assert_eq!(s["triangles_per_ray"], m["triangles_per_ray"], "{m}\n{s}");
        assert!(per_ray(s, "triangles_per_ray") > 0.0);
        // Boxes inside the mesh's tree only: a ray the top level turns away tests none.
        assert!(
            per_ray(s, "boxes_per_ray") <= per_ray(m, "boxes_per_ray"),
            "{m}\n{s}"
        );
        // The mesh's nodes, and at most the one entry into the instance per ray.
        let extra = per_ray(s, "nodes_per_ray") - per_ray(m, "nodes_per_ray");
        assert!(extra <= 1.0 + 1e-9, "{m}\n{s}");
    }
}
