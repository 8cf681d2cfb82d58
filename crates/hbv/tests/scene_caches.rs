//! Property tests: a scene's object caches ([`SceneShadowCache`], [`SceneLastHitCache`]) answer
//! exactly as the scene does, ray by ray, on random scenes of shared meshes with mirrored and
//! scaled transforms, masks, pending and removed instances; [`Scene::intersect_prim`] is the
//! scene's own test of one triangle; the counted queries answer as the plain ones.

use glam::{DAffine3, DQuat, DVec3, EulerRot, Vec3};
use hbv::cache::{SceneLastHitCache, SceneShadowCache};
use hbv::geometry::Ray;
use hbv::mesh::procedural::{ground_plane, icosphere, torus};
use hbv::scene::{InstanceId, InstanceTransform, Scene, SceneError, SceneHit, SceneRay};
use hbv::TraversalStats;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

mod common;

/// A scene drawn from `seed`: three shared meshes placed by `count` instances (rotated,
/// scaled unevenly, one in three mirrored, spread over a 12-wide cube), masks of one bit,
/// all bits or none; the top level built over the first `built`, the rest pending; instance
/// `removed` removed.
fn random_scene(seed: u64, count: usize, built: usize, removed: Option<usize>) -> Scene {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut scene = Scene::new();
    let meshes = [
        scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 1)),
        scene.add_mesh(torus(Vec3::new(0.2, 0.0, 0.0), 1.0, 0.4, 9, 5)),
        scene.add_mesh(ground_plane(1.2, 0.1, 2)),
    ];
    for k in 0..count {
        if k == built {
            scene.build();
        }
        let mut scale = DVec3::new(
            rng.random_range(0.3..2.5),
            rng.random_range(0.3..2.5),
            rng.random_range(0.3..2.5),
        );
        if rng.random_range(0..3) == 0 {
            scale.y = -scale.y;
        }
        let rotation = DQuat::from_euler(
            EulerRot::ZYX,
            rng.random_range(-3.2..3.2),
            rng.random_range(-3.2..3.2),
            rng.random_range(-3.2..3.2),
        );
        let at = DVec3::new(
            rng.random_range(-6.0..6.0),
            rng.random_range(-6.0..6.0),
            rng.random_range(-6.0..6.0),
        );
        let transform = InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            scale, rotation, at,
        ))
        .unwrap();
        let mask = match rng.random_range(0..8) {
            0 => 0,
            1..=3 => 1 << rng.random_range(0..3),
            _ => u32::MAX,
        };
        scene
            .add_instance(meshes[rng.random_range(0..3)], transform, mask)
            .unwrap();
    }
    if let Some(r) = removed.filter(|&r| r < count) {
        scene.remove_instance(InstanceId(r as u32)).unwrap();
    }
    scene
}

/// Coherent streams drawn from `seed`: from one eye, a small fan of rays around a random
/// aim (neighbouring pixels; some with an f64 origin), each followed by a shadow segment from its hit towards a light
/// and, now and then, a ray with another mask or a narrow interval.
fn ray_stream(seed: u64, scene: &Scene) -> Vec<SceneRay> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x5eed);
    let mut rays = Vec::new();
    let eye = Vec3::new(
        rng.random_range(-14.0..14.0),
        rng.random_range(-14.0..14.0),
        rng.random_range(-14.0..14.0),
    );
    let light = Vec3::new(3.0, 20.0, 11.0);
    for _ in 0..4 {
        let aim = Vec3::new(
            rng.random_range(-7.0..7.0),
            rng.random_range(-7.0..7.0),
            rng.random_range(-7.0..7.0),
        );
        let step = rng.random_range(0.001f32..0.2);
        for i in 0..6 {
            for j in 0..6 {
                let target = aim + Vec3::new(i as f32 * step, j as f32 * step, 0.0);
                let mask = match rng.random_range(0..10) {
                    0 => 1,
                    1 => 2,
                    2 => 0,
                    _ => u32::MAX,
                };
                let mut ray = Ray::new(eye, target - eye);
                if rng.random_range(0..10) == 0 {
                    ray = ray.with_interval(0.3, 0.8);
                }
                let mut camera = SceneRay::new(ray).with_mask(mask);
                if rng.random_range(0..7) == 0 {
                    // An origin given in f64, off the f32 grid.
                    let origin = eye.as_dvec3() + DVec3::splat(1e-9);
                    camera = SceneRay::from_f64(origin, (target - eye).as_dvec3())
                        .with_interval(ray.tmin, ray.tmax)
                        .with_mask(mask);
                }
                rays.push(camera);
                if let Some(hit) = scene.intersect(&camera) {
                    let point = camera.ray.at(hit.t);
                    let to_light = light - point;
                    let tmin = 1e-4 / to_light.length();
                    rays.push(SceneRay::new(
                        Ray::new(point, to_light).with_interval(tmin, 1.0 - 1e-4),
                    ));
                }
            }
        }
    }
    rays
}

/// The closest hit by testing every `(instance, prim)` alone: the smallest `(t, instance,
/// prim)`, as the scene's tie rule says.
fn closest_by_every_prim(scene: &Scene, ray: &SceneRay) -> Option<SceneHit> {
    let mut best: Option<SceneHit> = None;
    for id in 0..scene.instance_count() as u32 {
        let Some(bounds) = scene.instance_bounds(InstanceId(id)) else {
            continue;
        };
        if bounds.is_empty() {
            continue;
        }
        let prims = (0..scene.mesh_count() as u32)
            .filter_map(|m| scene.mesh(hbv::scene::MeshId(m)))
            .map(|m| m.triangle_count())
            .max()
            .unwrap_or(0) as u32;
        // Prims beyond the instance's own mesh answer `Ok(None)`: every id up to the largest
        // mesh's count may be asked.
        for prim in 0..prims {
            if let Some(hit) = scene.intersect_prim(ray, InstanceId(id), prim).unwrap() {
                if SceneHit::is_closer(hit.t, hit.instance, hit.prim, &best) {
                    best = Some(hit);
                }
            }
        }
    }
    best
}

proptest! {
    #![proptest_config(common::cases(40))]

    #[test]
    fn cached_and_counted_answers_equal_the_scenes(
        scene_seed in any::<u64>(),
        count in 1usize..14,
        built in 0usize..14,
        removed in prop::option::of(0usize..14),
        ray_seed in any::<u64>(),
    ) {
        let scene = random_scene(scene_seed, count, built, removed);
        let rays = ray_stream(ray_seed, &scene);
        let mut last = SceneLastHitCache::new(&scene);
        let mut counted_last = SceneLastHitCache::new(&scene);
        let mut shadow = SceneShadowCache::new(&scene);
        let mut counted_shadow = SceneShadowCache::new(&scene);
        let mut stats = TraversalStats::default();
        for ray in &rays {
            let want = scene.intersect(ray);
            prop_assert_eq!(last.intersect(ray), want, "last-hit {:?}", ray);
            prop_assert_eq!(counted_last.intersect_counted(ray, &mut stats), want);
            prop_assert_eq!(scene.intersect_counted(ray, &mut stats), want);
            let blocked = scene.occluded(ray);
            prop_assert_eq!(shadow.occluded(ray), blocked, "shadow {:?}", ray);
            prop_assert_eq!(counted_shadow.occluded_counted(ray, &mut stats), blocked);
            prop_assert_eq!(scene.occluded_counted(ray, &mut stats), blocked);
            // The occluder reported really blocks the ray, alone.
            let occluder = scene.occluder(ray);
            prop_assert_eq!(occluder.is_some(), blocked);
            if let Some((instance, prim)) = occluder {
                prop_assert!(scene.intersect_prim(ray, instance, prim).unwrap().is_some());
            }
            // The closest hit's triangle, alone, gives the very same answer.
            if let Some(hit) = want {
                let alone = scene.intersect_prim(ray, InstanceId(hit.instance), hit.prim);
                prop_assert_eq!(alone, Ok(Some(hit)));
            }
        }
        // Every counted query counts its ray once: two cached and two plain ones per ray.
        prop_assert_eq!(stats.rays, 4 * rays.len() as u64);
        let (l, s) = (last.stats(), shadow.stats());
        prop_assert!(l.hits + l.misses <= rays.len() as u64);
        prop_assert!(s.hits + s.misses <= rays.len() as u64);
    }

    #[test]
    fn testing_every_prim_alone_gives_the_closest_hit(
        scene_seed in any::<u64>(),
        count in 1usize..6,
        built in 0usize..6,
        removed in prop::option::of(0usize..6),
        ray_seed in any::<u64>(),
    ) {
        let scene = random_scene(scene_seed, count, built, removed);
        for ray in ray_stream(ray_seed, &scene).iter().step_by(5) {
            prop_assert_eq!(closest_by_every_prim(&scene, ray), scene.intersect(ray), "{:?}", ray);
        }
    }
}

#[test]
fn a_cache_holding_a_triangle_the_next_ray_does_not_see_asks_the_scene() {
    let mut scene = Scene::new();
    let plane = scene.add_mesh(ground_plane(1.0, 0.0, 1));
    let near = InstanceTransform::from_translation(DVec3::new(0.0, 0.0, 1.0)).unwrap();
    let far = InstanceTransform::IDENTITY;
    scene.add_instance(plane, near, 0b01).unwrap();
    scene.add_instance(plane, far, 0b10).unwrap();
    scene.build();
    let down = Ray::new(Vec3::new(0.1, 0.2, 5.0), Vec3::NEG_Z);
    let sees_both = SceneRay::new(down);
    let sees_far = sees_both.with_mask(0b10);
    let mut last = SceneLastHitCache::new(&scene);
    let mut shadow = SceneShadowCache::new(&scene);
    let first = last.intersect(&sees_both).unwrap();
    assert_eq!(first.instance, 0);
    assert!(shadow.occluded(&sees_both));
    assert_eq!(shadow.occluder().unwrap().0, InstanceId(0));
    // A neighbouring ray hits the cached triangle again: the caches answer from it.
    let neighbour = SceneRay::new(Ray::new(Vec3::new(0.1, 0.21, 5.0), Vec3::NEG_Z));
    assert_eq!(last.intersect(&neighbour), scene.intersect(&neighbour));
    assert!(shadow.occluded(&neighbour));
    assert_eq!((last.stats().hits, shadow.stats().hits), (1, 1));
    // The cached triangle is on instance 0, which the masked ray does not see.
    let second = last.intersect(&sees_far).unwrap();
    assert_eq!(second, scene.intersect(&sees_far).unwrap());
    assert_eq!(second.instance, 1);
    assert!(shadow.occluded(&sees_far));
    assert_eq!(shadow.occluder().unwrap().0, InstanceId(1));
    // A segment ending above the near plane is not blocked, though the cached triangle lies on
    // its line; nor is a ray of mask 0, nor an invalid one.
    let short = SceneRay::new(down.with_interval(0.0, 3.5));
    assert!(!shadow.occluded(&short));
    assert_eq!(last.intersect(&short), None);
    assert!(!shadow.occluded(&sees_both.with_mask(0)));
    assert_eq!(last.intersect(&sees_both.with_mask(0)), None);
    let nan = SceneRay::new(Ray::new(Vec3::new(f32::NAN, 0.0, 5.0), Vec3::NEG_Z));
    assert!(!shadow.occluded(&nan));
    assert_eq!(last.intersect(&nan), None);
    assert_eq!(
        scene.intersect_counted(&nan, &mut TraversalStats::default()),
        None
    );
    assert_eq!(scene.occluder(&nan), None);
}

#[test]
fn intersect_prim_refuses_ids_that_are_not_live_instances() {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 1));
    let empty = scene.add_mesh(hbv::TriangleMesh::new(Vec::new(), Vec::new()).unwrap());
    let a = scene
        .add_instance(sphere, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    let b = scene
        .add_instance(empty, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    let c = scene
        .add_instance(sphere, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    scene.remove_instance(c).unwrap();
    scene.build();
    let ray = SceneRay::new(Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z));
    assert_eq!(
        scene.intersect_prim(&ray, InstanceId(7), 0),
        Err(SceneError::UnknownInstance {
            instance: InstanceId(7),
            instances: 3
        })
    );
    assert_eq!(
        scene.intersect_prim(&ray, c, 0),
        Err(SceneError::RemovedInstance { instance: c })
    );
    // A prim beyond the mesh, on an empty mesh, or unseen by the mask: never hit.
    assert_eq!(scene.intersect_prim(&ray, a, 80), Ok(None));
    assert_eq!(scene.intersect_prim(&ray, a, u32::MAX), Ok(None));
    assert_eq!(scene.intersect_prim(&ray, b, 0), Ok(None));
    let hit = scene.intersect(&ray).unwrap();
    assert_eq!(scene.intersect_prim(&ray, a, hit.prim), Ok(Some(hit)));
    assert_eq!(
        scene.intersect_prim(&ray.with_mask(0), a, hit.prim),
        Ok(None)
    );
    // A degenerate triangle is never hit, even by a ray along it.
    let mut flat = Scene::new();
    let line = flat.add_mesh(
        hbv::TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]).unwrap(),
    );
    let only = flat
        .add_instance(line, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    flat.build();
    let along = SceneRay::new(Ray::new(Vec3::new(1.0, 0.0, 1.0), Vec3::NEG_Z));
    assert_eq!(flat.intersect_prim(&along, only, 0), Ok(None));
    assert_eq!(flat.intersect(&along), None);
}
