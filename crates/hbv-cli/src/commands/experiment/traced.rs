//! A structure under measurement in `hbv experiment seed-claims`, plain and under its object
//! cache: its work counted on every ray, its cached answers checked against its plain ones, and
//! its speed timed. Meshes and scenes are measured by the same code through [`Traced`].

use std::hint::black_box;
use std::time::Instant;

use hbv::cache::CacheStats;
use hbv::geometry::Ray;
use hbv::TraversalStats;
use serde::Serialize;

/// The query of a ray set and the cache that goes with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// Closest hit; cache: the last-hit cache.
    Closest,
    /// Any hit; cache: the shadow cache.
    Occluded,
}

/// A structure's plain queries, and a fresh pair of its caches on demand.
pub trait Traced {
    /// A closest hit, as compared between the plain and the cached query.
    type Hit: PartialEq;
    /// The structure's caches: a last-hit cache and a shadow cache over it.
    type Caches<'a>: CachedQueries<Hit = Self::Hit>
    where
        Self: 'a;

    fn closest(&self, ray: &Ray) -> Option<Self::Hit>;
    fn occluded(&self, ray: &Ray) -> bool;
    fn closest_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Self::Hit>;
    fn occluded_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> bool;
    /// Empty caches (one stream of rays, one light).
    fn caches(&self) -> Self::Caches<'_>;
}

/// The cached queries of a [`Traced`] structure, each with its own cache.
pub trait CachedQueries {
    type Hit;
    fn closest(&mut self, ray: &Ray) -> Option<Self::Hit>;
    fn occluded(&mut self, ray: &Ray) -> bool;
    fn closest_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> Option<Self::Hit>;
    fn occluded_counted(&mut self, ray: &Ray, stats: &mut TraversalStats) -> bool;
    /// The counts of the cache of `query`.
    fn stats(&self, query: Query) -> CacheStats;
}

/// One structure on one set: plain and cached.
#[derive(Serialize)]
pub struct Row {
    pub set: &'static str,
    pub structure: String,
    pub rays: usize,
    pub hit_fraction: f64,
    /// Median Mrays/s on one thread, without and with the cache.
    pub mrays_per_second: f64,
    pub cached_mrays_per_second: f64,
    /// Boxes plus triangles tested per ray (grid: triangles; its cells are in `nodes_per_ray`).
    pub tests_per_ray: f64,
    pub cached_tests_per_ray: f64,
    /// Nodes (BVH) or cells (grid) visited per ray.
    pub nodes_per_ray: f64,
    /// Triangle tests per ray saved by the grid's mailboxes.
    pub mailbox_skips_per_ray: f64,
    /// Fraction of queries where the cached triangle was hit.
    pub cache_hit_rate: f64,
    /// The same among the rays that hit something (or are occluded): how often the answer's
    /// triangle, or one blocking as well, was the cached one.
    pub cache_hit_rate_of_hits: f64,
    /// Rays whose cached answer differs from the plain one (must be 0).
    pub mismatches: usize,
    pub runs: Vec<f64>,
    pub cached_runs: Vec<f64>,
}

/// Counts the work of `traced` on one set, plain and cached, and checks that the cache changes
/// no answer. The timings are left to [`time_plain`] and [`time_cached`].
pub fn count_row<T: Traced>(
    set: &'static str,
    query: Query,
    rays: &[Ray],
    structure: &str,
    traced: &T,
) -> Row {
    let mut plain = TraversalStats::default();
    let mut cached = TraversalStats::default();
    let mut hits = 0usize;
    let mut mismatches = 0usize;
    let mut caches = traced.caches();
    for ray in rays {
        let (hit, same) = match query {
            Query::Closest => {
                let a = traced.closest_counted(ray, &mut plain);
                let b = caches.closest_counted(ray, &mut cached);
                (a.is_some(), a == b)
            }
            Query::Occluded => {
                let a = traced.occluded_counted(ray, &mut plain);
                let b = caches.occluded_counted(ray, &mut cached);
                (a, a == b)
            }
        };
        hits += hit as usize;
        mismatches += !same as usize;
    }
    let cache_stats = caches.stats(query);
    Row {
        set,
        structure: structure.to_string(),
        rays: rays.len(),
        hit_fraction: hits as f64 / rays.len().max(1) as f64,
        mrays_per_second: 0.0,
        cached_mrays_per_second: 0.0,
        tests_per_ray: plain.tests_per_ray(),
        cached_tests_per_ray: cached.tests_per_ray(),
        nodes_per_ray: plain.nodes_per_ray(),
        mailbox_skips_per_ray: plain.mailbox_skips_per_ray(),
        cache_hit_rate: cache_stats.hit_rate(),
        cache_hit_rate_of_hits: cache_stats.hits as f64 / hits.max(1) as f64,
        mismatches,
        runs: Vec::new(),
        cached_runs: Vec::new(),
    }
}

/// Mrays/s of the plain queries, one thread, in the set's order; the set is traced again until
/// [`MIN_SECONDS`] have passed, so that small sets are timed over more than a scheduler tick.
pub fn time_plain<T: Traced>(query: Query, rays: &[Ray], traced: &T) -> f64 {
    let start = Instant::now();
    let mut traced_rays = 0usize;
    let mut found = 0usize;
    while traced_rays == 0 || start.elapsed().as_secs_f64() < MIN_SECONDS {
        for ray in rays {
            found += match query {
                Query::Closest => traced.closest(black_box(ray)).is_some(),
                Query::Occluded => traced.occluded(black_box(ray)),
            } as usize;
        }
        traced_rays += rays.len().max(1);
    }
    black_box(found);
    mrays(traced_rays, start)
}

/// Mrays/s of the cached queries (fresh caches each pass), timed as [`time_plain`].
pub fn time_cached<T: Traced>(query: Query, rays: &[Ray], traced: &T) -> f64 {
    let start = Instant::now();
    let mut traced_rays = 0usize;
    let mut found = 0usize;
    while traced_rays == 0 || start.elapsed().as_secs_f64() < MIN_SECONDS {
        let mut caches = traced.caches();
        for ray in rays {
            found += match query {
                Query::Closest => caches.closest(black_box(ray)).is_some(),
                Query::Occluded => caches.occluded(black_box(ray)),
            } as usize;
        }
        traced_rays += rays.len().max(1);
    }
    black_box(found);
    mrays(traced_rays, start)
}

/// Shortest time of one measurement.
const MIN_SECONDS: f64 = 0.05;

fn mrays(count: usize, start: Instant) -> f64 {
    count as f64 / start.elapsed().as_secs_f64().max(1e-9) / 1e6
}

/// Prints `rows` as a table, with one more column `extra` (its title and one value per row)
/// when given.
pub fn print_rows(rows: &[&Row], extra: Option<(&str, &[usize])>) {
    let title = extra.map_or(String::new(), |(t, _)| format!(" {t:>10}"));
    println!(
        "{:<14} {:<16} {:>7} {:>6} {:>8} {:>9} {:>9} {:>8} {:>9} {:>9} {:>6} {:>6} {:>8}{title}",
        "set",
        "structure",
        "rays",
        "hit %",
        "Mrays/s",
        "tests/ray",
        "nodes/ray",
        "mb skips",
        "cached",
        "c tests",
        "c hit%",
        "of hit",
        "mismatch"
    );
    for (k, row) in rows.iter().enumerate() {
        let value = extra.map_or(String::new(), |(_, v)| format!(" {:>10}", v[k]));
        println!(
            "{:<14} {:<16} {:>7} {:>6.1} {:>8.3} {:>9.1} {:>9.1} {:>8.1} {:>9.3} {:>9.1} {:>6.1} {:>6.1} {:>8}{value}",
            row.set,
            row.structure,
            row.rays,
            100.0 * row.hit_fraction,
            row.mrays_per_second,
            row.tests_per_ray,
            row.nodes_per_ray,
            row.mailbox_skips_per_ray,
            row.cached_mrays_per_second,
            row.cached_tests_per_ray,
            100.0 * row.cache_hit_rate,
            100.0 * row.cache_hit_rate_of_hits,
            row.mismatches
        );
    }
}
