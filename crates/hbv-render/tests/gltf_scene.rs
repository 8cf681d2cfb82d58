//! A glTF file as a whole scene: its camera, its KHR_lights_punctual light and its materials.

use std::sync::Arc;

use hbv::BruteForce;
use hbv_render::material::Surface;
use hbv_render::scene::load_scene;
use hbv_render::{render, Light, RenderConfig, SceneTracer};

/// A unit quad at z = 0 (glass), a camera at z = 3 and a point light at z = 2, with the geometry
/// in a base64 buffer.
fn quad_gltf() -> String {
    let mut bin = Vec::new();
    for p in [
        [-1f32, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ] {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let data = base64(&bin);
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [
      {{"type": "point", "color": [1, 0.5, 0.25], "intensity": 4}}]}}}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1, 2]}}],
  "nodes": [
    {{"mesh": 0}},
    {{"camera": 0, "translation": [0, 0, 3]}},
    {{"translation": [0, 0, 2], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "znear": 0.01}}}}],
  "materials": [
    {{"pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.2, 0.2, 1], "metallicFactor": 0, "roughnessFactor": 0.5}}}},
    {{"extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 1}}, "KHR_materials_ior": {{"ior": 1.33}}}}}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
        len = bin.len()
    )
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[test]
fn gltf_scene_brings_its_camera_light_and_materials() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quad.gltf");
    std::fs::write(&path, quad_gltf()).unwrap();
    let mut scene = load_scene(&path).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert_eq!(scene.camera.position, glam::Vec3::new(0.0, 0.0, 3.0));
    assert!((scene.camera.fov_y_degrees - 0.8f32.to_degrees()).abs() < 1e-4);
    assert_eq!(
        scene.lights,
        vec![Light::Point {
            position: glam::Vec3::new(0.0, 0.0, 2.0),
            intensity: glam::Vec3::new(4.0, 2.0, 1.0),
        }]
    );
    let material = scene.materials[scene.instances[0].material as usize];
    assert!(
        matches!(material.surface, Surface::Phong { .. }),
        "{material:?}"
    );
    assert!(matches!(
        scene.materials[1].surface,
        Surface::Glass { ior, .. } if (ior - 1.33).abs() < 1e-6
    ));

    scene.settings.width = 8;
    scene.settings.height = 8;
    let bvh: Arc<dyn hbv::Accelerator> = Arc::new(BruteForce::new(scene.flat_mesh()));
    let frame = render(
        &scene,
        &SceneTracer::new(bvh.clone(), bvh),
        &RenderConfig::default(),
    );
    let centre = frame.film.radiance[4 * 8 + 4];
    assert!(centre.x > centre.y && centre.y > 0.0, "lit red: {centre}");
}

#[test]
fn a_broken_gltf_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.glb");
    std::fs::write(&path, b"glTF but not really").unwrap();
    let e = load_scene(&path).unwrap_err();
    assert!(e.to_string().contains("broken.glb"), "{e}");
}

/// A glTF scene is read with the mesh loader's checks: a buffer naming a device is refused (it
/// was read for ever), and so is a stride shorter than an element (the `gltf` crate panicked).
#[test]
fn a_gltf_scene_gets_the_mesh_loader_s_checks() {
    let dir = tempfile::tempdir().unwrap();
    let good = quad_gltf();
    let stride = good.replace(
        r#""byteOffset": 0, "byteLength": 48}"#,
        r#""byteOffset": 0, "byteLength": 48, "byteStride": 8}"#,
    );
    assert_ne!(stride, good);
    let path = dir.path().join("stride.gltf");
    std::fs::write(&path, stride).unwrap();
    let e = load_scene(&path).unwrap_err().to_string();
    assert!(
        e.contains("stride.gltf: accessor 0: POSITION's buffer view has a byte stride of 8"),
        "{e}"
    );
    #[cfg(unix)]
    {
        let start = good.find("data:application").unwrap();
        let end = start + good[start..].find('"').unwrap();
        let device = format!("{}/dev/zero{}", &good[..start], &good[end..]);
        let path = dir.path().join("device.gltf");
        std::fs::write(&path, device).unwrap();
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("/dev/zero is not a regular file"), "{e}");
    }
}

/// A glTF scene's camera, lights and materials are checked as a TOML scene's are (they were
/// taken as given, or a bad camera silently replaced by a default one).
#[test]
fn a_gltf_scene_s_values_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let good = quad_gltf();
    for (name, from, to, reason) in [
        (
            "yfov.gltf",
            r#""yfov": 0.8"#,
            r#""yfov": 0"#,
            "node 1: camera 0: fov must be between 0 and 180 degrees",
        ),
        (
            "light.gltf",
            r#""intensity": 4"#,
            r#""intensity": -4"#,
            "node 2: light 0: color times intensity must be finite and not negative",
        ),
        (
            "ior.gltf",
            r#""ior": 1.33"#,
            r#""ior": 0"#,
            "material 1: ior must be a number > 0, got 0",
        ),
    ] {
        let text = good.replace(from, to);
        assert_ne!(text, good, "{name}");
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains(&format!("{name}: {reason}")), "{e}");
    }
}
