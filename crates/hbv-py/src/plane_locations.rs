//! `trimesh_hits`: hbv's hits arranged as trimesh's Embree intersector lists them, with each
//! hit's location where the ray meets the plane of the triangle it hit, in float64 from the
//! mesh's float64 vertices (`hbv.trimesh`'s `intersects_id` and `intersects_location`).
//!
//! Done here rather than in NumPy because on a million rays the ordering and the locations took
//! 14 % and 67 % of the traversal's own time in NumPy (gathers and a sort); here they are a
//! counting sort and a pass over the hits, each on all cores.

use std::mem::MaybeUninit;
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use hbv::glam::DVec3;
use numpy::{IntoPyArray, PyArrayDescrMethods, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{as_ndarray, float_array, shape_text, ArrayValues, FloatSlice};
use crate::output_column::OutputColumn;
use crate::thread_pool::{fill_rows, run_on_threads, ThreadCount, SERIAL_ROWS};
use rayon::prelude::*;

/// Hits of one ray closer than this fraction of (their distance along the ray + the mesh's
/// size) are one hit: coincident faces hit at one place, reported once as trimesh reports a
/// place once (its Embree intersector steps 1e-6 of the mesh's size past each hit; float32 `t`
/// tells hits apart to about 1e-7 of that sum).
const SAME_PLACE: f64 = 1.0 / (1u64 << 20) as f64;

/// hbv's hit list `(index_ray, t, prim)` (grouped by ray, each ray's hits nearest first, as
/// `BVH.intersect_all` returns them; or one hit per ray, as from `BVH.intersect`) in trimesh's
/// Embree order: every ray's first hit (by ray), then every ray's second hit, and so on, at most
/// `max_hits` per ray (None: all), a hit at the place of its ray's previous hit left out
/// (see [`SAME_PLACE`]). Returns `(index_tri, index_ray, locations)`: int64, int64, and, when
/// `vertices` and `faces` are given, the (H, 3) float64 locations (else None).
///
/// A location is where the ray `o + s·d` meets the plane of its triangle, with float64 corners
/// `p0, p1, p2` and normal `n = (p1 - p0) × (p2 - p0)`: `s = n·(p0 - o) / n·d`, location
/// `o + s·d`, each step rounded once in float64, so its error is a few float64 ulps of
/// `|p0 - o|` (over the cosine between ray and normal), not float32's of a traced `t`. Where the
/// plane gives no finite point (a ray in the plane) it is `o + t·d`.
///
/// index_ray, prim: (H,) int64; t: (H,) float32; origins, directions: (N, 3) float32 or float64;
/// size: the mesh's size (its box's diagonal); vertices: (V, 3) float64 (float32 and integers
/// read too) and faces: (F, 3) integer. Arrays are read in place when aligned, C-ordered and of
/// these dtypes, converted otherwise. Indices out of range raise `ValueError` naming the
/// argument and the row.
#[pyfunction]
#[pyo3(signature = (index_ray, t, prim, origins, directions, size, max_hits=None, vertices=None, faces=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn trimesh_hits<'py>(
    py: Python<'py>,
    index_ray: &Bound<'py, PyAny>,
    t: &Bound<'py, PyAny>,
    prim: &Bound<'py, PyAny>,
    origins: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    size: f64,
    max_hits: Option<usize>,
    vertices: Option<&Bound<'py, PyAny>>,
    faces: Option<&Bound<'py, PyAny>>,
    threads: Option<ThreadCount>,
) -> PyResult<Bound<'py, PyTuple>> {
    let index_ray = int64_values("index_ray", index_ray, None, None)?;
    let hits = index_ray.as_slice().len();
    let (t, _) = float_array("t", t, None, Some((hits, "index_ray")))?;
    let prim = int64_values("prim", prim, None, Some((hits, "index_ray")))?;
    let (origins, rays) = float_array("origins", origins, Some(3), None)?;
    let (directions, _) = float_array("directions", directions, Some(3), Some((rays, "origins")))?;
    let planes = match (vertices, faces) {
        (Some(v), Some(f)) => Some((
            float_array("vertices", v, Some(3), None)?,
            int64_values("faces", f, Some(3), None)?,
        )),
        (None, None) => None,
        _ => {
            return Err(PyValueError::new_err(
                "vertices, faces: give both (for locations) or neither",
            ))
        }
    };
    let planes = planes
        .as_ref()
        .map(|((vertices, vertex_count), faces)| PlaneMesh {
            vertices: vertices.values(),
            vertex_count: *vertex_count,
            faces: faces.as_slice(),
        });
    let (index_ray, t, prim) = (index_ray.as_slice(), t.values(), prim.as_slice());
    check_indices("index_ray", index_ray, rays)?;
    if let Some(planes) = &planes {
        check_indices("prim", prim, planes.faces.len() / 3)?;
    }
    let list = HitList {
        index_ray,
        t,
        prim,
        origins: origins.values(),
        directions: directions.values(),
    };
    let rule = RankRule {
        size,
        max_hits: max_hits.unwrap_or(usize::MAX),
    };
    let (tri, ray, locations) = py.detach(|| list.arrange(&rule, planes.as_ref(), threads))?;
    let locations = match locations {
        Some(l) => {
            let rows = l.len();
            l.into_flattened()
                .into_pyarray(py)
                .reshape([rows, 3])?
                .into_any()
        }
        None => py.None().into_bound(py),
    };
    PyTuple::new(
        py,
        [
            tri.into_pyarray(py).into_any(),
            ray.into_pyarray(py).into_any(),
            locations,
        ],
    )
}

/// The hits of a query as hbv lists them, and the rays they are on.
struct HitList<'a> {
    index_ray: &'a [i64],
    t: FloatSlice<'a>,
    prim: &'a [i64],
    origins: FloatSlice<'a>,
    directions: FloatSlice<'a>,
}

/// Output columns: triangle, ray, and (when asked) location of each hit.
type Columns = (Vec<i64>, Vec<i64>, Option<Vec<[f64; 3]>>);

/// A hit's rank, noted in a byte, when the hit is not kept.
const NOT_KEPT: u8 = u8::MAX;

/// Which hits of a ray are kept, and their ranks: nearest first, a hit at the place of the
/// ray's previous hit left out (see [`SAME_PLACE`]), ranks from `max_hits` on left out.
struct RankRule {
    size: f64,
    max_hits: usize,
}

impl HitList<'_> {
    /// Calls `keep(k, rank)` for each hit `k` of `rows` kept by `rule`, in row order; `rows`
    /// starts at a ray's first hit.
    #[inline]
    fn for_each_kept(
        &self,
        rule: &RankRule,
        rows: Range<usize>,
        mut keep: impl FnMut(usize, usize),
    ) {
        let (index_ray, t) = (self.index_ray, self.t);
        let same_place = SAME_PLACE * rule.size;
        let mut next_rank = 0usize;
        // Written without branches on where a ray's hits begin, which no predictor guesses (a
        // ray has 0 to a few hits), and without a square root: ordering the Cornell box's
        // 2.48 M hits took 37 ms with them, 28 without (one thread).
        for k in rows.clone() {
            let t_k = f64::from(t.at(k));
            let same_ray = k > rows.start && index_ray[k] == index_ray[k - 1];
            next_rank *= usize::from(same_ray);
            // |t_k - t_previous|·|d| <= SAME_PLACE·(t_k·|d| + size), without a square root:
            // (t_k - t_previous - SAME_PLACE·t_k)·|d| <= SAME_PLACE·size.
            let t_previous = f64::from(t.at(k.saturating_sub(1)));
            let gap = t_k - t_previous - SAME_PLACE * t_k;
            let length = self
                .directions
                .row3_f64(index_ray[k] as usize)
                .length_squared();
            let repeat =
                same_ray & ((gap <= 0.0) | (gap * gap * length <= same_place * same_place));
            if !repeat && next_rank < rule.max_hits {
                keep(k, next_rank);
                next_rank += 1;
            }
        }
    }

    /// The kept hits in trimesh's Embree order (every ray's first hit by ray, then every ray's
    /// second, ...), with their locations on `planes`' triangles when given.
    ///
    /// A counting sort by rank, on all cores: the hits are cut into runs of whole rays; each
    /// run counts its kept hits of each rank; the output is cut into one piece per (rank, run),
    /// rank-major, so that each run writes its hits of rank r, in order, into its own piece of
    /// rank r's block; the locations are then computed row by row from the placed hits.
    fn arrange(
        &self,
        rule: &RankRule,
        planes: Option<&PlaneMesh<'_>>,
        threads: Option<ThreadCount>,
    ) -> PyResult<Columns> {
        let workers = threads.map_or_else(rayon::current_num_threads, ThreadCount::get);
        let runs = ray_runs(
            self.index_ray,
            if self.index_ray.len() <= SERIAL_ROWS {
                1
            } else {
                workers
            },
        );
        // How many hits of each rank each run keeps, and each hit's rank while they fit a byte.
        let walks = on_each(runs.clone(), threads, |run| {
            let mut per_rank = Vec::new();
            let mut ranks = vec![NOT_KEPT; run.len()];
            self.for_each_kept(rule, run.clone(), |k, rank| {
                if per_rank.len() == rank {
                    per_rank.push(0);
                }
                per_rank[rank] += 1;
                ranks[k - run.start] = u8::try_from(rank).unwrap_or(NOT_KEPT);
            });
            let ranks = (per_rank.len() <= usize::from(NOT_KEPT)).then_some(ranks);
            (per_rank, ranks)
        })?;
        let (counts, ranks): (Vec<_>, Vec<_>) = walks.into_iter().unzip();
        let kept = counts.iter().flatten().sum::<usize>();
        let mut tri = OutputColumn::<i64>::new(kept);
        let mut ray = OutputColumn::<i64>::new(kept);
        let mut t = OutputColumn::<f32>::new(if planes.is_some() { kept } else { 0 });
        let pieces = RunPieces {
            tri: pieces_of(tri.rows(), &counts),
            ray: pieces_of(ray.rows(), &counts),
            t: planes.map(|_| pieces_of(t.rows(), &counts)),
        };
        let work = pieces
            .into_runs()
            .into_iter()
            .zip(runs.into_iter().zip(ranks))
            .collect();
        on_each(
            work,
            threads,
            |((mut tri, mut ray, mut t), (run, ranks))| {
                let mut next = vec![0usize; tri.len()];
                let mut place = |k: usize, rank: usize| {
                    let row = next[rank];
                    tri[rank][row].write(self.prim[k]);
                    ray[rank][row].write(self.index_ray[k]);
                    if let Some(t) = t.as_mut() {
                        t[rank][row].write(self.t.at(k));
                    }
                    next[rank] += 1;
                };
                match ranks {
                    // The ranks the count noted, read back: cheaper than walking again (31 ms
                    // instead of 36 for the Cornell box's hits).
                    Some(ranks) => {
                        for (k, &rank) in run.zip(&ranks) {
                            if rank != NOT_KEPT {
                                place(k, usize::from(rank));
                            }
                        }
                    }
                    None => self.for_each_kept(rule, run, place),
                }
            },
        )?;
        // SAFETY: the pieces cover every row of each column once (`pieces_of` cuts the column
        // by the counts), and each run wrote all of its pieces' rows: it places the hits the
        // walk that counted them kept, with the same ranks (noted by that walk when every rank
        // fits below NOT_KEPT, else found again by the same walk).
        let (tri, ray) = unsafe { (tri.into_filled(), ray.into_filled()) };
        let Some(planes) = planes else {
            return Ok((tri, ray, None));
        };
        // SAFETY: as above, with locations asked (so the t column has `kept` rows).
        let t = unsafe { t.into_filled() };
        let mut locations = vec![[0.0f64; 3]; kept];
        let bad_face = AtomicUsize::new(usize::MAX);
        fill_rows(threads, locations.as_mut_slice(), |first, rows| {
            for (j, row) in (first..).zip(rows.iter_mut()) {
                match self.location(ray[j] as usize, tri[j] as usize, t[j], planes) {
                    Some(p) => *row = p.to_array(),
                    None => {
                        bad_face.fetch_min(tri[j] as usize, Ordering::Relaxed);
                    }
                }
            }
        })?;
        match bad_face.into_inner() {
            usize::MAX => Ok((tri, ray, Some(locations))),
            face => Err(PyValueError::new_err(format!(
                "faces: row {face}: a vertex index outside 0..{}",
                planes.vertex_count
            ))),
        }
    }

    /// Where ray `ray` meets the plane of triangle `face` (see [`trimesh_hits`]), `o + t·d`
    /// where the plane gives no finite point; None when the triangle has a vertex index out of
    /// range.
    #[inline]
    fn location(&self, ray: usize, face: usize, t: f32, planes: &PlaneMesh<'_>) -> Option<DVec3> {
        let o = self.origins.row3_f64(ray);
        let d = self.directions.row3_f64(ray);
        let [p0, p1, p2] = planes.corners(face)?;
        let n = (p1 - p0).cross(p2 - p0);
        let on_plane = o + (n.dot(p0 - o) / n.dot(d)) * d;
        Some(if on_plane.is_finite() {
            on_plane
        } else {
            o + f64::from(t) * d
        })
    }
}

/// The mesh whose triangles' planes locate the hits: (V, 3) vertices, read as float64, and
/// (F, 3) faces, flat.
struct PlaneMesh<'a> {
    vertices: FloatSlice<'a>,
    vertex_count: usize,
    faces: &'a [i64],
}

impl PlaneMesh<'_> {
    /// The corners of triangle `face`, or None if one of its vertex indices is out of range.
    #[inline]
    fn corners(&self, face: usize) -> Option<[DVec3; 3]> {
        let corner = |c: usize| {
            let v = usize::try_from(self.faces[3 * face + c]).ok()?;
            (v < self.vertex_count).then(|| self.vertices.row3_f64(v))
        };
        Some([corner(0)?, corner(1)?, corner(2)?])
    }
}

/// `work(item)` for each item, in parallel (on the calling thread alone for one item).
fn on_each<I: Send, T: Send>(
    items: Vec<I>,
    threads: Option<ThreadCount>,
    work: impl Fn(I) -> T + Sync + Send,
) -> PyResult<Vec<T>> {
    if items.len() == 1 {
        return Ok(items.into_iter().map(work).collect());
    }
    run_on_threads(threads, || items.into_par_iter().map(work).collect())
}

/// `len` hits cut into at most `parts` runs of about equal length, each starting at a ray's
/// first hit (hits are grouped by ray).
fn ray_runs(index_ray: &[i64], parts: usize) -> Vec<Range<usize>> {
    let len = index_ray.len();
    let mut starts = vec![0];
    for part in 1..parts.max(1) {
        let mut cut = (len * part / parts).max(*starts.last().unwrap_or(&0));
        while cut > 0 && cut < len && index_ray[cut] == index_ray[cut - 1] {
            cut += 1;
        }
        starts.push(cut);
    }
    starts.push(len);
    starts.windows(2).map(|w| w[0]..w[1]).collect()
}

/// An output column's rows, cut for the runs: `pieces[run][rank]` holds the run's hits of that
/// rank, after the pieces of lower ranks and, within the rank, after earlier runs' pieces.
fn pieces_of<'a, T>(
    mut column: &'a mut [MaybeUninit<T>],
    counts: &[Vec<usize>],
) -> Vec<Vec<&'a mut [MaybeUninit<T>]>> {
    let ranks = counts.iter().map(Vec::len).max().unwrap_or(0);
    let mut pieces: Vec<Vec<_>> = counts.iter().map(|_| Vec::with_capacity(ranks)).collect();
    for rank in 0..ranks {
        for (run, count) in counts.iter().enumerate() {
            let (piece, rest) =
                std::mem::take(&mut column).split_at_mut(count.get(rank).map_or(0, |&c| c));
            pieces[run].push(piece);
            column = rest;
        }
    }
    pieces
}

/// The pieces of each output column, by run.
struct RunPieces<'a> {
    tri: Vec<Vec<&'a mut [MaybeUninit<i64>]>>,
    ray: Vec<Vec<&'a mut [MaybeUninit<i64>]>>,
    t: Option<Vec<Vec<&'a mut [MaybeUninit<f32>]>>>,
}

/// One run's pieces of the triangle, ray and (when asked) t columns, by rank.
type Pieces<'a> = (
    Vec<&'a mut [MaybeUninit<i64>]>,
    Vec<&'a mut [MaybeUninit<i64>]>,
    Option<Vec<&'a mut [MaybeUninit<f32>]>>,
);

impl<'a> RunPieces<'a> {
    fn into_runs(self) -> Vec<Pieces<'a>> {
        let mut t = self.t.map(Vec::into_iter);
        self.tri
            .into_iter()
            .zip(self.ray)
            .map(|(tri, ray)| (tri, ray, t.as_mut().and_then(Iterator::next)))
            .collect()
    }
}

/// An integer array of shape (N,) (`columns` None) or (N, `columns`), read as int64 (in place
/// where [`ArrayValues`] can); `rows` fixes N. A TypeError for other dtypes, a ValueError for
/// other shapes, each naming the argument.
fn int64_values<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    columns: Option<usize>,
    rows: Option<(usize, &str)>,
) -> PyResult<ArrayValues<'py, i64>> {
    let array = as_ndarray(name, obj)?;
    let kind = array.dtype().kind();
    if kind != b'i' && kind != b'u' {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected an integer array, got dtype {}",
            array.dtype().str()?
        )));
    }
    let shape = array.shape();
    let columns_ok = match columns {
        Some(c) => shape.len() == 2 && shape[1] == c,
        None => shape.len() == 1,
    };
    let rows_ok = rows.is_none_or(|(n, _)| shape.first() == Some(&n));
    if !(columns_ok && rows_ok) {
        let want = match (columns, rows) {
            (Some(c), _) => format!("(N, {c})"),
            (None, Some((n, other))) => format!("({n},), as {other} has"),
            (None, None) => "(N,)".to_owned(),
        };
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {want}, got {}",
            shape_text(shape)
        )));
    }
    ArrayValues::read(name, &array)
}

/// Every index in `0..len`; a ValueError naming the argument and the first row outside. (A
/// fold without early exit first, which the compiler vectorizes: the search for the row, which
/// stops at it, does not.)
fn check_indices(name: &str, indices: &[i64], len: usize) -> PyResult<()> {
    let outside = |i: i64| i as u64 >= len as u64; // a negative index is above 2^63
    if !indices.iter().fold(false, |any, &i| any | outside(i)) {
        return Ok(());
    }
    let row = indices.iter().position(|&i| outside(i)).unwrap_or_default();
    Err(PyValueError::new_err(format!(
        "{name}: row {row}: index {} outside 0..{len}",
        indices[row]
    )))
}
