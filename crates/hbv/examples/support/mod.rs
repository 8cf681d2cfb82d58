//! What the nearest-point examples share.

use hbv::glam::DVec3;
use hbv::TriangleMesh;
use rand::{RngExt, SeedableRng};

/// `n` points uniform in `mesh`'s box grown by 10 % on each side (`bench/python_compare.py`'s
/// query points), rounded to f32 as NumPy float32 arrays hold them; the same for the same
/// `seed`.
pub fn points_around(mesh: &TriangleMesh, n: usize, seed: u64) -> Vec<DVec3> {
    let b = mesh.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let pad = 0.1 * (hi - lo);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let k = DVec3::new(rng.random(), rng.random(), rng.random());
            (lo - pad + (hi - lo + 2.0 * pad) * k).as_vec3().as_dvec3()
        })
        .collect()
}
