//! Ray, hit and occlusion files (`docs/RAYS.md`).

use std::fs::{self, File};
use std::path::Path;

use glam::Vec3;
use hbv::atomic_file::Replace;
use hbv::geometry::Ray;
use hbv::scene::SceneHit;
use hbv::Hit;
use hbv_cli::hit_file::{read_hits, read_occlusion, read_scene_hits, write_hits, write_occlusion};
use hbv_cli::ray_file::read_rays;
use ndarray::{array, Array1, Array2, ShapeBuilder};
use ndarray_npy::{NpzReader, NpzWriter, WriteNpyExt, WriteNpzError};

/// One member of an archive written by [`npz`].
trait Member {
    fn add(&self, npz: &mut NpzWriter<File>, name: &str) -> Result<(), WriteNpzError>;
}

impl<A: ndarray_npy::WritableElement, D: ndarray::Dimension> Member for ndarray::Array<A, D> {
    fn add(&self, npz: &mut NpzWriter<File>, name: &str) -> Result<(), WriteNpzError> {
        npz.add_array(name, self)
    }
}

/// Writes an `.npz` archive with ndarray-npy, deflated when `compressed`.
fn npz(path: &Path, compressed: bool, members: &[(&str, &dyn Member)]) {
    let file = File::create(path).unwrap();
    let mut w = if compressed {
        NpzWriter::new_compressed(file)
    } else {
        NpzWriter::new(file)
    };
    for (name, array) in members {
        array.add(&mut w, name).unwrap();
    }
    w.finish().unwrap();
}

fn origins_f32() -> Array2<f32> {
    array![[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [-1.5, 0.25, 1e6]]
}

fn directions_f32() -> Array2<f32> {
    array![[0.0, 0.0, 1.0], [1.0, -1.0, 0.5], [0.0, 2.0, 0.0]]
}

fn expected_rays() -> Vec<Ray> {
    let o = origins_f32();
    let d = directions_f32();
    (0..3)
        .map(|i| {
            Ray::new(
                Vec3::new(o[[i, 0]], o[[i, 1]], o[[i, 2]]),
                Vec3::new(d[[i, 0]], d[[i, 1]], d[[i, 2]]),
            )
        })
        .collect()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// The error message of reading `path` as rays.
fn ray_error(path: &Path) -> String {
    read_rays(path).unwrap_err().to_string()
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "message {message:?} does not mention {part:?}"
        );
    }
}

#[test]
fn rays_f32_uncompressed_default_interval() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    npz(
        &path,
        false,
        &[
            ("origins", &origins_f32()),
            ("directions", &directions_f32()),
        ],
    );
    assert_eq!(read_rays(&path).unwrap(), expected_rays());
}

#[test]
fn rays_f64_compressed_with_interval() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let tmin: Array1<f64> = array![0.5, 0.0, 1e-3];
    let tmax: Array1<f64> = array![10.0, f64::INFINITY, 0.1];
    npz(
        &path,
        true,
        &[
            ("origins", &origins_f32().mapv(f64::from)),
            ("directions", &directions_f32().mapv(f64::from)),
            ("tmin", &tmin),
            ("tmax", &tmax),
        ],
    );
    let expected: Vec<Ray> = expected_rays()
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.with_interval(tmin[i] as f32, tmax[i] as f32))
        .collect();
    assert_eq!(read_rays(&path).unwrap(), expected);
}

#[test]
fn rays_mixed_dtypes_and_dirs_alias() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let tmax: Array1<f32> = array![1.0, 2.0, 3.0];
    npz(
        &path,
        true,
        &[
            ("origins", &origins_f32()),
            ("dirs", &directions_f32().mapv(f64::from)),
            ("tmax", &tmax),
        ],
    );
    let expected: Vec<Ray> = expected_rays()
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.with_interval(0.0, tmax[i]))
        .collect();
    assert_eq!(read_rays(&path).unwrap(), expected);
}

#[test]
fn rays_fortran_order_read_correctly() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let mut origins = Array2::<f32>::zeros((3, 3).f());
    origins.assign(&origins_f32());
    let mut directions = Array2::<f64>::zeros((3, 3).f());
    directions.assign(&directions_f32().mapv(f64::from));
    // ndarray-npy writes such arrays with `'fortran_order': True`, as NumPy does.
    let mut header = Vec::new();
    origins.write_npy(&mut header).unwrap();
    assert!(String::from_utf8_lossy(&header[..128]).contains("'fortran_order': True"));
    npz(
        &path,
        false,
        &[("origins", &origins), ("directions", &directions)],
    );
    assert_eq!(read_rays(&path).unwrap(), expected_rays());
}

#[test]
fn rays_nan_and_inf_are_kept() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let origins: Array2<f32> = array![[f32::NAN, 0.0, 0.0], [0.0, f32::INFINITY, 0.0]];
    let directions: Array2<f32> = array![[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]];
    npz(
        &path,
        false,
        &[("origins", &origins), ("directions", &directions)],
    );
    let rays = read_rays(&path).unwrap();
    assert_eq!(rays.len(), 2);
    assert!(rays[0].origin.x.is_nan());
    assert_eq!(rays[1].origin.y, f32::INFINITY);
    assert!(!rays[0].is_valid() && !rays[1].is_valid());
}

#[test]
fn rays_empty_batch() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let none = Array2::<f32>::zeros((0, 3));
    npz(&path, false, &[("origins", &none), ("directions", &none)]);
    assert_eq!(read_rays(&path).unwrap(), vec![]);
}

/// CRC-32 (IEEE), as zip stores it.
fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A minimal uncompressed zip archive with members named exactly as given.
fn stored_zip(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, data) in members {
        let offset = out.len() as u32;
        let (crc, size, name_len) = (crc32(data), data.len() as u32, name.len() as u16);
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        out.extend_from_slice(&[20, 0, 0, 0, 0, 0, 0, 0, 0x21, 0]); // version, flags, stored, time, date
        for v in [crc, size, size] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&name_len.to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(data);

        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        central.extend_from_slice(&[20, 0, 20, 0, 0, 0, 0, 0, 0, 0, 0x21, 0]); // made by, needed, flags, stored, time, date
        for v in [crc, size, size] {
            central.extend_from_slice(&v.to_le_bytes());
        }
        central.extend_from_slice(&name_len.to_le_bytes());
        central.extend_from_slice(&[0; 8]); // extra, comment, disk, internal attributes
        central.extend_from_slice(&0u32.to_le_bytes()); // external attributes
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    let (cd_offset, cd_size, count) =
        (out.len() as u32, central.len() as u32, members.len() as u16);
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    out.extend_from_slice(&[0; 4]); // disk numbers
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(&cd_size.to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out
}

fn npy_bytes<T: WriteNpyExt>(array: &T) -> Vec<u8> {
    let mut bytes = Vec::new();
    array.write_npy(&mut bytes).unwrap();
    bytes
}

#[test]
fn rays_members_without_npy_suffix() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let tmin: Array1<f32> = array![0.0, 1.0, 2.0];
    let zip = stored_zip(&[
        ("origins", npy_bytes(&origins_f32())),
        ("directions", npy_bytes(&directions_f32())),
        ("tmin.npy", npy_bytes(&tmin)),
    ]);
    fs::write(&path, zip).unwrap();
    let expected: Vec<Ray> = expected_rays()
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.with_interval(tmin[i], f32::INFINITY))
        .collect();
    assert_eq!(read_rays(&path).unwrap(), expected);
}

#[test]
fn ray_error_missing_file() {
    let dir = tmp();
    let path = dir.path().join("absent.npz");
    let e = read_rays(&path).unwrap_err();
    assert_eq!(e.path(), path);
    assert_mentions(&e.to_string(), &["cannot open", "absent.npz"]);
}

#[test]
fn ray_error_not_an_archive() {
    let dir = tmp();
    let path = dir.path().join("rays.txt");
    fs::write(&path, "0 0 0 0 0 1\n").unwrap();
    assert_mentions(&ray_error(&path), &["rays.txt", "is not an .npz archive"]);
    let empty = dir.path().join("empty.npz");
    fs::write(&empty, "").unwrap();
    assert_mentions(&ray_error(&empty), &["empty.npz", "is not an .npz archive"]);
}

#[test]
fn ray_error_missing_members() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    npz(&path, false, &[("directions", &directions_f32())]);
    let e = read_rays(&path).unwrap_err();
    assert_eq!(e.member(), Some("origins"));
    assert_mentions(
        &e.to_string(),
        &["rays.npz", "no member `origins`", "members: directions"],
    );

    npz(&path, false, &[("origins", &origins_f32())]);
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "no member `directions` or `dirs`"],
    );
}

#[test]
fn ray_error_wrong_shapes() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let flat = Array2::<f32>::zeros((5, 2));
    npz(
        &path,
        false,
        &[("origins", &flat), ("directions", &directions_f32())],
    );
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "origins has shape (5, 2), expected (N, 3)"],
    );

    let one_d = Array1::<f64>::zeros(9);
    npz(
        &path,
        false,
        &[("origins", &origins_f32()), ("directions", &one_d)],
    );
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "directions has shape (9,), expected (N, 3)"],
    );

    let column = Array2::<f32>::zeros((3, 1));
    npz(
        &path,
        false,
        &[
            ("origins", &origins_f32()),
            ("directions", &directions_f32()),
            ("tmin", &column),
        ],
    );
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "tmin has shape (3, 1), expected (N,)"],
    );
}

#[test]
fn ray_error_mismatched_lengths() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let four = Array2::<f32>::zeros((4, 3));
    npz(
        &path,
        false,
        &[("origins", &origins_f32()), ("dirs", &four)],
    );
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "dirs has 4 rows but origins has 3"],
    );

    let tmax = Array1::<f32>::zeros(2);
    npz(
        &path,
        false,
        &[
            ("origins", &origins_f32()),
            ("directions", &directions_f32()),
            ("tmax", &tmax),
        ],
    );
    assert_mentions(
        &ray_error(&path),
        &["rays.npz", "tmax has 2 rows but origins has 3"],
    );
}

#[test]
fn ray_error_unsupported_dtype() {
    let dir = tmp();
    let path = dir.path().join("rays.npz");
    let ints = Array2::<i32>::zeros((3, 3));
    npz(
        &path,
        true,
        &[("origins", &ints), ("directions", &directions_f32())],
    );
    let e = read_rays(&path).unwrap_err();
    assert_eq!(e.member(), Some("origins"));
    assert_mentions(
        &e.to_string(),
        &[
            "rays.npz",
            "origins has unsupported dtype int32 ('<i4')",
            "accepted: float32, float64",
        ],
    );
}

fn sample_hits() -> Vec<Option<SceneHit>> {
    vec![
        Some(SceneHit {
            t: 1.5,
            prim: 7,
            u: 0.25,
            v: 0.5,
            instance: 3,
            normal: Vec3::new(0.0, -1.0, 0.0),
        }),
        None,
        Some(SceneHit {
            t: 0.0,
            prim: u32::MAX,
            u: 0.0,
            v: 1.0,
            instance: u32::MAX,
            normal: Vec3::new(0.6, 0.0, 0.8),
        }),
        None,
    ]
}

/// The mesh members of [`sample_hits`], as [`read_hits`] gives them.
fn sample_mesh_hits() -> Vec<Option<Hit>> {
    sample_hits()
        .iter()
        .map(|h| {
            h.map(|h| Hit {
                t: h.t,
                prim: h.prim,
                u: h.u,
                v: h.v,
            })
        })
        .collect()
}

#[test]
fn hits_round_trip_with_misses() {
    let dir = tmp();
    let path = dir.path().join("hits.npz");
    let hits = sample_hits();
    write_hits(&path, &hits, Replace::Always).unwrap();
    assert_eq!(read_scene_hits(&path).unwrap(), hits);
    assert_eq!(read_hits(&path).unwrap(), sample_mesh_hits());

    // The raw members: NumPy's names (`hit.npy`) and the values RAYS.md gives misses.
    let raw = fs::read(&path).unwrap();
    for name in [
        "hit.npy",
        "t.npy",
        "prim.npy",
        "u.npy",
        "v.npy",
        "instance.npy",
        "normal.npy",
    ] {
        assert!(raw.windows(name.len()).any(|w| w == name.as_bytes()));
    }
    let mut npz = NpzReader::new(File::open(&path).unwrap()).unwrap();
    let hit: Array1<bool> = npz.by_name("hit").unwrap();
    let t: Array1<f32> = npz.by_name("t").unwrap();
    let prim: Array1<i64> = npz.by_name("prim").unwrap();
    let u: Array1<f32> = npz.by_name("u").unwrap();
    let v: Array1<f32> = npz.by_name("v").unwrap();
    let instance: Array1<i64> = npz.by_name("instance").unwrap();
    let normal: Array2<f32> = npz.by_name("normal").unwrap();
    assert_eq!(hit, array![true, false, true, false]);
    assert_eq!(t, array![1.5, f32::INFINITY, 0.0, f32::INFINITY]);
    assert_eq!(prim, array![7, -1, i64::from(u32::MAX), -1]);
    assert_eq!(u, array![0.25, 0.0, 0.0, 0.0]);
    assert_eq!(v, array![0.5, 0.0, 1.0, 0.0]);
    assert_eq!(instance, array![3, -1, i64::from(u32::MAX), -1]);
    assert_eq!(
        normal,
        array![
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.6, 0.0, 0.8],
            [0.0, 0.0, 0.0]
        ]
    );

    // Writing again replaces the file.
    write_hits(&path, &[], Replace::Always).unwrap();
    assert_eq!(read_hits(&path).unwrap(), vec![]);
    assert_eq!(read_scene_hits(&path).unwrap(), vec![]);
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// A hit file of the mesh members only (as written before `instance` and `normal`, or by
/// NumPy) still reads as mesh hits; as scene hits it names the member that is missing.
#[test]
fn hit_files_without_scene_members_read_as_mesh_hits() {
    let dir = tmp();
    let path = dir.path().join("old.npz");
    let hit: Array1<bool> = array![true, false];
    let t: Array1<f32> = array![2.0, f32::INFINITY];
    let prim: Array1<i64> = array![4, -1];
    let zeros = Array1::<f32>::zeros(2);
    npz(
        &path,
        false,
        &[
            ("hit", &hit),
            ("t", &t),
            ("prim", &prim),
            ("u", &zeros),
            ("v", &zeros),
        ],
    );
    let want = vec![
        Some(Hit {
            t: 2.0,
            prim: 4,
            u: 0.0,
            v: 0.0,
        }),
        None,
    ];
    assert_eq!(read_hits(&path).unwrap(), want);
    assert_mentions(
        &read_scene_hits(&path).unwrap_err().to_string(),
        &["old.npz", "instance"],
    );

    // A hit whose instance is -1, and a normal of the wrong shape, are named.
    let cases: [(Array1<i64>, Array2<f32>, &[&str]); 2] = [
        (
            array![-1, -1],
            Array2::zeros((2, 3)),
            &["old.npz", "instance", "value -1 at index 0"],
        ),
        (
            array![0, -1],
            Array2::zeros((2, 2)),
            &["old.npz", "normal", "(N, 3)"],
        ),
    ];
    for (instance, normal, mentions) in cases {
        let members: [(&str, &dyn Member); 7] = [
            ("hit", &hit),
            ("t", &t),
            ("prim", &prim),
            ("u", &zeros),
            ("v", &zeros),
            ("instance", &instance),
            ("normal", &normal),
        ];
        npz(&path, false, &members);
        assert_mentions(&read_scene_hits(&path).unwrap_err().to_string(), mentions);
    }
}

#[test]
fn hits_errors_name_file_and_member() {
    let dir = tmp();
    let path = dir.path().join("hits.npz");
    let hit: Array1<bool> = array![true, false];
    let t: Array1<f32> = array![1.0, f32::INFINITY];
    let prim: Array1<i64> = array![-1, -1];
    let zeros = Array1::<f32>::zeros(2);
    npz(
        &path,
        false,
        &[
            ("hit", &hit),
            ("t", &t),
            ("prim", &prim),
            ("u", &zeros),
            ("v", &zeros),
        ],
    );
    assert_mentions(
        &read_hits(&path).unwrap_err().to_string(),
        &["hits.npz", "prim", "value -1 at index 0"],
    );

    let t64 = t.mapv(f64::from);
    npz(&path, false, &[("hit", &hit), ("t", &t64)]);
    assert_mentions(
        &read_hits(&path).unwrap_err().to_string(),
        &[
            "hits.npz",
            "t has unsupported dtype float64",
            "accepted: float32",
        ],
    );
}

#[test]
fn occlusion_round_trip() {
    let dir = tmp();
    let path = dir.path().join("occ.npz");
    let occluded = vec![true, false, false, true, true];
    write_occlusion(&path, &occluded, Replace::Always).unwrap();
    assert_eq!(read_occlusion(&path).unwrap(), occluded);
    let raw = fs::read(&path).unwrap();
    assert!(raw.windows(12).any(|w| w == b"occluded.npy"));
    assert_mentions(
        &read_occlusion(&dir.path().join("nope.npz"))
            .unwrap_err()
            .to_string(),
        &["nope.npz"],
    );
}

/// Hit and occlusion files name a missing folder (the writer itself is tested in
/// `crates/hbv/tests/atomic_file.rs`).
#[test]
fn hit_files_into_a_missing_folder_name_it() {
    let dir = tmp();
    let path = dir.path().join("no/such/dir/hits.npz");
    let e = write_hits(&path, &sample_hits(), Replace::Never).unwrap_err();
    assert_mentions(&e.to_string(), &["hits.npz", "does not exist"]);
    let e = write_occlusion(&path, &[true], Replace::Never).unwrap_err();
    assert_mentions(&e.to_string(), &["hits.npz", "does not exist"]);
}
