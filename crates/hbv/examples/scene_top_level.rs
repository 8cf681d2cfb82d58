//! Rays through scenes where the top level matters: its build time and the closest-hit and
//! any-hit rates of incoherent rays, one thread.
//!
//! ```text
//! cargo run --release -p hbv --example scene_top_level -- [--rays K] [--runs R] [--scene NAME]
//! ```
//!
//! Three scenes, each placed at random (seed 33) with turns and scales:
//!
//! - `small`: 5,000 instances of four small meshes (icospheres of 80 and 320 triangles, tori of
//!   144 and 576) in a cube 40 wide: many instances along every ray, each cheap.
//! - `large`: 40 instances of three meshes of 20,480 to 81,920 triangles in a cube 12 wide,
//!   overlapping: few instances, each a deep tree.
//! - `field`: 10,000 instances of a torus of 69,696 triangles on a square grid 8 apart (the
//!   scene of `scene_update`).
//!
//! Rays: `K` (default 200,000) with origins uniform in the scene's box and directions uniform
//! on the sphere, traced one at a time on the calling thread by [`Scene::intersect`] and
//! [`Scene::occluded`]; `R` rounds (default 5), closest and any hit alternated, the median
//! printed in Mrays/s, with a checksum of the answers (equal across builds that answer alike).

use std::time::Instant;

use hbv::geometry::Ray;
use hbv::glam::{DAffine3, DQuat, DVec3, EulerRot, Vec3};
use hbv::mesh::procedural::{icosphere, torus};
use hbv::scene::{InstanceTransform, Scene, SceneRay};
use hbv::TriangleMesh;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut ray_count, mut runs, mut only) = (200_000usize, 5usize, None::<String>);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--rays" => ray_count = value()?.parse()?,
            "--runs" => runs = value()?.parse::<usize>()?.max(1),
            "--scene" => only = Some(value()?),
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }
    println!(
        "{:>6} {:>9} {:>13} {:>9} {:>10} {:>10} {:>6} {:>18}",
        "scene", "instances", "seen tris", "build ms", "closest", "any hit", "hits", "checksum"
    );
    for name in ["small", "large", "field"] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let mut rng = Pcg64Mcg::seed_from_u64(33);
        let (scene, seen) = make_scene(name, &mut rng)?;
        let mut probe = scene.clone();
        let build_ms = median(runs, || {
            let start = Instant::now();
            probe.build();
            start.elapsed().as_secs_f64() * 1e3
        });
        let rays = random_rays(&scene, ray_count, &mut rng);
        let (mut closest, mut any) = (Vec::new(), Vec::new());
        let (mut hits, mut checksum) = (0usize, 0u64);
        for _ in 0..runs {
            let start = Instant::now();
            (hits, checksum) = (0, 0);
            for ray in &rays {
                if let Some(hit) = scene.intersect(ray) {
                    hits += 1;
                    checksum = checksum
                        .wrapping_mul(31)
                        .wrapping_add(u64::from(hit.instance) << 32 | u64::from(hit.prim));
                }
            }
            closest.push(rate(rays.len(), start));
            let start = Instant::now();
            let occluded = rays.iter().filter(|r| scene.occluded(r)).count();
            any.push(rate(rays.len(), start));
            if occluded != hits {
                eprintln!("{name}: {occluded} rays occluded but {hits} with a closest hit");
            }
        }
        println!(
            "{:>6} {:>9} {:>13} {:>9.2} {:>10.3} {:>10.3} {:>5.1}% {:>18x}",
            name,
            scene.instance_count(),
            seen,
            build_ms,
            median(runs, || closest.pop().unwrap_or(0.0)),
            median(runs, || any.pop().unwrap_or(0.0)),
            100.0 * hits as f64 / rays.len().max(1) as f64,
            checksum
        );
    }
    Ok(())
}

/// The scene called `name` (module notes), built, and its triangle count as seen.
fn make_scene(
    name: &str,
    rng: &mut Pcg64Mcg,
) -> Result<(Scene, usize), Box<dyn std::error::Error>> {
    let (meshes, instances, extent, scales): (Vec<TriangleMesh>, usize, f64, (f64, f64)) =
        match name {
            "small" => (
                vec![
                    icosphere(Vec3::ZERO, 1.0, 1),
                    icosphere(Vec3::ZERO, 1.0, 2),
                    torus(Vec3::ZERO, 1.0, 0.3, 12, 6),
                    torus(Vec3::ZERO, 1.0, 0.3, 24, 12),
                ],
                5_000,
                40.0,
                (0.3, 1.0),
            ),
            "large" => (
                vec![
                    icosphere(Vec3::ZERO, 1.0, 5),
                    torus(Vec3::ZERO, 1.0, 0.3, 264, 132),
                    icosphere(Vec3::ZERO, 1.0, 6),
                ],
                40,
                12.0,
                (1.0, 2.5),
            ),
            _ => (
                vec![torus(Vec3::ZERO, 1.0, 0.3, 264, 132)],
                10_000,
                0.0,
                (0.7, 1.3),
            ),
        };
    let mut scene = Scene::new();
    let triangles: Vec<usize> = meshes.iter().map(TriangleMesh::triangle_count).collect();
    let ids: Vec<_> = meshes.into_iter().map(|m| scene.add_mesh(m)).collect();
    let side = (instances as f64).sqrt().ceil() as usize;
    let mut seen = 0;
    for k in 0..instances {
        let at = if name == "field" {
            DVec3::new((k % side) as f64, (k / side) as f64, 0.0) * 8.0
        } else {
            DVec3::new(
                rng.random_range(0.0..extent),
                rng.random_range(0.0..extent),
                rng.random_range(0.0..extent),
            )
        };
        let turn = DQuat::from_euler(
            EulerRot::XYZ,
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
        );
        let scale = DVec3::splat(rng.random_range(scales.0..scales.1));
        let transform =
            InstanceTransform::new(DAffine3::from_scale_rotation_translation(scale, turn, at))?;
        let mesh = k % ids.len();
        scene.add_instance(ids[mesh], transform, u32::MAX)?;
        seen += triangles[mesh];
    }
    scene.build();
    Ok((scene, seen))
}

/// `n` rays from points uniform in the scene's box in directions uniform on the sphere.
fn random_rays(scene: &Scene, n: usize, rng: &mut Pcg64Mcg) -> Vec<SceneRay> {
    let b = scene.bounds();
    (0..n)
        .map(|_| {
            let k = Vec3::new(rng.random(), rng.random(), rng.random());
            let origin = b.min + (b.max - b.min) * k;
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            SceneRay::new(Ray::new(origin, Vec3::new(r * phi.cos(), r * phi.sin(), z)))
        })
        .collect()
}

/// Mrays/s of `n` rays since `start`.
fn rate(n: usize, start: Instant) -> f64 {
    n as f64 / start.elapsed().as_secs_f64() / 1e6
}

/// The median of `runs` calls of `sample`.
fn median(runs: usize, mut sample: impl FnMut() -> f64) -> f64 {
    let mut values: Vec<f64> = (0..runs).map(|_| sample()).collect();
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}
