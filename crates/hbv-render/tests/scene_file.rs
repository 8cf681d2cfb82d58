//! The TOML scene format from the outside: a scene that loads, and errors that name the file,
//! the line and the key.

use std::path::{Path, PathBuf};

use hbv_render::scene::load_scene;
use hbv_render::{Light, SceneError};

/// A folder with a small OBJ (two triangles) and `scene.toml` holding `text`.
fn scene_dir(text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("quad.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
    )
    .unwrap();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

const GOOD: &str = r#"
[render]
width = 32
height = 24
spp = 2
background = [0.1, 0.1, 0.1]

[camera]
position = [0.5, 0.5, 3]
look_at = [0.5, 0.5, 0]
fov = 40

[materials.glass]
type = "glass"
ior = 1.5

[materials.red]
type = "phong"
color = [0.8, 0.1, 0.1]
specular = [0.2, 0.2, 0.2]
exponent = 30

[[mesh]]
file = "quad.obj"
material = "red"
translate = [0, 0, -1]
scale = 2

[[mesh]]
file = "quad.obj"
material = "glass"
rotate = [0, 90, 0]
scale = [1, 2, 1]

[[light]]
type = "area"
corner = [0, 2, 0]
edge_u = [1, 0, 0]
edge_v = [0, 0, 1]
intensity = 5
samples = 9

[[light]]
type = "point"
position = [0, 1, 1]
"#;

fn error_of(text: &str) -> (SceneError, PathBuf) {
    let (dir, path) = scene_dir(text);
    let e = load_scene(&path).expect_err("the scene is invalid");
    drop(dir);
    (e, path)
}

/// Replaces the first occurrence of `from` in the good scene.
fn good_with(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replacen(from, to, 1)
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

fn assert_error(text: &str, line_needle: &str, key: &str, reason: &str) {
    let (e, path) = error_of(text);
    let message = e.to_string();
    assert_eq!(e.key(), Some(key), "{message}");
    assert_eq!(e.line(), Some(line_of(text, line_needle)), "{message}");
    assert!(message.contains(&path.display().to_string()), "{message}");
    assert!(message.contains(reason), "{message}");
}

#[test]
fn a_good_scene_loads_with_everything_it_names() {
    let (_dir, path) = scene_dir(GOOD);
    let scene = load_scene(&path).unwrap();
    // Two quads of two triangles, and the area light's visible panel.
    assert_eq!(scene.triangle_count(), 6);
    assert_eq!(scene.settings.width, 32);
    assert_eq!(scene.settings.spp, 2);
    assert_eq!(scene.lights.len(), 2);
    assert!(matches!(scene.lights[0], Light::Rect { samples: 9, .. }));
    // Placement: the first quad is scaled by 2 and moved back.
    let bounds = scene.bounds();
    assert_eq!(bounds.min.z, -1.0);
    assert!((bounds.max.y - 2.0).abs() < 1e-6);
}

#[test]
fn syntax_errors_name_line_and_key() {
    assert_error(
        &good_with("ior = 1.5", "ior = 1.5.3"),
        "ior = 1.5.3",
        "materials.glass.ior",
        "",
    );
}

#[test]
fn unknown_keys_and_wrong_types_name_line_and_key() {
    assert_error(
        &good_with("exponent = 30", "exponant = 30"),
        "exponant",
        "materials.red.exponant",
        "unknown field",
    );
    assert_error(
        &good_with("samples = 9", "samples = \"many\""),
        "samples = \"many\"",
        "light[0].samples",
        "",
    );
}

/// A 3-vector takes exactly three numbers (a fourth passed unnoticed before), a scale one
/// number or three.
#[test]
fn vectors_of_the_wrong_length_name_line_and_key() {
    assert_error(
        &good_with("position = [0.5, 0.5, 3]", "position = [0.5, 0.5, 3, 1]"),
        "position = [0.5, 0.5, 3, 1]",
        "camera.position",
        "invalid length 4, expected 3 numbers",
    );
    assert_error(
        &good_with("color = [0.8, 0.1, 0.1]", "color = [0.8, 0.1]"),
        "color = [0.8, 0.1]",
        "materials.red.color",
        "invalid length 2, expected 3 numbers",
    );
    assert_error(
        &good_with("scale = [1, 2, 1]", "scale = [1, 2, 1, 1]"),
        "scale = [1, 2, 1, 1]",
        "mesh[1].scale",
        "invalid length 4, expected a number or 3 numbers",
    );
}

#[test]
fn bad_values_name_line_and_key() {
    assert_error(
        &good_with("ior = 1.5", "ior = -1.5"),
        "ior = -1.5",
        "materials.glass.ior",
        "> 0",
    );
    assert_error(
        &good_with("samples = 9", "samples = 0"),
        "samples = 0",
        "light[0].samples",
        "out of range",
    );
    assert_error(
        &good_with("width = 32", "width = 0"),
        "width = 0",
        "render.width",
        "out of range",
    );
    assert_error(
        &good_with("type = \"glass\"", "type = \"glas\""),
        "type = \"glas\"",
        "materials.glass.type",
        "unknown material type",
    );
    assert_error(
        &good_with("material = \"red\"", "material = \"blue\""),
        "material = \"blue\"",
        "mesh[0].material",
        "no material named \"blue\"",
    );
    assert_error(
        &good_with("look_at = [0.5, 0.5, 0]", "look_at = [0.5, 0.5, 3]"),
        "[camera]",
        "camera",
        "look_at equals position",
    );
}

#[test]
fn missing_and_broken_meshes_name_the_mesh_entry() {
    let text = good_with("file = \"quad.obj\"", "file = \"missing.obj\"");
    let (e, _) = error_of(&text);
    assert!(matches!(e, SceneError::Mesh { .. }), "{e}");
    assert_eq!(e.key(), Some("mesh[0].file"));
    assert_eq!(e.line(), Some(line_of(&text, "missing.obj")));
    assert!(e.to_string().contains("missing.obj"), "{e}");
}

#[test]
fn a_missing_file_is_reported_as_such() {
    let e = load_scene(Path::new("/nonexistent/scene.toml")).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/scene.toml"));
}

#[test]
fn the_example_scenes_load_when_shared_scenes_exist() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let shared = examples.join("../../shared/scenes");
    if !shared.join("bunny.ply").exists() || !shared.join("dragon.ply").exists() {
        eprintln!("skipped: ../shared/scenes is not beside the repository");
        return;
    }
    for name in ["bunny.toml", "dragon.toml"] {
        let scene = load_scene(examples.join(name)).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.triangle_count() > 10_000, "{name}");
        assert!(!scene.lights.is_empty(), "{name}");
    }
}

/// A scene saved as Latin-1: the first byte that is not UTF-8 is named by line, column and
/// offset, once (it was "stream did not contain valid UTF-8" twice, with no place).
#[test]
fn a_file_that_is_not_utf8_names_its_first_bad_byte() {
    let text = good_with("[[light]]", "# caf\u{e9}\n[[light]]");
    let bad_line = line_of(&text, "# caf");
    let at = text.find('\u{e9}').unwrap();
    let mut bytes = text.into_bytes();
    bytes.splice(at..at + 2, [0xe9]); // é in Latin-1
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("latin1.toml");
    std::fs::write(&path, &bytes).unwrap();
    let e = load_scene(&path).unwrap_err();
    let message = e.to_string();
    assert!(matches!(e, SceneError::NotUtf8 { .. }), "{message}");
    assert_eq!(e.line(), Some(bad_line), "{message}");
    let expected = format!(
        "latin1.toml: line {bad_line}, column 6 (byte offset {at}): not UTF-8 text (byte 0xE9)"
    );
    assert!(message.contains(&expected), "{message}");
    assert_eq!(message.matches("UTF-8").count(), 2, "{message}");
    assert!(!message.contains('\n'), "{message}");
}

/// `/dev/zero` given as a scene was read until memory ran out.
#[cfg(unix)]
#[test]
fn a_device_is_refused_not_read_for_ever() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zero.toml");
    std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
    let e = load_scene(&path).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }), "{e}");
    assert!(
        e.to_string()
            .ends_with("zero.toml: cannot read: a device or a socket, not a scene file"),
        "{e}"
    );
}
