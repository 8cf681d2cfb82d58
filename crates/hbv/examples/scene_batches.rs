//! Scene batches against single rays: [`Scene::intersect_batch`] / [`Scene::occluded_batch`]
//! (rays traced in waves, `scene/ray_waves.rs`) and a loop of [`Scene::intersect`] /
//! [`Scene::occluded`] on the same rays, alternated round by round, on one thread.
//!
//! ```text
//! cargo run --release -p hbv --example scene_batches -- SCENE.glb ...
//!     [--rays K] [--runs R] [--only single|batch]
//! ```
//!
//! Each `.glb` scene (`scene_write_glb`'s) is traced with `K` random rays (default 200,000):
//! origins uniform in the scene's box, directions uniform on the sphere. Printed per
//! scene and query: Mrays/s of each way in each of `R` rounds (default 5), their medians and
//! the ratio batch / single of the medians. The answers of both ways are checked equal.
//! `--only` times one way alone, for profiling.

use std::path::PathBuf;
use std::time::Instant;

use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::scene::{Scene, SceneRay};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut ray_count, mut runs) = (200_000usize, 5usize);
    let mut only = None::<String>;
    let mut scenes = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--rays" => ray_count = value()?.parse::<usize>()?.max(1),
            "--runs" => runs = value()?.parse::<usize>()?.max(1),
            "--only" => only = Some(value()?),
            _ => scenes.push(PathBuf::from(arg)),
        }
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut rng = Pcg64Mcg::seed_from_u64(34);
    for path in &scenes {
        let mut scene = Scene::load(path)?;
        scene.build();
        let rays = random_rays(&scene, ray_count, &mut rng);
        let name = path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy());
        pool.install(|| compare(&name, &scene, &rays, runs, only.as_deref()));
    }
    Ok(())
}

/// Prints both ways' rates of closest and any hit, alternated over `runs` rounds, after
/// checking that they answer alike.
fn compare(name: &str, scene: &Scene, rays: &[SceneRay], runs: usize, only: Option<&str>) {
    let single: Vec<_> = rays.iter().map(|r| scene.intersect(r)).collect();
    assert!(
        scene.intersect_batch(rays) == single,
        "{name}: closest hits differ"
    );
    let blocked: Vec<bool> = rays.iter().map(|r| scene.occluded(r)).collect();
    assert!(
        scene.occluded_batch(rays) == blocked,
        "{name}: any hits differ"
    );
    let hits = single.iter().flatten().count();
    println!(
        "{name}: {} instances, {} rays, {:.1}% hit",
        scene.instance_count(),
        rays.len(),
        100.0 * hits as f64 / rays.len() as f64
    );
    let rate = |way: &str, work: &dyn Fn()| {
        if only.is_some_and(|o| o != way) {
            return f64::NAN;
        }
        let start = Instant::now();
        work();
        rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6
    };
    let (mut c1, mut cb, mut a1, mut ab) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..runs {
        c1.push(rate("single", &|| {
            std::hint::black_box(rays.iter().map(|r| scene.intersect(r)).collect::<Vec<_>>());
        }));
        cb.push(rate("batch", &|| {
            std::hint::black_box(scene.intersect_batch(rays));
        }));
        a1.push(rate("single", &|| {
            std::hint::black_box(rays.iter().map(|r| scene.occluded(r)).collect::<Vec<_>>());
        }));
        ab.push(rate("batch", &|| {
            std::hint::black_box(scene.occluded_batch(rays));
        }));
    }
    for (what, single, batch) in [("closest", c1, cb), ("any hit", a1, ab)] {
        let rounds = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.3}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let (s, b) = (median(&single), median(&batch));
        println!(
            "  {what:>8}: single {s:.3} [{}], batch {b:.3} [{}] Mrays/s; batch / single {:.2}",
            rounds(&single),
            rounds(&batch),
            b / s
        );
    }
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

/// `count` rays from origins uniform in the scene's box, directions uniform on the sphere.
fn random_rays(scene: &Scene, count: usize, rng: &mut Pcg64Mcg) -> Vec<SceneRay> {
    let bounds = scene.bounds();
    (0..count)
        .map(|_| {
            let k = Vec3::new(rng.random(), rng.random(), rng.random());
            let origin = bounds.min + (bounds.max - bounds.min) * k;
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            let direction = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            SceneRay::new(Ray::new(origin, direction))
        })
        .collect()
}
