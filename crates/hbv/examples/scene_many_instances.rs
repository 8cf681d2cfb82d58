//! Many instances of one mesh: the top level's build time, the memory the instances take, and
//! the rays' rate against the mesh's own.
//!
//! ```text
//! cargo run --release -p hbv --example scene_many_instances -- [--instances N] [--rays K] [--runs R] [--only PREFIX] [--batches]
//! ```
//!
//! The scene: `N` instances (default 10,000) of one torus of 69,696 triangles (radii 1 and
//! 0.3), on a square grid 8 apart, each turned at random and scaled by 0.7 to 1.3 (seed 33).
//! Printed:
//!
//! - the time of [`Scene::add_mesh`] and of [`Scene::build`] (the top level alone; median of
//!   `R`, default 5);
//! - resident memory (Linux `VmRSS`) after the mesh is added and after the instances are
//!   added and the top level built, and their difference per instance; and the process's peak;
//! - Mrays/s on one thread, closest hit ([`Scene::intersect`]) and any hit
//!   ([`Scene::occluded`]), median of `R` rounds of `K` rays (default 200,000), of three ray
//!   sets: `box` (origins uniform in the torus's own box, directions uniform on the sphere)
//!   traced on the mesh alone by its own layout ([`Accelerator`]), on a scene of that one
//!   instance (identity), and on the field, each ray carried into the world by a random
//!   instance's placement; `field` (origins uniform in the field's box, directions uniform on
//!   the sphere) and `level` (the same origins, directions within 0.2 of the grid's plane:
//!   each ray crosses many cells). `--only PREFIX` traces only the rows whose name starts so
//!   (`box, the field`, ...), for profiling. `--batches` times each scene row also as one batch
//!   ([`Scene::intersect_batch`], [`Scene::occluded_batch`]) on a pool of one thread, the two
//!   ways alternated round by round, in a row marked `(batch)`.

use std::time::Instant;

use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::geometry::Ray;
use hbv::glam::{DAffine3, DQuat, DVec3, EulerRot, Vec3};
use hbv::mesh::procedural::torus;
use hbv::scene::{InstanceTransform, Scene, SceneRay};
use hbv::Accelerator;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Grid spacing of the instances: about three torus widths.
const SPACING: f64 = 8.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut instances, mut ray_count, mut runs) = (10_000usize, 200_000usize, 5usize);
    let mut only = None::<String>;
    let mut batches = false;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut text = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--instances" => instances = text()?.parse::<usize>()?.max(1),
            "--rays" => ray_count = text()?.parse::<usize>()?.max(1),
            "--runs" => runs = text()?.parse::<usize>()?.max(1),
            "--only" => only = Some(text()?),
            "--batches" => batches = true,
            _ => return Err(format!("unknown argument {arg}").into()),
        }
    }
    let mesh = torus(Vec3::ZERO, 1.0, 0.3, 264, 132);
    let triangles = mesh.triangle_count();
    let rss_start = resident_kib("VmRSS");
    let mut scene = Scene::new();
    let start = Instant::now();
    let torus_id = scene.add_mesh(mesh.clone());
    let add_mesh_ms = ms(start);
    let rss_mesh = resident_kib("VmRSS");
    let side = (instances as f64).sqrt().ceil() as usize;
    // The placements are made again below rather than kept, so that the memory measured is
    // the scene's alone.
    let mut placements = Placements::new(side);
    for _ in 0..instances {
        scene.add_instance(torus_id, placements.next_transform()?, u32::MAX)?;
    }
    let start = Instant::now();
    scene.build();
    let first_build_ms = ms(start);
    let rss_built = resident_kib("VmRSS");
    let peak = resident_kib("VmHWM");
    let mut builds: Vec<f64> = (0..runs)
        .map(|_| {
            let mut copy = scene.clone();
            let start = Instant::now();
            copy.build();
            ms(start)
        })
        .collect();
    builds.sort_by(f64::total_cmp);
    println!(
        "{instances} instances of a torus of {triangles} triangles ({} as seen)",
        instances * triangles
    );
    println!(
        "add_mesh {add_mesh_ms:.1} ms; top-level build {:.2} ms (median of {runs}; first {first_build_ms:.2} ms)",
        builds[runs / 2]
    );
    match (rss_start, rss_mesh, rss_built, peak) {
        (Some(s), Some(m), Some(b), Some(p)) => println!(
            "resident: {:.1} MiB the mesh and its BVH, {:.1} MiB with the instances and the top \
             level ({:.0} bytes an instance); peak {:.1} MiB",
            (m - s) as f64 / 1024.0,
            (b - s) as f64 / 1024.0,
            (b - m) as f64 * 1024.0 / instances as f64,
            p as f64 / 1024.0
        ),
        _ => println!("resident memory: not available on this system"),
    }

    let mut rng = Pcg64Mcg::seed_from_u64(34);
    let bounds = scene.bounds();
    let field_origin = |rng: &mut Pcg64Mcg| {
        let k = Vec3::new(rng.random(), rng.random(), rng.random());
        bounds.min + (bounds.max - bounds.min) * k
    };
    let field: Vec<Ray> = (0..ray_count)
        .map(|_| Ray::new(field_origin(&mut rng), sphere_direction(&mut rng)))
        .collect();
    let level: Vec<Ray> = (0..ray_count)
        .map(|_| {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.2..0.2),
            );
            Ray::new(field_origin(&mut rng), d)
        })
        .collect();
    let local = mesh.bounds();
    let inside: Vec<Ray> = (0..ray_count)
        .map(|_| {
            let k = Vec3::new(rng.random(), rng.random(), rng.random());
            Ray::new(
                local.min + (local.max - local.min) * k,
                sphere_direction(&mut rng),
            )
        })
        .collect();
    // The same rays, each carried into the world by a random instance's placement.
    let mut placements = Placements::new(side);
    let transforms: Vec<DAffine3> = (0..instances)
        .map(|_| placements.next_transform().map(|t| t.affine()))
        .collect::<Result<_, _>>()?;
    let inside_placed: Vec<Ray> = inside
        .iter()
        .map(|r| {
            let placed = transforms[rng.random_range(0..instances)];
            Ray::new(
                placed.transform_point3(r.origin.as_dvec3()).as_vec3(),
                placed.transform_vector3(r.direction.as_dvec3()).as_vec3(),
            )
        })
        .collect();
    let mut alone = Scene::new();
    let alone_id = alone.add_mesh(mesh.clone());
    alone.add_instance(alone_id, InstanceTransform::IDENTITY, u32::MAX)?;
    alone.build();
    let options = BuilderOptions::default();
    let tree = BuilderKind::BinnedSah.build(&mesh, &options);
    let layout = LayoutKind::Wide8.lay_out(&tree, &mesh, &LayoutOptions::default());

    println!(
        "{:>26} {:>12} {:>12} {:>6}",
        "rays, traced on", "closest", "any hit", "hits"
    );
    let wanted = |what: &str| only.as_deref().is_none_or(|o| what.starts_with(o));
    if wanted("box, the mesh") {
        let mesh_rates = rates(
            runs,
            &inside,
            |r| layout.intersect(r).is_some(),
            |r| layout.occluded(r),
        );
        print_rates("box, the mesh's own layout", mesh_rates);
    }
    let scene_rates = |what: &str, scene: &Scene, rays: &[Ray]| {
        if !wanted(what) {
            return;
        }
        let rays: Vec<SceneRay> = rays.iter().map(|r| SceneRay::new(*r)).collect();
        if batches {
            let (single, batch) = single_and_batch_rates(runs, &rays, scene);
            print_rates(what, single);
            print_rates(&format!("{what} (batch)"), batch);
            return;
        }
        let measured = rates(
            runs,
            &rays,
            |r| scene.intersect(r).is_some(),
            |r| scene.occluded(r),
        );
        print_rates(what, measured);
    };
    scene_rates("box, one instance", &alone, &inside);
    scene_rates("box, the field", &scene, &inside_placed);
    scene_rates("field, the field", &scene, &field);
    scene_rates("level, the field", &scene, &level);
    Ok(())
}

/// Median Mrays/s of closest and any hit over `runs` alternated rounds, and the hit fraction.
fn rates<R>(
    runs: usize,
    rays: &[R],
    closest: impl Fn(&R) -> bool,
    any: impl Fn(&R) -> bool,
) -> (f64, f64, f64) {
    let (mut c, mut a, mut hits) = (Vec::new(), Vec::new(), 0);
    for _ in 0..runs {
        let start = Instant::now();
        hits = rays.iter().filter(|r| closest(r)).count();
        c.push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
        let start = Instant::now();
        std::hint::black_box(rays.iter().filter(|r| any(r)).count());
        a.push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
    }
    c.sort_by(f64::total_cmp);
    a.sort_by(f64::total_cmp);
    (c[runs / 2], a[runs / 2], hits as f64 / rays.len() as f64)
}

/// [`rates`] of single rays and of one-thread batches of the same rays on `scene`, the four
/// timings alternated round by round; the batches' answers checked equal to the single rays'.
fn single_and_batch_rates(
    runs: usize,
    rays: &[SceneRay],
    scene: &Scene,
) -> ((f64, f64, f64), (f64, f64, f64)) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    let single: Vec<_> = rays.iter().map(|r| scene.intersect(r)).collect();
    assert!(pool.install(|| scene.intersect_batch(rays)) == single);
    let blocked: Vec<bool> = rays.iter().map(|r| scene.occluded(r)).collect();
    assert!(pool.install(|| scene.occluded_batch(rays)) == blocked);
    let rate = |work: &dyn Fn()| {
        let start = Instant::now();
        work();
        rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6
    };
    let mut timings = [(); 4].map(|_| Vec::with_capacity(runs));
    for _ in 0..runs {
        timings[0].push(rate(&|| {
            std::hint::black_box(rays.iter().filter(|r| scene.intersect(r).is_some()).count());
        }));
        timings[1].push(rate(&|| {
            std::hint::black_box(pool.install(|| scene.intersect_batch(rays)));
        }));
        timings[2].push(rate(&|| {
            std::hint::black_box(rays.iter().filter(|r| scene.occluded(r)).count());
        }));
        timings[3].push(rate(&|| {
            std::hint::black_box(pool.install(|| scene.occluded_batch(rays)));
        }));
    }
    let [c1, cb, a1, ab] = timings.map(|mut v| {
        v.sort_by(f64::total_cmp);
        v[runs / 2]
    });
    let hits = single.iter().flatten().count() as f64 / rays.len() as f64;
    ((c1, a1, hits), (cb, ab, hits))
}

fn print_rates(what: &str, (closest, any, hits): (f64, f64, f64)) {
    println!(
        "{what:>26} {closest:>12.3} {any:>12.3} {:>5.1}%",
        100.0 * hits
    );
}

/// The instances' placements in turn: grid cell `k`, a random turn, a scale of 0.7 to 1.3.
struct Placements {
    rng: Pcg64Mcg,
    side: usize,
    next: usize,
}

impl Placements {
    fn new(side: usize) -> Self {
        Self {
            rng: Pcg64Mcg::seed_from_u64(33),
            side,
            next: 0,
        }
    }

    fn next_transform(&mut self) -> Result<InstanceTransform, hbv::scene::SceneError> {
        let k = self.next;
        self.next += 1;
        let at = DVec3::new((k % self.side) as f64, (k / self.side) as f64, 0.0) * SPACING;
        let rng = &mut self.rng;
        let turn = DQuat::from_euler(
            EulerRot::XYZ,
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
            rng.random_range(0.0..6.3),
        );
        let scale = DVec3::splat(rng.random_range(0.7..1.3));
        InstanceTransform::new(DAffine3::from_scale_rotation_translation(scale, turn, at))
    }
}

/// A direction uniform on the unit sphere.
fn sphere_direction(rng: &mut Pcg64Mcg) -> Vec3 {
    let z: f32 = rng.random_range(-1.0..1.0);
    let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A memory figure of this process in KiB from `/proc/self/status` (`VmRSS`, `VmHWM`), where
/// the system has one.
fn resident_kib(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
