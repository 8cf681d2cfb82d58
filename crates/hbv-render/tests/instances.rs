//! `[[instance]]` tables: a scene that places meshes by instances renders the picture of the
//! same scene with every copy transformed by hand into its own mesh, and bad tables are errors
//! naming the file, the line and the key.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Vec3};
use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::bvh::layout::Wide8Layout;
use hbv::mesh::procedural::icosphere;
use hbv::TriangleMesh;
use hbv_render::scene::load_scene;
use hbv_render::{render, Frame, QueryCacheConfig, RayKind, RenderConfig, Scene, SceneTracer};

const HEAD: &str = r#"
[render]
width = 96
height = 64
spp = 2
max_depth = 4
background = [0.3, 0.4, 0.5]
ambient = [0.1, 0.1, 0.1]

[camera]
position = [1, 4, 7]
look_at = [1, 0, 0]
fov = 45

[materials.red]
type = "phong"
color = [0.8, 0.1, 0.1]
exponent = 30

[materials.blue]
type = "diffuse"
color = [0.1, 0.2, 0.8]

[materials.glass]
type = "glass"
ior = 1.5

[materials.ground]
type = "diffuse"
color = [0.6, 0.6, 0.5]

[[light]]
type = "point"
position = [2, 6, 3]
intensity = 40

[[light]]
type = "area"
corner = [-1, 5, -1]
edge_u = [1, 0, 0]
edge_v = [0, 0, 1]
intensity = 3
samples = 4
"#;

/// A grid of boxes turned and scaled unevenly, a smooth sphere mirrored by a matrix, and the
/// ground: as `[[instance]]` tables of two shared meshes.
const INSTANCED: &str = r#"
[[mesh]]
name = "ground"
file = "quad.obj"
material = "ground"
scale = [4, 1, 4]
translate = [0, -0.01, 0]

[[mesh]]
name = "box"
file = "box.obj"
translate = [0, 0.5, 0]
place = false

[[mesh]]
name = "ball"
file = "ball.obj"
smooth = true
place = false

[[instance]]
mesh = "box"
grid = [3, 1, 2]
spacing = [1.5, 0, 1.5]
translate = [-1, 0, -1.5]
rotate = [10, 30, 0]
scale = [0.5, 0.8, 0.6]
material = "red"

[[instance]]
mesh = "ball"
matrix = [[-0.6, 0, 0, 2.5], [0, 0.5, 0, 0.6], [0, 0, 0.7, 1.2]]
material = "glass"

[[instance]]
mesh = "ball"
translate = [0, 0.4, 1.5]
scale = [0.4, 0.4, 0.8]
rotate = [0, 0, 30]
material = "blue"
"#;

/// The unit cube of the examples (`examples/box.obj`).
fn box_mesh() -> TriangleMesh {
    TriangleMesh::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/box.obj"))
        .unwrap()
}

fn obj(mesh: &TriangleMesh, place: impl Fn(Vec3) -> Vec3) -> String {
    let mut text = String::new();
    for &p in mesh.positions() {
        let q = place(p);
        writeln!(text, "v {:e} {:e} {:e}", q.x, q.y, q.z).unwrap();
    }
    for t in mesh.indices() {
        writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    text
}

/// `p ↦ t + Rz Ry Rx (s ⊙ p)`, angles in degrees: the scene format's placement, written out.
fn placed(t: Vec3, degrees: Vec3, s: Vec3) -> impl Fn(Vec3) -> Vec3 {
    let r = degrees * (std::f32::consts::PI / 180.0);
    let m = Mat3::from_rotation_z(r.z) * Mat3::from_rotation_y(r.y) * Mat3::from_rotation_x(r.x);
    move |p| t + m * (s * p)
}

/// The folder with the meshes and both scenes: `instanced.toml`, and `flat.toml`, where every
/// copy is its own mesh file, transformed here.
fn scenes() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
    let quad = "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3 4\n";
    write("quad.obj", quad);
    let cube = box_mesh();
    let ball = icosphere(Vec3::ZERO, 1.0, 2);
    write("box.obj", &obj(&cube, |p| p));
    write("ball.obj", &obj(&ball, |p| p));
    write("instanced.toml", &format!("{HEAD}{INSTANCED}"));

    let mut flat = String::from(HEAD);
    let mut add = |file: String, text: String, material: &str, smooth: bool| {
        write(&file, &text);
        writeln!(
            flat,
            "[[mesh]]\nfile = \"{file}\"\nmaterial = \"{material}\"\nsmooth = {smooth}\n"
        )
        .unwrap();
    };
    let ground = TriangleMesh::load(dir.path().join("quad.obj")).unwrap();
    let ground_place = placed(
        Vec3::new(0.0, -0.01, 0.0),
        Vec3::ZERO,
        Vec3::new(4.0, 1.0, 4.0),
    );
    add(
        "ground.obj".into(),
        obj(&ground, ground_place),
        "ground",
        false,
    );
    for z in 0..2 {
        for x in 0..3 {
            let at = Vec3::new(-1.0 + 1.5 * x as f32, 0.0, -1.5 + 1.5 * z as f32);
            let copy = placed(at, Vec3::new(10.0, 30.0, 0.0), Vec3::new(0.5, 0.8, 0.6));
            let text = obj(&cube, |p| copy(p + Vec3::new(0.0, 0.5, 0.0)));
            add(format!("box{x}{z}.obj"), text, "red", false);
        }
    }
    let mirrored = |p: Vec3| Vec3::new(-0.6 * p.x + 2.5, 0.5 * p.y + 0.6, 0.7 * p.z + 1.2);
    add("glass.obj".into(), obj(&ball, mirrored), "glass", true);
    let turned = placed(
        Vec3::new(0.0, 0.4, 1.5),
        Vec3::new(0.0, 0.0, 30.0),
        Vec3::new(0.4, 0.4, 0.8),
    );
    add("blue.obj".into(), obj(&ball, turned), "blue", true);
    write("flat.toml", &flat);
    let (a, b) = (
        dir.path().join("instanced.toml"),
        dir.path().join("flat.toml"),
    );
    (dir, a, b)
}

fn render_two_level(scene: &Scene) -> Frame {
    let tracer = SceneTracer::two_level(Arc::new(scene.two_level(Default::default())));
    render(scene, &tracer, &RenderConfig::default())
}

fn render_flat(scene: &Scene) -> Frame {
    let mesh = scene.flat_mesh();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh);
    let bvh: Arc<dyn hbv::Accelerator> = Arc::new(Wide8Layout::new(&tree, mesh));
    render(
        scene,
        &SceneTracer::new(bvh.clone(), bvh),
        &RenderConfig::default(),
    )
}

/// Equal within noise: the mean difference per channel at most 0.004 (1 of 255), and at most
/// 2% of the pixels differing by more than 0.05 in a channel (rays that graze an edge may hit
/// or miss either way, the rounding of the two placements being different).
fn assert_same_picture(a: &Frame, b: &Frame, what: &str) {
    let (x, y) = (&a.film.radiance, &b.film.radiance);
    assert_eq!(x.len(), y.len());
    let diffs: Vec<f32> = x
        .iter()
        .zip(y)
        .map(|(p, q)| (p.min(Vec3::ONE) - q.min(Vec3::ONE)).abs().max_element())
        .collect();
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let far = diffs.iter().filter(|&&d| d > 0.05).count();
    assert!(mean <= 0.004, "{what}: mean difference {mean}");
    assert!(far * 50 <= diffs.len(), "{what}: {far} pixels differ");
    let lit = x.iter().map(|c| c.max_element()).sum::<f32>() / x.len() as f32;
    assert!(lit > 0.1, "{what}: a picture, not black ({lit})");
}

#[test]
fn instances_render_as_the_scene_flattened_by_hand() {
    let (_dir, instanced_path, flat_path) = scenes();
    let instanced = load_scene(&instanced_path).unwrap();
    let by_hand = load_scene(&flat_path).unwrap();
    // The area light's panel, the ground and two shared meshes; the same triangles as seen as
    // the hand-made scene.
    assert_eq!(instanced.meshes.len(), 4);
    assert_eq!(instanced.instances.len(), 1 + 1 + 6 + 2);
    assert!(instanced.shares_meshes() && !by_hand.shares_meshes());
    assert_eq!(instanced.triangle_count(), by_hand.triangle_count());
    assert!(instanced.stored_triangle_count() < by_hand.stored_triangle_count());
    let b = (instanced.flat_mesh().bounds(), by_hand.flat_mesh().bounds());
    assert!((b.0.min - b.1.min).abs().max_element() < 1e-4, "{b:?}");
    assert!((b.0.max - b.1.max).abs().max_element() < 1e-4, "{b:?}");

    let reference = render_flat(&by_hand);
    let two_level = render_two_level(&instanced);
    assert_same_picture(&two_level, &reference, "two-level against by hand");
    assert_same_picture(
        &render_flat(&instanced),
        &reference,
        "flattened against by hand",
    );
    // The glass ball (mirrored) is seen through: its refracted rays are cast.
    assert!(two_level.stats.rays[2] > 0);
    // The same rays are cast, and both count their work.
    assert_eq!(two_level.stats.rays[0], reference.stats.rays[0]);
    assert_eq!(
        two_level.stats.total_work().rays,
        two_level.stats.total_rays()
    );
}

/// On the two-level scene of shared, turned, scaled and mirrored meshes, seen through glass and
/// lit by an area light, the scene's object caches (keyed by instance and prim) and the counted
/// queries change the work, never the picture: bit for bit the uncached, uncounted one, with
/// every cache on or off, on one thread or three; the counted work fills the cost heatmaps.
#[test]
fn two_level_caches_and_counted_work_leave_the_picture_unchanged() {
    let (_dir, instanced_path, _) = scenes();
    let scene = load_scene(&instanced_path).unwrap();
    let tracer = SceneTracer::two_level(Arc::new(scene.two_level(Default::default())));
    let on = |threads: usize, caches: QueryCacheConfig, count_work: bool| {
        let config = RenderConfig {
            count_work,
            ..RenderConfig::default()
        };
        let traced = tracer.clone().with_caches(caches);
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&scene, &traced, &config))
    };
    let plain = on(1, QueryCacheConfig::none(), false);
    let every_cache = QueryCacheConfig {
        secondary: true,
        shadow_per_sample: true,
        ..QueryCacheConfig::default()
    };
    let runs = [
        (3, QueryCacheConfig::none(), true),
        (1, QueryCacheConfig::default(), false),
        (3, QueryCacheConfig::default(), true),
        (1, every_cache, true),
    ];
    for (threads, caches, count_work) in runs {
        let what = format!("{caches:?}, work counted: {count_work}, {threads} threads");
        let frame = on(threads, caches, count_work);
        assert!(frame.film.radiance == plain.film.radiance, "{what}");
        assert!(frame.film.prim == plain.film.prim, "{what}");
        assert_eq!(frame.stats.rays, plain.stats.rays, "{what}");
        assert_eq!(frame.stats.shadow_blocked, plain.stats.shadow_blocked);
        let work = frame.stats.total_work();
        let rays = frame.stats.total_rays();
        assert_eq!(work.rays, if count_work { rays } else { 0 }, "{what}");
        let heat = frame
            .film
            .nodes_visited
            .iter()
            .filter(|&&n| n > 0.0)
            .count();
        if count_work {
            assert!(heat * 2 > frame.film.nodes_visited.len(), "{what}: {heat}");
        } else {
            assert_eq!(heat, 0, "{what}");
        }
        let cache = &frame.stats.cache;
        let kinds = [
            RayKind::Primary,
            RayKind::Reflected,
            RayKind::Transmitted,
            RayKind::Shadow { light: 0 },
        ];
        for kind in kinds {
            let (k, c) = (kind.index(), cache[kind.index()]);
            let cached = caches.caches(kind).then_some(frame.stats.rays[k]);
            assert_eq!(c.hits + c.misses, cached.unwrap_or(0), "{what}: {kind:?}");
        }
        if caches.shadow {
            assert!(cache[3].hits > 0 && cache[3].hits <= frame.stats.shadow_blocked);
        }
        if caches.primary {
            assert!(cache[0].hits > 0, "{what}");
        }
    }
}

/// Each copy of a grid with random turns, sizes, offsets and materials is drawn from its
/// table's seed: the same file gives the same scene, another seed another one.
#[test]
fn random_copies_follow_the_seed() {
    let (dir, instanced_path, _) = scenes();
    let text = std::fs::read_to_string(&instanced_path).unwrap().replace(
        "material = \"red\"",
        "material = [\"red\", \"blue\"]\nrandom_rotate = [0, 360, 0]\nrandom_scale = [0.5, 1.5]\nrandom_offset = [0.2, 0, 0.2]\nseed = 7",
    );
    let path = dir.path().join("random.toml");
    std::fs::write(&path, &text).unwrap();
    let a = load_scene(&path).unwrap();
    let b = load_scene(&path).unwrap();
    assert_eq!(a.instances, b.instances);
    std::fs::write(&path, text.replace("seed = 7", "seed = 8")).unwrap();
    let c = load_scene(&path).unwrap();
    assert_ne!(a.instances, c.instances);
    let materials: std::collections::BTreeSet<u32> =
        a.instances[2..8].iter().map(|i| i.material).collect();
    assert_eq!(materials.len(), 2, "both materials are drawn");
}

fn load_error(dir: &Path, text: &str) -> String {
    let path = dir.join("bad.toml");
    std::fs::write(&path, format!("{HEAD}{text}")).unwrap();
    let e = load_scene(&path).unwrap_err().to_string();
    assert!(e.contains(&path.display().to_string()), "{e}");
    e
}

fn line_of(text: &str, needle: &str) -> usize {
    let full = format!("{HEAD}{text}");
    full[..full.find(needle).unwrap()].lines().count() + 1
}

#[test]
fn bad_instance_tables_name_the_file_the_line_and_the_key() {
    let (dir, _, _) = scenes();
    let dir = dir.path();
    let mesh = "[[mesh]]\nname = \"box\"\nfile = \"box.obj\"\nplace = false\n\n";
    let cases: [(String, &str, &str, &str); 7] = [
        (
            format!("{mesh}[[instance]]\nmesh = \"crate\"\n"),
            "mesh = \"crate\"",
            "instance[0].mesh",
            "no mesh named \"crate\" (the scene's [[mesh]] tables name: \"box\")",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"box\"\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [1, 1, 0, 0]]\n"),
            "matrix =",
            "instance[0].matrix",
            "singular",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"box\"\nscale = [1e-7, 1e-7, 1]\n"),
            "[[instance]]",
            "instance[0]",
            "singular",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"box\"\nmatrix = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n"),
            "matrix =",
            "instance[0].matrix",
            "must be 3 rows of 4 numbers",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"box\"\ngrid = [3, 0, 2]\n"),
            "grid =",
            "instance[0].grid",
            "3 whole numbers ≥ 1",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"box\"\nrandom_scale = [0, 2]\n"),
            "random_scale",
            "instance[0].random_scale",
            "0 < smallest",
        ),
        (
            format!("{mesh}{mesh}[[instance]]\nmesh = \"box\"\n"),
            "mesh = \"box\"",
            "instance[0].mesh",
            "2 [[mesh]] tables are named \"box\" (mesh[0], mesh[1])",
        ),
    ];
    for (text, needle, key, reason) in cases {
        let e = load_error(dir, &text);
        let line = line_of(&text, needle);
        assert!(e.contains(&format!("line {line}: {key}: ")), "{e}");
        assert!(e.contains(reason), "{e}");
    }
}
