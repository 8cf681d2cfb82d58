//! The tree cost E[X] is what a traversal counts: the mean number of tests along isotropic
//! random lines through the root box, traversed without early exit, equals E[X] within sampling
//! error.

use glam::Vec3;
use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig, InsertionOrder};
use hbv::bvh::expected_tests;
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::measured_cost::{isotropic_lines, tests_per_line};
use hbv::mesh::procedural::{default_scene, icosphere};

#[test]
fn expected_tests_equals_mean_counted_tests_on_isotropic_lines() {
    let meshes = [
        icosphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 4),
        default_scene(1),
    ];
    for mesh in &meshes {
        let lines = isotropic_lines(&mesh.bounds(), 40_000, 11);
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
            let measured = tests_per_line(&layout, &lines);
            eprintln!(
                "{} triangles, {order:?}, leaf {leaf}: E[X] = {predicted:.3}, measured {:.3} ± {:.3}",
                mesh.triangle_count(),
                measured.mean,
                measured.standard_error
            );
            // 5 standard errors, plus the f32 box tests' slack (a relative 4e-6 widening).
            assert!(
                (measured.mean - predicted).abs()
                    < 5.0 * measured.standard_error + 1e-3 * predicted,
                "{} triangles, {order:?}: E[X] = {predicted:.3}, measured {measured:?}",
                mesh.triangle_count()
            );
        }
    }
}
