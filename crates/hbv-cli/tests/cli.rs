//! The `hbv` binary from the outside: `info` and `trace`, their outputs and their errors.

use std::path::{Path, PathBuf};

mod common;
use common::{hbv, point_in_box, random_direction, stderr, stdout, write_obj};

use glam::Vec3;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce, TriangleMesh};
use hbv_cli::{hit_file, ray_file};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Random rays at `mesh`: from inside its box, from outside at vertices (exactly), axis-aligned,
/// and finite segments.
fn rays_at(mesh: &TriangleMesh, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let b = mesh.bounds();
    let (lo, ext) = (b.min, b.extent());
    (0..count)
        .map(|i| {
            let inside = point_in_box(&mut rng, lo, ext);
            let dir = random_direction(&mut rng);
            match i % 4 {
                0 => Ray::new(inside, dir),
                1 => {
                    let v = mesh.positions()
                        [mesh.indices()[rng.random_range(0..mesh.triangle_count())][0] as usize];
                    let o = b.center() + dir * ext.length() * 2.0;
                    Ray::new(o, v - o)
                }
                2 => {
                    let mut d = Vec3::ZERO;
                    d[i % 3] = if rng.random::<bool>() { 1.0 } else { -1.0 };
                    Ray::new(inside, d)
                }
                _ => Ray::new(inside, dir)
                    .with_interval(0.1 * ext.length() * rng.random::<f32>(), 0.3 * ext.length()),
            }
        })
        .collect()
}

/// Traces `rays` with `hbv trace` (given `build_flags`) and checks every answer against brute
/// force: same hit, `t` within 1e-6 relative, the same triangle or another at equal `t`; the same
/// occlusion.
fn assert_trace_matches_brute_force(
    mesh_path: &Path,
    mesh: &TriangleMesh,
    rays: &[Ray],
    dir: &Path,
    build_flags: &[&str],
) {
    let trace = |args: &[&str]| {
        let mut all = args.to_vec();
        all.extend(build_flags);
        hbv(&all)
    };
    let rays_path = dir.join("rays.npz");
    let hits_path = dir.join("hits.npz");
    let occ_path = dir.join("occluded.npz");
    ray_file::write_rays(&rays_path, rays, hbv::atomic_file::Replace::Always).unwrap();
    let m = mesh_path.to_str().unwrap();
    let r = rays_path.to_str().unwrap();
    let out = trace(&[
        "trace",
        m,
        "--rays",
        r,
        "--out",
        hits_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = trace(&[
        "trace",
        m,
        "--rays",
        r,
        "--out",
        occ_path.to_str().unwrap(),
        "--occluded",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));

    let brute = BruteForce::new(mesh);
    let want = brute.intersect_batch(rays);
    let got = hit_file::read_hits(&hits_path).unwrap();
    assert_eq!(want.len(), got.len());
    for (i, (w, g)) in want.iter().zip(&got).enumerate() {
        match (w, g) {
            (None, None) => {}
            (Some(w), Some(g)) => {
                assert!(
                    (w.t - g.t).abs() <= 1e-6 * w.t.abs(),
                    "ray {i}: t {} vs {}",
                    w.t,
                    g.t
                );
                assert!(
                    w.prim == g.prim || w.t == g.t,
                    "ray {i}: prim {} vs {}",
                    w.prim,
                    g.prim
                );
            }
            _ => panic!("ray {i} {:?}: brute force {w:?}, hbv trace {g:?}", rays[i]),
        }
    }
    let occluded = hit_file::read_occlusion(&occ_path).unwrap();
    assert_eq!(occluded, brute.occluded_batch(rays));

    // A mesh is a scene of one instance: each hit's `instance` is 0, its `normal` the unit
    // geometric normal of the triangle hit (docs/RAYS.md, "Scenes (glTF)").
    let scene_hits = hit_file::read_scene_hits(&hits_path).unwrap();
    for (i, (g, h)) in got.iter().zip(&scene_hits).enumerate() {
        assert_eq!(g.is_some(), h.is_some(), "ray {i}");
        let Some(h) = h else { continue };
        assert_eq!(h.instance, 0, "ray {i}");
        let n = mesh.triangle(h.prim as usize).scaled_normal().normalize();
        assert!(
            (h.normal.as_dvec3() - n).length() < 1e-6,
            "ray {i}: normal {} vs {n}",
            h.normal
        );
    }

    // Without packets of coherent rays, the same answers, whatever the rays.
    let alone_path = dir.join("alone.npz");
    let out = trace(&[
        "trace",
        m,
        "--rays",
        r,
        "--out",
        alone_path.to_str().unwrap(),
        "--no-packets",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(hit_file::read_hits(&alone_path).unwrap(), got);

    // One call per ray gives the interleaved batch's answers, for both queries.
    let single_path = dir.join("single.npz");
    for query in [None, Some("--occluded")] {
        let mut args = vec![
            "trace",
            m,
            "--rays",
            r,
            "--out",
            single_path.to_str().unwrap(),
            "--one-by-one",
            "--force",
        ];
        args.extend(query);
        let out = trace(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        if query.is_some() {
            assert_eq!(hit_file::read_occlusion(&single_path).unwrap(), occluded);
        } else {
            assert_eq!(hit_file::read_hits(&single_path).unwrap(), got);
        }
    }
}

#[test]
fn info_on_builtin_scene_prints_the_cost() {
    let out = hbv(&["info"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s = stdout(&out);
    assert!(
        s.contains("built-in scene") && s.contains("E[X]") && s.contains("SAH cost"),
        "{s}"
    );
}

#[test]
fn info_json_has_the_documented_keys() {
    let out = hbv(&["info", "--json", "--order", "morton", "--leaf-size", "2"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "triangles",
        "degenerate",
        "nodes",
        "leaves",
        "depth_max",
        "build_seconds",
        "expected_tests",
        "sah_cost",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    let triangles = v["triangles"].as_u64().unwrap();
    assert!(triangles > 10_000);
    assert!(v["expected_tests"].as_f64().unwrap() > 1.0);
    assert!(v["leaves"].as_u64().unwrap() >= triangles / 2);
}

#[test]
fn info_says_whether_the_mesh_is_closed() {
    let dir = tempfile::tempdir().unwrap();
    let closed = torus(Vec3::ZERO, 2.0, 0.5, 16, 8);
    // The same torus without its first two triangles (one quad): a hole with a rim of four.
    let open =
        TriangleMesh::new(closed.positions().to_vec(), closed.indices()[2..].to_vec()).unwrap();
    for (mesh, name, open_edges) in [(&closed, "closed.obj", 0), (&open, "open.obj", 4)] {
        let path = dir.path().join(name);
        write_obj(mesh, &path);
        let out = hbv(&["info", "--json", path.to_str().unwrap()]);
        assert!(out.status.success(), "{}", stderr(&out));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["open_edges"].as_u64(), Some(open_edges), "{name}: {v}");
        let out = hbv(&["info", path.to_str().unwrap()]);
        let expected = if open_edges == 0 {
            "closed      yes"
        } else {
            "closed      no (4 open edges"
        };
        assert!(stdout(&out).contains(expected), "{}", stdout(&out));
    }
}

#[test]
fn info_on_missing_mesh_is_one_clear_line() {
    let out = hbv(&["info", "no/such/mesh.ply"]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(
        e.contains("no/such/mesh.ply") && e.contains("cannot read"),
        "{e}"
    );
}

#[test]
fn trace_matches_brute_force_on_a_generated_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::new(0.5, -1.0, 2.0), 2.0, 0.7, 40, 20);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let loaded = TriangleMesh::load(&path).unwrap();
    assert_trace_matches_brute_force(&path, &loaded, &rays_at(&loaded, 4000, 1), dir.path(), &[]);
}

#[test]
fn trace_json_reports_timings_and_threads_or_repeats_do_not_change_answers() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.7, 24, 12);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let rays_path = dir.path().join("rays.npz");
    ray_file::write_rays(
        &rays_path,
        &rays_at(&mesh, 1000, 2),
        hbv::atomic_file::Replace::Always,
    )
    .unwrap();
    // `hbv trace` of the torus and its rays into `out`, with more options.
    let trace = |out: &Path, options: &[&str]| {
        let mut args = vec![
            "trace",
            path.to_str().unwrap(),
            "--rays",
            rays_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(options);
        hbv(&args)
    };
    let mut answers = Vec::new();
    for (threads, repeat) in [("1", "1"), ("2", "1"), ("1", "3")] {
        let out_path = dir.path().join(format!("hits{threads}_{repeat}.npz"));
        let out = trace(
            &out_path,
            &["--threads", threads, "--repeat", repeat, "--json"],
        );
        assert!(out.status.success(), "{}", stderr(&out));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        for key in ["build_seconds", "trace_seconds", "rays", "rays_per_second"] {
            assert!(v.get(key).is_some(), "missing {key} in {v}");
        }
        assert_eq!(v["rays"], 1000);
        // One time per run; the one reported is their median, so one of them for an odd count.
        let each: Vec<f64> = v["trace_seconds_each"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_f64().unwrap())
            .collect();
        assert_eq!(each.len().to_string(), repeat, "{v}");
        assert!(each.contains(&v["trace_seconds"].as_f64().unwrap()), "{v}");
        answers.push(hit_file::read_hits(&out_path).unwrap());
    }
    assert_eq!(answers[0], answers[1]);
    assert_eq!(answers[0], answers[2]);

    let out_path = dir.path().join("never.npz");
    let out = trace(&out_path, &["--repeat", "0"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--repeat"), "{}", stderr(&out));
    assert!(!out_path.exists());
}

#[test]
fn trace_with_bad_ray_file_fails_and_leaves_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.7, 8, 4);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let rays_path = dir.path().join("rays.npz");
    std::fs::write(&rays_path, b"not a zip file").unwrap();
    let out_path = dir.path().join("hits.npz");
    std::fs::write(&out_path, b"precious").unwrap();
    let out = hbv(&[
        "trace",
        path.to_str().unwrap(),
        "--rays",
        rays_path.to_str().unwrap(),
        "--out",
        out_path.to_str().unwrap(),
        // Even when asked to replace it, a failed run leaves the output alone.
        "--force",
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("rays.npz") && e.contains("npz"), "{e}");
    assert_eq!(std::fs::read(&out_path).unwrap(), b"precious");
    let leftovers: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(leftovers.len(), 3, "{leftovers:?}");
}

/// `hbv trace` on every mesh of `../shared/scenes`, ray by ray against brute force.
#[test]
fn trace_matches_brute_force_on_shared_scenes() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    if !scenes.is_dir() {
        eprintln!("skipped: {} is absent", scenes.display());
        return;
    }
    for (name, rays) in [
        ("cornell_box", 4000),
        ("spot", 3000),
        ("teapot", 3000),
        ("bunny", 2000),
        ("igea", 800),
        ("dragon", 400),
    ] {
        let path = scenes.join(format!("{name}.ply"));
        if !path.exists() {
            eprintln!("skipped {name}: absent");
            continue;
        }
        let mesh = TriangleMesh::load(&path).unwrap();
        let dir = tempfile::tempdir().unwrap();
        assert_trace_matches_brute_force(&path, &mesh, &rays_at(&mesh, rays, 7), dir.path(), &[]);
    }
}

#[test]
fn build_compare_rows_agree_with_their_expected_cost_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.7, 48, 24);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let plot = dir.path().join("cost.png");
    let out = hbv(&[
        "build-compare",
        path.to_str().unwrap(),
        "--rays",
        "20000",
        "--builder",
        "insertion",
        "--builder",
        "binned-sah",
        "--json",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["builder"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "insertion",
            "insertion+optimize",
            "binned-sah",
            "binned-sah+optimize"
        ]
    );
    for r in &rows {
        for key in [
            "optimize",
            "build_seconds",
            "expected_tests",
            "sah_cost",
            "measured_tests_per_line",
        ] {
            assert!(r.get(key).is_some(), "missing {key} in {r}");
        }
        let (e, m, se) = (
            r["expected_tests"].as_f64().unwrap(),
            r["measured_tests_per_line"].as_f64().unwrap(),
            r["measured_tests_per_line_std_error"].as_f64().unwrap(),
        );
        assert!((m - e).abs() < 5.0 * se + 1e-3 * e, "{r}");
    }
    let png = std::fs::read(&plot).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // The image is not replaced unless asked, and the refusal comes before any work.
    let again = hbv(&[
        "build-compare",
        path.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(!again.status.success());
    assert!(
        stderr(&again).contains("cost.png: the output file exists; pass --force to replace it"),
        "{}",
        stderr(&again)
    );
    assert_eq!(std::fs::read(&plot).unwrap(), png);
}

/// `hbv info --json` on the built-in scene with `flags`: the report, checked to have succeeded.
fn info_json(flags: &[&str]) -> serde_json::Value {
    let mut args = vec!["info", "--json"];
    args.extend(flags);
    let out = hbv(&args);
    assert!(out.status.success(), "{flags:?}: {}", stderr(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn quality_names_a_builder_and_optimizer_and_explicit_flags_replace_them() {
    let low = info_json(&["--quality", "low"]);
    assert_eq!(low["builder"], "lbvh");
    assert_eq!(low["optimize"], false);
    let high = info_json(&["--quality", "high"]);
    assert_eq!(high["builder"], "binned-sah");
    assert_eq!(high["optimize"], true);
    let described = high["builder_options"].as_str().unwrap();
    assert!(
        described.contains("reinsertion") && described.contains("quality high"),
        "{described}"
    );
    // --builder and --leaf-size replace the quality's builder and leaf size; its optimizer stays.
    let replaced = info_json(&[
        "--quality",
        "high",
        "--builder",
        "median",
        "--leaf-size",
        "2",
    ]);
    assert_eq!(replaced["builder"], "median");
    assert_eq!(replaced["optimize"], true);
    let described = replaced["builder_options"].as_str().unwrap();
    assert!(described.contains("leaf size 2"), "{described}");
    // Without --quality, `info` builds as it always did.
    assert_eq!(info_json(&[])["builder"], "insertion");

    let out = hbv(&["info", "--quality", "best"]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("best") && e.contains("low") && e.contains("medium") && e.contains("high"),
        "{e}"
    );
}

#[test]
fn trace_with_ploc_and_each_quality_matches_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::new(0.5, -1.0, 2.0), 2.0, 0.7, 40, 20);
    let path = dir.path().join("torus.obj");
    write_obj(&mesh, &path);
    let loaded = TriangleMesh::load(&path).unwrap();
    let rays = rays_at(&loaded, 2000, 7);
    for (k, flags) in [
        ["--builder", "ploc"],
        ["--quality", "low"],
        ["--quality", "medium"],
        ["--quality", "high"],
    ]
    .iter()
    .enumerate()
    {
        let run = dir.path().join(k.to_string());
        std::fs::create_dir(&run).unwrap();
        assert_trace_matches_brute_force(&path, &loaded, &rays, &run, flags);
    }
}

#[test]
fn quality_is_refused_for_a_saved_tree() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("torus.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.6, 20, 10), &obj);
    let saved = dir.path().join("torus.hbv");
    let out = hbv(&[
        "build",
        obj.to_str().unwrap(),
        "-o",
        saved.to_str().unwrap(),
        "--quality",
        "low",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = hbv(&["info", saved.to_str().unwrap(), "--quality", "high"]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("holds a saved tree") && e.contains("--quality"),
        "{e}"
    );
}
