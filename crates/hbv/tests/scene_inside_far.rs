//! Inside tests, batch forms and float64 meshes far from the origin, on scenes: each against a
//! brute force (the flattened instances' own parity tests, single queries, f64 arithmetic).

use glam::{DAffine3, DQuat, DVec3, EulerRot, Vec3};
use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::geometry::Ray;
use hbv::mesh::procedural::{icosphere, torus};
use hbv::proximity::{closest_point_on_triangle, contains};
use hbv::scene::{InstanceId, InstanceTransform, Scene, SceneRay};
use hbv::{BruteForce, TriangleMesh};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

mod common;

/// Closed meshes only: inside is defined.
fn closed_meshes() -> Vec<TriangleMesh> {
    vec![
        icosphere(Vec3::ZERO, 1.0, 1),
        torus(Vec3::new(0.3, 0.0, 0.0), 1.0, 0.35, 8, 5),
    ]
}

/// Mirrored, non-uniformly scaled, rotated and moved placements of mesh 0 or 1, with masks.
fn placement() -> impl Strategy<Value = (usize, DAffine3, u32)> {
    let scale = (0.3f64..2.5, any::<bool>()).prop_map(|(s, m)| if m { -s } else { s });
    (
        0usize..2,
        (scale.clone(), scale.clone(), scale),
        (-3.2f64..3.2, -3.2f64..3.2, -3.2f64..3.2),
        (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..3.0),
        prop_oneof![3 => Just(u32::MAX), 2 => (0u32..3).prop_map(|b| 1 << b)],
    )
        .prop_map(|(mesh, (x, y, z), (a, b, c), (tx, ty, tz), mask)| {
            let affine = DAffine3::from_scale_rotation_translation(
                DVec3::new(x, y, z),
                DQuat::from_euler(EulerRot::XYZ, a, b, c),
                DVec3::new(tx, ty, tz),
            );
            (mesh, affine, mask)
        })
}

/// A scene of `placements`, the top level built over the first half (the rest pending) and
/// instance 0 removed when `remove_first`.
fn scene_of(placements: &[(usize, DAffine3, u32)], remove_first: bool) -> Scene {
    let mut scene = Scene::new();
    let ids: Vec<_> = closed_meshes()
        .into_iter()
        .map(|m| scene.add_mesh(m))
        .collect();
    for (k, &(mesh, affine, mask)) in placements.iter().enumerate() {
        if k == placements.len() / 2 {
            scene.build();
        }
        let transform = InstanceTransform::new(affine).unwrap();
        scene.add_instance(ids[mesh], transform, mask).unwrap();
    }
    if remove_first {
        scene.remove_instance(InstanceId(0)).unwrap();
    }
    scene
}

/// The world-space triangles of each live instance (`None` for a removed one), in f64.
fn world_triangles(
    scene: &Scene,
    placements: &[(usize, DAffine3, u32)],
) -> Vec<Option<Vec<[DVec3; 3]>>> {
    placements
        .iter()
        .enumerate()
        .map(|(id, &(mesh, affine, _))| {
            scene.instance_bounds(InstanceId(id as u32))?;
            let mesh = &closed_meshes()[mesh];
            Some(
                mesh.triangles()
                    .map(|t| [t.p0, t.p1, t.p2].map(|p| affine.transform_point3(p.as_dvec3())))
                    .collect(),
            )
        })
        .collect()
}

/// The distance from `p` to the nearest of `triangles`.
fn distance_to(triangles: &[[DVec3; 3]], p: DVec3) -> f64 {
    triangles
        .iter()
        .map(|[a, b, c]| (closest_point_on_triangle(p, *a, *b, *c).point - p).length())
        .fold(f64::INFINITY, f64::min)
}

proptest! {
    #![proptest_config(common::cases(48))]

    /// A point is inside the scene when it is inside an instance it sees: each instance's own
    /// parity test on its world-space triangles (a brute force), or'ed. Points within rounding
    /// of a surface are excused.
    #[test]
    fn contains_is_the_union_of_the_instances_it_sees(
        placements in prop::collection::vec(placement(), 1..6),
        remove_first in any::<bool>(),
        points in prop::collection::vec(
            ((-5.0f32..5.0, -5.0f32..5.0, -5.0f32..5.0), prop_oneof![Just(u32::MAX), (0u32..3).prop_map(|b| 1 << b)]),
            40,
        ),
    ) {
        let scene = scene_of(&placements, remove_first);
        let worlds = world_triangles(&scene, &placements);
        let flat_meshes: Vec<Option<TriangleMesh>> = worlds
            .iter()
            .map(|w| {
                w.as_ref().map(|triangles| {
                    let positions = triangles.iter().flatten().map(|p| p.as_vec3()).collect();
                    let indices = (0..triangles.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
                    TriangleMesh::new(positions, indices).unwrap()
                })
            })
            .collect();
        let mut checked = 0;
        for &((x, y, z), mask) in &points {
            let p = Vec3::new(x, y, z);
            let mut expected = false;
            let mut near_a_surface = false;
            for (id, mesh) in flat_meshes.iter().enumerate() {
                let Some(mesh) = mesh else { continue };
                if placements[id].2 & mask == 0 {
                    continue;
                }
                near_a_surface |= distance_to(worlds[id].as_ref().unwrap(), p.as_dvec3()) < 1e-4;
                expected |= contains(&BruteForce::new(mesh), p);
            }
            if near_a_surface {
                continue;
            }
            checked += 1;
            prop_assert_eq!(scene.contains_with_mask(p.as_dvec3(), mask), expected, "point {} mask {:#x}", p, mask);
        }
        prop_assert!(checked > 0);
        prop_assert!(!scene.contains(DVec3::new(f64::NAN, 0.0, 0.0)));
        prop_assert!(!scene.contains_with_mask(DVec3::ZERO, 0));
    }

    /// Every batch form answers as its single query, ray by ray and point by point.
    #[test]
    fn batches_answer_as_single_queries(
        placements in prop::collection::vec(placement(), 1..6),
        seeds in prop::collection::vec(
            ((-5.0f32..5.0, -5.0f32..5.0, -5.0f32..5.0), (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0), prop_oneof![Just(u32::MAX), (0u32..3).prop_map(|b| 1 << b)]),
            30,
        ),
    ) {
        let scene = scene_of(&placements, false);
        let rays: Vec<SceneRay> = seeds
            .iter()
            .map(|&((x, y, z), (a, b, c), mask)| {
                SceneRay::new(Ray::new(Vec3::new(x, y, z), Vec3::new(a, b, c))).with_mask(mask)
            })
            .collect();
        let points: Vec<DVec3> = rays.iter().map(|r| r.ray.origin.as_dvec3()).collect();
        let masks: Vec<u32> = rays.iter().map(|r| r.mask).collect();
        let all = scene.intersect_all_batch(&rays);
        let counts = scene.count_batch(&rays);
        let inside = scene.contains_batch(&points, Some(&masks));
        let nearest = scene.closest_point_batch(&points, Some(&masks));
        let nearest_any = scene.closest_point_batch(&points, None);
        for (i, ray) in rays.iter().enumerate() {
            prop_assert_eq!(&all[i], &scene.intersect_all(ray));
            prop_assert_eq!(counts[i], scene.count(ray));
            prop_assert_eq!(inside[i], scene.contains_with_mask(points[i], masks[i]));
            prop_assert_eq!(nearest[i], scene.nearest_points().closest_point_with_mask(points[i], masks[i]));
            prop_assert_eq!(nearest_any[i], scene.closest_point(points[i]));
        }
    }
}

/// The closest hit of the f64 ray `o + t d` on `triangles` (Möller–Trumbore in f64): `(t,
/// triangle)`.
fn closest_hit_f64(triangles: &[[DVec3; 3]], o: DVec3, d: DVec3) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (k, [a, b, c]) in triangles.iter().enumerate() {
        let (e1, e2) = (*b - *a, *c - *a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            continue;
        }
        let s = o - *a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= 0.0 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, k));
        }
    }
    best
}

/// A 1 m cube of 12 triangles with its lower corner at `corner`, in f64.
fn cube_at(corner: DVec3) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let positions = (0..8)
        .map(|i| corner + DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    let faces = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (positions, faces)
}

/// Issue's test: a 1 m cube at UTM coordinates, given in float64, answers with the accuracy
/// of its own size: hits agree with an f64 brute force to float32 precision of a few metres,
/// not of 5e6 (where float32 alone is off by decimetres, as the same cube given in float32
/// shows).
#[test]
fn a_float64_mesh_far_from_the_origin_answers_as_precisely_as_at_the_origin() {
    let corner = DVec3::new(500_000.3, 5_000_000.7, 100.1);
    let (positions, faces) = cube_at(corner);
    let moved = DVec3::new(3.25, -1.5, 0.0);
    let rotated = DAffine3::from_rotation_translation(DQuat::from_rotation_z(0.4), DVec3::ZERO);
    // The rotated instance turns the cube about the world origin: place it back near the
    // first by a translation computed in f64.
    let rotated =
        DAffine3::from_translation(corner + 2.0 * moved - rotated.transform_point3(corner))
            * rotated;
    let placements = [
        DAffine3::IDENTITY,
        DAffine3::from_translation(moved),
        rotated,
    ];

    let mut precise = Scene::new();
    let mesh = precise.add_mesh_f64(&positions, &faces).unwrap();
    let mut plain = Scene::new();
    let plain_mesh = plain.add_mesh(
        TriangleMesh::new(
            positions.iter().map(|p| p.as_vec3()).collect(),
            faces.clone(),
        )
        .unwrap(),
    );
    let mut world: Vec<[DVec3; 3]> = Vec::new();
    for affine in placements {
        let transform = InstanceTransform::new(affine).unwrap();
        precise.add_instance(mesh, transform, u32::MAX).unwrap();
        plain.add_instance(plain_mesh, transform, u32::MAX).unwrap();
        world.extend(
            faces
                .iter()
                .map(|f| f.map(|i| affine.transform_point3(positions[i as usize]))),
        );
    }
    precise.build();
    plain.build();

    let mut rng = Pcg64Mcg::seed_from_u64(7);
    let (mut worst_precise, mut worst_plain) = (0.0f64, 0.0f64);
    let mut hits = 0;
    for _ in 0..2000 {
        let centre = placements[rng.random_range(0..3)].transform_point3(corner + 0.5);
        let target = centre
            + DVec3::new(
                rng.random_range(-0.7..0.7),
                rng.random_range(-0.7..0.7),
                rng.random_range(-0.7..0.7),
            );
        let origin = target
            + DVec3::new(
                rng.random_range(-8.0..8.0),
                rng.random_range(-8.0..8.0),
                rng.random_range(3.0..9.0),
            );
        let direction = (target - origin).as_vec3().as_dvec3();
        let expected = closest_hit_f64(&world, origin, direction);
        let ray = SceneRay::from_f64(origin, direction);
        let got = precise.intersect(&ray);
        let got_plain = plain.intersect(&ray);
        match (expected, got) {
            (Some((t, _)), Some(hit)) => {
                hits += 1;
                let error = (f64::from(hit.t) - t).abs() * direction.length();
                worst_precise = worst_precise.max(error);
                if let Some(p) = got_plain {
                    worst_plain = worst_plain.max((f64::from(p.t) - t).abs() * direction.length());
                }
            }
            (None, None) => {}
            // A ray grazing an edge may hit or miss within rounding: it must pass within the
            // bound of the cube's surface.
            (e, g) => {
                let t = e.map(|e| e.0).or(g.map(|g| f64::from(g.t))).unwrap();
                let p = origin + t * direction;
                assert!(distance_to(&world, p) < 1e-5, "hit {e:?} vs {g:?}");
            }
        }
    }
    assert!(hits > 1000, "{hits} hits");
    // Distances are about 10 m: float32 of that is 1e-6 m; 5e6 in float32 is 0.5 m.
    assert!(
        worst_precise < 2e-5,
        "float64 mesh: hits off by up to {worst_precise} m"
    );
    assert!(
        worst_plain > 1e-2,
        "float32 mesh: the test should see its error ({worst_plain} m)"
    );

    // Nearest points and inside tests are as precise.
    for k in 0..200 {
        let p = corner + DVec3::new(-1.0 + 0.03 * k as f64, 0.37, 0.52 + 0.001 * k as f64);
        let found = precise.closest_point(p).unwrap();
        let exact = distance_to(&world, p);
        assert!(
            (found.distance - exact).abs() < 1e-6,
            "{} vs {exact}",
            found.distance
        );
        let in_cube = (p - corner).cmpgt(DVec3::ZERO).all() && (p - corner).cmplt(DVec3::ONE).all();
        if exact > 1e-5 && !(p - corner - moved).cmpgt(DVec3::ZERO).all() {
            assert_eq!(precise.contains(p), in_cube, "point {p}");
        }
    }
}

/// Moving an instance of a float64 mesh places the mesh as given, as on its first placement.
#[test]
fn moving_an_instance_of_a_float64_mesh_places_it_as_given() {
    let corner = DVec3::new(-123_456.7, 654_321.9, 10.3);
    let (positions, faces) = cube_at(corner);
    let mut scene = Scene::new();
    let mesh = scene.add_mesh_f64(&positions, &faces).unwrap();
    let id = scene
        .add_instance(mesh, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    scene.build();
    let above = corner + DVec3::new(0.5, 0.5, 5.0);
    let down = SceneRay::from_f64(above, DVec3::NEG_Z);
    let t0 = scene.intersect(&down).unwrap().t;
    assert!((f64::from(t0) - 4.0).abs() < 1e-5, "{t0}");
    scene
        .set_transform(
            id,
            InstanceTransform::from_translation(DVec3::new(0.0, 0.0, -2.0)).unwrap(),
        )
        .unwrap();
    let t1 = scene.intersect(&down).unwrap().t;
    assert!((f64::from(t1) - 6.0).abs() < 1e-5, "{t1}");
    scene.update();
    assert_eq!(scene.intersect(&down).unwrap().t, t1);
    assert!(scene.mesh(mesh).unwrap().bounds().max.max_element() <= 0.5);
}

#[test]
fn a_float64_mesh_with_a_bad_coordinate_or_index_is_refused_by_place() {
    let mut scene = Scene::new();
    let bad = [DVec3::ZERO, DVec3::X, DVec3::new(0.0, f64::NAN, 0.0)];
    let error = scene
        .add_mesh_f64(&bad, &[[0, 1, 2]])
        .unwrap_err()
        .to_string();
    assert!(error.contains("vertex 2"), "{error}");
    let error = scene
        .add_mesh_f64(&[DVec3::ZERO, DVec3::X, DVec3::Y], &[[0, 1, 3]])
        .unwrap_err()
        .to_string();
    assert!(error.contains('3'), "{error}");
    let huge = [DVec3::ZERO, DVec3::X, DVec3::new(0.0, 1e300, 0.0)];
    assert!(scene.add_mesh_f64(&huge, &[[0, 1, 2]]).is_err());
    assert_eq!(scene.mesh_count(), 0);
}

/// A mesh added with a tree already built answers as one the scene builds itself.
#[test]
fn a_mesh_added_with_its_tree_answers_as_one_built_by_the_scene() {
    let mesh = torus(Vec3::ZERO, 1.0, 0.3, 24, 12);
    let tree = BuilderKind::Median.build(&mesh, &BuilderOptions::default());
    let mut built = Scene::new();
    let mut given = Scene::new();
    let a = built.add_mesh(mesh.clone());
    let b = given.add_built_mesh(mesh, &tree);
    for scene_and_mesh in [(&mut built, a), (&mut given, b)] {
        let (scene, m) = scene_and_mesh;
        for k in 0..4 {
            let t =
                InstanceTransform::from_translation(DVec3::new(3.0 * k as f64, 0.0, 0.0)).unwrap();
            scene.add_instance(m, t, u32::MAX).unwrap();
        }
        scene.build();
    }
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    for _ in 0..500 {
        let o = Vec3::new(
            rng.random_range(-2.0..11.0),
            rng.random_range(-2.0..2.0),
            4.0,
        );
        let d = Vec3::new(
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
            -1.0,
        );
        let ray = SceneRay::new(Ray::new(o, d));
        assert_eq!(built.intersect(&ray), given.intersect(&ray));
    }
}
