//! The renderer's TOML scene reader on arbitrary text: it must return a scene or an error naming
//! file, line and key, never panic or hang. Meshes the scene names are not read from disk (a
//! fuzzed path could name any file): every one is a small built-in sphere, so that the whole
//! reader — tables, keys, values, transforms, materials, lights — sees every input.
#![no_main]

use std::path::Path;

use hbv::glam::Vec3;
use hbv::mesh::procedural::icosphere;
use hbv_render::scene::parse_scene;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(source) = std::str::from_utf8(data) else {
        return;
    };
    let sphere = |_: &Path| Ok(icosphere(Vec3::ZERO, 1.0, 1));
    let _ = parse_scene(source, Path::new("fuzz.toml"), &sphere);
});
