//! `hbv render` from the outside: the default scene, its output files, refusing to overwrite,
//! and one-line errors for bad scenes.

use std::path::Path;
use std::process::{Command, Output};

fn hbv_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hbv"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the hbv binary runs")
}

const SMALL: [&str; 7] = ["--width", "32", "--height", "24", "--spp", "1", "--quiet"];

#[test]
fn default_render_writes_png_passes_and_exr_then_refuses_to_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["render"];
    args.extend(SMALL);
    args.extend([
        "--pass", "nodes", "--pass", "depth", "--exr", "out.exr", "--json",
    ]);
    let o = hbv_in(dir.path(), &args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["width"], 32);
    assert!(report["by_kind"]["shadow"]["rays"].as_u64().unwrap() > 0);
    assert!(report["tests_per_ray"].as_f64().unwrap() > 1.0);
    for f in [
        "render.png",
        "render.nodes.png",
        "render.depth.png",
        "out.exr",
    ] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
    let png = image::open(dir.path().join("render.png")).unwrap();
    assert_eq!((png.width(), png.height()), (32, 24));
    // The heatmap carries its legend below the image.
    let heat = image::open(dir.path().join("render.nodes.png")).unwrap();
    assert!(heat.height() > 24);

    let before = std::fs::read(dir.path().join("render.png")).unwrap();
    let mut args = vec!["render"];
    args.extend(SMALL);
    args.extend(["--max-depth", "2"]);
    let o = hbv_in(dir.path(), &args);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("render.png already exists"), "{err}");
    assert_eq!(
        std::fs::read(dir.path().join("render.png")).unwrap(),
        before
    );
    args.push("--force");
    assert!(hbv_in(dir.path(), &args).status.success());
}

#[test]
fn a_bad_scene_is_one_line_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.toml"),
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n\n[[mesh]]\nfile = \"nothing.obj\"\n",
    )
    .unwrap();
    let o = hbv_in(
        dir.path(),
        &["render", "bad.toml", "-o", "x.png", "--quiet"],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bad.toml: line 7: mesh[0].file"), "{err}");
    // The mesh loader's reason once (the error chain repeated it).
    assert_eq!(err.matches("nothing.obj: cannot read").count(), 1, "{err}");
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn grid_per_ray_kind_and_caches_off_render_the_default_image() {
    let dir = tempfile::tempdir().unwrap();
    let variants: [&[&str]; 4] = [
        &[],
        &["--primary", "grid", "--shadow", "grid"],
        &["--no-cache"],
        &["--primary", "grid", "--cache-secondary"],
    ];
    let mut images = Vec::new();
    for (i, extra) in variants.iter().enumerate() {
        let out = format!("v{i}.png");
        let mut args = vec!["render", "-o", &out, "--json"];
        args.extend(SMALL);
        args.extend(*extra);
        let o = hbv_in(dir.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let kinds = &report["by_kind"];
        if extra.contains(&"--no-cache") {
            assert!(kinds["shadow"]["cache"].is_null());
        } else {
            let lookups = kinds["shadow"]["cache"]["lookups"].as_u64().unwrap();
            assert_eq!(lookups, kinds["shadow"]["rays"].as_u64().unwrap());
            assert!(kinds["primary"]["cache"]["hit_rate"].as_f64().unwrap() > 0.0);
            let hits = kinds["shadow"]["cache"]["hits"].as_u64().unwrap();
            assert!(hits <= kinds["shadow"]["blocked"].as_u64().unwrap());
        }
        if extra.contains(&"grid") {
            assert_eq!(report["primary"], "grid");
            assert!(kinds["primary"]["mailbox_skips"].as_u64().unwrap() > 0);
        }
        images.push(std::fs::read(dir.path().join(&out)).unwrap());
    }
    for (i, image) in images.iter().enumerate() {
        assert!(*image == images[0], "variant {i} renders a different image");
    }
}

#[test]
fn an_image_too_large_for_memory_is_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let o = hbv_in(
        dir.path(),
        &["render", "--width", "32768", "--height", "32768", "--quiet"],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("too large"), "{err}");
    assert!(!dir.path().join("render.png").exists());
}

/// The outputs are written all or none: an EXR into a missing folder leaves no PNG behind,
/// and one file named twice is refused before rendering.
#[test]
fn outputs_are_written_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["render"];
    args.extend(SMALL);
    args.extend(["--pass", "depth", "--exr", "no/such/out.exr"]);
    let o = hbv_in(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("no/such/out.exr") && stderr.contains("does not exist"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "left behind"
    );

    let mut args = vec!["render"];
    args.extend(SMALL);
    args.extend(["-o", "same.png", "--exr", "same.png"]);
    let o = hbv_in(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("same.png is named twice among the outputs"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// The example field of instances renders as a two-level scene on a fresh clone, with its object
/// caches and a heatmap of its counted work (the same picture with the caches off); a run that
/// asks the two-level scene for the uniform grid is refused before rendering.
#[test]
fn the_field_of_instances_renders_as_a_two_level_scene() {
    let dir = tempfile::tempdir().unwrap();
    let field = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/field.toml");
    let field = field.to_str().unwrap();
    let mut images = Vec::new();
    let heatmaps: &[&str] = &["--pass", "nodes", "--pass", "triangles"];
    for (out, extra) in [("cached.png", heatmaps), ("plain.png", &["--no-cache"])] {
        let mut args = vec!["render", field, "-o", out, "--json"];
        args.extend(SMALL);
        args.extend(extra);
        let o = hbv_in(dir.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert!(report["instances"].as_u64().unwrap() > 3000);
        assert_eq!(report["meshes"], 4);
        assert!(report["triangles"].as_u64().unwrap() > 1_000_000);
        assert!(report["structure"]
            .as_str()
            .unwrap()
            .starts_with("two-level"));
        assert!(report["tests_per_ray"].as_f64().unwrap() > 1.0);
        let shadow = &report["by_kind"]["shadow"];
        if extra.contains(&"--no-cache") {
            assert!(shadow["cache"].is_null());
        } else {
            let lookups = shadow["cache"]["lookups"].as_u64().unwrap();
            assert_eq!(lookups, shadow["rays"].as_u64().unwrap());
            let primary = &report["by_kind"]["primary"]["cache"];
            assert!(primary["hit_rate"].as_f64().unwrap() > 0.0);
            for pass in ["nodes", "triangles"] {
                let heat = image::open(dir.path().join(format!("cached.{pass}.png"))).unwrap();
                assert!(heat.height() > 24, "{pass}: the legend below the image");
            }
        }
        images.push(std::fs::read(dir.path().join(out)).unwrap());
    }
    assert!(images[0] == images[1], "the caches change the picture");

    let mut args = vec![
        "render",
        field,
        "-o",
        "grid.png",
        "--instancing",
        "two-level",
        "--primary",
        "grid",
    ];
    args.extend(SMALL);
    let o = hbv_in(dir.path(), &args);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("needs --instancing flat"), "{err}");
    assert!(!dir.path().join("grid.png").exists());
}
