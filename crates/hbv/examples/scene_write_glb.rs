//! Scenes of tens of instances of meshes of 5k to 100k triangles, written as `.glb` files for
//! comparing hbv's two-level answers and speed with Embree's (BENCHMARKS.md, "Scenes against
//! Embree").
//!
//! ```text
//! cargo run --release -p hbv --example scene_write_glb -- OUT_DIR [--shared DIR]
//! ```
//!
//! Writes `OUT_DIR/procedural.glb`: 40 instances of five generated meshes (icospheres of 5,120
//! and 20,480 triangles, tori of 16,384, 40,000 and 69,696), and, when `DIR` (default
//! `../shared/scenes`) holds them, `OUT_DIR/shared.glb`: 30 instances of spot (5,856), the
//! teapot (6,320) and the bunny (69,451) with the 69,696-triangle torus. Instances are placed
//! at random (seed 33) in a cube about four mesh widths wide, so that they overlap, turned,
//! scaled by 0.6 to 1.8 times the mesh's size, one in five mirrored; the same files for the
//! same seed. Without the shared meshes only the first file is written.

use std::path::{Path, PathBuf};

use hbv::atomic_file::Replace;
use hbv::glam::{DAffine3, DMat3, DQuat, DVec3, EulerRot, Vec3};
use hbv::mesh::procedural::{icosphere, torus};
use hbv::scene::{InstanceTransform, Scene};
use hbv::TriangleMesh;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut out = None::<PathBuf>;
    let mut shared = PathBuf::from("../shared/scenes");
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--shared" => shared = args.next().ok_or("--shared needs a folder")?.into(),
            _ if out.is_none() => out = Some(arg.into()),
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }
    let out = out.ok_or("usage: scene_write_glb OUT_DIR [--shared DIR]")?;
    std::fs::create_dir_all(&out)?;
    let procedural = vec![
        icosphere(Vec3::ZERO, 1.0, 4),
        torus(Vec3::ZERO, 1.0, 0.3, 128, 64),
        icosphere(Vec3::ZERO, 1.0, 5),
        torus(Vec3::ZERO, 1.0, 0.4, 200, 100),
        torus(Vec3::ZERO, 1.0, 0.3, 264, 132),
    ];
    write_scene(&out.join("procedural.glb"), procedural, 40)?;
    let names = ["spot.ply", "teapot.ply", "bunny.ply"];
    if names.iter().all(|n| shared.join(n).is_file()) {
        let mut meshes = names
            .iter()
            .map(|n| TriangleMesh::load(shared.join(n)))
            .collect::<Result<Vec<_>, _>>()?;
        meshes.push(torus(Vec3::ZERO, 1.0, 0.3, 264, 132));
        write_scene(&out.join("shared.glb"), meshes, 30)?;
    } else {
        println!(
            "{} lacks {names:?}: shared.glb not written",
            shared.display()
        );
    }
    Ok(())
}

/// Writes `instances` instances of `meshes`, taken in turn, placed as the module notes say.
fn write_scene(
    path: &Path,
    meshes: Vec<TriangleMesh>,
    instances: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut rng = Pcg64Mcg::seed_from_u64(33);
    let mut scene = Scene::new();
    let (mut placed, mut ids) = (Vec::new(), Vec::new());
    for mesh in meshes {
        // Each mesh scaled to a size of about 2 and centred at the origin before its placement.
        let b = mesh.bounds();
        let size = f64::from((b.max - b.min).max_element()).max(f64::MIN_POSITIVE);
        let centre = ((b.min + b.max) * 0.5).as_dvec3();
        placed.push((mesh.triangle_count(), 2.0 / size, centre));
        ids.push(scene.add_mesh(mesh));
    }
    let extent = 4.0 * (instances as f64).cbrt();
    let mut seen = 0;
    for k in 0..instances {
        let mesh = k % ids.len();
        let (triangles, unit, centre) = placed[mesh];
        let turn = DQuat::from_euler(
            EulerRot::XYZ,
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
        );
        let scale = unit * rng.random_range(0.6..1.8);
        let mirror = if k % 5 == 4 { -1.0 } else { 1.0 };
        let at = DVec3::new(
            rng.random_range(0.0..extent),
            rng.random_range(0.0..extent),
            rng.random_range(0.0..extent),
        );
        let linear = DMat3::from_quat(turn) * DMat3::from_diagonal(DVec3::new(mirror, 1.0, 1.0));
        let matrix3 = linear * scale;
        let affine = DAffine3 {
            matrix3,
            translation: at - matrix3 * centre,
        };
        scene.add_instance(ids[mesh], InstanceTransform::new(affine)?, u32::MAX)?;
        seen += triangles;
    }
    scene.write_gltf(path, Replace::Always)?;
    println!(
        "{}: {} meshes, {instances} instances, {seen} triangles as seen",
        path.display(),
        ids.len()
    );
    Ok(())
}
