//! `hbv bench` from the outside: its JSON report, the ray files it writes, and the ray sets behind
//! both.

use std::process::{Command, Output};

use glam::Vec3;
use hbv::mesh::procedural::{icosphere, torus};
use hbv::TriangleMesh;
use hbv_cli::ray_file;
use hbv_cli::ray_sets::{RaySet, Stage, SHADOW_TMAX};
use serde_json::Value;

fn hbv(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_hbv"))
        .args(args)
        .output()
        .expect("the hbv binary runs");
    assert!(
        out.status.success(),
        "hbv {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Every layout `--layout` accepts today; the report must cover at least these.
const LAYOUTS: [&str; 5] = ["recursive", "skip", "ordered", "wide4", "wide8"];

/// (ray set, query) pairs measured for every layout.
const CASES: [(&str, &str); 4] = [
    ("primary", "closest"),
    ("diffuse", "closest"),
    ("diffuse", "occluded"),
    ("shadow", "occluded"),
];

#[test]
fn json_report_has_every_layout_set_query_and_thread_count() {
    let out = hbv(&["bench", "--rays", "2000", "--repeat", "1", "--json"]);
    let report: Value = serde_json::from_slice(&out.stdout).expect("bench --json prints JSON");
    assert!(report["build_seconds"].as_f64().unwrap() >= 0.0);
    let threads: Vec<u64> = report["thread_counts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_u64().unwrap())
        .collect();
    assert_eq!(threads[0], 1, "always measured on one thread");

    let layouts = report["layouts"].as_array().unwrap();
    for name in LAYOUTS {
        let layout = layouts
            .iter()
            .find(|l| l["layout"] == name)
            .unwrap_or_else(|| panic!("no layout {name} in {layouts:?}"));
        assert!(layout["memory_bytes"].as_u64().unwrap() > 0);
    }

    let results = report["results"].as_array().unwrap();
    assert_eq!(results.len(), layouts.len() * CASES.len() * threads.len());
    for name in LAYOUTS {
        for (set, query) in CASES {
            for &t in &threads {
                let m = results
                    .iter()
                    .find(|m| {
                        m["layout"] == name
                            && m["ray_set"] == set
                            && m["query"] == query
                            && m["threads"] == t
                    })
                    .unwrap_or_else(|| panic!("no result for {name} {set} {query} {t}"));
                assert_eq!(m["rays"], 2000);
                let runs = m["runs"].as_array().unwrap();
                assert_eq!(runs.len(), 1, "--repeat 1");
                assert_eq!(m["mrays_per_second"], runs[0], "median of one run");
                assert!(m["mrays_per_second"].as_f64().unwrap() > 0.0);
                for key in [
                    "memory_bytes",
                    "nodes_per_ray",
                    "boxes_per_ray",
                    "triangles_per_ray",
                ] {
                    assert!(m[key].as_f64().unwrap() > 0.0, "{key} of {m}");
                }
                let hits = m["hit_fraction"].as_f64().unwrap();
                assert!((0.0..=1.0).contains(&hits));
            }
        }
    }

    // Every layout answers the same: the hit fractions of one (set, query) agree.
    for (set, query) in CASES {
        let fractions: Vec<f64> = results
            .iter()
            .filter(|m| m["ray_set"] == set && m["query"] == query)
            .map(|m| m["hit_fraction"].as_f64().unwrap())
            .collect();
        assert!(
            fractions.windows(2).all(|w| w[0] == w[1]),
            "{set} {query}: {fractions:?}"
        );
    }
}

#[test]
fn write_rays_writes_three_readable_files_of_the_asked_count() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("sets");
    let args = |extra: &'static [&'static str]| {
        let mut args = vec![
            "bench",
            "--rays",
            "1000",
            "--write-rays",
            out_dir.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        args
    };
    hbv(&args(&[]));
    let mut first = Vec::new();
    for set in ["primary", "diffuse", "shadow"] {
        let rays = ray_file::read_rays(&out_dir.join(format!("{set}.npz"))).unwrap();
        assert_eq!(rays.len(), 1000, "{set}");
        assert!(rays.iter().all(|r| r.is_valid() && r.tmin <= r.tmax));
        first.push(rays);
    }
    // A second run refuses to replace them, and says so; with --force it writes the same rays.
    let refused = Command::new(env!("CARGO_BIN_EXE_hbv"))
        .args(args(&[]))
        .output()
        .unwrap();
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        message.contains("primary.npz: the output file exists; pass --force to replace it"),
        "{message}"
    );
    hbv(&args(&["--force"]));
    for (set, rays) in ["primary", "diffuse", "shadow"].iter().zip(&first) {
        let again = ray_file::read_rays(&out_dir.join(format!("{set}.npz"))).unwrap();
        assert_eq!(&again, rays, "{set}");
    }
}

#[test]
fn ray_sets_are_deterministic_per_seed() {
    let mesh = torus(Vec3::new(1.0, 2.0, 3.0), 2.0, 0.5, 24, 12);
    for set in RaySet::ALL {
        let a = set.generate(&mesh, 500, 42);
        assert_eq!(a.len(), 500);
        assert_eq!(a, set.generate(&mesh, 500, 42), "{set:?}");
        let other = set.generate(&mesh, 500, 43);
        match set {
            RaySet::Primary => assert_eq!(a, other, "the camera takes no seed"),
            _ => assert_ne!(a, other, "{set:?} ignores its seed"),
        }
    }
    assert_ne!(
        RaySet::Diffuse.generate(&mesh, 10, 1)[0].origin,
        RaySet::Shadow.generate(&mesh, 10, 1)[0].origin,
        "the surface sets draw independent points"
    );
}

#[test]
fn shadow_segments_end_at_the_light() {
    let mesh: TriangleMesh = icosphere(Vec3::new(10.0, -4.0, 2.0), 3.0, 2);
    let stage = Stage::new(&mesh.bounds());
    for ray in RaySet::Shadow.generate(&mesh, 1000, 5) {
        // t = 1 is the light; the interval stops just short of it and starts a fixed distance
        // off the surface.
        assert!((ray.at(1.0) - stage.light).length() < 1e-5 * stage.diagonal);
        assert_eq!(ray.tmax, SHADOW_TMAX);
        let start = ray.tmin * ray.direction.length();
        assert!(
            (start - stage.offset).abs() < 1e-3 * stage.offset,
            "{ray:?}"
        );
    }
}
