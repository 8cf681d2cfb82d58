//! `hbv trace` a chunk at a time (`--chunk-rays`): ray files read in chunks give the rays of the
//! whole-file reader, hit files written in chunks are byte for byte the file of one chunk, for
//! meshes (BVH and grid) and scenes (glTF and saved), and a ray file that fails part way leaves
//! no output behind.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::scenes::{instanced_scene, rays_at as scene_rays_at};
use common::{hbv, point_in_box, random_direction, stderr, write_obj};

use glam::Vec3;
use hbv::atomic_file::Replace;
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::scene::{Scene, SceneRay};
use hbv::{Accelerator, BruteForce};
use hbv_cli::hit_file;
use hbv_cli::ray_file::{read_rays, write_rays};
use hbv_cli::ray_stream::RayChunks;
use ndarray::{Array1, Array2, ShapeBuilder};
use ndarray_npy::NpzWriter;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Runs `hbv` with `args`, asserting success.
fn run(args: &[&str]) {
    let out = hbv(args);
    assert!(out.status.success(), "hbv {args:?}: {}", stderr(&out));
}

/// Runs `hbv trace MESH --rays RAYS --out OUT` with `flags`.
fn trace(mesh: &Path, rays: &Path, out: &Path, flags: &[&str]) -> Output {
    let mut args = vec!["trace", s(mesh), "--rays", s(rays), "--out", s(out)];
    args.extend(flags);
    hbv(&args)
}

/// [`trace`], asserting success.
fn trace_ok(mesh: &Path, rays: &Path, out: &Path, flags: &[&str]) {
    let o = trace(mesh, rays, out, flags);
    assert!(o.status.success(), "hbv trace {flags:?}: {}", stderr(&o));
}

/// Rays from random points of the box around `lo..lo + extent` in random directions, every
/// fifth with a finite interval, one with a NaN origin (a miss).
fn random_rays(count: usize, lo: Vec3, extent: Vec3, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    (0..count)
        .map(|i| {
            let ray = Ray::new(
                point_in_box(&mut rng, lo, extent),
                random_direction(&mut rng),
            );
            match i % 5 {
                0 => ray.with_interval(0.05, 0.5 * extent.length()),
                _ if i == 11 => Ray::new(Vec3::NAN, ray.direction),
                _ => ray,
            }
        })
        .collect()
}

/// How a ray file stores its arrays.
#[derive(Clone, Copy, Debug)]
struct Storage {
    compressed: bool,
    float64: bool,
    fortran: bool,
}

/// Writes `rays` to `path` stored as `storage` says, with ndarray-npy (as NumPy would).
fn write_stored(path: &Path, rays: &[Ray], storage: Storage) {
    let n = rays.len();
    let rows = |f: fn(&Ray) -> Vec3| -> Array2<f64> {
        let c = Array2::from_shape_fn((n, 3), |(i, j)| f64::from(f(&rays[i])[j]));
        if storage.fortran {
            let mut a = Array2::zeros((n, 3).f());
            a.assign(&c);
            a
        } else {
            c
        }
    };
    let column =
        |f: fn(&Ray) -> f32| -> Array1<f64> { rays.iter().map(|r| f64::from(f(r))).collect() };
    let file = File::create(path).unwrap();
    let mut npz = if storage.compressed {
        NpzWriter::new_compressed(file)
    } else {
        NpzWriter::new(file)
    };
    let members = [
        ("origins", rows(|r| r.origin)),
        ("directions", rows(|r| r.direction)),
    ];
    for (member, a) in members {
        if storage.float64 {
            npz.add_array(member, &a).unwrap();
        } else {
            npz.add_array(member, &a.mapv(|x| x as f32)).unwrap();
        }
    }
    for (member, a) in [("tmin", column(|r| r.tmin)), ("tmax", column(|r| r.tmax))] {
        if storage.float64 {
            npz.add_array(member, &a).unwrap();
        } else {
            npz.add_array(member, &a.mapv(|x| x as f32)).unwrap();
        }
    }
    npz.finish().unwrap();
}

/// The bits of each ray's values (NaN compares unequal to itself).
fn ray_bits(rays: &[Ray]) -> Vec<[u32; 8]> {
    rays.iter()
        .map(|r| {
            let [a, b, c] = r.origin.to_array().map(f32::to_bits);
            let [d, e, f] = r.direction.to_array().map(f32::to_bits);
            [a, b, c, d, e, f, r.tmin.to_bits(), r.tmax.to_bits()]
        })
        .collect()
}

/// Every storage of a ray file: compressed or not, float32 or 64, C or Fortran order.
fn storages() -> Vec<Storage> {
    let mut all = Vec::new();
    for bits in 0..8 {
        all.push(Storage {
            compressed: bits & 1 != 0,
            float64: bits & 2 != 0,
            fortran: bits & 4 != 0,
        });
    }
    all
}

/// Reads `path` in chunks of `chunk` rays.
fn read_chunked(path: &Path, chunk: usize) -> Vec<Ray> {
    let mut chunks = RayChunks::open(path).unwrap();
    let mut all = Vec::new();
    let mut rays = Vec::new();
    let mut sizes = Vec::new();
    loop {
        let read = chunks.read_next(chunk, &mut rays).unwrap();
        if read == 0 {
            break;
        }
        assert_eq!(read, rays.len());
        sizes.push(read);
        all.extend_from_slice(&rays);
    }
    assert_eq!(chunks.remaining(), 0);
    assert!(sizes.iter().rev().skip(1).all(|&n| n == chunk), "{sizes:?}");
    all
}

#[test]
fn chunked_reads_give_the_whole_file_reader_rays_in_every_storage() {
    let dir = tempfile::tempdir().unwrap();
    let rays = random_rays(157, Vec3::splat(-1.0), Vec3::splat(2.0), 1);
    for storage in storages() {
        let path = dir.path().join("rays.npz");
        write_stored(&path, &rays, storage);
        let whole = read_rays(&path).unwrap();
        for chunk in [1, 2, 7, 156, 157, 1000] {
            let chunked = read_chunked(&path, chunk);
            assert_eq!(
                ray_bits(&chunked),
                ray_bits(&whole),
                "{storage:?}, chunks of {chunk}"
            );
        }
    }
}

#[test]
fn an_empty_ray_file_gives_an_empty_hit_file() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = dir.path().join("torus.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.7, 12, 6), &mesh_path);
    let rays_path = dir.path().join("rays.npz");
    write_rays(&rays_path, &[], Replace::Never).unwrap();
    assert_eq!(RayChunks::open(&rays_path).unwrap().len(), 0);
    let out = dir.path().join("hits.npz");
    trace_ok(&mesh_path, &rays_path, &out, &[]);
    assert!(hit_file::read_scene_hits(&out).unwrap().is_empty());
}

/// Traces `target` with the rays of `rays_path` in chunks of each of `chunks` (and the default
/// chunk), with `flags`; asserts every hit file is byte for byte the first; returns its path.
fn assert_same_file_whatever_the_chunk(
    dir: &Path,
    target: &Path,
    rays_path: &Path,
    chunks: &[usize],
    flags: &[&str],
) -> PathBuf {
    let reference = dir.join("hits-default.npz");
    trace_ok(
        target,
        rays_path,
        &reference,
        &[&["--force"], flags].concat(),
    );
    let expected = std::fs::read(&reference).unwrap();
    for &chunk in chunks {
        let out = dir.join(format!("hits-{chunk}.npz"));
        let chunk = chunk.to_string();
        let chunked = [&["--force", "--chunk-rays", &chunk], flags].concat();
        trace_ok(target, rays_path, &out, &chunked);
        assert!(
            std::fs::read(&out).unwrap() == expected,
            "{flags:?}: chunks of {chunk} give another file than one chunk"
        );
    }
    reference
}

#[test]
fn mesh_hit_files_are_the_same_bytes_whatever_the_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::new(0.5, -1.0, 2.0), 2.0, 0.7, 30, 15);
    let mesh_path = dir.path().join("torus.obj");
    write_obj(&mesh, &mesh_path);
    let b = mesh.bounds();
    let rays = random_rays(1001, b.min - 0.5, b.extent() + 1.0, 2);
    let rays_path = dir.path().join("rays.npz");
    write_rays(&rays_path, &rays, Replace::Never).unwrap();
    // 1 ray a chunk, 7 (the last chunk partial: 1001 = 143 · 7), 500 (two full, one of one),
    // the whole file, and more than the file.
    let chunks = [1, 7, 500, 1001, 5000];
    for flags in [
        &[][..],
        &["--occluded"],
        &["--accel", "grid"],
        &["--accel", "grid", "--occluded"],
        &["--layout", "recursive"],
        &["--one-by-one"],
        &["--no-packets", "--repeat", "2"],
    ] {
        let file =
            assert_same_file_whatever_the_chunk(dir.path(), &mesh_path, &rays_path, &chunks, flags);
        // And the answers are those of a brute force over every triangle, to rounding.
        if flags.is_empty() {
            let got = hit_file::read_hits(&file).unwrap();
            let want = BruteForce::new(&mesh).intersect_batch(&rays);
            assert_eq!(got.len(), want.len());
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                match (g, w) {
                    (Some(g), Some(w)) => assert!(
                        (g.t - w.t).abs() <= 1e-5 * w.t.abs().max(1.0),
                        "ray {i}: {g:?} against {w:?}"
                    ),
                    (None, None) => {}
                    _ => panic!("ray {i}: {g:?} against {w:?}"),
                }
            }
        }
    }
}

#[test]
fn every_ray_file_storage_traces_to_the_same_hit_file() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = torus(Vec3::ZERO, 2.0, 0.7, 20, 10);
    let mesh_path = dir.path().join("torus.obj");
    write_obj(&mesh, &mesh_path);
    let b = mesh.bounds();
    let rays = random_rays(300, b.min - 0.5, b.extent() + 1.0, 3);
    let plain = dir.path().join("plain.npz");
    write_rays(&plain, &rays, Replace::Never).unwrap();
    let reference = dir.path().join("hits-plain.npz");
    trace_ok(&mesh_path, &plain, &reference, &[]);
    let expected = std::fs::read(&reference).unwrap();
    // float64 copies of float32 values convert back exactly: every storage holds the same rays.
    for storage in storages() {
        let path = dir.path().join("stored.npz");
        write_stored(&path, &rays, storage);
        let out = dir.path().join("hits.npz");
        trace_ok(&mesh_path, &path, &out, &["--force", "--chunk-rays", "37"]);
        assert!(std::fs::read(&out).unwrap() == expected, "{storage:?}");
    }
}

#[test]
fn scene_hit_files_are_the_same_bytes_whatever_the_chunk_and_answer_as_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = instanced_scene();
    let glb = dir.path().join("scene.glb");
    scene.write_gltf(&glb, Replace::Never).unwrap();
    let saved = dir.path().join("scene.hbv");
    run(&["build", s(&glb), "-o", s(&saved)]);
    let rays = scene_rays_at(&scene, 900, 5);
    let rays_path = dir.path().join("rays.npz");
    write_rays(&rays_path, &rays, Replace::Never).unwrap();
    let loaded = Scene::load(&glb).unwrap();
    let scene_rays: Vec<SceneRay> = rays.iter().map(|&r| SceneRay::from(r)).collect();
    let want = loaded.intersect_batch(&scene_rays);
    for target in [&glb, &saved] {
        for flags in [&[][..], &["--occluded"]] {
            let file = assert_same_file_whatever_the_chunk(
                dir.path(),
                target,
                &rays_path,
                &[1, 64, 899, 10_000],
                flags,
            );
            if flags.is_empty() {
                let got = hit_file::read_scene_hits(&file).unwrap();
                assert_eq!(got, want, "{}", target.display());
            }
        }
    }
}

/// The rays of a file read whole with [`read_rays`] or in chunks of 10 with [`RayChunks`], as
/// bits, or the error message.
type ReadResult = Result<Vec<[u32; 8]>, String>;

fn both_readers(path: &Path) -> (ReadResult, ReadResult) {
    let whole = read_rays(path)
        .map(|r| ray_bits(&r))
        .map_err(|e| e.to_string());
    let chunked = (|| {
        let mut chunks = RayChunks::open(path)?;
        let mut all = Vec::new();
        let mut rays = Vec::new();
        while chunks.read_next(10, &mut rays)? > 0 {
            all.extend_from_slice(&rays);
        }
        Ok(ray_bits(&all))
    })()
    .map_err(|e: hbv_cli::ray_file::RayFileError| e.to_string());
    (whole, chunked)
}

/// A bit flipped anywhere in a ray file: the chunked reader reads the rays the whole-file
/// reader reads, or fails where it fails, with a one-line message naming the file.
#[test]
fn damaged_ray_files_are_refused_by_both_readers_alike_never_with_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let rays = random_rays(40, Vec3::splat(-1.0), Vec3::splat(2.0), 6);
    let mut rng = Pcg64Mcg::seed_from_u64(6);
    for compressed in [false, true] {
        let path = dir.path().join("rays.npz");
        let storage = Storage {
            compressed,
            float64: false,
            fortran: false,
        };
        write_stored(&path, &rays, storage);
        let good = std::fs::read(&path).unwrap();
        for _ in 0..300 {
            let mut bytes = good.clone();
            let at = rng.random_range(0..bytes.len());
            bytes[at] ^= 1 << rng.random_range(0..8);
            std::fs::write(&path, &bytes).unwrap();
            match both_readers(&path) {
                (Ok(whole), Ok(chunked)) => assert_eq!(whole, chunked, "byte {at}"),
                (Err(_), Err(e)) => assert!(!e.contains('\n') && e.contains("rays.npz"), "{e}"),
                (whole, chunked) => panic!("byte {at}: {whole:?} but in chunks {chunked:?}"),
            }
        }
    }
}

/// Flips a byte in the middle of member `name`'s stored bytes.
fn damage_member(path: &Path, name: &str) {
    let mut bytes = std::fs::read(path).unwrap();
    let middle = {
        let mut zip = zip::ZipArchive::new(File::open(path).unwrap()).unwrap();
        let member = zip.by_name(name).unwrap();
        (member.data_start() + member.compressed_size() / 2) as usize
    };
    bytes[middle] ^= 0x5a;
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_ray_file_that_fails_part_way_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = dir.path().join("torus.obj");
    write_obj(&torus(Vec3::ZERO, 2.0, 0.7, 12, 6), &mesh_path);
    let rays = random_rays(2000, Vec3::splat(-3.0), Vec3::splat(6.0), 4);
    let out = dir.path().join("hits.npz");
    let listing = || -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let cases = [
        // A stored member whose bytes no longer match its CRC-32: found after its last chunk.
        (false, "the archive's CRC-32 checksum"),
        // A deflated member damaged in the middle: the decoder fails, or the CRC-32 does.
        (true, "directions"),
    ];
    for (compressed, expected) in cases {
        let rays_path = dir.path().join("rays.npz");
        let storage = Storage {
            compressed,
            float64: false,
            fortran: false,
        };
        write_stored(&rays_path, &rays, storage);
        damage_member(&rays_path, "directions.npy");
        let before = listing();
        let o = trace(&mesh_path, &rays_path, &out, &["--chunk-rays", "300"]);
        assert!(!o.status.success());
        let message = stderr(&o);
        assert!(message.contains("cannot read rays"), "{message}");
        assert!(
            message.contains(s(&rays_path)) && message.contains(expected),
            "{message}"
        );
        assert!(!out.exists(), "a half-written hit file is left: {message}");
        assert_eq!(listing(), before, "a temporary file is left behind");
    }

    // A file cut short is refused before anything is written, and an existing output stays.
    let rays_path = dir.path().join("cut.npz");
    write_rays(&rays_path, &rays, Replace::Never).unwrap();
    let bytes = std::fs::read(&rays_path).unwrap();
    std::fs::write(&rays_path, &bytes[..bytes.len() / 2]).unwrap();
    std::fs::write(&out, b"keep").unwrap();
    let o = trace(&mesh_path, &rays_path, &out, &["--force"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("cut.npz is not an .npz archive"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"keep");
}

#[test]
fn a_chunk_of_zero_rays_is_refused() {
    let (m, r, h) = (Path::new("m.obj"), Path::new("r.npz"), Path::new("h.npz"));
    let o = trace(m, r, h, &["--chunk-rays", "0"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--chunk-rays"), "{}", stderr(&o));
}
