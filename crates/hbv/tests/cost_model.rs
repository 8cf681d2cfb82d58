//! The tree cost E[X] is what a traversal counts: the mean number of tests along isotropic
//! random lines through the root box, traversed without early exit, equals E[X] within sampling
//! error.

use glam::Vec3;
use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig, InsertionOrder};
use hbv::bvh::expected_tests;
use hbv::bvh::layout::RecursiveLayout;
use hbv::geometry::Ray;
use hbv::mesh::procedural::{default_scene, icosphere};
use hbv::{TraversalStats, TriangleMesh};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Isotropic lines meeting `mesh`'s box: a uniform direction, then a uniform point of the disk
/// (perpendicular to it) that covers the box's bounding sphere, kept when the line meets the box.
/// Lines uniform over those meeting the sphere are uniform over those meeting the box.
fn mean_tests_per_line(
    layout: &RecursiveLayout,
    mesh: &TriangleMesh,
    lines: usize,
    seed: u64,
) -> (f64, f64) {
    let b = mesh.bounds();
    let (center, radius) = (b.center(), 0.5 * b.extent().length());
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut samples = Vec::with_capacity(lines);
    while samples.len() < lines {
        let z: f32 = rng.random_range(-1.0..1.0);
        let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let r = (1.0 - z * z).sqrt();
        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let (u, v) = d.any_orthonormal_pair();
        let (a, s): (f32, f32) = (
            rng.random_range(0.0..std::f32::consts::TAU),
            radius * rng.random::<f32>().sqrt(),
        );
        let o = center + s * (a.cos() * u + a.sin() * v);
        let line = Ray::new(o, d).with_interval(f32::NEG_INFINITY, f32::INFINITY);
        let mut stats = TraversalStats::default();
        layout.count_tests_without_early_exit(&line, &mut stats);
        if stats.nodes_visited > 0 {
            // Not counting the root's own box test, as E[X] does not.
            samples.push((stats.tests() - 1) as f64);
        }
    }
    let n = samples.len() as f64;
    let mean = samples.iter().sum::<f64>() / n;
    let var = samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

#[test]
fn expected_tests_equals_mean_counted_tests_on_isotropic_lines() {
    let meshes = [
        icosphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 4),
        default_scene(1),
    ];
    for mesh in &meshes {
        for (order, leaf) in [
            (InsertionOrder::Shuffle { seed: 3 }, 1),
            (InsertionOrder::Morton, 4),
        ] {
            let tree = InsertionBuilder::new(InsertionConfig {
                order,
                max_leaf_size: leaf,
            })
            .build(mesh);
            let layout = RecursiveLayout::new(&tree, mesh);
            let predicted = expected_tests(&tree);
            let (measured, std_error) = mean_tests_per_line(&layout, mesh, 40_000, 11);
            eprintln!("{} triangles, {order:?}, leaf {leaf}: E[X] = {predicted:.3}, measured {measured:.3} ± {std_error:.3}", mesh.triangle_count());
            // 5 standard errors, plus the f32 box tests' slack (a relative 4e-6 widening).
            assert!(
                (measured - predicted).abs() < 5.0 * std_error + 1e-3 * predicted,
                "{} triangles, {order:?}: E[X] = {predicted:.3}, measured {measured:.3} ± {std_error:.3}",
                mesh.triangle_count()
            );
        }
    }
}
