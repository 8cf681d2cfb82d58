//! Hit files (closest hits: `hit`, `t`, `prim`, `u`, `v`, `instance`, `normal`) and occlusion
//! files (`occluded`), as uncompressed `.npz` archives that `numpy.load` reads (see
//! `docs/RAYS.md`, "Scenes (glTF)" for `instance` and `normal`).

use std::io;
use std::path::Path;

use hbv::geometry::Triangle;
use hbv::glam::Vec3;
use hbv::scene::SceneHit;
use hbv::{Hit, TriangleMesh};

use crate::hit_file_writer::{write_hit_file, HitFileKind};
use crate::ray_file::{Archive, RayFileError};
use hbv::atomic_file::{write_atomically, Replace};

/// Writes closest hits to `path` atomically ([`write_atomically`], replacing a file only as
/// `replace` says): members `hit` (bool), `t` (float32, +inf on a miss), `prim` (int64, -1 on a
/// miss), `u` and `v` (float32, 0 on a miss), `instance` (int64, -1 on a miss), all (N,), and
/// `normal` (float32, (N, 3), 0 on a miss). [`write_hit_file`] writes the same file a chunk at
/// a time.
pub fn write_hits(path: &Path, hits: &[Option<SceneHit>], replace: Replace) -> io::Result<()> {
    write_atomically(path, replace, |file| {
        write_hit_file(file, HitFileKind::Closest, hits.len(), |w| {
            w.write_hits(hits)
        })
    })
}

/// A mesh's hit as a hit file holds it: a mesh is a scene of one instance, id 0, and the normal
/// is the triangle's unit geometric normal `normalize(cross(p1 - p0, p2 - p0))` (computed in
/// f64, as [`hbv::scene::Scene`] computes it on an identity instance, so both give the same
/// bits; 0 for a degenerate triangle, which is never hit).
pub fn mesh_hit(mesh: &TriangleMesh, hit: &Hit) -> SceneHit {
    SceneHit {
        t: hit.t,
        u: hit.u,
        v: hit.v,
        prim: hit.prim,
        instance: 0,
        normal: unit_normal(&mesh.triangle(hit.prim as usize)),
    }
}

/// `normalize(cross(p1 - p0, p2 - p0))` in f64, rounded to f32; 0 for a degenerate triangle.
fn unit_normal(triangle: &Triangle) -> Vec3 {
    triangle.scaled_normal().normalize_or_zero().as_vec3()
}

/// Writes any-hit answers to `path` atomically, replacing a file only as `replace` says:
/// member `occluded` (bool, (N,)).
pub fn write_occlusion(path: &Path, occluded: &[bool], replace: Replace) -> io::Result<()> {
    write_atomically(path, replace, |file| {
        write_hit_file(file, HitFileKind::Occlusion, occluded.len(), |w| {
            w.write_occluded(occluded)
        })
    })
}

/// Reads the mesh members of a hit file written by [`write_hits`] (or by NumPy in the same
/// format): `hit`, `t`, `prim`, `u`, `v`; `instance` and `normal` need not be there (see
/// [`read_scene_hits`]).
///
/// Members must have the dtypes [`write_hits`] writes; a hit's `prim` must fit in `u32`. The
/// values of misses other than `hit` are ignored.
pub fn read_hits(path: &Path) -> Result<Vec<Option<Hit>>, RayFileError> {
    let mut npz = Archive::open(path)?;
    read_mesh_members(&mut npz)
}

/// Reads every member of a hit file written by [`write_hits`]: the mesh members as
/// [`read_hits`] reads them, and `instance` (int64, (N,); a hit's must fit in `u32`) and
/// `normal` (float32, (N, 3)).
pub fn read_scene_hits(path: &Path) -> Result<Vec<Option<SceneHit>>, RayFileError> {
    let mut npz = Archive::open(path)?;
    let hits = read_mesh_members(&mut npz)?;
    let n = hits.len();
    let (instance, _) = column::<i64>(&mut npz, "instance", "int64", Some(n))?;
    let a = npz.read::<f32>("normal", "float32")?;
    let (normal, rows) = npz.rows("normal", a, Some(3))?;
    npz.same_length("normal", rows, "hit", n)?;
    hits.into_iter()
        .enumerate()
        .map(|(i, hit)| {
            let Some(hit) = hit else {
                return Ok(None);
            };
            let id = u32::try_from(instance[i]).map_err(|_| {
                npz.invalid(
                    "instance",
                    format!("value {} at index {i} is not an instance id", instance[i]),
                )
            })?;
            Ok(Some(SceneHit {
                t: hit.t,
                u: hit.u,
                v: hit.v,
                prim: hit.prim,
                instance: id,
                normal: Vec3::from_slice(&normal[3 * i..3 * i + 3]),
            }))
        })
        .collect()
}

/// The members `hit`, `t`, `prim`, `u`, `v` of an open hit file.
fn read_mesh_members(npz: &mut Archive) -> Result<Vec<Option<Hit>>, RayFileError> {
    let (hit, n) = column::<bool>(npz, "hit", "bool", None)?;
    let (t, _) = column::<f32>(npz, "t", "float32", Some(n))?;
    let (prim, _) = column::<i64>(npz, "prim", "int64", Some(n))?;
    let (u, _) = column::<f32>(npz, "u", "float32", Some(n))?;
    let (v, _) = column::<f32>(npz, "v", "float32", Some(n))?;
    (0..n)
        .map(|i| {
            if !hit[i] {
                return Ok(None);
            }
            let p = u32::try_from(prim[i]).map_err(|_| {
                npz.invalid(
                    "prim",
                    format!("value {} at index {i} is not a triangle index", prim[i]),
                )
            })?;
            Ok(Some(Hit {
                t: t[i],
                prim: p,
                u: u[i],
                v: v[i],
            }))
        })
        .collect()
}

/// Reads an occlusion file written by [`write_occlusion`]: member `occluded` (bool, (N,)).
pub fn read_occlusion(path: &Path) -> Result<Vec<bool>, RayFileError> {
    let mut npz = Archive::open(path)?;
    Ok(column::<bool>(&mut npz, "occluded", "bool", None)?.0)
}

/// Reads a 1-D member of dtype `T` with `expected_len` rows, if given (checked against `hit`).
fn column<T: ndarray_npy::ReadableElement + Clone>(
    npz: &mut Archive,
    name: &str,
    dtype: &'static str,
    expected_len: Option<usize>,
) -> Result<(Vec<T>, usize), RayFileError> {
    let a = npz.read::<T>(name, dtype)?;
    let (v, len) = npz.rows(name, a, None)?;
    if let Some(n) = expected_len {
        npz.same_length(name, len, "hit", n)?;
    }
    Ok((v, len))
}
