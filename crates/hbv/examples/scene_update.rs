//! Time of [`Scene::update`] on a live scene: refit against rebuild of the top level, and what
//! each leaves for tracing.
//!
//! ```text
//! cargo run --release -p hbv --example scene_update -- [--instances N] [--runs R] [--rays K]
//! ```
//!
//! The scene: `N` instances (default 10,000) of one torus of 69,696 triangles, on a square
//! grid three widths apart, each turned and scaled at random. For each fraction (1 %, 10 %,
//! 100 %) of the instances and each size of move (`step`: up to half a torus width; `drift`:
//! up to a grid cell; `far`: up to four cells; `jump`: anywhere in the field): those instances are moved from the built scene, then the top level is
//! refitted ([`Scene::refit`]), rebuilt ([`Scene::build`]) and updated by the rule
//! ([`Scene::update`]), each the median of `R` runs (default 5). Printed: the milliseconds of
//! each, the refitted tree's SAH cost over the rebuilt tree's, what the rule chose, and the
//! microseconds per ray of `K` random closest-hit rays (default 50,000, one thread) on the
//! refitted and the rebuilt tree. Last, the time of moving the torus's vertices
//! ([`Scene::set_mesh_positions`], a refit of its tree and a new layout) against building it.

use std::time::Instant;

use hbv::geometry::Ray;
use hbv::glam::{DAffine3, DQuat, DVec3, Vec3};
use hbv::mesh::procedural::torus;
use hbv::scene::{InstanceId, InstanceTransform, Scene, SceneRay};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Grid spacing of the instances: about three torus widths (the torus is 2.6 wide, scaled by
/// 0.7 to 1.3).
const SPACING: f64 = 8.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut instances, mut runs, mut ray_count) = (10_000usize, 5usize, 50_000usize);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || -> Result<usize, Box<dyn std::error::Error>> {
            Ok(args
                .next()
                .ok_or(format!("{arg} needs a number"))?
                .parse()?)
        };
        match arg.as_str() {
            "--instances" => instances = value()?,
            "--runs" => runs = value()?.max(1),
            "--rays" => ray_count = value()?,
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }
    let mesh = torus(Vec3::ZERO, 1.0, 0.3, 264, 132);
    let wobbled: Vec<Vec3> = mesh
        .positions()
        .iter()
        .map(|p| *p * (1.0 + 0.05 * (3.0 * p.x).sin()))
        .collect();
    println!(
        "{instances} instances of a torus of {} triangles",
        mesh.triangle_count()
    );
    let mut rng = Pcg64Mcg::seed_from_u64(33);
    let side = (instances as f64).sqrt().ceil() as usize;
    let field = side as f64 * SPACING;
    let placement = |rng: &mut Pcg64Mcg, at: DVec3| {
        let turn = DQuat::from_euler(
            hbv::glam::EulerRot::XYZ,
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
        );
        let scale = DVec3::splat(rng.random_range(0.7..1.3));
        InstanceTransform::new(DAffine3::from_scale_rotation_translation(scale, turn, at))
            .expect("a turn and a scale are invertible")
    };
    let mut scene = Scene::new();
    let start = Instant::now();
    let id = scene.add_mesh(mesh);
    let add_mesh_ms = ms(start);
    let mut centres = Vec::with_capacity(instances);
    for k in 0..instances {
        let at = DVec3::new((k % side) as f64, (k / side) as f64, 0.0) * SPACING;
        centres.push(at);
        let transform = placement(&mut rng, at);
        scene.add_instance(id, transform, u32::MAX)?;
    }
    let start = Instant::now();
    scene.build();
    println!(
        "first build {:.2} ms, SAH cost {:.1}",
        ms(start),
        scene.top_level_cost().current
    );
    let rays: Vec<SceneRay> = (0..ray_count)
        .map(|_| {
            let origin = Vec3::new(
                rng.random_range(0.0..field as f32),
                rng.random_range(0.0..field as f32),
                rng.random_range(-3.0..3.0),
            );
            let direction = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.2..0.2),
            );
            SceneRay::new(Ray::new(origin, direction))
        })
        .collect();
    println!(
        "{:>6} {:>5} {:>8} {:>9} {:>10} {:>17} {:>8} {:>11} {:>12}",
        "moved",
        "move",
        "set ms",
        "refit ms",
        "rebuild ms",
        "update ms",
        "cost",
        "refit µs/r",
        "rebuild µs/r"
    );
    for percent in [1usize, 10, 100] {
        for (kind, reach) in [
            ("step", 1.3),
            ("drift", SPACING),
            ("far", 4.0 * SPACING),
            ("jump", field),
        ] {
            let moved = instances * percent / 100;
            let mut changed = scene.clone();
            let start = Instant::now();
            for k in 0..moved {
                // Every `100 / percent`-th instance, spread over the field.
                let k = k * instances / moved;
                let step = DVec3::new(
                    rng.random_range(-reach..reach),
                    rng.random_range(-reach..reach),
                    0.0,
                );
                let at = if kind == "jump" {
                    DVec3::new(
                        rng.random_range(0.0..field),
                        rng.random_range(0.0..field),
                        0.0,
                    )
                } else {
                    centres[k] + step
                };
                changed.set_transform(InstanceId(k as u32), placement(&mut rng, at))?;
            }
            let set = ms(start);
            let (refitted, refit_ms) = median_of(runs, &changed, Scene::refit);
            let (rebuilt, rebuild_ms) = median_of(runs, &changed, Scene::build);
            let (updated, update_ms) = median_of(runs, &changed, |s| {
                s.update();
            });
            let chose = if updated.top_level_cost() == rebuilt.top_level_cost() {
                "rebuild"
            } else {
                "refit"
            };
            let cost = refitted.top_level_cost().current / rebuilt.top_level_cost().current;
            println!(
                "{:>5}% {:>5} {:>8.2} {:>9.3} {:>10.3} {:>9.3} {:>7} {:>8.3} {:>11.2} {:>12.2}",
                percent,
                kind,
                set,
                refit_ms,
                rebuild_ms,
                update_ms,
                chose,
                cost,
                trace_us(&refitted, &rays),
                trace_us(&rebuilt, &rays),
            );
        }
    }
    // The mesh's vertices move: the first call builds the tree it then keeps; later ones
    // only refit it.
    let mut deformed = scene.clone();
    let start = Instant::now();
    deformed.set_mesh_positions(id, wobbled.clone())?;
    let first = ms(start);
    let (_, refit_mesh_ms) = median_of(runs, &deformed, |s| {
        s.set_mesh_positions(id, wobbled.clone())
            .expect("the positions are the mesh's, moved");
    });
    let (_, update_ms) = median_of(runs, &deformed, |s| {
        s.update();
    });
    println!(
        "mesh vertices moved: set_mesh_positions {refit_mesh_ms:.2} ms ({first:.2} ms the first \
         time), then update {update_ms:.2} ms; add_mesh (build and lay out) took {add_mesh_ms:.2} ms"
    );
    Ok(())
}

/// Runs `change` on `runs` copies of `scene`, returning the last copy and the median
/// milliseconds.
fn median_of(runs: usize, scene: &Scene, change: impl Fn(&mut Scene)) -> (Scene, f64) {
    let mut times = Vec::with_capacity(runs);
    let mut last = scene.clone();
    for _ in 0..runs {
        let mut copy = scene.clone();
        let start = Instant::now();
        change(&mut copy);
        times.push(ms(start));
        last = copy;
    }
    times.sort_by(f64::total_cmp);
    (last, times[times.len() / 2])
}

/// Microseconds per ray of closest-hit queries, one thread.
fn trace_us(scene: &Scene, rays: &[SceneRay]) -> f64 {
    let start = Instant::now();
    let hits = rays.iter().filter(|r| scene.intersect(r).is_some()).count();
    std::hint::black_box(hits);
    start.elapsed().as_secs_f64() * 1e6 / rays.len().max(1) as f64
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
