//! Hit files (closest hits: `hit`, `t`, `prim`, `u`, `v`) and occlusion files (`occluded`), as
//! uncompressed `.npz` archives that `numpy.load` reads (see `docs/RAYS.md`).

use std::io;
use std::path::Path;

use hbv::Hit;
use ndarray::Array1;

use crate::npz_writer::NpzStream;
use crate::ray_file::{Archive, RayFileError};
use hbv::atomic_file::{write_atomically, Replace};

/// Writes closest hits to `path` atomically ([`write_atomically`], replacing a file only as
/// `replace` says): members `hit` (bool), `t` (float32,
/// +inf on a miss), `prim` (int64, -1 on a miss), `u` and `v` (float32, 0 on a miss), all (N,).
pub fn write_hits(path: &Path, hits: &[Option<Hit>], replace: Replace) -> io::Result<()> {
    let column = |f: fn(&Hit) -> f32, miss: f32| -> Array1<f32> {
        hits.iter().map(|h| h.as_ref().map_or(miss, f)).collect()
    };
    let hit: Array1<bool> = hits.iter().map(Option::is_some).collect();
    let t = column(|h| h.t, f32::INFINITY);
    let prim: Array1<i64> = hits
        .iter()
        .map(|h| h.map_or(-1, |h| i64::from(h.prim)))
        .collect();
    let u = column(|h| h.u, 0.0);
    let v = column(|h| h.v, 0.0);
    write_atomically(path, replace, |file| {
        let mut npz = NpzStream::new(file);
        npz.add("hit", &hit)?;
        npz.add("t", &t)?;
        npz.add("prim", &prim)?;
        npz.add("u", &u)?;
        npz.add("v", &v)?;
        npz.finish()
    })
}

/// Writes any-hit answers to `path` atomically, replacing a file only as `replace` says: member `occluded` (bool, (N,)).
pub fn write_occlusion(path: &Path, occluded: &[bool], replace: Replace) -> io::Result<()> {
    let occluded = Array1::from(occluded.to_vec());
    write_atomically(path, replace, |file| {
        let mut npz = NpzStream::new(file);
        npz.add("occluded", &occluded)?;
        npz.finish()
    })
}

/// Reads a hit file written by [`write_hits`] (or by NumPy in the same format).
///
/// Members must have the dtypes [`write_hits`] writes; a hit's `prim` must fit in `u32`. The
/// values of misses other than `hit` are ignored.
pub fn read_hits(path: &Path) -> Result<Vec<Option<Hit>>, RayFileError> {
    let mut npz = Archive::open(path)?;
    let (hit, n) = column::<bool>(&mut npz, "hit", "bool", None)?;
    let (t, _) = column::<f32>(&mut npz, "t", "float32", Some(n))?;
    let (prim, _) = column::<i64>(&mut npz, "prim", "int64", Some(n))?;
    let (u, _) = column::<f32>(&mut npz, "u", "float32", Some(n))?;
    let (v, _) = column::<f32>(&mut npz, "v", "float32", Some(n))?;
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
