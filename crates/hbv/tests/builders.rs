//! Property tests of the builders (binned and sweep SAH, median, LBVH, PLOC): on adversarial
//! triangle soups and closed meshes, every tree keeps the tree invariants and answers exactly what
//! brute force answers; and the SAH builders make cheaper trees than the baselines.

use glam::Vec3;
use hbv::bvh::build::{
    primitive_bounds, BinnedSahBuilder, BinnedSahConfig, Builder, LbvhBuilder, LbvhConfig,
    LeafPolicy, MedianBuilder, MedianConfig, PlocBuilder, PlocConfig, SweepSahBuilder,
    SweepSahConfig,
};
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::{sah_cost, BuildTree, NodeContent, SahWeights};
use hbv::geometry::{Aabb, Ray};
use hbv::mesh::procedural::default_scene;
use hbv::{Accelerator, BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{closed_mesh, mesh_and_rays, soup};

/// A builder under test with its options, and the leaf size its trees must respect.
#[derive(Clone, Debug)]
enum BuilderUnderTest {
    BinnedSah(BinnedSahConfig),
    SweepSah(SweepSahConfig),
    Median(MedianConfig),
    Lbvh(LbvhConfig),
    Ploc(PlocConfig),
}

impl BuilderUnderTest {
    fn builder(&self) -> Box<dyn Builder> {
        match *self {
            Self::BinnedSah(c) => Box::new(BinnedSahBuilder::new(c)),
            Self::SweepSah(c) => Box::new(SweepSahBuilder::new(c)),
            Self::Median(c) => Box::new(MedianBuilder::new(c)),
            Self::Lbvh(c) => Box::new(LbvhBuilder::new(c)),
            Self::Ploc(c) => Box::new(PlocBuilder::new(c)),
        }
    }

    fn max_leaf_size(&self) -> usize {
        match self {
            Self::BinnedSah(c) => c.leaf.max_leaf_size,
            Self::SweepSah(c) => c.leaf.max_leaf_size,
            Self::Median(c) => c.max_leaf_size,
            Self::Lbvh(c) => c.max_leaf_size,
            Self::Ploc(c) => c.leaf.max_leaf_size,
        }
    }
}

fn leaf_policy() -> impl Strategy<Value = LeafPolicy> {
    (
        1usize..=8,
        1usize..=4,
        prop_oneof![Just(1.0f64), Just(0.25), Just(4.0)],
    )
        .prop_map(|(max_leaf_size, min_leaf_size, traversal)| LeafPolicy {
            max_leaf_size,
            min_leaf_size,
            sah: SahWeights {
                traversal,
                intersection: 1.0,
            },
        })
}

fn builder_under_test() -> impl Strategy<Value = BuilderUnderTest> {
    prop_oneof![
        (
            prop_oneof![Just(2usize), Just(3), Just(16), Just(32), Just(64)],
            leaf_policy()
        )
            .prop_map(|(bins, leaf)| BuilderUnderTest::BinnedSah(BinnedSahConfig { bins, leaf })),
        leaf_policy().prop_map(|leaf| BuilderUnderTest::SweepSah(SweepSahConfig { leaf })),
        (1usize..=8)
            .prop_map(|max_leaf_size| BuilderUnderTest::Median(MedianConfig { max_leaf_size })),
        (1usize..=8).prop_map(|max_leaf_size| BuilderUnderTest::Lbvh(LbvhConfig { max_leaf_size })),
        (1usize..=20, leaf_policy())
            .prop_map(|(radius, leaf)| BuilderUnderTest::Ploc(PlocConfig { radius, leaf })),
    ]
}

/// Checks the tree invariants, that the tree is binary with tight boxes, and that its recursive
/// layout answers every ray exactly like brute force (same `t`, same triangle under the shared
/// smallest-id tie rule, same any-hit answer).
fn check(
    mesh: &TriangleMesh,
    under_test: &BuilderUnderTest,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    let tree = under_test.builder().build(mesh);
    let bounds = primitive_bounds(mesh);
    let max_leaf_size = under_test.max_leaf_size();
    if let Err(e) = tree.validate(&bounds, max_leaf_size) {
        prop_assert!(false, "{under_test:?}: {e}");
    }
    assert_binary_and_tight(&tree, &bounds)?;

    let bvh = RecursiveLayout::new(&tree, mesh);
    let reference = BruteForce::new(mesh);
    for (i, ray) in rays.iter().enumerate() {
        prop_assert_eq!(
            reference.intersect(ray),
            bvh.intersect(ray),
            "closest hit, ray {} {:?}",
            i,
            ray
        );
        prop_assert_eq!(
            reference.occluded(ray),
            bvh.occluded(ray),
            "any hit, ray {} {:?}",
            i,
            ray
        );
    }
    Ok(())
}

/// Every internal node has exactly two children, and every box is exactly the union of what it
/// holds.
fn assert_binary_and_tight(tree: &BuildTree, bounds: &[Aabb]) -> Result<(), TestCaseError> {
    let mut problem = None;
    tree.walk(|id, _| {
        let node = tree.node(id);
        let union = match &node.content {
            NodeContent::Internal(children) => {
                if children.len() != 2 {
                    problem = Some(format!("node {id} has {} children", children.len()));
                }
                children
                    .iter()
                    .fold(Aabb::EMPTY, |b, &c| b.union(&tree.node(c).bounds))
            }
            NodeContent::Leaf(prims) => prims
                .iter()
                .fold(Aabb::EMPTY, |b, &p| b.union(&bounds[p as usize])),
        };
        if node.bounds != union {
            problem = Some(format!("node {id}'s box is not tight"));
        }
    });
    prop_assert!(problem.is_none(), "{}", problem.unwrap_or_default());
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(1000))]

    #[test]
    fn soup_trees_are_valid_and_answer_like_brute_force(
        (mesh, rays) in mesh_and_rays(soup()),
        under_test in builder_under_test(),
    ) {
        check(&mesh, &under_test, &rays)?;
    }

    #[test]
    fn closed_mesh_trees_are_valid_and_answer_like_brute_force(
        (mesh, rays) in mesh_and_rays(closed_mesh()),
        under_test in builder_under_test(),
    ) {
        check(&mesh, &under_test, &rays)?;
    }
}

fn default_builders() -> [Box<dyn Builder>; 5] {
    [
        Box::new(BinnedSahBuilder::default()),
        Box::new(SweepSahBuilder::default()),
        Box::new(MedianBuilder::default()),
        Box::new(LbvhBuilder::default()),
        Box::new(PlocBuilder::default()),
    ]
}

#[test]
fn names() {
    let names: Vec<&str> = default_builders().iter().map(|b| b.name()).collect();
    assert_eq!(names, ["binned-sah", "sweep-sah", "median", "lbvh", "ploc"]);
}

#[test]
fn empty_and_all_degenerate_meshes_give_empty_trees() {
    for mesh in common::empty_and_all_degenerate_meshes() {
        for builder in default_builders() {
            assert!(builder.build(&mesh).is_empty(), "{}", builder.name());
        }
    }
}

#[test]
fn sah_builders_beat_the_baselines_on_the_default_scene() {
    let mesh = default_scene(2);
    let bounds = primitive_bounds(&mesh);
    let cost: Vec<f64> = default_builders()
        .iter()
        .map(|builder| {
            let tree = builder.build(&mesh);
            tree.validate(&bounds, 8).unwrap();
            sah_cost(&tree, SahWeights::default())
        })
        .collect();
    let [binned, sweep, median, lbvh, ploc] = cost[..] else {
        unreachable!()
    };
    assert!(binned < median, "binned {binned}, median {median}");
    assert!(binned < lbvh, "binned {binned}, lbvh {lbvh}");
    assert!(sweep <= binned * 1.02, "sweep {sweep}, binned {binned}");
    assert!(ploc < lbvh, "ploc {ploc}, lbvh {lbvh}");
}

#[test]
fn builds_are_deterministic_whatever_the_thread_count() {
    let mesh = default_scene(1);
    for builder in default_builders() {
        let many = builder.build(&mesh);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| builder.build(&mesh));
        assert!(many == one, "{}", builder.name());
    }
}

#[test]
fn extreme_coordinates_build_valid_trees() {
    // Boxes whose centres, extents and areas overflow f32 if computed carelessly (the largest
    // coordinates a mesh may have).
    let big = hbv::mesh::MAX_COORDINATE;
    let positions = vec![
        Vec3::new(-big, -big, 0.0),
        Vec3::new(big, -big, 0.0),
        Vec3::new(big, big, big),
        Vec3::new(-big, big, -big),
        Vec3::new(1e-38, 0.0, 0.0),
        Vec3::new(0.0, 1e-38, 0.0),
        Vec3::new(0.0, 0.0, 1e-38),
    ];
    let indices = vec![
        [0, 1, 2],
        [1, 2, 3],
        [0, 2, 3],
        [4, 5, 6],
        [0, 5, 6],
        [4, 5, 2],
    ];
    let mesh = TriangleMesh::new(positions, indices).unwrap();
    let bounds = primitive_bounds(&mesh);
    for max_leaf_size in [1, 2] {
        for under_test in [
            BuilderUnderTest::BinnedSah(BinnedSahConfig {
                leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
                ..BinnedSahConfig::default()
            }),
            BuilderUnderTest::SweepSah(SweepSahConfig {
                leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
            }),
            BuilderUnderTest::Median(MedianConfig { max_leaf_size }),
            BuilderUnderTest::Lbvh(LbvhConfig { max_leaf_size }),
            BuilderUnderTest::Ploc(PlocConfig {
                leaf: LeafPolicy::with_max_leaf_size(max_leaf_size),
                ..PlocConfig::default()
            }),
        ] {
            let tree = under_test.builder().build(&mesh);
            tree.validate(&bounds, max_leaf_size)
                .unwrap_or_else(|e| panic!("{under_test:?}: {e}"));
        }
    }
}
