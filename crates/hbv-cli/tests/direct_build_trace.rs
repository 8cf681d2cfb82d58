//! `hbv trace` builds a mesh straight into wide nodes when nothing else is asked for and it is
//! large enough (`LayoutKind::builds_direct`): its hit files are byte for byte those of the same binned SAH
//! tree saved by `hbv build` and laid out from the file, and those of the uniform grid (both
//! exact, ties to the smaller triangle).

use std::path::Path;

mod common;
use common::{hbv, point_in_box, random_direction, stderr, stdout, write_obj};

use glam::Vec3;
use hbv::atomic_file::Replace;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv_cli::ray_file::write_rays;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The members of an `.npz` hit file, by name, as their stored bytes.
fn members(path: &Path) -> Vec<(String, Vec<u8>)> {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    let mut out = Vec::new();
    for i in 0..archive.len() {
        let mut member = archive.by_index(i).unwrap();
        let mut bytes = Vec::new();
        std::io::copy(&mut member, &mut bytes).unwrap();
        out.push((member.name().to_string(), bytes));
    }
    out.sort();
    out
}

#[test]
fn a_mesh_built_straight_into_wide_nodes_traces_as_its_saved_tree_and_the_grid() {
    let dir = tempfile::tempdir().unwrap();
    // More triangles than the direct build's least (9,216 against 8,192), several levels of
    // wide nodes, leaves of many sizes.
    let mesh = torus(Vec3::new(0.3, -0.2, 1.0), 2.0, 0.7, 96, 48);
    let obj = dir.path().join("torus.obj");
    write_obj(&mesh, &obj);
    let b = mesh.bounds();
    let mut rng = Pcg64Mcg::seed_from_u64(35);
    let rays: Vec<Ray> = (0..3000)
        .map(|_| {
            Ray::new(
                point_in_box(&mut rng, b.min - 0.5, b.extent() + 1.0),
                random_direction(&mut rng),
            )
        })
        .collect();
    let rays_path = dir.path().join("rays.npz");
    write_rays(&rays_path, &rays, Replace::Never).unwrap();

    let saved = dir.path().join("torus.hbv");
    let out = hbv(&["build", p(&obj), "-o", p(&saved), "--builder", "binned-sah"]);
    assert!(out.status.success(), "{}", stderr(&out));

    for (layout, occluded) in [("wide8", false), ("wide4", false), ("wide8", true)] {
        let trace = |input: &Path, name: &str, extra: &[&str]| {
            let hits = dir.path().join(format!("{name}-{layout}-{occluded}.npz"));
            let mut args = vec![
                "trace",
                p(input),
                "--rays",
                p(&rays_path),
                "--out",
                p(&hits),
            ];
            args.extend(extra);
            if occluded {
                args.push("--occluded");
            }
            let out = hbv(&args);
            assert!(out.status.success(), "{args:?}: {}", stderr(&out));
            (members(&hits), stdout(&out))
        };
        let (direct, said) = trace(&obj, "direct", &["--layout", layout]);
        assert!(said.contains("straight into"), "{said}");
        let (from_file, said) = trace(&saved, "saved", &["--layout", layout]);
        assert!(!said.contains("straight into"), "{said}");
        let (grid, _) = trace(&obj, "grid", &["--accel", "grid"]);
        assert_eq!(
            direct, from_file,
            "{layout}, occluded {occluded}: the saved tree"
        );
        assert_eq!(direct, grid, "{layout}, occluded {occluded}: the grid");
    }
}

#[test]
fn options_the_direct_build_does_not_make_build_the_tree() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.6, 20, 10);
    let obj = dir.path().join("torus.obj");
    write_obj(&mesh, &obj);
    let rays_path = dir.path().join("rays.npz");
    let rays = [Ray::new(
        Vec3::new(0.0, 2.0, 5.0),
        Vec3::new(0.0, 0.0, -1.0),
    )];
    write_rays(&rays_path, &rays, Replace::Never).unwrap();
    for flags in [
        &["--layout", "ordered"][..],
        &["--optimize"],
        &["--builder", "lbvh"],
        &["--leaf-size", "65"],
    ] {
        let hits = dir.path().join("hits.npz");
        let mut args = vec!["trace", p(&obj), "--rays", p(&rays_path), "--out", p(&hits)];
        args.extend(flags);
        args.push("--force");
        let out = hbv(&args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        assert!(!stdout(&out).contains("straight into"), "{flags:?}");
    }
}
