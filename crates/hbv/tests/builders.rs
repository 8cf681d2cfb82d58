//! Property tests of the top-down builders (binned and sweep SAH, median, LBVH): on adversarial
//! triangle soups and closed meshes, every tree keeps the tree invariants and answers exactly what
//! brute force answers; and the SAH builders make cheaper trees than the baselines.

use glam::Vec3;
use hbv::bvh::build::{
    primitive_bounds, BinnedSahBuilder, BinnedSahConfig, Builder, LbvhBuilder, LbvhConfig,
    LeafPolicy, MedianBuilder, MedianConfig, SweepSahBuilder, SweepSahConfig,
};
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::{sah_cost, BuildTree, NodeContent, SahWeights};
use hbv::geometry::{Aabb, Ray};
use hbv::mesh::procedural::{default_scene, torus};
use hbv::{Accelerator, BruteForce, TriangleMesh};
use proptest::prelude::*;

/// A builder under test with its options, and the leaf size its trees must respect.
#[derive(Clone, Debug)]
enum BuilderUnderTest {
    BinnedSah(BinnedSahConfig),
    SweepSah(SweepSahConfig),
    Median(MedianConfig),
    Lbvh(LbvhConfig),
}

impl BuilderUnderTest {
    fn builder(&self) -> Box<dyn Builder> {
        match *self {
            Self::BinnedSah(c) => Box::new(BinnedSahBuilder::new(c)),
            Self::SweepSah(c) => Box::new(SweepSahBuilder::new(c)),
            Self::Median(c) => Box::new(MedianBuilder::new(c)),
            Self::Lbvh(c) => Box::new(LbvhBuilder::new(c)),
        }
    }

    fn max_leaf_size(&self) -> usize {
        match self {
            Self::BinnedSah(c) => c.leaf.max_leaf_size,
            Self::SweepSah(c) => c.leaf.max_leaf_size,
            Self::Median(c) => c.max_leaf_size,
            Self::Lbvh(c) => c.max_leaf_size,
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
    ]
}

/// A coordinate scale: tiny, unit, large and huge scenes.
fn scale() -> impl Strategy<Value = f32> {
    prop_oneof![Just(1e-4f32), Just(1.0), Just(1e3), Just(1e6)]
}

fn point(s: f32) -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(move |(x, y, z)| Vec3::new(x, y, z) * s)
}

/// A triangle soup with slivers, degenerate (collinear, coincident), duplicated and huge
/// triangles mixed in.
fn soup() -> impl Strategy<Value = TriangleMesh> {
    scale().prop_flat_map(|s| {
        let tri = prop_oneof![
            6 => (point(s), point(s), point(s)).prop_map(|(a, b, c)| [a, b, c]),
            // Small triangle around a point.
            3 => (point(s), point(s * 0.05), point(s * 0.05)).prop_map(|(a, b, c)| [a, a + b, a + c]),
            // Sliver: third vertex almost on the first edge.
            1 => (point(s), point(s), 0.0f32..1.0).prop_map(|(a, b, k)| [a, b, a + (b - a) * k + Vec3::splat(1e-6)]),
            // Degenerate: collinear or coincident.
            1 => (point(s), point(s)).prop_map(|(a, b)| [a, b, a + (b - a) * 0.5]),
            1 => point(s).prop_map(|a| [a, a, a]),
            // The same triangle every time: many coincident centroids.
            1 => Just([Vec3::ZERO, Vec3::X * s, Vec3::Y * s]),
            // Huge: much larger than the scene.
            1 => (point(s * 100.0), point(s * 100.0), point(s * 100.0)).prop_map(|(a, b, c)| [a, b, c]),
        ];
        prop::collection::vec(tri, 1..120).prop_map(|tris| {
            let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
            let indices = (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            TriangleMesh::new(positions, indices).unwrap()
        })
    })
}

/// A closed torus with shared edges, randomly sized and placed.
fn closed_mesh() -> impl Strategy<Value = TriangleMesh> {
    (scale(), 3u32..24, 3u32..12, point(1.0))
        .prop_map(|(s, m, n, c)| torus(c * s, 2.0 * s, 0.7 * s, m, n))
}

/// A ray aimed at the mesh: from inside its box in any or an axis direction, from outside at
/// the box, from a point on a triangle, or a finite segment.
fn ray_for(mesh: &TriangleMesh) -> impl Strategy<Value = Ray> {
    let b = mesh.bounds();
    let (lo, hi) = (b.min, b.max);
    let ext = (hi - lo).max_element().max(1e-30);
    let n = mesh.triangle_count();
    let inside = move || {
        (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0)
            .prop_map(move |(x, y, z)| lo + (hi - lo) * Vec3::new(x, y, z))
    };
    let dir = || point(1.0).prop_filter("nonzero", |d| d.length() > 1e-3);
    let axis = || {
        (0usize..3, any::<bool>()).prop_map(|(k, neg)| {
            let mut d = Vec3::ZERO;
            d[k] = if neg { -1.0 } else { 1.0 };
            d
        })
    };
    let mesh = mesh.clone();
    let on_surface = (0..n, 0.0f32..1.0, 0.0f32..1.0).prop_map(move |(i, a, b)| {
        let t = mesh.triangle(i);
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        t.p0 + (t.p1 - t.p0) * a + (t.p2 - t.p0) * b
    });
    prop_oneof![
        (inside(), dir()).prop_map(|(o, d)| Ray::new(o, d)),
        (inside(), axis()).prop_map(|(o, d)| Ray::new(o, d)),
        (point(1.0), inside(), 0.01f32..100.0).prop_map(move |(o, target, k)| {
            let o = (lo + hi) * 0.5 + o.normalize_or(Vec3::X) * 3.0 * ext;
            Ray::new(o, (target - o) * k / ext)
        }),
        (on_surface, dir()).prop_map(|(o, d)| Ray::new(o, d)),
        (inside(), dir(), 0.0f32..1.0, 0.0f32..2.0)
            .prop_map(move |(o, d, a, len)| Ray::new(o, d).with_interval(a * ext, (a + len) * ext)),
    ]
}

fn mesh_and_rays(
    mesh: impl Strategy<Value = TriangleMesh>,
) -> impl Strategy<Value = (TriangleMesh, Vec<Ray>)> {
    mesh.prop_flat_map(|m| {
        let rays = prop::collection::vec(ray_for(&m), 1..48);
        (Just(m), rays)
    })
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
    #![proptest_config(ProptestConfig::with_cases(1000))]

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

fn default_builders() -> [Box<dyn Builder>; 4] {
    [
        Box::new(BinnedSahBuilder::default()),
        Box::new(SweepSahBuilder::default()),
        Box::new(MedianBuilder::default()),
        Box::new(LbvhBuilder::default()),
    ]
}

#[test]
fn names() {
    let names: Vec<&str> = default_builders().iter().map(|b| b.name()).collect();
    assert_eq!(names, ["binned-sah", "sweep-sah", "median", "lbvh"]);
}

#[test]
fn empty_and_all_degenerate_meshes_give_empty_trees() {
    let empty = TriangleMesh::new(vec![], vec![]).unwrap();
    let flat = TriangleMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        vec![[0, 1, 2], [0, 0, 0]],
    )
    .unwrap();
    for mesh in [empty, flat] {
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
    let [binned, sweep, median, lbvh] = cost[..] else {
        unreachable!()
    };
    assert!(binned < median, "binned {binned}, median {median}");
    assert!(binned < lbvh, "binned {binned}, lbvh {lbvh}");
    assert!(sweep <= binned * 1.02, "sweep {sweep}, binned {binned}");
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
    // Boxes whose centres, extents and areas overflow f32 if computed carelessly.
    let big = f32::MAX;
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
        ] {
            let tree = under_test.builder().build(&mesh);
            tree.validate(&bounds, max_leaf_size)
                .unwrap_or_else(|e| panic!("{under_test:?}: {e}"));
        }
    }
}
