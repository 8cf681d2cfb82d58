//! Property tests: a scene's batches ([`Scene::intersect_batch`], [`Scene::occluded_batch`])
//! answer exactly what its single-ray queries answer, ray by ray and bit for bit, on random
//! live scenes (shared, mirrored and scaled meshes, masks, instances pending, moved and
//! removed, exact duplicates whose hits tie) and adversarial rays, on one thread and on two.

use glam::{DAffine3, DQuat, DVec3, EulerRot, Vec3};
use hbv::bvh::layout::LayoutKind;
use hbv::geometry::Ray;
use hbv::mesh::procedural::{ground_plane, icosphere, torus};
use hbv::scene::{
    InstanceId, InstanceTransform, MeshId, Scene, SceneHit, SceneRay, SceneStructure,
};
use hbv::TriangleMesh;
use proptest::prelude::*;

mod common;

/// One placement as generated: mesh, per-axis scale (a negative one mirrors), turn,
/// translation and mask; or a copy of an earlier placement (`copy_of`), whose hits then tie.
#[derive(Clone, Debug)]
struct Placement {
    mesh: usize,
    scale: DVec3,
    turn: (f64, f64, f64),
    at: DVec3,
    mask: u32,
    copy_of: Option<usize>,
}

impl Placement {
    fn transform(&self) -> InstanceTransform {
        let (a, b, c) = self.turn;
        InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            self.scale,
            DQuat::from_euler(EulerRot::XYZ, a, b, c),
            self.at,
        ))
        .unwrap()
    }
}

/// What happens to the scene after its first build, in order.
#[derive(Clone, Debug)]
enum Change {
    /// A new instance: pending until the next update.
    Add(Placement),
    /// Instance `k % count` moves (pending until the next update).
    Move(usize, Placement),
    SetMask(usize, u32),
    Remove(usize),
    Update,
}

/// A ray as generated: origin, direction, mask, interval, and how it is aimed or spoiled.
#[derive(Clone, Debug)]
struct RaySeed {
    origin: Vec3,
    direction: Vec3,
    mask: u32,
    tmin: f32,
    tmax: f32,
    kind: u8,
}

/// Small meshes, one of them empty, and after them each nonempty one again with one more
/// triangle far off (`with_far_triangle`).
fn meshes() -> Vec<TriangleMesh> {
    let meshes = [
        icosphere(Vec3::ZERO, 1.0, 2),
        torus(Vec3::new(0.2, 0.0, -0.1), 1.0, 0.35, 12, 6),
        ground_plane(1.5, -0.25, 4),
        TriangleMesh::new(Vec::new(), Vec::new()).unwrap(),
    ];
    let grown: Vec<TriangleMesh> = meshes[..3].iter().map(with_far_triangle).collect();
    meshes.into_iter().chain(grown).collect()
}

/// Mesh `mesh` of [`meshes`] with one more triangle far off: its faces are the mesh's, with the
/// same ids, so a copy of an instance placed so ties with it on every face, but its box is
/// larger, so rays enter it first and find its hits first: the tie must still go to the
/// smaller instance.
fn with_far_triangle(mesh: &TriangleMesh) -> TriangleMesh {
    let mut positions = mesh.positions().to_vec();
    let mut indices = mesh.indices().to_vec();
    let first = positions.len() as u32;
    positions.extend([
        Vec3::new(-3.0, -3.0, -3.0),
        Vec3::new(-2.8, -3.0, -3.0),
        Vec3::new(-3.0, -2.8, -3.0),
    ]);
    indices.push([first, first + 1, first + 2]);
    TriangleMesh::new(positions, indices).unwrap()
}

fn axis_scale() -> impl Strategy<Value = f64> {
    (0.3f64..2.5, any::<bool>()).prop_map(|(s, mirror)| if mirror { -s } else { s })
}

fn mask() -> impl Strategy<Value = u32> {
    prop_oneof![
        4 => Just(u32::MAX),
        3 => (0u32..4).prop_map(|b| 1 << b),
        1 => Just(0),
    ]
}

fn placement() -> impl Strategy<Value = Placement> {
    let uniform = (0.3f64..2.5).prop_map(DVec3::splat);
    let scale = prop_oneof![
        uniform,
        (axis_scale(), axis_scale(), axis_scale()).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
    ];
    (
        0usize..4,
        scale,
        (-3.2f64..3.2, -3.2f64..3.2, -3.2f64..3.2),
        (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0),
        mask(),
        prop_oneof![3 => Just(None), 1 => any::<usize>().prop_map(Some)],
    )
        .prop_map(|(mesh, scale, turn, (x, y, z), mask, copy_of)| Placement {
            mesh,
            scale,
            turn,
            at: DVec3::new(x, y, z),
            mask,
            copy_of,
        })
}

fn change() -> impl Strategy<Value = Change> {
    prop_oneof![
        2 => placement().prop_map(Change::Add),
        2 => (any::<usize>(), placement()).prop_map(|(k, p)| Change::Move(k, p)),
        1 => (any::<usize>(), mask()).prop_map(|(k, m)| Change::SetMask(k, m)),
        2 => any::<usize>().prop_map(Change::Remove),
        1 => Just(Change::Update),
    ]
}

fn ray_seed() -> impl Strategy<Value = RaySeed> {
    let c = || -8.0f32..8.0;
    (
        (c(), c(), c()),
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        prop_oneof![4 => Just(u32::MAX), 2 => any::<u32>(), 2 => (0u32..4).prop_map(|b| 1 << b)],
        prop_oneof![3 => Just(0.0f32), 1 => 0.0f32..6.0],
        prop_oneof![3 => Just(f32::INFINITY), 1 => 0.5f32..12.0],
        any::<u8>(),
    )
        .prop_map(|((x, y, z), (a, b, c), mask, tmin, tmax, kind)| RaySeed {
            origin: Vec3::new(x, y, z),
            direction: Vec3::new(a, b, c),
            mask,
            tmin,
            tmax,
            kind,
        })
}

/// The scene: every mesh, the first placements built into the top level, then the changes
/// (moves and additions left pending unless an update follows).
fn make_scene(layout: LayoutKind, placements: &[Placement], changes: &[Change]) -> Scene {
    let mut scene = Scene::with_structure(SceneStructure {
        layout,
        ..SceneStructure::default()
    });
    let ids: Vec<MeshId> = meshes().into_iter().map(|m| scene.add_mesh(m)).collect();
    let mut placed: Vec<Placement> = Vec::new();
    // A copy takes an earlier placement's transform and its mesh, or that mesh with a far
    // triangle more (mask its own): its hits tie with the earlier one's.
    let resolve = |p: &Placement, placed: &[Placement]| match p.copy_of {
        Some(k) if !placed.is_empty() => {
            let original = &placed[k % placed.len()];
            Placement {
                mesh: match original.mesh {
                    m @ 0..3 if k % 3 != 0 => m + 4,
                    m => m,
                },
                mask: p.mask,
                copy_of: None,
                ..original.clone()
            }
        }
        _ => p.clone(),
    };
    let add = |scene: &mut Scene, p: &Placement, placed: &mut Vec<Placement>| {
        let p = resolve(p, placed);
        scene
            .add_instance(ids[p.mesh], p.transform(), p.mask)
            .unwrap();
        placed.push(p);
    };
    for p in placements {
        add(&mut scene, p, &mut placed);
    }
    scene.build();
    for change in changes {
        let id = |k: usize| InstanceId((k % placed.len()) as u32);
        // Changes to a removed instance are refused: that is tested elsewhere (`scene.rs`).
        match change {
            Change::Add(p) => add(&mut scene, p, &mut placed),
            Change::Move(k, p) => {
                let p = resolve(p, &placed);
                let _ = scene.set_transform(id(*k), p.transform());
            }
            Change::SetMask(k, mask) => {
                let _ = scene.set_mask(id(*k), *mask);
            }
            Change::Remove(k) => {
                let _ = scene.remove_instance(id(*k));
            }
            Change::Update => {
                scene.update();
            }
        }
    }
    scene
}

/// The rays of `seeds`: random, along an axis, aimed at an instance's box centre (most hit),
/// from inside an instance, and spoiled ones (NaN, a zero direction, an empty interval).
fn rays(seeds: &[RaySeed], scene: &Scene) -> Vec<SceneRay> {
    let boxes: Vec<_> = (0..scene.instance_count() as u32)
        .filter_map(|k| scene.instance_bounds(InstanceId(k)))
        .filter(|b| !b.is_empty())
        .collect();
    seeds
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let target = boxes
                .get(s.kind as usize % boxes.len().max(1))
                .map_or(Vec3::ZERO, |b| b.center());
            let (origin, direction) = match s.kind % 8 {
                0 | 1 => (s.origin, s.direction),
                2 => (s.origin, [Vec3::X, -Vec3::Y, Vec3::Z][k % 3]),
                3 => (target + s.direction * 0.3, s.direction),
                4 => (s.origin, Vec3::ZERO),
                5 if s.kind & 64 != 0 => (Vec3::new(f32::NAN, 0.0, 0.0), s.direction),
                _ => (s.origin, target - s.origin + s.direction * 0.1),
            };
            let (tmin, tmax) = if s.kind & 128 != 0 && s.kind % 8 == 7 {
                (s.tmax, s.tmin) // often empty: tmin > tmax
            } else {
                (s.tmin, s.tmax)
            };
            SceneRay::new(Ray::new(origin, direction).with_interval(tmin, tmax)).with_mask(s.mask)
        })
        .collect()
}

/// A closest hit as bits, so that equal means bit for bit (`-0.0` is not `0.0`).
fn bits(hit: &Option<SceneHit>) -> Option<(u32, u32, u32, u32, u32, [u32; 3])> {
    hit.map(|h| {
        (
            h.t.to_bits(),
            h.u.to_bits(),
            h.v.to_bits(),
            h.prim,
            h.instance,
            h.normal.to_array().map(f32::to_bits),
        )
    })
}

/// Both batches of `rays`, on a pool of `threads` threads, against the single-ray answers.
fn check(scene: &Scene, rays: &[SceneRay], threads: usize) -> Result<(), TestCaseError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (hits, occluded) =
        pool.install(|| (scene.intersect_batch(rays), scene.occluded_batch(rays)));
    prop_assert_eq!(hits.len(), rays.len());
    prop_assert_eq!(occluded.len(), rays.len());
    for (k, ray) in rays.iter().enumerate() {
        let single = scene.intersect(ray);
        prop_assert_eq!(
            bits(&hits[k]),
            bits(&single),
            "closest hit of ray {} ({:?}) on {} threads: batch {:?}, single {:?}",
            k,
            ray,
            threads,
            hits[k],
            single
        );
        prop_assert_eq!(
            occluded[k],
            scene.occluded(ray),
            "any hit of ray {} ({:?}) on {} threads",
            k,
            ray,
            threads
        );
    }
    Ok(())
}

fn layout() -> impl Strategy<Value = LayoutKind> {
    prop_oneof![
        4 => Just(LayoutKind::Wide8),
        1 => Just(LayoutKind::Wide4),
        1 => Just(LayoutKind::Skip),
        1 => Just(LayoutKind::Ordered),
    ]
}

proptest! {
    #![proptest_config(common::cases(48))]

    #[test]
    fn batches_answer_as_single_rays_on_live_scenes(
        layout in layout(),
        placements in prop::collection::vec(placement(), 1..14),
        changes in prop::collection::vec(change(), 0..10),
        seeds in prop::collection::vec(ray_seed(), 1..160),
    ) {
        let scene = make_scene(layout, &placements, &changes);
        let rays = rays(&seeds, &scene);
        check(&scene, &rays, 1)?;
        check(&scene, &rays, 2)?;
    }
}

/// A batch of several waves of rays through a field of tied duplicates: the waves split the
/// batch across threads, and every ray answers as alone.
#[test]
fn batches_of_many_waves_answer_as_single_rays() {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
    let ring = scene.add_mesh(torus(Vec3::ZERO, 1.0, 0.3, 16, 8));
    let larger_sphere = scene.add_mesh(with_far_triangle(&icosphere(Vec3::ZERO, 1.0, 2)));
    for k in 0..60 {
        let at = DVec3::new(
            (k % 5) as f64 * 2.5,
            (k / 5 % 4) as f64 * 2.5,
            (k / 20) as f64,
        );
        let transform = InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            DVec3::new(if k % 3 == 0 { -1.0 } else { 1.0 }, 1.0, 0.8),
            DQuat::from_rotation_y(k as f64 * 0.4),
            at,
        ))
        .unwrap();
        let mesh = if k % 2 == 0 { sphere } else { ring };
        scene.add_instance(mesh, transform, 1 << (k % 3)).unwrap();
        // Every fourth sphere again, with a far triangle more: the copy ties with it on every
        // face, and rays enter its larger box first.
        if k % 4 == 0 {
            scene
                .add_instance(larger_sphere, transform, 1 << (k % 3))
                .unwrap();
        }
    }
    scene.build();
    scene.remove_instance(InstanceId(7)).unwrap();
    scene
        .set_transform(InstanceId(9), InstanceTransform::IDENTITY)
        .unwrap();
    let mut state = 12345u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    let rays: Vec<SceneRay> = (0..9_000)
        .map(|k| {
            let origin = Vec3::new(5.0 + 8.0 * next(), 4.0 + 6.0 * next(), 1.0 + 4.0 * next());
            let direction = Vec3::new(next(), next(), next());
            SceneRay::new(Ray::new(origin, direction)).with_mask(if k % 5 == 0 {
                0b10
            } else {
                u32::MAX
            })
        })
        .collect();
    for threads in [1, 2] {
        check(&scene, &rays, threads).unwrap();
    }
}
