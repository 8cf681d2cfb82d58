//! `hbv experiment seed-claims` on scenes: the built-in field of instances answers with every
//! cached answer equal to its plain one, and a bad scene file is refused by name.

mod common;
use common::{hbv, stderr, stdout};

#[test]
fn the_built_in_field_is_measured_with_no_mismatch() {
    let out = hbv(&[
        "experiment",
        "seed-claims",
        "--scene-default",
        "--instances",
        "12",
        "--rays",
        "900",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let reports: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let reports = reports.as_array().unwrap();
    assert_eq!(reports.len(), 1, "only the field, without a named input");
    let field = &reports[0];
    assert_eq!(field["instances"], 13);
    assert_eq!(field["meshes"], 4);
    assert!(field["triangles_seen"].as_u64() > field["triangles_stored"].as_u64());
    let rows = field["rows"].as_array().unwrap();
    // Five sets, three structures each.
    assert_eq!(rows.len(), 15);
    for row in rows {
        assert_eq!(row["mismatches"], 0, "{row}");
        assert_eq!(row["runs"].as_array().unwrap().len(), 1);
        assert!(row["mrays_per_second"].as_f64().unwrap() > 0.0);
    }
    let two_level: Vec<_> = rows
        .iter()
        .filter(|r| r["structure"] == "two-level")
        .collect();
    assert_eq!(two_level.len(), 5);
    assert!(two_level.iter().all(|r| r["differs_from_two_level"] == 0));
    assert!(rows[0]["hit_fraction"].as_f64().unwrap() > 0.0);
}

#[test]
fn a_scene_file_that_is_not_one_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.glb");
    std::fs::write(&path, b"glTF but not really").unwrap();
    let path = path.to_str().unwrap();
    let out = hbv(&["experiment", "seed-claims", path, "--rays", "16"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("broken.glb") && !err.contains("panicked"),
        "{err}"
    );
    let out = hbv(&[
        "experiment",
        "seed-claims",
        "--scene-default",
        "--instances",
        "0",
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--instances"), "{}", stderr(&out));
}
