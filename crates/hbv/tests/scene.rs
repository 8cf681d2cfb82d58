//! Property tests: a scene answers as a brute force over its flattened world-space triangles,
//! within the accuracy bound stated in `hbv::scene` (module notes), ray by ray.

use glam::{DAffine3, DMat4, DQuat, DVec3, EulerRot, Vec3};
use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::geometry::Ray;
use hbv::mesh::procedural::{ground_plane, icosphere, torus};
use hbv::scene::{
    FlattenedScene, InstanceId, InstanceTransform, MeshId, Scene, SceneError, SceneHit, SceneRay,
    SceneStructure, TopLevelUpdate,
};
use hbv::TriangleMesh;
use proptest::prelude::*;
use proptest::strategy::ValueTree;

mod common;

/// One instance as generated: which mesh, and its scale, rotation, translation and mask.
#[derive(Clone, Debug)]
struct InstanceSpec {
    mesh: usize,
    scale: DVec3,
    euler: (f64, f64, f64),
    translation: DVec3,
    mask: u32,
}

impl InstanceSpec {
    fn affine(&self, far: DVec3) -> DAffine3 {
        let (a, b, c) = self.euler;
        DAffine3::from_scale_rotation_translation(
            self.scale,
            DQuat::from_euler(EulerRot::XYZ, a, b, c),
            self.translation + far,
        )
    }
}

/// A scene as generated: its instances, a far offset added to every translation (and ray
/// origin), and the rays' seeds.
#[derive(Clone, Debug)]
struct SceneSpec {
    instances: Vec<InstanceSpec>,
    far: DVec3,
    rays: Vec<(Vec3, Vec3, u32, u8)>,
}

/// The shared meshes: small, so that the brute force stays quick.
fn meshes() -> Vec<TriangleMesh> {
    vec![
        icosphere(Vec3::ZERO, 1.0, 1),
        torus(Vec3::new(0.3, 0.0, 0.0), 1.0, 0.35, 8, 5),
        ground_plane(1.5, -0.25, 3),
    ]
}

fn scale() -> impl Strategy<Value = f64> {
    (0.25f64..3.0, any::<bool>()).prop_map(|(s, mirror)| if mirror { -s } else { s })
}

fn instance_mask() -> impl Strategy<Value = u32> {
    prop_oneof![
        4 => Just(u32::MAX),
        3 => (0u32..4).prop_map(|b| 1 << b),
        1 => Just(0),
    ]
}

fn instance_spec() -> impl Strategy<Value = InstanceSpec> {
    (
        0usize..3,
        (scale(), scale(), scale()),
        (-3.2f64..3.2, -3.2f64..3.2, -3.2f64..3.2),
        (-6.0f64..6.0, -6.0f64..6.0, -6.0f64..6.0),
        instance_mask(),
    )
        .prop_map(
            |(mesh, (x, y, z), euler, (tx, ty, tz), mask)| InstanceSpec {
                mesh,
                scale: DVec3::new(x, y, z),
                euler,
                translation: DVec3::new(tx, ty, tz),
                mask,
            },
        )
}

fn scene_spec() -> impl Strategy<Value = SceneSpec> {
    let coordinate = -9.0f32..9.0;
    let ray = (
        (coordinate.clone(), coordinate.clone(), coordinate),
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        prop_oneof![4 => Just(u32::MAX), 2 => any::<u32>(), 2 => (0u32..4).prop_map(|b| 1 << b)],
        any::<u8>(),
    )
        .prop_map(|((x, y, z), (a, b, c), mask, kind)| {
            (Vec3::new(x, y, z), Vec3::new(a, b, c), mask, kind)
        });
    (
        prop::collection::vec(instance_spec(), 1..9),
        prop_oneof![
            3 => Just(DVec3::ZERO),
            1 => Just(DVec3::new(1e5, -1e5, 5e4)),
        ],
        prop::collection::vec(ray, 48),
    )
        .prop_map(|(instances, far, rays)| SceneSpec {
            instances,
            far,
            rays,
        })
}

/// The scene of `spec` (built, or with its last instances left out of the top level when
/// `partly_built`), and its flattened form.
fn make_scene(spec: &SceneSpec, partly_built: bool) -> (Scene, FlattenedScene) {
    let mut scene = Scene::new();
    let ids: Vec<MeshId> = meshes().into_iter().map(|m| scene.add_mesh(m)).collect();
    for (k, instance) in spec.instances.iter().enumerate() {
        let transform = InstanceTransform::new(instance.affine(spec.far)).unwrap();
        scene
            .add_instance(ids[instance.mesh], transform, instance.mask)
            .unwrap();
        if partly_built && k == spec.instances.len() / 2 {
            scene.build();
        }
    }
    if !partly_built {
        scene.build();
    }
    let flat = scene.flattened().unwrap();
    (scene, flat)
}

/// The rays of `spec`: random ones, ones along an axis or with a zero component, ones aimed at
/// a world vertex (through edges) and at a corner or face of an instance's world box.
fn rays(spec: &SceneSpec, scene: &Scene, flat: &FlattenedScene) -> Vec<SceneRay> {
    let far = spec.far.as_vec3();
    let positions = flat.mesh.positions();
    spec.rays
        .iter()
        .enumerate()
        .map(|(k, &(origin, dir, mask, kind))| {
            let origin = origin + far;
            let instance = InstanceId((k % scene.instance_count()) as u32);
            // A removed instance (live scenes) has no box: aim at the whole scene's instead.
            let instance_box = scene
                .instance_bounds(instance)
                .unwrap_or_else(|| scene.bounds());
            // A point near a face chosen by the seeds: most such rays hit something.
            let face =
                flat.mesh.indices()[(kind as usize * 104_729 + k * 7) % flat.mesh.indices().len()];
            let inside = face
                .iter()
                .map(|&v| positions[v as usize] - far)
                .sum::<Vec3>()
                / 3.0
                + far
                + dir * 0.2;
            let direction = match kind % 7 {
                0 => dir,
                1 => [Vec3::X, -Vec3::Y, Vec3::Z][k % 3],
                2 => (inside - origin) * Vec3::new(1.0, 0.0, 1.0),
                6 => inside - origin,
                3 => positions[(kind as usize * 7919 + k * 31) % positions.len()] - origin,
                4 => {
                    // At a corner of an instance's world box.
                    let corner = Vec3::select(
                        glam::BVec3::new(kind & 8 != 0, kind & 16 != 0, kind & 32 != 0),
                        instance_box.min,
                        instance_box.max,
                    );
                    corner - origin
                }
                _ => {
                    // Through a face of an instance's world box, at a point set by the direction
                    // seed.
                    let t = (dir + Vec3::ONE) * 0.5;
                    let mut target = instance_box.min + t * (instance_box.max - instance_box.min);
                    target[k % 3] = if kind & 64 != 0 {
                        instance_box.min[k % 3]
                    } else {
                        instance_box.max[k % 3]
                    };
                    target - origin
                }
            };
            SceneRay::new(Ray::new(origin, direction)).with_mask(mask)
        })
        .collect()
}

/// What the test knows of an instance: its transform and the size terms of the bound.
struct InstanceTerms {
    affine: DAffine3,
    conditioning: f64,
    largest_world: f64,
}

fn instance_terms(spec: &SceneSpec, flat: &FlattenedScene) -> Vec<InstanceTerms> {
    spec.instances
        .iter()
        .enumerate()
        .map(|(i, instance)| {
            let affine = instance.affine(spec.far);
            let faces =
                &flat.mesh.indices()[flat.offsets[i] as usize..flat.offsets[i + 1] as usize];
            let largest_world = faces
                .iter()
                .flatten()
                .map(|&v| f64::from(flat.mesh.positions()[v as usize].abs().max_element()))
                .fold(0.0, f64::max);
            InstanceTerms {
                affine,
                conditioning: InstanceTransform::new(affine).unwrap().conditioning(),
                largest_world,
            }
        })
        .collect()
}

/// The module's `ε` for `instance` and the ray at `t`.
fn epsilon(terms: &InstanceTerms, ray: &Ray, t: f64) -> f64 {
    let o = ray.origin.as_dvec3();
    let d = ray.direction.as_dvec3();
    let b = terms.affine.translation;
    let k = terms.conditioning;
    2f64.powi(-22)
        * (k * ((o - b).abs().max_element() + t * d.abs().max_element()) + terms.largest_world)
        + 2f64.powi(-48) * k * (o.abs().max_element() + b.abs().max_element())
}

/// The world vertices of `prim` of `instance`, mapped exactly in f64.
fn world_triangle(
    meshes: &[TriangleMesh],
    spec: &SceneSpec,
    terms: &InstanceTerms,
    instance: u32,
    prim: u32,
) -> [DVec3; 3] {
    let mesh = &meshes[spec.instances[instance as usize].mesh];
    let t = mesh.triangle(prim as usize);
    [t.p0, t.p1, t.p2].map(|p| terms.affine.transform_point3(p.as_dvec3()))
}

/// Whether the ray's line passes within `eps` of an edge of `triangle`.
fn near_an_edge(ray: &Ray, triangle: &[DVec3; 3], eps: f64) -> bool {
    (0..3).any(|k| common::line_segment_distance(ray, triangle[k], triangle[(k + 1) % 3]) <= eps)
}

/// The module's bound on `|t_scene - t_flat|` for a hit at `t` on `triangle`.
fn t_bound(terms: &InstanceTerms, ray: &Ray, triangle: &[DVec3; 3], t: f64) -> f64 {
    let o = ray.origin.as_dvec3();
    let d = ray.direction.as_dvec3();
    let normal = (triangle[1] - triangle[0])
        .cross(triangle[2] - triangle[0])
        .normalize();
    let far = triangle
        .iter()
        .map(|p| (*p - o).abs().max_element())
        .fold(0.0, f64::max);
    epsilon(terms, ray, t) / normal.dot(d).abs()
        + 2f64.powi(-20) * (terms.conditioning + 1.0) * far / d.abs().max_element()
}

/// How the scene's answers compared with the brute force's.
#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    hits: usize,
    /// Disagreements the bound excuses, on rays aimed at a vertex (through edges by design).
    excused_at_vertices: usize,
    /// Disagreements the bound excuses, on the other rays.
    excused: usize,
}

/// Checks every ray of `spec` on the scene against the flattened brute force (module notes of
/// `hbv::scene`), returning the tally.
fn check_scene(spec: &SceneSpec, scene: &Scene, flat: &FlattenedScene) -> Tally {
    let meshes = meshes();
    let terms = instance_terms(spec, flat);
    let rays = rays(spec, scene, flat);
    let batch = scene.intersect_batch(&rays);
    let occluded = scene.occluded_batch(&rays);
    let mut tally = Tally::default();
    for (k, ray) in rays.iter().enumerate() {
        let (ours, theirs) = (scene.intersect(ray), flat.intersect(ray));
        assert_eq!(batch[k], ours, "ray {k}: batch and single answers differ");
        assert_eq!(
            occluded[k],
            ours.is_some(),
            "ray {k}: occluded and intersect disagree"
        );
        assert_eq!(scene.occluded(ray), ours.is_some(), "ray {k}");
        tally.rays += 1;
        let same = matches!((ours, theirs), (Some(a), Some(b)) if (a.instance, a.prim) == (b.instance, b.prim));
        let r = &ray.ray;
        if let (Some(a), true) = (ours, same) {
            tally.hits += 1;
            let b = theirs.unwrap();
            let term = &terms[a.instance as usize];
            let tri = world_triangle(&meshes, spec, term, a.instance, a.prim);
            let bound = t_bound(term, r, &tri, f64::from(a.t.max(b.t)));
            let difference = f64::from(a.t - b.t).abs();
            assert!(
                difference <= bound,
                "ray {k} {ray:?}: t {} vs flattened {}, bound {bound:e}",
                a.t,
                b.t
            );
            check_normal(&a, &b, &tri, k);
            continue;
        }
        if ours.is_none() && theirs.is_none() {
            continue;
        }
        // A disagreement: excused only near an edge of a triangle involved, or at a near tie.
        let involved: Vec<(u32, u32, f32)> = [ours, theirs]
            .iter()
            .flatten()
            .map(|h| (h.instance, h.prim, h.t))
            .collect();
        let t_far = involved.iter().map(|h| f64::from(h.2)).fold(0.0, f64::max);
        let near_edge = involved.iter().any(|&(i, p, _)| {
            let term = &terms[i as usize];
            let tri = world_triangle(&meshes, spec, term, i, p);
            near_an_edge(r, &tri, epsilon(term, r, t_far))
        });
        let near_tie = match (ours, theirs) {
            (Some(a), Some(b)) => [a, b].iter().all(|h| {
                let term = &terms[h.instance as usize];
                let tri = world_triangle(&meshes, spec, term, h.instance, h.prim);
                f64::from(a.t - b.t).abs() <= 2.0 * t_bound(term, r, &tri, t_far)
            }),
            _ => false,
        };
        // Or a hit within the t bound of an end of the ray's interval (a ray that starts on a
        // surface, far from the origin): the other side's hit may lie just outside it.
        let near_end = involved.iter().any(|&(i, p, t)| {
            let term = &terms[i as usize];
            let tri = world_triangle(&meshes, spec, term, i, p);
            let bound = t_bound(term, r, &tri, t_far);
            let t = f64::from(t);
            t - f64::from(r.tmin) <= bound || f64::from(r.tmax) - t <= bound
        });
        if std::env::var("SCENE_TEST_VERBOSE").is_ok() {
            eprintln!("excused ray {k} {ray:?}: scene {ours:?}, flattened {theirs:?}, edge {near_edge} tie {near_tie} end {near_end}");
        }
        assert!(
            near_edge || near_tie || near_end,
            "ray {k} {ray:?}: scene {ours:?}, flattened {theirs:?}, not excused"
        );
        if spec.rays[k].3 % 7 == 3 {
            tally.excused_at_vertices += 1;
        } else {
            tally.excused += 1;
        }
    }
    tally
}

/// The scene's normal is the exact world normal of the triangle, to f32 rounding, and points
/// the way the flattened (rounded) triangle's does.
fn check_normal(ours: &SceneHit, theirs: &SceneHit, triangle: &[DVec3; 3], k: usize) {
    let exact = (triangle[1] - triangle[0])
        .cross(triangle[2] - triangle[0])
        .normalize();
    let n = ours.normal.as_dvec3();
    assert!(
        (n - exact).length() < 1e-6,
        "ray {k}: normal {n} vs exact {exact}"
    );
    assert!(
        n.dot(theirs.normal.as_dvec3()) > 0.0,
        "ray {k}: normal {n} vs flattened {}",
        theirs.normal
    );
}

proptest! {
    #![proptest_config(common::cases(64))]

    #[test]
    fn scenes_answer_as_their_flattened_brute_force(spec in scene_spec(), partly in any::<bool>()) {
        let (scene, flat) = make_scene(&spec, partly);
        let tally = check_scene(&spec, &scene, &flat);
        // Excused rays are rare: the bound is a few ulps of the coordinates, the meshes'
        // triangles are thousands of ulps across (at the far offset, hundreds).
        if std::env::var("SCENE_TEST_VERBOSE").is_ok() {
            eprintln!("far {} {tally:?}", spec.far.x);
        }
        let limit = if spec.far == DVec3::ZERO { 1 } else { tally.rays / 8 };
        prop_assert!(tally.excused <= limit, "{tally:?}");
    }
}

#[test]
fn excused_rays_are_rare_over_many_scenes() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let mut total = Tally::default();
    for _ in 0..24 {
        let spec = scene_spec().new_tree(&mut runner).unwrap().current();
        let (scene, flat) = make_scene(&spec, false);
        let tally = check_scene(&spec, &scene, &flat);
        total.rays += tally.rays;
        total.hits += tally.hits;
        total.excused += tally.excused;
        total.excused_at_vertices += tally.excused_at_vertices;
    }
    assert!(
        total.hits * 5 > total.rays,
        "{total:?}: too few hits to test"
    );
    eprintln!("{total:?}");
    assert!(total.excused * 100 <= total.rays, "{total:?}");
}

#[test]
fn every_structure_gives_the_same_answers() {
    let spec = scene_spec()
        .new_tree(&mut proptest::test_runner::TestRunner::deterministic())
        .unwrap()
        .current();
    let (reference, flat) = make_scene(&spec, false);
    let rays = rays(&spec, &reference, &flat);
    for (builder, layout) in [
        (BuilderKind::Insertion, LayoutKind::Recursive),
        (BuilderKind::SweepSah, LayoutKind::Ordered),
        (BuilderKind::Lbvh, LayoutKind::Wide4),
    ] {
        let mut scene = Scene::with_structure(SceneStructure {
            builder,
            builder_options: BuilderOptions::default(),
            layout,
            layout_options: LayoutOptions::default(),
        });
        for mesh in meshes() {
            scene.add_mesh(mesh);
        }
        for instance in &spec.instances {
            let transform = InstanceTransform::new(instance.affine(spec.far)).unwrap();
            scene
                .add_instance(MeshId(instance.mesh as u32), transform, instance.mask)
                .unwrap();
        }
        scene.build();
        assert_eq!(
            scene.intersect_batch(&rays),
            reference.intersect_batch(&rays),
            "{builder} {layout}"
        );
    }
}

#[test]
fn ties_go_to_the_smaller_instance_then_the_smaller_prim() {
    // Two instances of one sphere at the same place: every hit is a tie between them.
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
    for _ in 0..3 {
        scene
            .add_instance(sphere, InstanceTransform::IDENTITY, u32::MAX)
            .unwrap();
    }
    scene.build();
    for k in 0..50 {
        let d = Vec3::new((k as f32 * 0.7).sin(), (k as f32 * 1.3).cos(), 0.4);
        let ray = SceneRay::new(Ray::new(-4.0 * d, d));
        let hit = scene.intersect(&ray).unwrap();
        assert_eq!(hit.instance, 0);
        assert_eq!(scene.intersect(&ray.with_mask(0)), None);
    }
}

#[test]
fn a_mirrored_instance_flips_the_normal() {
    let mut scene = Scene::new();
    let plane = scene.add_mesh(ground_plane(1.0, 0.0, 1));
    let mirror = InstanceTransform::new(DAffine3::from_scale(DVec3::new(1.0, -1.0, 1.0))).unwrap();
    scene
        .add_instance(plane, InstanceTransform::IDENTITY, 1)
        .unwrap();
    scene.add_instance(plane, mirror, 2).unwrap();
    scene.build();
    let ray = |mask| SceneRay::new(Ray::new(Vec3::new(0.1, 0.2, 3.0), -Vec3::Z)).with_mask(mask);
    let (a, b) = (
        scene.intersect(&ray(1)).unwrap(),
        scene.intersect(&ray(2)).unwrap(),
    );
    assert_eq!((a.instance, b.instance), (0, 1));
    assert!((a.t - 3.0).abs() < 1e-6 && (b.t - 3.0).abs() < 1e-6);
    assert_eq!(a.normal, -b.normal);
    assert_eq!(a.normal.z.abs(), 1.0);
}

#[test]
fn bad_transforms_and_unknown_meshes_are_refused() {
    let bad = [
        DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0)),
        DAffine3::from_scale(DVec3::ZERO),
        DAffine3::from_translation(DVec3::new(f64::NAN, 0.0, 0.0)),
        DAffine3::from_translation(DVec3::new(0.0, f64::INFINITY, 0.0)),
        DAffine3::from_scale(DVec3::new(1.0, f64::NEG_INFINITY, 1.0)),
        DAffine3::from_cols(DVec3::X, DVec3::Y, DVec3::X + DVec3::Y, DVec3::ZERO),
    ];
    for affine in bad {
        let error = InstanceTransform::new(affine).unwrap_err();
        assert!(error.to_string().starts_with("transform: "), "{error}");
        assert!(matches!(
            error,
            SceneError::NonFiniteTransform { .. } | SceneError::SingularTransform { .. }
        ));
    }
    let mut projective = DMat4::IDENTITY;
    projective.w_axis.w = 2.0;
    assert!(matches!(
        InstanceTransform::from_mat4(projective),
        Err(SceneError::NotAffine { .. })
    ));
    let mut scene = Scene::new();
    let error = scene
        .add_instance(MeshId(0), InstanceTransform::IDENTITY, 1)
        .unwrap_err();
    assert_eq!(
        error,
        SceneError::UnknownMesh {
            mesh: MeshId(0),
            meshes: 0
        }
    );
    assert_eq!(
        error.to_string(),
        "mesh: id 0 does not exist; the scene has 0 mesh(es)"
    );
    let id = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 0));
    assert!(scene
        .add_instance(MeshId(id.0 + 1), InstanceTransform::IDENTITY, 1)
        .is_err());
    assert_eq!(scene.instance_count(), 0);
    assert_eq!(scene.instance_bounds(InstanceId(0)), None);
}

#[test]
fn a_scene_of_one_identity_instance_answers_as_its_mesh() {
    let mesh = torus(Vec3::ZERO, 1.0, 0.3, 12, 6);
    let mut scene = Scene::new();
    let id = scene.add_mesh(mesh.clone());
    scene
        .add_instance(id, InstanceTransform::IDENTITY, 1)
        .unwrap();
    scene.build();
    let bvh = LayoutKind::Wide8.lay_out(
        &BuilderKind::BinnedSah.build(&mesh, &BuilderOptions::default()),
        &mesh,
        &LayoutOptions::default(),
    );
    use hbv::Accelerator;
    for k in 0..200 {
        let a = k as f32 * 0.31;
        let ray = Ray::new(
            Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.5 * (a * 0.7).sin()),
            Vec3::new(-a.cos(), -(a * 1.1).sin(), 0.1 * (a * 3.0).cos()),
        );
        let ours = scene.intersect(&SceneRay::new(ray));
        let theirs = bvh.intersect(&ray);
        assert_eq!(
            ours.map(|h| (h.t, h.prim, h.u, h.v)),
            theirs.map(|h| (h.t, h.prim, h.u, h.v))
        );
    }
}

/// One step of a live scene's life.
#[derive(Clone, Debug)]
enum LiveOp {
    Add(InstanceSpec),
    /// Moves instance `pick % count` anywhere.
    Move(usize, InstanceSpec),
    /// Moves instance `pick % count` by a small step.
    Nudge(usize, DVec3),
    SetMask(usize, u32),
    Remove(usize),
    Update,
    Build,
}

fn live_op() -> impl Strategy<Value = LiveOp> {
    prop_oneof![
        2 => instance_spec().prop_map(LiveOp::Add),
        2 => (any::<usize>(), instance_spec()).prop_map(|(k, s)| LiveOp::Move(k, s)),
        3 => (any::<usize>(), (-0.3f64..0.3, -0.3f64..0.3, -0.3f64..0.3))
            .prop_map(|(k, (x, y, z))| LiveOp::Nudge(k, DVec3::new(x, y, z))),
        2 => (any::<usize>(), instance_mask()).prop_map(|(k, m)| LiveOp::SetMask(k, m)),
        2 => any::<usize>().prop_map(LiveOp::Remove),
        3 => Just(LiveOp::Update),
        1 => Just(LiveOp::Build),
    ]
}

/// Applies `op` to the scene and to `model` (each instance's spec, `None` once removed),
/// checking that ids are refused or accepted as the model says.
fn apply_live_op(
    scene: &mut Scene,
    model: &mut Vec<Option<InstanceSpec>>,
    op: &LiveOp,
    far: DVec3,
) {
    let live = model.iter().flatten().count();
    let pick = |k: usize| k % model.len();
    let expect_refusal = |result: Result<(), SceneError>, k: usize| {
        assert_eq!(
            result,
            Err(SceneError::RemovedInstance {
                instance: InstanceId(k as u32)
            })
        );
    };
    match op {
        LiveOp::Add(spec) => {
            let transform = InstanceTransform::new(spec.affine(far)).unwrap();
            let id = scene
                .add_instance(MeshId(spec.mesh as u32), transform, spec.mask)
                .unwrap();
            assert_eq!(id.0 as usize, model.len(), "ids are handed out in order");
            model.push(Some(spec.clone()));
        }
        LiveOp::Move(k, new) => {
            let k = pick(*k);
            let transform = InstanceTransform::new(new.affine(far)).unwrap();
            let result = scene.set_transform(InstanceId(k as u32), transform);
            match &mut model[k] {
                Some(spec) => {
                    result.unwrap();
                    *spec = InstanceSpec {
                        mesh: spec.mesh,
                        mask: spec.mask,
                        ..new.clone()
                    };
                }
                None => expect_refusal(result, k),
            }
        }
        LiveOp::Nudge(k, step) => {
            let k = pick(*k);
            match &mut model[k] {
                Some(spec) => {
                    spec.translation += *step;
                    let transform = InstanceTransform::new(spec.affine(far)).unwrap();
                    scene
                        .set_transform(InstanceId(k as u32), transform)
                        .unwrap();
                }
                None => expect_refusal(
                    scene.set_transform(InstanceId(k as u32), InstanceTransform::IDENTITY),
                    k,
                ),
            }
        }
        LiveOp::SetMask(k, mask) => {
            let k = pick(*k);
            let result = scene.set_mask(InstanceId(k as u32), *mask);
            match &mut model[k] {
                Some(spec) => {
                    result.unwrap();
                    spec.mask = *mask;
                }
                None => expect_refusal(result, k),
            }
        }
        LiveOp::Remove(k) => {
            let k = pick(*k);
            // The checks aim rays at faces of the scene: keep one instance.
            if live == 1 && model[k].is_some() {
                return;
            }
            let result = scene.remove_instance(InstanceId(k as u32));
            match model[k].take() {
                Some(_) => result.unwrap(),
                None => expect_refusal(result, k),
            }
            assert_eq!(scene.instance_bounds(InstanceId(k as u32)), None);
        }
        LiveOp::Update => {
            scene.update();
        }
        LiveOp::Build => scene.build(),
    }
    assert_eq!(scene.instance_count(), model.len());
    assert_eq!(scene.live_instance_count(), model.iter().flatten().count());
    scene.validate().unwrap();
}

proptest! {
    #![proptest_config(common::cases(32))]

    /// Random sequences of adds, moves, mask changes, removals, updates and builds: after every
    /// step the top level's invariants hold and the scene answers as the brute force over the
    /// flattened live instances (removed ones holes), before and after each update.
    #[test]
    fn live_scenes_answer_as_their_flattened_brute_force(
        start in scene_spec(),
        ops in prop::collection::vec(live_op(), 1..24),
    ) {
        let (mut scene, _) = make_scene(&start, false);
        let mut model: Vec<Option<InstanceSpec>> =
            start.instances.iter().cloned().map(Some).collect();
        for (step, op) in ops.iter().enumerate() {
            apply_live_op(&mut scene, &mut model, op, start.far);
            // The brute force's spec: removed instances keep their last spec, which no answer
            // consults (they are holes of no faces in the flattened scene).
            let mut last = start.instances.clone();
            last.extend(model.iter().skip(last.len()).map(|s| s.clone().unwrap_or_else(|| start.instances[0].clone())));
            let instances = model
                .iter()
                .zip(last)
                .map(|(now, before)| now.clone().unwrap_or(before))
                .collect();
            let spec = SceneSpec { instances, far: start.far, rays: start.rays.clone() };
            let flat = scene.flattened().unwrap();
            let tally = check_scene(&spec, &scene, &flat);
            let limit = if spec.far == DVec3::ZERO { 1 } else { tally.rays / 8 };
            prop_assert!(tally.excused <= limit, "step {step} {op:?}: {tally:?}");
            // Nearest points too, with moved instances pending and stale leaves in the top
            // level: as near as the flattened triangles of every instance whose mask is not 0.
            let tolerance = 2f64.powi(-22) * flat.mesh.bounds().max.abs().max(flat.mesh.bounds().min.abs()).max_element() as f64 + 1e-9;
            for p in spec.rays.iter().take(6).map(|r| r.0.as_dvec3() + start.far) {
                let ours = scene.closest_point(p).map(|c| c.distance);
                let theirs = nearest_seen_distance(&flat, p);
                match (ours, theirs) {
                    (Some(a), Some(b)) => prop_assert!((a - b).abs() <= tolerance, "step {step} {op:?}: {a} vs {b}"),
                    (a, b) => prop_assert!(a.is_none() && b.is_none(), "step {step} {op:?}: {a:?} vs {b:?}"),
                }
            }
        }
    }
}

#[test]
fn a_moved_instance_is_found_where_it_is_before_the_update() {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
    let at = |x: f64| InstanceTransform::from_translation(DVec3::new(x, 0.0, 0.0)).unwrap();
    let ids: Vec<InstanceId> = (0..40)
        .map(|k| scene.add_instance(sphere, at(4.0 * k as f64), 1).unwrap())
        .collect();
    scene.build();
    let down = |x: f32| SceneRay::new(Ray::new(Vec3::new(x, 0.0, 5.0), -Vec3::Z));
    // Instance 3 leaves x = 12 for x = -20: its stale box in the tree must not answer.
    scene.set_transform(ids[3], at(-20.0)).unwrap();
    assert_eq!(scene.intersect(&down(12.0)), None);
    assert_eq!(scene.intersect(&down(-20.0)).unwrap().instance, 3);
    assert!(!scene.occluded(&down(12.0)) && scene.occluded(&down(-20.0)));
    // A mask change takes effect at once.
    scene.set_mask(ids[5], 2).unwrap();
    assert_eq!(scene.intersect(&down(20.0).with_mask(1)), None);
    assert_eq!(
        scene.intersect(&down(20.0).with_mask(2)).unwrap().instance,
        5
    );
    // One change in forty: a refit, after which the same answers hold.
    assert_eq!(scene.update(), TopLevelUpdate::Refitted);
    scene.validate().unwrap();
    assert_eq!(scene.intersect(&down(12.0)), None);
    assert_eq!(scene.intersect(&down(-20.0)).unwrap().instance, 3);
    // Removal leaves a hole: the next instance keeps its id, a new one gets a new id.
    scene.remove_instance(ids[4]).unwrap();
    assert_eq!(scene.intersect(&down(16.0)), None);
    let new = scene.add_instance(sphere, at(16.0), 1).unwrap();
    assert_eq!(new, InstanceId(40));
    assert_eq!(scene.intersect(&down(16.0)).unwrap().instance, 40);
    assert_eq!(scene.update(), TopLevelUpdate::Refitted);
    scene.validate().unwrap();
    assert_eq!(scene.intersect(&down(16.0)).unwrap().instance, 40);
    assert_eq!(scene.intersect(&down(24.0)).unwrap().instance, 6);
    assert_eq!(scene.update(), TopLevelUpdate::Unchanged);
    // Mirrored, the line keeps its tree: a refit is as good as a rebuild.
    for (k, &id) in ids.iter().enumerate().filter(|&(k, _)| k != 4) {
        scene.set_transform(id, at(-4.0 * k as f64)).unwrap();
    }
    assert_eq!(scene.update(), TopLevelUpdate::Refitted);
    assert_eq!(scene.intersect(&down(-24.0)).unwrap().instance, 6);
    // Shuffled along it, the old tree's boxes overlap everywhere: a rebuild.
    for (k, &id) in ids.iter().enumerate().filter(|&(k, _)| k != 4) {
        scene
            .set_transform(id, at(4.0 * (k * 17 % 40) as f64))
            .unwrap();
    }
    assert_eq!(scene.update(), TopLevelUpdate::Rebuilt);
    scene.validate().unwrap();
    assert_eq!(scene.intersect(&down(88.0)).unwrap().instance, 6);
    let cost = scene.top_level_cost();
    assert_eq!(cost.current, cost.at_build);
}

#[test]
fn unknown_and_removed_instances_are_refused() {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 0));
    let id = scene
        .add_instance(sphere, InstanceTransform::IDENTITY, 1)
        .unwrap();
    let unknown = InstanceId(7);
    let error = scene.set_mask(unknown, 1).unwrap_err();
    assert_eq!(
        error,
        SceneError::UnknownInstance {
            instance: unknown,
            instances: 1
        }
    );
    assert_eq!(
        error.to_string(),
        "instance: id 7 does not exist; the scene has handed out 1 instance id(s)"
    );
    assert!(scene
        .set_transform(unknown, InstanceTransform::IDENTITY)
        .is_err());
    assert!(scene.remove_instance(unknown).is_err());
    scene.remove_instance(id).unwrap();
    let error = scene.remove_instance(id).unwrap_err();
    assert_eq!(error, SceneError::RemovedInstance { instance: id });
    assert!(error.to_string().starts_with("instance: id 0 was removed"));
    assert_eq!(scene.set_mask(id, 1), Err(error));
    assert_eq!(
        (scene.instance_count(), scene.live_instance_count()),
        (1, 0)
    );
    scene.update();
    scene.validate().unwrap();
    let ray = SceneRay::new(Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z));
    assert_eq!(scene.intersect(&ray), None);
    assert_eq!(scene.flattened().unwrap().offsets, vec![0, 0]);
}

#[test]
fn a_mesh_whose_vertices_move_answers_as_one_built_at_its_new_place() {
    // A torus that swells and twists, placed by three instances (one of them removed): after
    // each move the scene answers as a scene built afresh from the moved mesh, before and
    // after the update.
    let rest = torus(Vec3::ZERO, 1.0, 0.35, 24, 12);
    let placements = [
        DAffine3::IDENTITY,
        DAffine3::from_scale_rotation_translation(
            DVec3::new(1.5, -1.0, 0.5),
            DQuat::from_rotation_x(0.7),
            DVec3::new(4.0, 0.0, 0.0),
        ),
        DAffine3::from_translation(DVec3::new(-4.0, 1.0, 0.0)),
    ];
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::new(0.0, 4.0, 0.0), 1.0, 1));
    let moving = scene.add_mesh(rest.clone());
    scene
        .add_instance(sphere, InstanceTransform::IDENTITY, u32::MAX)
        .unwrap();
    for placement in placements {
        let transform = InstanceTransform::new(placement).unwrap();
        scene.add_instance(moving, transform, u32::MAX).unwrap();
    }
    scene.build();
    scene.remove_instance(InstanceId(3)).unwrap();
    let rays: Vec<SceneRay> = (0..400)
        .map(|k| {
            let a = k as f32 * 0.37;
            let origin = Vec3::new(8.0 * a.cos(), 8.0 * a.sin(), 2.0 * (a * 0.3).sin());
            let target = Vec3::new(4.0 * (a * 1.7).sin(), 2.0 * (a * 0.9).cos(), 0.0);
            SceneRay::new(Ray::new(origin, target - origin))
        })
        .collect();
    for step in 1..4 {
        let s = step as f32;
        let positions: Vec<Vec3> = rest
            .positions()
            .iter()
            .map(|p| {
                let twist = glam::Quat::from_rotation_z(0.2 * s * p.z);
                twist * (*p * (1.0 + 0.15 * s)) + Vec3::Z * 0.1 * s * p.x
            })
            .collect();
        scene.set_mesh_positions(moving, positions.clone()).unwrap();
        let mut fresh = Scene::new();
        fresh.add_mesh(icosphere(Vec3::new(0.0, 4.0, 0.0), 1.0, 1));
        let moved = fresh.add_mesh(TriangleMesh::new(positions, rest.indices().to_vec()).unwrap());
        fresh
            .add_instance(MeshId(0), InstanceTransform::IDENTITY, u32::MAX)
            .unwrap();
        for placement in placements {
            let transform = InstanceTransform::new(placement).unwrap();
            fresh.add_instance(moved, transform, u32::MAX).unwrap();
        }
        fresh.remove_instance(InstanceId(3)).unwrap();
        fresh.build();
        let expected = fresh.intersect_batch(&rays);
        assert!(expected.iter().filter(|h| h.is_some()).count() > 100);
        let agree = |scene: &Scene, when: &str| {
            let ours = scene.intersect_batch(&rays);
            for (k, (a, b)) in ours.iter().zip(&expected).enumerate() {
                assert_eq!(a, b, "step {step}, {when} the update, ray {k}");
            }
            assert_eq!(scene.occluded_batch(&rays), fresh.occluded_batch(&rays));
        };
        agree(&scene, "before");
        scene.update();
        scene.validate().unwrap();
        agree(&scene, "after");
    }
    let count = rest.positions().len();
    assert_eq!(
        scene.set_mesh_positions(moving, vec![Vec3::ZERO; count - 1]),
        Err(SceneError::PositionCount {
            mesh: moving,
            expected: count,
            given: count - 1
        })
    );
    let mut bad = rest.positions().to_vec();
    bad[5].y = f32::NAN;
    let error = scene.set_mesh_positions(moving, bad).unwrap_err();
    assert_eq!(
        error,
        SceneError::InvalidPosition {
            mesh: moving,
            vertex: 5
        }
    );
    assert!(error.to_string().starts_with("positions: vertex 5"));
    assert!(matches!(
        scene.set_mesh_positions(MeshId(9), Vec::new()),
        Err(SceneError::UnknownMesh { .. })
    ));
}

/// The distance from `p` to the nearest flattened triangle of an instance whose mask is not 0.
fn nearest_seen_distance(flat: &FlattenedScene, p: DVec3) -> Option<f64> {
    flat.offsets
        .windows(2)
        .enumerate()
        .filter(|(instance, _)| flat.masks[*instance] != 0)
        .flat_map(|(_, faces)| faces[0]..faces[1])
        .map(|face| flat.mesh.triangle(face as usize))
        .filter(|t| !t.is_degenerate())
        .map(|t| {
            let q = hbv::proximity::closest_point_on_triangle(
                p,
                t.p0.as_dvec3(),
                t.p1.as_dvec3(),
                t.p2.as_dvec3(),
            );
            (q.point - p).length()
        })
        .min_by(f64::total_cmp)
}
