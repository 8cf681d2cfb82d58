//! The Ply loader on arbitrary bytes: it must return a mesh or an error, never panic, hang or
//! allocate more than the input can fill. A mesh it returns is built and traced (see
//! `hbv_fuzz::exercise`), so that odd but valid meshes reach the builders and layouts too.
#![no_main]

use hbv::mesh::MeshFormat;
use hbv::TriangleMesh;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = TriangleMesh::from_bytes(MeshFormat::Ply, "fuzz.ply", data) {
        hbv_fuzz::exercise(&mesh);
    }
});
