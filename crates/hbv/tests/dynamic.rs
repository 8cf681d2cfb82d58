//! The dynamic tree against brute force: random sequences of insertions, removals, moves with
//! refit, and optimization passes; after every step the tree's invariants hold and every query
//! equals brute force over the triangles live at that moment.

mod common;

use common::{assert_agrees, point, ray_for, scale};
use hbv::bvh::dynamic::{DynamicBvh, DynamicConfig};
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::optimize::ReinsertionConfig;
use hbv::glam::Vec3;
use proptest::prelude::*;
use proptest::strategy::ValueTree;

/// One change to the scene. Ids are picked by index into the live ids (modulo their count).
#[derive(Clone, Debug)]
enum Step {
    Insert(Vec<[Vec3; 3]>),
    Remove(Vec<usize>),
    /// Move some triangles by an offset (or flatten one to a degenerate shape), then refit
    /// (false) or reinsert the moved triangles (true).
    Move(Vec<(usize, Vec3, bool)>, bool),
    Optimize(u64),
}

fn triangle(s: f32) -> impl Strategy<Value = [Vec3; 3]> {
    prop_oneof![
        6 => (point(s), point(s), point(s)).prop_map(|(a, b, c)| [a, b, c]),
        3 => (point(s), point(s * 0.05), point(s * 0.05)).prop_map(|(a, b, c)| [a, a + b, a + c]),
        1 => (point(s), point(s)).prop_map(|(a, b)| [a, b, a + (b - a) * 0.5]),
        1 => Just([Vec3::ZERO, Vec3::X * s, Vec3::Y * s]),
        1 => (point(s * 100.0), point(s * 100.0), point(s * 100.0)).prop_map(|(a, b, c)| [a, b, c]),
    ]
}

fn step(s: f32) -> impl Strategy<Value = Step> {
    prop_oneof![
        3 => prop::collection::vec(triangle(s), 1..20).prop_map(Step::Insert),
        2 => prop::collection::vec(any::<usize>(), 1..12).prop_map(Step::Remove),
        2 => prop::collection::vec((any::<usize>(), point(s * 0.5), prop::bool::weighted(0.1)), 1..12)
            .prop_flat_map(|moves| (Just(moves), any::<bool>()))
            .prop_map(|(moves, reinsert)| Step::Move(moves, reinsert)),
        1 => any::<u64>().prop_map(Step::Optimize),
    ]
}

/// A leaf size and a sequence of steps at one coordinate scale.
fn scenario() -> impl Strategy<Value = (usize, Vec<Step>)> {
    scale().prop_flat_map(|s| (1usize..4, prop::collection::vec(step(s), 1..12)))
}

fn live_ids(bvh: &DynamicBvh) -> Vec<u32> {
    (0..bvh.capacity() as u32)
        .filter(|&id| bvh.triangle(id).is_some())
        .collect()
}

fn apply(bvh: &mut DynamicBvh, step: &Step) {
    let live = live_ids(bvh);
    match step {
        Step::Insert(tris) => {
            let ids = bvh.insert(tris).unwrap();
            assert_eq!(ids.len(), tris.len());
        }
        Step::Remove(picks) => {
            if live.is_empty() {
                return;
            }
            let mut ids: Vec<u32> = picks.iter().map(|&k| live[k % live.len()]).collect();
            ids.sort_unstable();
            ids.dedup();
            bvh.remove(&ids).unwrap();
        }
        Step::Move(moves, reinsert) => {
            if live.is_empty() {
                return;
            }
            for &(k, offset, flatten) in moves {
                let id = live[k % live.len()];
                let t = bvh.triangle(id).unwrap();
                let moved = if flatten {
                    [t.p0, t.p1, t.p0]
                } else {
                    [t.p0 + offset, t.p1 + offset * 0.5, t.p2 - offset]
                };
                bvh.set_triangle(id, moved).unwrap();
            }
            if *reinsert {
                bvh.reinsert_moved();
            } else {
                bvh.refit();
            }
        }
        Step::Optimize(seed) => {
            bvh.optimize(ReinsertionConfig {
                seed: *seed,
                max_passes: 3,
                ..ReinsertionConfig::default()
            });
        }
    }
}

proptest! {
    #![proptest_config(common::cases(128))]

    #[test]
    fn every_step_keeps_the_tree_valid_and_equal_to_brute_force(
        (leaf, steps) in scenario(),
        ray_seed in any::<u64>(),
    ) {
        let mut bvh = DynamicBvh::new(DynamicConfig { max_leaf_size: leaf });
        for (k, st) in steps.iter().enumerate() {
            apply(&mut bvh, st);
            bvh.validate().map_err(|e| TestCaseError::fail(format!("step {k} {st:?}: {e}")))?;
            let mesh = bvh.mesh();
            if mesh.is_empty() {
                continue;
            }
            // Rays drawn from the scene as it is now, deterministically from the seed.
            let mut runner = proptest::test_runner::TestRunner::new_with_rng(
                ProptestConfig::default(),
                proptest::test_runner::TestRng::from_seed(
                    proptest::test_runner::RngAlgorithm::ChaCha,
                    &{
                        let mut b = [0u8; 32];
                        b[..8].copy_from_slice(&(ray_seed ^ k as u64).to_le_bytes());
                        b
                    },
                ),
            );
            let rays: Vec<_> = (0..24)
                .map(|_| ray_for(&mesh).new_tree(&mut runner).unwrap().current())
                .collect();
            assert_agrees(&mesh, &bvh, &rays)?;
            // The live tree laid out gives the same answers.
            assert_agrees(&mesh, &RecursiveLayout::new(bvh.tree(), &mesh), &rays)?;
        }
    }
}
