//! Scene files: glTF files generated here (a `.gltf` with a `.bin` buffer) loaded as scenes of
//! instances, as `RAYS.md`'s "Scenes (glTF)" says; OBJ files as scenes of one instance; broken
//! files refused naming the place; and (when present) the shared `menagerie.glb` against its
//! flattened mesh.

use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec3, Vec3};
use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::geometry::{Ray, Triangle};
use hbv::mesh::MeshFormat;
use hbv::scene::{MeshId, Scene, SceneRay};
use hbv::{Accelerator, TriangleMesh};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use tempfile::TempDir;

/// glTF's component types of indices.
#[derive(Clone, Copy)]
enum IndexType {
    U8 = 5121,
    U16 = 5123,
    U32 = 5125,
}

/// A glTF file being written: one `.bin` buffer, its views and accessors, then the nodes,
/// meshes and scenes as JSON text.
#[derive(Default)]
struct GltfFile {
    bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
}

impl GltfFile {
    /// Appends `bytes` (4-aligned) as a buffer view; returns its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(format!(
            r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#,
            self.bin.len(),
            bytes.len()
        ));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// A float VEC3 POSITION accessor; returns its index.
    fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = points
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let view = self.view(&bytes);
        let min = points.iter().fold([f32::MAX; 3], |m, p| {
            std::array::from_fn(|k| m[k].min(p[k]))
        });
        let max = points.iter().fold([f32::MIN; 3], |m, p| {
            std::array::from_fn(|k| m[k].max(p[k]))
        });
        self.accessors.push(format!(
            r#"{{"bufferView": {view}, "componentType": 5126, "count": {}, "type": "VEC3",
                "min": {min:?}, "max": {max:?}}}"#,
            points.len()
        ));
        self.accessors.len() - 1
    }

    /// A SCALAR index accessor of `kind`; returns its index.
    fn indices(&mut self, indices: &[u32], kind: IndexType) -> usize {
        let bytes: Vec<u8> = match kind {
            IndexType::U8 => indices.iter().map(|&i| i as u8).collect(),
            IndexType::U16 => indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect(),
            IndexType::U32 => indices.iter().flat_map(|&i| i.to_le_bytes()).collect(),
        };
        let view = self.view(&bytes);
        self.accessors.push(format!(
            r#"{{"bufferView": {view}, "componentType": {}, "count": {}, "type": "SCALAR"}}"#,
            kind as u32,
            indices.len()
        ));
        self.accessors.len() - 1
    }

    /// Writes `name.gltf` and `name.bin` in `dir`; `rest` is the JSON members for the nodes,
    /// meshes and scenes (`"nodes": [...], ...`). Returns the `.gltf` path.
    fn write(&self, dir: &Path, name: &str, rest: &str) -> PathBuf {
        std::fs::write(dir.join(format!("{name}.bin")), &self.bin).unwrap();
        let json = format!(
            r#"{{"asset": {{"version": "2.0"}},
  {rest},
  "accessors": [{}],
  "bufferViews": [{}],
  "buffers": [{{"byteLength": {}, "uri": "{name}.bin"}}]}}"#,
            self.accessors.join(",\n    "),
            self.views.join(",\n    "),
            self.bin.len()
        );
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, json).unwrap();
        path
    }
}

const TRIANGLE: [[f32; 3]; 3] = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];
const SECOND_TRIANGLE: [[f32; 3]; 3] = [[0., 0., 0.5], [1., 1., 0.5], [0., 1., 0.5]];
const SQUARE: [[f32; 3]; 4] = [[-1., -1., 0.], [1., -1., 0.], [1., 1., 0.], [-1., 1., 0.]];

/// Three meshes: mesh 0 is a TRIANGLES primitive (u16 indices), a LINES primitive and a second
/// TRIANGLES primitive (u8 indices, reversed); mesh 1 a square (u32 indices); mesh 2 a triangle
/// no node places. Returns the file and the primitives' accessors as JSON.
fn three_meshes() -> (GltfFile, String) {
    let mut file = GltfFile::default();
    let tri = file.positions(&TRIANGLE);
    let tri_indices = file.indices(&[0, 1, 2], IndexType::U16);
    let second = file.positions(&SECOND_TRIANGLE);
    let second_indices = file.indices(&[2, 1, 0], IndexType::U8);
    let square = file.positions(&SQUARE);
    let square_indices = file.indices(&[0, 1, 2, 0, 2, 3], IndexType::U32);
    let meshes = format!(
        r#""meshes": [
    {{"primitives": [{{"attributes": {{"POSITION": {tri}}}, "indices": {tri_indices}}},
                     {{"attributes": {{"POSITION": {tri}}}, "mode": 1}},
                     {{"attributes": {{"POSITION": {second}}}, "indices": {second_indices}, "mode": 4}}]}},
    {{"primitives": [{{"attributes": {{"POSITION": {square}}}, "indices": {square_indices}}}]}},
    {{"primitives": [{{"attributes": {{"POSITION": {tri}}}}}]}}
  ]"#
    );
    (file, meshes)
}

/// The nodes of the main test scene (scene 1, the default): node 0 carries no mesh, has a
/// column-major `matrix` (a quarter turn about z, then a translation) and children 1 and 2;
/// node 1 places mesh 0 by TRS; node 2 places mesh 1 mirrored in x, with child 3 placing mesh 0
/// again; node 4, a root, places mesh 1 again; node 5 (mesh 0) is only in scene 0.
const NODES: &str = r#""scene": 1,
  "scenes": [{"nodes": [5]}, {"nodes": [0, 4]}],
  "nodes": [
    {"matrix": [0, 1, 0, 0,  -1, 0, 0, 0,  0, 0, 1, 0,  5, 0, 0, 1], "children": [1, 2]},
    {"mesh": 0, "translation": [0, 0, 1], "rotation": [0, 0, 0.38268343, 0.9238795],
     "scale": [2, 2, 3]},
    {"mesh": 1, "scale": [-1, 1, 1], "children": [3]},
    {"mesh": 0, "translation": [0, 3, 0]},
    {"mesh": 1, "translation": [0.5, 0, -4]},
    {"mesh": 0}
  ]"#;

/// The world transforms the instances of [`NODES`] must have, in instance order, computed here
/// from the numbers in the file.
fn expected_transforms() -> Vec<DMat4> {
    let root = DMat4::from_cols_array(&[
        0., 1., 0., 0., -1., 0., 0., 0., 0., 0., 1., 0., 5., 0., 0., 1.,
    ]);
    let quat = DQuat::from_xyzw(0.0, 0.0, f64::from(0.38268343f32), f64::from(0.9238795f32));
    let node1 = DMat4::from_translation(DVec3::new(0., 0., 1.))
        * DMat4::from_quat(quat)
        * DMat4::from_scale(DVec3::new(2., 2., 3.));
    let node2 = DMat4::from_scale(DVec3::new(-1., 1., 1.));
    let node3 = DMat4::from_translation(DVec3::new(0., 3., 0.));
    let node4 = DMat4::from_translation(DVec3::new(0.5, 0., -4.));
    vec![root * node1, root * node2, root * node2 * node3, node4]
}

fn corners(t: &Triangle) -> [Vec3; 3] {
    [t.p0, t.p1, t.p2]
}

fn error_of(path: &Path) -> String {
    let message = match Scene::load(path) {
        Ok(scene) => panic!(
            "{} loaded ({} instances) but should fail",
            path.display(),
            scene.instance_count()
        ),
        Err(e) => e.to_string(),
    };
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(message.contains(name), "does not name the file: {message}");
    message
}

fn assert_mentions(message: &str, words: &[&str]) {
    for word in words {
        assert!(message.contains(word), "message lacks {word:?}: {message}");
    }
}

/// Rays through points of every triangle of `flat`, from around its box.
fn rays_at(mesh: &TriangleMesh, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let bounds = mesh.bounds();
    let centre = (bounds.min + bounds.max) * 0.5;
    let radius = (bounds.max - bounds.min).length().max(1.0);
    (0..count)
        .map(|_| {
            let t = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
            let (a, b): (f32, f32) = (rng.random(), rng.random());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            let target = t.p0 + a * (t.p1 - t.p0) + b * (t.p2 - t.p0);
            let away = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let origin = centre + away * radius;
            Ray::new(origin, target - origin)
        })
        .collect()
}

#[test]
fn nodes_with_meshes_are_instances_in_depth_first_order_sharing_meshes() {
    let dir = TempDir::new().unwrap();
    let (file, meshes) = three_meshes();
    let path = file.write(dir.path(), "scene", &format!("{NODES},\n  {meshes}"));
    let scene = Scene::load(&path).unwrap();

    // Nodes 1, 2, 3, 4 carry meshes; nodes 1 and 3 share mesh 0, nodes 2 and 4 mesh 1, each
    // built once; mesh 2 is placed by no node and not added.
    assert_eq!(scene.instance_count(), 4);
    assert_eq!(scene.mesh_count(), 2);
    let mesh0 = scene.mesh(MeshId(0)).unwrap();
    // The TRIANGLES primitives concatenated (u16, then u8 indices); the LINES one ignored.
    assert_eq!(mesh0.indices(), &[[0, 1, 2], [5, 4, 3]]);
    let positions: Vec<[f32; 3]> = mesh0.positions().iter().map(|p| p.to_array()).collect();
    assert_eq!(positions, [TRIANGLE, SECOND_TRIANGLE].concat());
    let mesh1 = scene.mesh(MeshId(1)).unwrap();
    assert_eq!(mesh1.indices(), &[[0, 1, 2], [0, 2, 3]]); // u32 indices

    // World vertices: the f64 product of the node matrices, root down.
    let flat = scene.flattened().unwrap();
    assert_eq!(flat.offsets, [0, 2, 4, 6, 8]);
    let local = [mesh0, mesh1, mesh0, mesh1];
    for (i, m) in expected_transforms().iter().enumerate() {
        for prim in 0..2 {
            let face = flat.offsets[i] as usize + prim;
            let want = corners(&local[i].triangle(prim))
                .map(|p| m.transform_point3(p.as_dvec3()).as_vec3());
            let got = corners(&flat.mesh.triangle(face));
            assert_eq!(got, want, "instance {i} prim {prim}");
        }
    }

    // The flattened loader gives the same triangles, within its f32 products.
    let loaded = TriangleMesh::load(&path).unwrap();
    assert_eq!(loaded.triangle_count(), flat.mesh.triangle_count());
    for face in 0..loaded.triangle_count() {
        let (a, b) = (loaded.triangle(face), flat.mesh.triangle(face));
        for (p, q) in corners(&a).iter().zip(corners(&b)) {
            assert!(
                (*p - q).abs().max_element() < 1e-5,
                "face {face}: {p} vs {q}"
            );
        }
    }

    // Answers: as the brute force over the flattened triangles, the mirrored instance's normal
    // flipped.
    let rays = rays_at(&flat.mesh, 2000, 7);
    let mut mirrored_hits = 0;
    for ray in &rays {
        let ray = SceneRay::new(*ray);
        let (ours, theirs) = (scene.intersect(&ray), flat.intersect(&ray));
        let (Some(ours), Some(theirs)) = (ours, theirs) else {
            assert_eq!(ours.is_some(), theirs.is_some(), "{ray:?}");
            continue;
        };
        assert!(
            (ours.t - theirs.t).abs() <= 1e-4 * ours.t.max(1.0),
            "{ray:?}"
        );
        if (ours.instance, ours.prim) == (theirs.instance, theirs.prim) {
            assert!((ours.normal - theirs.normal).length() < 1e-5);
            mirrored_hits += usize::from(ours.instance == 1);
        }
    }
    assert!(mirrored_hits > 100);
    // The mirrored square (instance 1) faces -z in the world: its local normal is +z, and the
    // mirror flips it (the root's quarter turn about z leaves z alone).
    let down = SceneRay::new(Ray::new(Vec3::new(5.0, 0.0, 5.0), -Vec3::Z));
    let up = SceneRay::new(Ray::new(Vec3::new(5.0, 0.0, -1.0), Vec3::Z));
    let hit = scene.intersect(&up).unwrap();
    assert_eq!(hit.instance, 1);
    assert!((hit.normal - -Vec3::Z).length() < 1e-6, "{:?}", hit.normal);
    assert!(scene.intersect(&down).is_some());
}

#[test]
fn a_file_without_scenes_places_each_mesh_once() {
    let dir = TempDir::new().unwrap();
    let (file, meshes) = three_meshes();
    let path = file.write(dir.path(), "meshes", &meshes);
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.instance_count(), 3);
    assert_eq!(scene.mesh_count(), 3);
    let flat = scene.flattened().unwrap();
    assert_eq!(flat.mesh, TriangleMesh::load(&path).unwrap());
}

#[test]
fn strips_and_fans_are_not_scene_triangles() {
    let dir = TempDir::new().unwrap();
    let mut file = GltfFile::default();
    let square = file.positions(&SQUARE);
    let tri = file.positions(&TRIANGLE);
    let meshes = format!(
        r#""scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {square}}}, "mode": 5}},
                              {{"attributes": {{"POSITION": {tri}}}}},
                              {{"attributes": {{"POSITION": {square}}}, "mode": 6}},
                              {{"attributes": {{"POSITION": {square}}}, "mode": 0}}]}}]"#
    );
    let path = file.write(dir.path(), "strips", &meshes);
    let scene = Scene::load(&path).unwrap();
    let mesh = scene.mesh(MeshId(0)).unwrap();
    assert_eq!(mesh.indices(), &[[0, 1, 2]]);
    assert_eq!(mesh.positions().len(), 3);
    // The flattened mesh loader reads strips and fans too.
    assert_eq!(TriangleMesh::load(&path).unwrap().triangle_count(), 5);
}

#[test]
fn an_obj_file_is_a_scene_of_one_instance() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("quad.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
    let scene = Scene::load(&path).unwrap();
    assert_eq!((scene.mesh_count(), scene.instance_count()), (1, 1));
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(scene.mesh(MeshId(0)), Some(&mesh));
    assert_eq!(scene.flattened().unwrap().mesh, mesh);
    let hit = scene
        .intersect(&SceneRay::new(Ray::new(
            Vec3::new(0.75, 0.25, 1.0),
            -Vec3::Z,
        )))
        .unwrap();
    assert_eq!((hit.instance, hit.prim), (0, 0));
}

/// A scene of one node, `node` (JSON), placing the triangle as mesh 0 below a root `parent`.
fn one_node(dir: &Path, name: &str, parent: &str, node: &str) -> PathBuf {
    let mut file = GltfFile::default();
    let tri = file.positions(&TRIANGLE);
    file.write(
        dir,
        name,
        &format!(
            r#""scenes": [{{"nodes": [0]}}],
  "nodes": [{{{parent} "children": [1]}}, {{"mesh": 0, {node}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {tri}}}}}]}}]"#
        ),
    )
}

#[test]
fn bad_node_transforms_are_refused_naming_the_node() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let flat = one_node(d, "flat", "", r#""scale": [1, 1, 0]"#);
    assert_mentions(&error_of(&flat), &["node 1", "mesh 0", "singular"]);
    // A singular parent without a mesh makes its child's world transform singular.
    let parent = one_node(d, "parent", r#""scale": [0, 0, 0],"#, r#""name": "child""#);
    assert_mentions(&error_of(&parent), &["node 1", "singular"]);
    let huge = one_node(
        d,
        "huge",
        r#""translation": [1e39, 0, 0],"#,
        r#""name": "x""#,
    );
    assert_mentions(&error_of(&huge), &["node 0", "not finite"]);
    let projective = one_node(
        d,
        "projective",
        "",
        r#""matrix": [1, 0, 0, 0.5,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]"#,
    );
    assert_mentions(&error_of(&projective), &["node 1", "bottom row"]);
    let fine = one_node(
        d,
        "fine",
        r#""scale": [1e-3, 1e-3, 1e-3],"#,
        r#""scale": [-2, 2, 2]"#,
    );
    assert_eq!(Scene::load(&fine).unwrap().instance_count(), 1);
}

#[test]
fn broken_buffers_and_indices_are_refused_naming_the_place() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();

    // An index past the primitive's positions.
    let mut file = GltfFile::default();
    let tri = file.positions(&TRIANGLE);
    let bad = file.indices(&[0, 1, 9], IndexType::U16);
    let meshes = format!(
        r#""scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {tri}}}, "indices": {bad}}}]}}]"#
    );
    let path = file.write(d, "index", &meshes);
    assert_mentions(
        &error_of(&path),
        &["mesh 0 primitive 0", "index 9", "out of range"],
    );

    // A position that is not a number.
    let mut file = GltfFile::default();
    let nan = file.positions(&[[0., 0., 0.], [f32::NAN, 0., 0.], [0., 1., 0.]]);
    let meshes = format!(
        r#""scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {nan}}}}}]}}]"#
    );
    let path = file.write(d, "nan", &meshes);
    assert_mentions(&error_of(&path), &["mesh 0 vertex 1", "not finite"]);

    // A buffer file shorter than the buffer's declared length.
    let path = one_node(d, "truncated", "", r#""name": "x""#);
    std::fs::write(d.join("truncated.bin"), [0u8; 20]).unwrap();
    assert_mentions(&error_of(&path), &["buffer 0", "truncated.bin", "36"]);

    // A node that is its own ancestor.
    let path = d.join("cycle.gltf");
    std::fs::write(
        &path,
        r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
            "nodes": [{"children": [1]}, {"children": [0]}]}"#,
    )
    .unwrap();
    assert_mentions(&error_of(&path), &["node 0", "cycle"]);

    // Bytes that name an external buffer are refused without touching the file system.
    let json = std::fs::read(d.join("index.gltf")).unwrap();
    let e = Scene::from_bytes(
        MeshFormat::Gltf,
        "in-memory.gltf",
        &json,
        Default::default(),
    )
    .unwrap_err()
    .to_string();
    assert_mentions(&e, &["in-memory.gltf", "buffer 0", "external files"]);
}

/// The shared `menagerie.glb` (201 instances of 5 meshes) as a scene: its flattened mesh is the
/// flattened loader's, and random rays hit the same (instance, prim) as a BVH over that mesh.
/// Skipped without `../shared/scenes`.
#[test]
fn menagerie_answers_as_its_flattened_mesh() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes/menagerie.glb");
    if !path.is_file() {
        eprintln!("skipping: {} not found", path.display());
        return;
    }
    let scene = Scene::load(&path).unwrap();
    assert_eq!((scene.mesh_count(), scene.instance_count()), (5, 201));
    let flat = scene.flattened().unwrap();
    assert_eq!(flat.mesh.triangle_count(), 7_168_082);

    // Triangle for triangle the flattened loader's mesh, within its f32 products.
    let loaded = TriangleMesh::load(&path).unwrap();
    assert_eq!(loaded.triangle_count(), flat.mesh.triangle_count());
    let size = flat.mesh.bounds().max.abs().max_element();
    let size = size.max(flat.mesh.bounds().min.abs().max_element());
    let mut largest = 0.0f32;
    for face in 0..loaded.triangle_count() {
        let (a, b) = (loaded.triangle(face), flat.mesh.triangle(face));
        for (p, q) in corners(&a).iter().zip(corners(&b)) {
            largest = largest.max((*p - q).abs().max_element());
        }
    }
    eprintln!("largest vertex difference {largest:e} in a scene of size {size}");
    assert!(largest <= 1e-5 * size, "{largest} of {size}");

    // Random rays at points of the flattened triangles: the scene's (instance, prim) is the
    // face a BVH over the flattened mesh hits, through the offsets, but where the ray passes
    // within rounding of an edge of either triangle (`ε` of the module notes of `hbv::scene`,
    // with the menagerie's `κ ≤ 3` of rotations and uniform scales, taken 4 times).
    let bvh = LayoutKind::Wide8.lay_out(
        &BuilderKind::BinnedSah.build(&flat.mesh, &BuilderOptions::default()),
        &flat.mesh,
        &LayoutOptions::default(),
    );
    let rays = rays_at(&flat.mesh, 20_000, 11);
    let (mut same, mut near_edges) = (0, 0);
    for ray in &rays {
        let ours = scene.intersect(&SceneRay::new(*ray));
        let theirs = bvh.intersect(ray);
        let epsilon = |t: f32| {
            let (o, d) = (
                ray.origin.abs().max_element(),
                ray.direction.abs().max_element(),
            );
            f64::from(3.0 * (o + size + t * d) + size) / f64::from(1u32 << 20)
        };
        match (ours, theirs) {
            (Some(o), Some(t)) if flat.instance_of(t.prim) == (o.instance, o.prim) => {
                // Moving the plane or the ray by `ε` moves the hit by `ε / |n̂ · d|` along it.
                let slope = f64::from(o.normal.dot(ray.direction).abs());
                assert!(
                    f64::from((o.t - t.t).abs()) * slope <= epsilon(o.t),
                    "{ray:?}: {o:?} vs {t:?}"
                );
                same += 1;
            }
            (None, None) => same += 1,
            (Some(o), Some(t)) => {
                let face = flat.offsets[o.instance as usize] + o.prim;
                let near = |face: u32, at: f32| {
                    let triangle = flat.mesh.triangle(face as usize);
                    let slope = triangle
                        .scaled_normal()
                        .normalize()
                        .dot(ray.direction.as_dvec3().normalize())
                        .abs();
                    edge_distance(&triangle, ray.at(at).as_dvec3()) * slope.max(1e-3) <= epsilon(at)
                };
                assert!(
                    near(face, o.t) || near(t.prim, t.t),
                    "{ray:?}: {o:?} vs face {} {:?} at {}",
                    t.prim,
                    flat.instance_of(t.prim),
                    t.t
                );
                near_edges += 1;
            }
            (o, t) => panic!("{ray:?}: {o:?} vs {t:?}"),
        }
    }
    eprintln!(
        "{same} of {} rays agree, {near_edges} differ near an edge",
        rays.len()
    );
    assert!(same as f64 >= 0.995 * rays.len() as f64);
}

/// The distance from `p` to the nearest edge of `triangle` (as segments), in f64.
fn edge_distance(triangle: &Triangle, p: DVec3) -> f64 {
    let [a, b, c] = corners(triangle).map(|v| v.as_dvec3());
    [(a, b), (b, c), (c, a)]
        .into_iter()
        .map(|(s, e)| {
            let along = (p - s).dot(e - s) / (e - s).length_squared().max(f64::MIN_POSITIVE);
            (s + (e - s) * along.clamp(0.0, 1.0) - p).length()
        })
        .fold(f64::INFINITY, f64::min)
}
