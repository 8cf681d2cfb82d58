//! The tree cost, measured: tests counted along random lines and rays, to hold against the
//! predicted E\[X\] ([`expected_tests`](super::expected_tests)).

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use super::layout::RecursiveLayout;
use crate::geometry::{Aabb, Ray};
use crate::stats::TraversalStats;

/// `n` isotropic random lines that meet `bounds`: lines distributed uniformly over all lines
/// (uniform direction, uniform position on the plane perpendicular to it), kept when they meet
/// the box. Each is a [`Ray`] over `[-inf, +inf]`.
///
/// Drawn as a uniform direction on the sphere and a uniform point of the disk, perpendicular to
/// it, that covers the box's bounding sphere: uniform over the lines meeting the sphere, hence,
/// after rejection, over the lines meeting the box (at most about half are rejected).
pub fn isotropic_lines(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let (center, radius) = (bounds.center(), 0.5 * bounds.extent().length());
    let mut lines = Vec::with_capacity(n);
    if bounds.is_empty() {
        return lines;
    }
    while lines.len() < n {
        let z: f32 = rng.random_range(-1.0..1.0);
        let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let (u, v) = d.any_orthonormal_pair();
        let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let s = radius * rng.random::<f32>().sqrt();
        let line = Ray::new(center + s * (a.cos() * u + a.sin() * v), d)
            .with_interval(f32::NEG_INFINITY, f32::INFINITY);
        if bounds.hit_by(&crate::geometry::PreparedRay::new(&line)) {
            lines.push(line);
        }
    }
    lines
}

/// A sample mean with its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanEstimate {
    pub mean: f64,
    pub standard_error: f64,
}

impl MeanEstimate {
    /// From the count, sum and sum of squares of the samples.
    fn from_sums((n, sum, sum_sq): (f64, f64, f64)) -> Self {
        if n < 2.0 {
            return Self {
                mean: if n == 1.0 { sum } else { 0.0 },
                standard_error: f64::INFINITY,
            };
        }
        let mean = sum / n;
        let variance = ((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0);
        Self {
            mean,
            standard_error: (variance / n).sqrt(),
        }
    }
}

/// Mean tests per line (box and triangle tests, not counting the root's own box) when each line
/// is traversed without early exit: the quantity E\[X\] predicts for isotropic lines.
/// In parallel on the current rayon pool.
pub fn tests_per_line(layout: &RecursiveLayout, lines: &[Ray]) -> MeanEstimate {
    let sums = lines
        .par_iter()
        .map(|line| {
            let mut stats = TraversalStats::default();
            layout.count_tests_without_early_exit(line, &mut stats);
            let x = stats.tests().saturating_sub(1) as f64;
            (1.0, x, x * x)
        })
        .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    MeanEstimate::from_sums(sums)
}

/// Work of closest-hit queries (with early termination) on the given rays: boxes and
/// triangles tested, summed over all rays (root box included). In parallel.
pub fn closest_hit_work(layout: &RecursiveLayout, rays: &[Ray]) -> TraversalStats {
    use crate::query::Accelerator;
    rays.par_chunks(1024)
        .map(|chunk| {
            let mut stats = TraversalStats::default();
            for ray in chunk {
                layout.intersect_counted(ray, &mut stats);
            }
            stats
        })
        .reduce(TraversalStats::default, |mut a, b| {
            a += b;
            a
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{Builder, InsertionBuilder};
    use crate::bvh::expected_tests;
    use crate::mesh::procedural::icosphere;

    #[test]
    fn lines_meet_the_box_and_estimate_expected_tests() {
        let mesh = icosphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 3);
        let tree = InsertionBuilder::default().build(&mesh);
        let layout = RecursiveLayout::new(&tree, &mesh);
        let lines = isotropic_lines(&mesh.bounds(), 20_000, 5);
        assert_eq!(lines.len(), 20_000);
        let e = expected_tests(&tree);
        let m = tests_per_line(&layout, &lines);
        assert!(
            (m.mean - e).abs() < 5.0 * m.standard_error + 1e-3 * e,
            "{e} vs {m:?}"
        );
    }
}
