//! Scenes in `.hbv` files (format version 2): a saved scene opens to one that answers every ray
//! exactly as it did, ids and holes included; mesh files and scene files are told apart; files
//! written before scenes existed still read; and every kind of bad scene file gives a clear
//! error naming the file, never a panic.

mod common;

use std::path::Path;

use glam::{DAffine3, DQuat, DVec3, Vec3};
use hbv::atomic_file::Replace;
use hbv::bvh::build::{BuilderKind, BuilderOptions, InsertionOrder};
use hbv::bvh::file::{kind_of_bytes, BvhFile, BvhFileError, BvhFileKind, FORMAT_VERSION};
use hbv::bvh::layout::{LayoutKind, LayoutOptions, RecursiveLayout};
use hbv::geometry::Ray;
use hbv::mesh::procedural::{ground_plane, icosphere, torus};
use hbv::scene::{
    AnyBvhFile, InstanceId, InstanceTransform, MeshId, Scene, SceneError, SceneRay, SceneStructure,
};
use hbv::{Accelerator, BruteForce, TriangleMesh};
use proptest::prelude::*;

const SOURCE: &str = "city.hbv";

fn open(bytes: &[u8]) -> Result<Scene, BvhFileError> {
    Scene::from_hbv_bytes(bytes, Path::new(SOURCE))
}

/// Opening `bytes` fails with a message naming the file and containing `want`.
fn assert_fails(bytes: &[u8], want: &str) {
    let err = open(bytes).expect_err(want).to_string();
    assert!(err.starts_with(SOURCE), "{err}");
    assert!(err.contains(want), "wanted {want:?} in: {err}");
}

/// A placement: signed scales (a negative one mirrors), a rotation, a translation.
fn placement(scale: DVec3, angles: DVec3, offset: DVec3) -> InstanceTransform {
    let rotation = DQuat::from_euler(glam::EulerRot::ZYX, angles.x, angles.y, angles.z);
    InstanceTransform::new(DAffine3::from_scale_rotation_translation(
        scale, rotation, offset,
    ))
    .unwrap()
}

/// What a random scene is made of, and what happens to it after its first build.
#[derive(Clone, Debug)]
struct Plan {
    /// Mesh, scales, angles, offset, mask of each instance.
    instances: Vec<(usize, DVec3, DVec3, DVec3, u32)>,
    /// Instances added after the first build (pending in the saved scene).
    late: usize,
    /// Instance ids (modulo the count) removed, moved, given a new mask, in turn.
    removed: Vec<usize>,
    moved: Vec<(usize, DVec3)>,
    remasked: Vec<(usize, u32)>,
    /// Whether the top level is updated before the save (else the changes are pending).
    update: bool,
    /// Whether mesh 1's vertices move (its refitted tree is then kept and saved).
    breathe: bool,
    far: DVec3,
    /// Ray origins, targets (fractions of an instance's box) and masks.
    rays: Vec<(Vec3, Vec3, usize, u32)>,
}

fn signed_scale() -> impl Strategy<Value = f64> {
    (0.3f64..2.5, any::<bool>()).prop_map(|(s, mirror)| if mirror { -s } else { s })
}

fn mask() -> impl Strategy<Value = u32> {
    prop_oneof![3 => Just(u32::MAX), 2 => (0u32..3).prop_map(|b| 1 << b), 1 => Just(0)]
}

fn plan() -> impl Strategy<Value = Plan> {
    let vec3 = |r: f64| (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| DVec3::new(x, y, z));
    let instance = (
        0usize..5,
        (signed_scale(), signed_scale(), signed_scale()).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
        vec3(3.2),
        vec3(6.0),
        mask(),
    );
    let ray = (
        (-9f32..9.0, -9f32..9.0, -9f32..9.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
        (0f32..1.0, 0f32..1.0, 0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
        any::<usize>(),
        prop_oneof![Just(u32::MAX), any::<u32>(), (0u32..3).prop_map(|b| 1 << b)],
    );
    (
        prop::collection::vec(instance, 1..10),
        0usize..4,
        prop::collection::vec(any::<usize>(), 0..3),
        prop::collection::vec((any::<usize>(), vec3(2.0)), 0..3),
        prop::collection::vec((any::<usize>(), mask()), 0..3),
        (any::<bool>(), any::<bool>()),
        prop_oneof![3 => Just(DVec3::ZERO), 1 => Just(DVec3::new(5e5, 5e6, 0.0))],
        prop::collection::vec(ray, 64),
    )
        .prop_map(
            |(instances, late, removed, moved, remasked, (update, breathe), far, rays)| Plan {
                late: late.min(instances.len() - 1),
                instances,
                removed,
                moved,
                remasked,
                update,
                breathe,
                far,
                rays,
            },
        )
}

/// The meshes of every random scene: shared by several instances, one of them empty.
fn meshes() -> Vec<TriangleMesh> {
    vec![
        icosphere(Vec3::ZERO, 1.0, 1),
        torus(Vec3::new(0.2, 0.0, 0.0), 1.0, 0.3, 9, 5),
        ground_plane(1.5, -0.3, 3),
        TriangleMesh::default(),
    ]
}

/// Where the far mesh of [`make_scene`] lies: at UTM coordinates.
const FAR_CENTRE: DVec3 = DVec3::new(500_000.25, 5_000_000.75, 12.5);

/// A float64 mesh far from the origin (stored relative to its centre): a small sphere at
/// [`FAR_CENTRE`].
fn far_sphere() -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let sphere = icosphere(Vec3::ZERO, 0.5, 1);
    let positions = sphere
        .positions()
        .iter()
        .map(|p| FAR_CENTRE + p.as_dvec3())
        .collect();
    (positions, sphere.indices().to_vec())
}

/// [`placement`] of mesh `mesh` of [`make_scene`]: the far sphere (mesh 4) is first moved from
/// [`FAR_CENTRE`] to the origin, so that its instances lie among the others.
fn placement_of(mesh: usize, scale: DVec3, angles: DVec3, offset: DVec3) -> InstanceTransform {
    let placed = placement(scale, angles, offset);
    if mesh != 4 {
        return placed;
    }
    let home = DAffine3::from_translation(-FAR_CENTRE);
    InstanceTransform::new(placed.affine() * home).unwrap()
}

/// The scene `plan` describes, with every kind of state an instance can be in when saved.
fn make_scene(plan: &Plan, structure: SceneStructure) -> Scene {
    let mut scene = Scene::with_structure(structure);
    let mut ids: Vec<MeshId> = meshes().into_iter().map(|m| scene.add_mesh(m)).collect();
    let (positions, faces) = far_sphere();
    ids.push(scene.add_mesh_f64(&positions, &faces).unwrap());
    let count = plan.instances.len();
    for (k, &(mesh, scale, angles, offset, mask)) in plan.instances.iter().enumerate() {
        if k == count - plan.late {
            scene.build();
        }
        let t = placement_of(mesh, scale, angles, offset + plan.far);
        scene.add_instance(ids[mesh], t, mask).unwrap();
    }
    if plan.late == 0 {
        scene.build();
    }
    for &k in &plan.removed {
        // Removing twice is refused; the hole stays either way.
        let _ = scene.remove_instance(InstanceId((k % count) as u32));
    }
    for &(k, shift) in &plan.moved {
        let (mesh, scale, angles, offset, _) = plan.instances[k % count];
        let t = placement_of(mesh, scale, angles, offset + shift + plan.far);
        let _ = scene.set_transform(InstanceId((k % count) as u32), t);
    }
    for &(k, mask) in &plan.remasked {
        let _ = scene.set_mask(InstanceId((k % count) as u32), mask);
    }
    if plan.breathe {
        let torus = scene.mesh(ids[1]).unwrap();
        let moved = torus.positions().iter().map(|p| *p * 1.1).collect();
        scene.set_mesh_positions(ids[1], moved).unwrap();
    }
    if plan.update {
        scene.update();
    }
    scene
}

/// Rays from random origins, most aimed into an instance's world box.
fn rays(plan: &Plan, scene: &Scene) -> Vec<SceneRay> {
    let far = plan.far.as_vec3();
    plan.rays
        .iter()
        .map(|&(origin, fraction, pick, mask)| {
            let origin = origin + far;
            let target = scene
                .instance_bounds(InstanceId((pick % scene.instance_count()) as u32))
                .filter(|b| !b.is_empty())
                .map_or(origin + fraction - 0.5, |b| {
                    b.min + fraction * (b.max - b.min)
                });
            SceneRay::new(Ray::new(origin, target - origin)).with_mask(mask)
        })
        .collect()
}

/// `opened` answers as `saved`, ray by ray and id by id, and keeps every invariant.
fn assert_same_scene(saved: &Scene, opened: &Scene, rays: &[SceneRay]) {
    opened.validate().unwrap();
    assert_eq!(opened.mesh_count(), saved.mesh_count());
    assert_eq!(opened.instance_count(), saved.instance_count());
    assert_eq!(opened.live_instance_count(), saved.live_instance_count());
    let mut probe = opened.clone();
    for id in 0..saved.instance_count() as u32 {
        let id = InstanceId(id);
        assert_eq!(opened.instance_bounds(id), saved.instance_bounds(id));
        if saved.instance_bounds(id).is_none() {
            assert_eq!(
                probe.set_mask(id, 1),
                Err(SceneError::RemovedInstance { instance: id })
            );
        }
    }
    for m in 0..saved.mesh_count() as u32 {
        assert_eq!(opened.mesh(MeshId(m)), saved.mesh(MeshId(m)));
    }
    for ray in rays {
        assert_eq!(opened.intersect(ray), saved.intersect(ray), "{ray:?}");
        assert_eq!(opened.occluded(ray), saved.occluded(ray), "{ray:?}");
        assert_eq!(opened.count(ray), saved.count(ray), "{ray:?}");
    }
}

proptest! {
    #![proptest_config(common::cases(32))]

    #[test]
    fn a_reopened_scene_answers_every_ray_as_the_saved_one(plan in plan()) {
        let saved = make_scene(&plan, SceneStructure::default());
        let bytes = saved.to_hbv_bytes();
        let mut opened = open(&bytes).unwrap();
        let rays = rays(&plan, &saved);
        assert_same_scene(&saved, &opened, &rays);
        // Saved again, the same bytes; a refitted mesh's tree is built afresh instead.
        if !plan.breathe {
            prop_assert!(opened.to_hbv_bytes() == bytes);
        }
        // Instances moved after the open are placed as in the saved scene (a float64 mesh's
        // origin was saved with it).
        let mut moved = saved.clone();
        let mut moved_opened = opened.clone();
        for id in 0..saved.instance_count() as u32 {
            let t = placement(DVec3::ONE, DVec3::ZERO, plan.far + DVec3::X * f64::from(id));
            if moved.set_transform(InstanceId(id), t).is_ok() {
                moved_opened.set_transform(InstanceId(id), t).unwrap();
            }
        }
        assert_same_scene(&moved, &moved_opened, &rays);
        // The opened scene lives on as the saved one does: ids continue after the holes.
        let next = opened
            .add_instance(MeshId(0), InstanceTransform::IDENTITY, 1)
            .unwrap();
        prop_assert_eq!(next.0 as usize, saved.instance_count());
        opened.update();
        opened.validate().unwrap();
    }
}

/// A plan of every kind of instance: mirrored, scaled, masked, removed, moved, pending; and
/// rays aimed at each instance.
fn fixed_plan() -> Plan {
    let instance = |k: usize| {
        let f = k as f64;
        let scale = DVec3::new(
            1.0 + 0.2 * f,
            if k.is_multiple_of(2) { -1.0 } else { 0.7 },
            1.3,
        );
        let angles = DVec3::new(0.3 * f, -0.2 * f, 0.1);
        let offset = DVec3::new(4.0 * (f - 2.5), 0.5 * f, -1.0);
        (
            k % 3,
            scale,
            angles,
            offset,
            if k == 4 { 1 } else { u32::MAX },
        )
    };
    let rays = (0..96)
        .map(|k| {
            let f = k as f32;
            let origin = Vec3::new((f * 0.37).sin() * 8.0, 6.0, (f * 0.61).cos() * 8.0);
            let fraction = Vec3::new((f * 0.13).fract(), (f * 0.29).fract(), 0.5);
            (origin, fraction, k, if k % 5 == 0 { 2 } else { u32::MAX })
        })
        .collect();
    Plan {
        instances: (0..6).map(instance).collect(),
        late: 2,
        removed: vec![1],
        moved: vec![(2, DVec3::new(0.5, -0.5, 0.25))],
        remasked: vec![(3, 6)],
        update: false,
        breathe: false,
        far: DVec3::ZERO,
        rays,
    }
}

/// Every builder and layout, with non-default options, is saved and used by the opened scene.
#[test]
fn the_structure_is_saved_with_the_scene() {
    let structure = SceneStructure {
        builder: BuilderKind::Insertion,
        builder_options: BuilderOptions {
            leaf_size: Some(2),
            insertion_order: InsertionOrder::Shuffle { seed: 7 },
            optimize: true,
        },
        layout: LayoutKind::Ordered,
        layout_options: LayoutOptions { ray_packets: false },
    };
    let plan = fixed_plan();
    let saved = make_scene(&plan, structure);
    let bytes = saved.to_hbv_bytes();
    let opened = open(&bytes).unwrap();
    let rays = rays(&plan, &saved);
    assert_same_scene(&saved, &opened, &rays);
    assert!(
        rays.iter()
            .filter(|r| opened.intersect(r).is_some())
            .count()
            > 8
    );
    // The insertion builder's trees, saved again from the opened scene: the same bytes.
    assert!(opened.to_hbv_bytes() == bytes);
    // Each mesh file inside says how its tree was built.
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("insertion (leaf size 2) + reinsertion optimization"));
}

#[test]
fn empty_scenes_and_scenes_of_empty_meshes_round_trip() {
    let empty = Scene::new();
    let opened = open(&empty.to_hbv_bytes()).unwrap();
    assert_eq!((opened.mesh_count(), opened.instance_count()), (0, 0));
    opened.validate().unwrap();
    let mut scene = Scene::new();
    let nothing = scene.add_mesh(TriangleMesh::default());
    scene
        .add_instance(nothing, InstanceTransform::IDENTITY, 1)
        .unwrap();
    let opened = open(&scene.to_hbv_bytes()).unwrap();
    assert_eq!(opened.live_instance_count(), 1);
    let ray = SceneRay::new(Ray::new(Vec3::ZERO, Vec3::X));
    assert_eq!(opened.intersect(&ray), None);
}

/// A small scene: two shared meshes, three instances (one mirrored), one removed.
fn sample() -> Scene {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 1));
    let plane = scene.add_mesh(ground_plane(2.0, 0.0, 2));
    let at = |x: f64| placement(DVec3::ONE, DVec3::ZERO, DVec3::new(x, 0.0, 0.0));
    scene.add_instance(sphere, at(-3.0), u32::MAX).unwrap();
    let gone = scene.add_instance(plane, at(0.0), 2).unwrap();
    let mirrored = placement(DVec3::new(-1.0, 2.0, 1.0), DVec3::ZERO, DVec3::X * 3.0);
    scene.add_instance(sphere, mirrored, 1).unwrap();
    scene.build();
    scene.remove_instance(gone).unwrap();
    scene
}

#[test]
fn save_writes_the_bytes_and_replaces_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.hbv");
    let scene = sample();
    let bytes = scene.save(&path, Replace::Never).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), scene.to_hbv_bytes());
    assert_eq!(bytes, scene.to_hbv_bytes().len() as u64);
    let e = scene.save(&path, Replace::Never).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::AlreadyExists);
    assert!(e.to_string().contains("scene.hbv"), "{e}");
    std::fs::write(&path, b"old").unwrap();
    scene.save(&path, Replace::Always).unwrap();
    let opened = Scene::open(&path).unwrap();
    assert_eq!(opened.instance_count(), 3);
    assert_eq!(opened.instance_bounds(InstanceId(1)), None);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let e = Scene::open(dir.path().join("missing.hbv")).unwrap_err();
    assert!(e.to_string().contains("missing.hbv: "), "{e}");
}

/// Written by hbv before scene files existed (`hbv build tet.obj --builder binned-sah
/// --leaf-size 1`): 4 triangles, 7 nodes.
const VERSION_1_FILE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/hbv_files/tetrahedron_v1.hbv"
);

#[test]
fn a_version_1_file_still_reads_and_mesh_files_are_still_written_as_version_1() {
    let old = std::fs::read(VERSION_1_FILE).unwrap();
    assert_eq!(kind_of_bytes(&old).unwrap(), BvhFileKind::Mesh);
    let file = BvhFile::load(VERSION_1_FILE).unwrap();
    assert_eq!(file.mesh.triangle_count(), 4);
    assert_eq!(file.settings, "binned-sah (leaf size 1)");
    // Every ray as a brute force answers it.
    let layout = RecursiveLayout::new(&file.tree, &file.mesh);
    let brute = BruteForce::new(&file.mesh);
    for k in 0..200 {
        let a = k as f32 * 0.61;
        let origin = Vec3::new(a.cos() * 3.0, (a * 0.7).sin() * 3.0, a.sin() * 3.0);
        let ray = Ray::new(
            origin,
            Vec3::splat(0.3) - origin + Vec3::splat(0.01 * a.sin()),
        );
        assert_eq!(
            layout.intersect(&ray).map(|h| (h.prim, h.t)),
            brute.intersect(&ray).map(|h| (h.prim, h.t))
        );
    }
    // Written again, byte for byte the old file: mesh files did not change.
    assert_eq!(file.to_bytes(), old);
    match AnyBvhFile::load(VERSION_1_FILE).unwrap() {
        AnyBvhFile::Mesh(mesh) => assert_eq!(mesh, file),
        AnyBvhFile::Scene(_) => panic!("a mesh file read as a scene"),
    }
}

#[test]
fn mesh_files_and_scene_files_are_told_apart() {
    let scene = sample().to_hbv_bytes();
    let mesh = std::fs::read(VERSION_1_FILE).unwrap();
    let err = BvhFile::from_bytes(&scene, Path::new("s.hbv"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "s.hbv: the file holds a scene (format version 2), not a single mesh: read it as a scene"
    );
    assert_fails(
        &mesh,
        "the file holds a single mesh (format version 1), not a scene: read it as a single mesh",
    );
    assert_eq!(kind_of_bytes(&scene).unwrap(), BvhFileKind::Scene);
    let any = AnyBvhFile::from_bytes(&scene, Path::new(SOURCE)).unwrap();
    assert_eq!(any.kind(), BvhFileKind::Scene);
    let any = AnyBvhFile::from_bytes(&mesh, Path::new(SOURCE)).unwrap();
    assert_eq!(any.kind(), BvhFileKind::Mesh);
    let err = AnyBvhFile::from_bytes(b"v 0 0 0\n", Path::new(SOURCE)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "city.hbv: not an hbv BVH file (it does not start with the .hbv magic number)"
    );
}

/// Offsets in `sample()`'s scene file (2 meshes, 3 instances).
const RECORDS: usize = 64;
const ORIGINS: usize = RECORDS + 32;
const INSTANCES: usize = ORIGINS + 2 * 24;
const MESHES: usize = INSTANCES + 3 * 112;

/// Rewrites the header's CRC-32 after a deliberate change to it.
fn reseal_header(bytes: &mut [u8]) {
    let crc = crc32(&bytes[..60]);
    bytes[60..64].copy_from_slice(&crc.to_le_bytes());
}

/// Rewrites the records' CRC-32 (and the header's) after a deliberate change to a record: the
/// file is then well-sealed but lies, as a hostile file would.
fn reseal(bytes: &mut [u8]) {
    let crc = crc32(&bytes[RECORDS..MESHES]);
    bytes[56..60].copy_from_slice(&crc.to_le_bytes());
    reseal_header(bytes);
}

/// CRC-32 (IEEE) written out, so that the tests do not lean on the code under test.
fn crc32(bytes: &[u8]) -> u32 {
    !bytes.iter().fold(!0u32, |crc, &b| {
        (0..8).fold(crc ^ u32::from(b), |c, _| {
            (c >> 1) ^ (0xEDB8_8320 & 0u32.wrapping_sub(c & 1))
        })
    })
}

fn put_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

fn put_u64(bytes: &mut [u8], at: usize, value: u64) {
    bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
}

#[test]
fn truncation_anywhere_names_the_part_it_ends_in() {
    let bytes = sample().to_hbv_bytes();
    let cases = [
        (4, "not an hbv BVH file"),
        (63, "truncated: it ends in the header"),
        (64, "ends in the structure"),
        (INSTANCES - 1, "ends in the origins"),
        (INSTANCES + 111, "ends in the instances"),
        (MESHES + 100, "ends in the meshes"),
        (
            MESHES + 130,
            "mesh 0: the file is truncated: it ends in the positions",
        ),
        (
            bytes.len() - 1,
            "mesh 1: the file is truncated: it ends in the leaf entries",
        ),
    ];
    for (len, want) in cases {
        assert_fails(&bytes[..len], want);
    }
    // The sizes in a mesh's message count from the start of the scene file.
    let err = open(&bytes[..bytes.len() - 1]).unwrap_err().to_string();
    assert!(
        err.contains(&format!("the file has {})", bytes.len() - 1)),
        "{err}"
    );
    for len in 0..bytes.len() {
        assert!(open(&bytes[..len]).is_err(), "{len} bytes");
    }
    let mut longer = bytes.clone();
    longer.extend_from_slice(&[0; 4]);
    assert_fails(&longer, "4 unexpected bytes after the end of the data");
}

#[test]
fn a_flipped_byte_anywhere_is_caught() {
    let bytes = sample().to_hbv_bytes();
    for at in (0..bytes.len()).step_by(5).chain([60, 64, bytes.len() - 1]) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        let err = open(&bad).expect_err("a flipped byte").to_string();
        assert!(err.starts_with(SOURCE), "{err}");
    }
    let mut bad = bytes.clone();
    bad[INSTANCES + 20] ^= 1;
    assert_fails(&bad, "the record section is corrupted: CRC-32");
    let mut bad = bytes.clone();
    bad[30] ^= 1;
    assert_fails(&bad, "the header is corrupted: CRC-32");
    let mut bad = bytes.clone();
    bad[MESHES + 70] ^= 1;
    assert_fails(&bad, "mesh 0: the payload is corrupted: CRC-32");
}

#[test]
fn foreign_and_future_files_are_named_as_such() {
    let bytes = sample().to_hbv_bytes();
    assert_fails(b"", "not an hbv BVH file");
    let mut future = bytes.clone();
    put_u32(&mut future, 8, FORMAT_VERSION + 1);
    assert_fails(&future, "format version 3 is newer than this hbv reads (2)");
    let mut big_endian = bytes.clone();
    big_endian[12..16].copy_from_slice(&0x0102_0304u32.to_be_bytes());
    reseal_header(&mut big_endian);
    assert_fails(&big_endian, "wrong byte-order mark 0x04030201");
}

#[test]
fn sizes_that_lie_are_caught_before_anything_is_allocated() {
    let bytes = sample().to_hbv_bytes();
    let lie = |at: usize, value: u64, want: &str| {
        let mut bad = bytes.clone();
        put_u64(&mut bad, at, value);
        reseal_header(&mut bad);
        assert_fails(&bad, want);
    };
    lie(32, 1 << 40, "ends in the instances");
    lie(32, u64::MAX / 8, "impossible size for the instances");
    lie(24, 1 << 40, "ends in the origins");
    lie(24, u64::MAX, "impossible size for the origins");
    lie(24, 100, "ends in the meshes");
    // The record section then ends elsewhere.
    lie(24, 1, "the record section is corrupted");
    lie(40, 1, "header: reserved bytes (20..24, 40..56) are not 0");
}

#[test]
fn well_sealed_records_that_lie_are_refused() {
    let bytes = sample().to_hbv_bytes();
    let edit = |at: usize, value: &[u8], want: &str| {
        let mut bad = bytes.clone();
        bad[at..at + value.len()].copy_from_slice(value);
        reseal(&mut bad);
        assert_fails(&bad, want);
    };
    let second = INSTANCES + 112;
    edit(
        second,
        &9u32.to_le_bytes(),
        "instance 1: mesh 9 is out of range",
    );
    edit(
        second + 8,
        &2u32.to_le_bytes(),
        "instance 1: unknown state 2",
    );
    edit(second + 12, &1u32.to_le_bytes(), "instance 1: reserved");
    // Entry (0, 3) of [A | b] is the translation's x.
    edit(
        second + 16 + 24,
        &f64::NAN.to_le_bytes(),
        "instance 1: transform: entry at row 0, column 3 is NaN",
    );
    let zeros = [0u8; 32];
    edit(
        second + 16,
        &zeros,
        "instance 1: transform: the linear part is singular",
    );
    edit(
        RECORDS + 4,
        &9u32.to_le_bytes(),
        "structure: unknown layout code 9",
    );
    edit(
        ORIGINS + 24,
        &f64::INFINITY.to_le_bytes(),
        "mesh 1: its origin [inf, 0.0, 0.0] is not finite",
    );
    edit(
        RECORDS,
        &0u32.to_le_bytes(),
        "structure: unknown builder code 0",
    );
}

/// `/dev/zero` under a `.hbv` name is refused, not read for ever.
#[cfg(unix)]
#[test]
fn a_device_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zero.hbv");
    std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
    let err = Scene::open(&path).unwrap_err().to_string();
    assert!(
        err.ends_with("a device or a socket, not a .hbv file"),
        "{err}"
    );
    let err = AnyBvhFile::load(&path).unwrap_err().to_string();
    assert!(
        err.ends_with("a device or a socket, not a .hbv file"),
        "{err}"
    );
}
