//! Build time of the Goldsmith–Salmon insertion builder at 10k, 100k and 1M triangles, for every
//! insertion order: the data for the build-time exponent in BENCHMARKS.md.
//!
//! `cargo bench -p hbv --bench insertion_build`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig, InsertionOrder};
use hbv::mesh::procedural::torus;
use std::time::Duration;

fn insertion(c: &mut Criterion) {
    let mut group = c.benchmark_group("insertion_build");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5));
    for triangles in [10_000u32, 100_000, 1_000_000] {
        // A torus of m × n quads, m = 2n: 4 n² triangles.
        let n = ((triangles / 4) as f32).sqrt().round() as u32;
        let mesh = torus(Vec3::ZERO, 2.0, 0.6, 2 * n, n);
        group.throughput(Throughput::Elements(mesh.triangle_count() as u64));
        for (name, order) in [
            ("shuffle", InsertionOrder::Shuffle { seed: 1 }),
            ("input", InsertionOrder::Input),
            ("morton", InsertionOrder::Morton),
        ] {
            let builder = InsertionBuilder::new(InsertionConfig {
                order,
                max_leaf_size: 1,
            });
            group.bench_with_input(BenchmarkId::new(name, triangles), &mesh, |b, mesh| {
                b.iter(|| builder.build(mesh))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, insertion);
criterion_main!(benches);
