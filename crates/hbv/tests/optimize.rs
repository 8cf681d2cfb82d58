//! Optimized trees, from the outside: reinsertion and leaf collapse keep every invariant, never
//! raise the cost they lower, and the optimized tree answers every query exactly as brute force.

use glam::Vec3;
use hbv::bvh::build::{
    primitive_bounds, Builder, InsertionBuilder, InsertionConfig, InsertionOrder,
};
use hbv::bvh::optimize::{
    collapse_leaves, CollapseConfig, ReinsertionConfig, ReinsertionOptimizer,
};
use hbv::bvh::TreeCost;
use hbv::bvh::{expected_tests, sah_cost, BuildTree, SahWeights};
use hbv::geometry::{Aabb, Ray};
use hbv::mesh::procedural::{default_scene, icosphere, torus};
use hbv::TriangleMesh;
use proptest::prelude::*;

mod common;
use common::{assert_agrees, closed_mesh, every_layout, mesh_and_rays, order, soup};

fn insertion_tree(mesh: &TriangleMesh, order: InsertionOrder, max_leaf_size: usize) -> BuildTree {
    InsertionBuilder::new(InsertionConfig {
        order,
        max_leaf_size,
    })
    .build(mesh)
}

/// A binary tree by object-median splits on the widest axis, with leaves of up to
/// `max_leaf_size` triangles: the shape of a top-down builder's output, made here so that this
/// test does not depend on one.
fn median_tree(mesh: &TriangleMesh, max_leaf_size: usize) -> BuildTree {
    fn build(tree: &mut BuildTree, prims: &mut [u32], bounds: &[Aabb], leaf: usize) -> u32 {
        let union = prims
            .iter()
            .fold(Aabb::EMPTY, |b, &p| b.union(&bounds[p as usize]));
        if prims.len() <= leaf {
            return tree.push_leaf(prims.to_vec(), union);
        }
        let axis = union.extent().max_position();
        let mid = prims.len() / 2;
        prims.select_nth_unstable_by(mid, |&a, &b| {
            let c = |p: u32| bounds[p as usize].center()[axis];
            c(a).total_cmp(&c(b))
        });
        let (left, right) = prims.split_at_mut(mid);
        let l = build(tree, left, bounds, leaf);
        let r = build(tree, right, bounds, leaf);
        tree.push_internal(vec![l, r])
    }
    let bounds = primitive_bounds(mesh);
    let mut prims: Vec<u32> = (0..bounds.len() as u32)
        .filter(|&p| !bounds[p as usize].is_empty())
        .collect();
    let mut tree = BuildTree::new();
    if !prims.is_empty() {
        let root = build(&mut tree, &mut prims, &bounds, max_leaf_size.max(1));
        tree.set_root(Some(root));
    }
    tree
}

/// Runs `config` one pass at a time (the seed changing each pass), checking after each that the
/// tree is valid and that neither the objective nor, for E[X], E[X] itself went up.
fn optimize_checking_every_pass(
    tree: &mut BuildTree,
    mesh: &TriangleMesh,
    max_leaf_size: usize,
    config: ReinsertionConfig,
    passes: usize,
) -> Result<(), TestCaseError> {
    let prim_bounds = primitive_bounds(mesh);
    let mut cost = config.objective.of(tree);
    for pass in 0..passes {
        let report = ReinsertionOptimizer::new(ReinsertionConfig {
            max_passes: 1,
            min_gain: 0.0,
            seed: config.seed.wrapping_add(pass as u64),
            ..config
        })
        .optimize(tree);
        if let Err(e) = tree.validate(&prim_bounds, max_leaf_size) {
            return Err(TestCaseError::fail(format!("pass {pass}: {e}")));
        }
        let after = config.objective.of(tree);
        prop_assert!(after <= cost, "pass {}: {} -> {}", pass, cost, after);
        prop_assert_eq!(after, report.cost_after);
        cost = after;
    }
    Ok(())
}

/// Asserts that every layout of `tree` answers every ray as brute force does. (An optimized
/// tree reuses the ids of the nodes it took out, so some children are stored after their
/// parents, and may be binary or not: the layouts' paths for trees in any order.)
fn assert_tree_agrees(
    mesh: &TriangleMesh,
    tree: &BuildTree,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    for (name, layout) in every_layout(tree, mesh) {
        assert_agrees(mesh, layout.as_ref(), rays)
            .map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
    }
    Ok(())
}

fn objective() -> impl Strategy<Value = TreeCost> {
    prop_oneof![
        Just(TreeCost::ExpectedTests),
        Just(TreeCost::Sah(SahWeights::default())),
        Just(TreeCost::Sah(SahWeights {
            traversal: 1.2,
            intersection: 0.5
        })),
    ]
}

/// Optimizes, checking every pass, then collapses, checking again, then compares with brute
/// force: the property every optimized tree must have.
fn optimize_collapse_and_trace(
    mesh: &TriangleMesh,
    mut tree: BuildTree,
    leaf: usize,
    config: ReinsertionConfig,
    collapse_to: usize,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    optimize_checking_every_pass(&mut tree, mesh, leaf, config, 4)?;
    assert_tree_agrees(mesh, &tree, rays)?;

    let collapse = CollapseConfig {
        max_leaf_size: collapse_to,
        sah: SahWeights::default(),
    };
    let before = sah_cost(&tree, collapse.sah);
    collapse_leaves(&mut tree, &collapse);
    prop_assert!(sah_cost(&tree, collapse.sah) <= before);
    let max_leaf = leaf.max(collapse_to);
    if let Err(e) = tree.validate(&primitive_bounds(mesh), max_leaf) {
        return Err(TestCaseError::fail(format!("after collapse: {e}")));
    }
    tree.compact();
    prop_assert_eq!(tree.nodes().len(), tree.shape().nodes);
    assert_tree_agrees(mesh, &tree, rays)
}

proptest! {
    #![proptest_config(common::cases(200))]

    #[test]
    fn optimized_soups_answer_as_brute_force(
        (mesh, rays) in mesh_and_rays(soup()),
        order in order(),
        leaf in 1usize..5,
        objective in objective(),
        batch_fraction in 0.01f64..0.6,
        seed in any::<u64>(),
        collapse_to in 1usize..9,
    ) {
        let tree = insertion_tree(&mesh, order, leaf);
        let config = ReinsertionConfig { objective, batch_fraction, seed, ..Default::default() };
        optimize_collapse_and_trace(&mesh, tree, leaf, config, collapse_to, &rays)?;
    }

    #[test]
    fn optimized_tori_answer_as_brute_force(
        (mesh, rays) in mesh_and_rays(closed_mesh()),
        order in order(),
        leaf in 1usize..5,
        objective in objective(),
        seed in any::<u64>(),
        collapse_to in 1usize..9,
    ) {
        let tree = insertion_tree(&mesh, order, leaf);
        let config = ReinsertionConfig { objective, seed, ..Default::default() };
        optimize_collapse_and_trace(&mesh, tree, leaf, config, collapse_to, &rays)?;
    }

    #[test]
    fn optimized_binary_trees_answer_as_brute_force(
        (mesh, rays) in mesh_and_rays(prop_oneof![soup(), closed_mesh()]),
        leaf in 1usize..5,
        objective in objective(),
        seed in any::<u64>(),
    ) {
        let tree = median_tree(&mesh, leaf);
        let config = ReinsertionConfig { objective, seed, ..Default::default() };
        optimize_collapse_and_trace(&mesh, tree, leaf, config, leaf, &rays)?;
    }
}

#[test]
fn cost_never_rises_from_pass_to_pass() {
    let mesh = icosphere(Vec3::ZERO, 1.0, 4);
    for objective in [
        TreeCost::ExpectedTests,
        TreeCost::Sah(SahWeights::default()),
    ] {
        for mut tree in [
            insertion_tree(&mesh, InsertionOrder::Shuffle { seed: 9 }, 1),
            insertion_tree(&mesh, InsertionOrder::Morton, 4),
            median_tree(&mesh, 2),
        ] {
            let e_before = expected_tests(&tree);
            let report = ReinsertionOptimizer::new(ReinsertionConfig {
                objective,
                max_passes: 30,
                min_gain: 0.0,
                ..Default::default()
            })
            .optimize(&mut tree);
            let costs: Vec<f64> = std::iter::once(report.cost_before)
                .chain(report.pass_costs.iter().copied())
                .collect();
            assert!(
                costs.windows(2).all(|w| w[1] <= w[0]),
                "{objective:?}: {costs:?}"
            );
            assert!(report.cost_after < report.cost_before);
            if objective == TreeCost::ExpectedTests {
                assert!(expected_tests(&tree) < e_before);
            }
        }
    }
}

#[test]
fn optimization_lowers_expected_tests_of_an_input_order_scene_by_a_tenth() {
    let mesh = default_scene(2);
    let mut tree = insertion_tree(&mesh, InsertionOrder::Input, 1);
    let before = expected_tests(&tree);
    let report = ReinsertionOptimizer::default().optimize(&mut tree);
    let after = expected_tests(&tree);
    eprintln!(
        "default_scene(2), input order: E[X] {before:.3} -> {after:.3} in {} passes, {} of {} \
         nodes moved, {:?}",
        report.pass_costs.len(),
        report.moves,
        report.attempts,
        report.elapsed
    );
    assert!(after <= 0.9 * before, "E[X] {before} -> {after}");
    tree.validate(&primitive_bounds(&mesh), 1).unwrap();
}

#[test]
fn binary_trees_of_any_leaf_size_are_improved() {
    let mesh = torus(Vec3::ZERO, 2.0, 0.5, 48, 24);
    for leaf in [1, 4] {
        for objective in [
            TreeCost::ExpectedTests,
            TreeCost::Sah(SahWeights::default()),
        ] {
            let mut tree = median_tree(&mesh, leaf);
            let report = ReinsertionOptimizer::new(ReinsertionConfig {
                objective,
                ..Default::default()
            })
            .optimize(&mut tree);
            tree.validate(&primitive_bounds(&mesh), leaf).unwrap();
            // Leaves of four, which moves never split, leave the SAH little to gain.
            let target = match (objective, leaf) {
                (TreeCost::Sah(_), 4) => 0.995,
                _ => 0.95,
            };
            assert!(
                report.cost_after < target * report.cost_before,
                "{objective:?}, leaf {leaf}: {report:?}"
            );
            if matches!(objective, TreeCost::Sah(_)) {
                // Pairing moves keep a binary tree binary.
                assert_eq!(tree.shape().arity_histogram.len(), 3);
            }
        }
    }
}
