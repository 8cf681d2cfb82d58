//! Rays through edges and vertices exactly, on closed meshes with integer vertices (so that
//! rays aimed at a vertex or an edge point really pass through it): a touch is a hit for the
//! closest- and any-hit queries, and a crossing is counted once by the all-hits queries.

use hbv::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder, InsertionConfig};
use hbv::bvh::layout::{Wide4Layout, Wide8Layout};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::proximity::contains_along;
use hbv::{Accelerator, AllHits, BruteForce, TriangleMesh};

mod common;

/// The octahedron `|x| + |y| + |z| = 2`: every face slanted, so the ray frame's shear rounds.
fn octahedron() -> TriangleMesh {
    let vertices = vec![
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(-2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(0.0, -2.0, 0.0),
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(0.0, 0.0, -2.0),
    ];
    let mut faces = Vec::new();
    for x in [0, 1] {
        for y in [2, 3] {
            for z in [4, 5] {
                faces.push([x, y, z]);
            }
        }
    }
    TriangleMesh::new(vertices, faces).unwrap()
}

/// A closed block of `n × n` unit cells: a flat bottom at `z = 0`, walls, and a top of integer
/// heights 1 to 4 (a fixed pseudo-random pattern), each cell split along a diagonal that
/// alternates.
fn terrain(n: u32) -> TriangleMesh {
    terrain_of_heights(n, |i, j| 1 + (i * 7 + j * 13 + i * j * 3) % 4)
}

/// [`terrain`] with the given integer heights (at least 1) at the grid's vertices.
fn terrain_of_heights(n: u32, height: impl Fn(u32, u32) -> u32) -> TriangleMesh {
    let mut vertices = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut vertex = |p: [u32; 3]| -> u32 {
        *index.entry(p).or_insert_with(|| {
            vertices.push(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32));
            vertices.len() as u32 - 1
        })
    };
    let mut faces = Vec::new();
    let quad = |faces: &mut Vec<[u32; 3]>, q: [u32; 4], flip: bool| {
        if flip {
            faces.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
        } else {
            faces.extend([[q[0], q[1], q[3]], [q[1], q[2], q[3]]]);
        }
    };
    for i in 0..n {
        for j in 0..n {
            let flip = (i + j) % 2 == 0;
            let top = [[i, j], [i + 1, j], [i + 1, j + 1], [i, j + 1]]
                .map(|[a, b]| vertex([a, b, height(a, b)]));
            quad(&mut faces, top, flip);
            let bottom =
                [[i, j], [i, j + 1], [i + 1, j + 1], [i + 1, j]].map(|[a, b]| vertex([a, b, 0]));
            quad(&mut faces, bottom, flip);
        }
    }
    // The walls: each boundary edge of the top joined to the bottom.
    for k in 0..n {
        for [a, b] in [
            [[k, 0], [k + 1, 0]],
            [[n, k], [n, k + 1]],
            [[k + 1, n], [k, n]],
            [[0, k + 1], [0, k]],
        ] {
            let wall = [
                vertex([a[0], a[1], 0]),
                vertex([b[0], b[1], 0]),
                vertex([b[0], b[1], height(b[0], b[1])]),
                vertex([a[0], a[1], height(a[0], a[1])]),
            ];
            quad(&mut faces, wall, false);
        }
    }
    let mesh = TriangleMesh::new(vertices, faces).unwrap();
    assert!(mesh.is_closed());
    mesh
}

/// Every all-hits structure: brute force, the wide layouts of two builders, and uniform grids.
fn all_hits_structures(mesh: &TriangleMesh) -> Vec<(&'static str, Box<dyn AllHits>)> {
    let insertion = InsertionBuilder::new(InsertionConfig::default()).build(mesh);
    let sah = BinnedSahBuilder::default().build(mesh);
    vec![
        ("brute force", Box::new(BruteForce::new(mesh))),
        (
            "insertion wide4",
            Box::new(Wide4Layout::new(&insertion, mesh)),
        ),
        ("binned-sah wide8", Box::new(Wide8Layout::new(&sah, mesh))),
        (
            "grid with mailboxes",
            Box::new(UniformGrid::new(mesh, GridConfig::default())),
        ),
        (
            "dense grid without mailboxes",
            Box::new(UniformGrid::new(
                mesh,
                GridConfig {
                    lambda: 6.0,
                    mailbox: false,
                },
            )),
        ),
    ]
}

/// Brute force, every layout of a binned-SAH tree, and the uniform grid.
fn accelerators(mesh: &TriangleMesh) -> Vec<(&'static str, Box<dyn Accelerator>)> {
    let tree = BinnedSahBuilder::default().build(mesh);
    let mut all = common::every_accelerator(&tree, mesh);
    all.push((
        "grid",
        Box::new(UniformGrid::new(mesh, GridConfig::default())),
    ));
    all
}

/// The points a ray may be aimed at: every vertex, and points along every edge at quarters
/// (exact for integer vertices).
fn targets(mesh: &TriangleMesh) -> Vec<Vec3> {
    let mut points = mesh.positions().to_vec();
    for face in mesh.indices() {
        for k in 0..3 {
            let (p, q) = (
                mesh.positions()[face[k] as usize],
                mesh.positions()[face[(k + 1) % 3] as usize],
            );
            points.extend([0.25, 0.5, 0.75].map(|s| p + (q - p) * s));
        }
    }
    points
}

/// Rays from points strictly inside a closed mesh aimed exactly at its vertices and edges cross
/// the surface there: each such crossing is counted once, so every count is odd. Rays from
/// points outside aimed alike either cross twice or touch: every count is even. (Before the
/// exact edge signs and the half-open rule, a ray through an edge of axis-aligned or integer
/// geometry hit both triangles there: their f64 edge functions were exactly 0, and zero counted
/// as inside.) The inside test, one ray's parity, is right along every such ray.
#[test]
fn crossings_through_edges_and_vertices_are_counted_once() {
    let cases: Vec<(TriangleMesh, Vec<Vec3>, Vec<Vec3>)> = vec![
        (
            octahedron(),
            vec![
                Vec3::new(0.25, 0.125, -0.5),
                Vec3::new(-0.5, 0.75, 0.25),
                Vec3::ZERO,
            ],
            vec![Vec3::new(3.0, 2.5, 1.0), Vec3::new(-5.0, 0.5, -4.0)],
        ),
        (
            terrain(6),
            vec![
                Vec3::new(0.5, 0.5, 0.5),
                Vec3::new(3.25, 4.5, 0.75),
                Vec3::new(5.5, 2.0, 0.25),
            ],
            vec![
                Vec3::new(3.5, 2.5, 9.0),
                Vec3::new(-2.0, -1.0, 6.0),
                Vec3::new(8.0, 3.0, -2.0),
            ],
        ),
    ];
    for (mesh_index, (mesh, inside, outside)) in cases.iter().enumerate() {
        let structures = all_hits_structures(mesh);
        let mut rays = 0;
        for (origins, parity) in [(inside, 1), (outside, 0)] {
            for &origin in origins {
                for target in targets(mesh) {
                    let ray = Ray::new(origin, target - origin);
                    for (name, structure) in &structures {
                        let count = structure.count_hits(&ray);
                        assert_eq!(
                            contains_along(structure.as_ref(), origin, ray.direction),
                            parity == 1,
                            "mesh {mesh_index}, {name}: from {origin} towards {target}"
                        );
                        assert_eq!(
                            count % 2,
                            parity,
                            "mesh {mesh_index}, {name}: {count} hits from {origin} towards {target}"
                        );
                    }
                    rays += 1;
                }
            }
        }
        assert!(rays > 100, "mesh {mesh_index}: {rays} rays");
    }
}

/// Rays of axis-aligned and diagonal directions (shear slopes 0 and ±1, so that the exact edge
/// signs come from exactly sheared coordinates) from points inside the terrain on its grid
/// lines: along the grid they pass exactly through walls' edges and the top's vertices; every
/// count is odd.
#[test]
fn axis_aligned_and_diagonal_rays_along_grid_lines_count_crossings_once() {
    let n = 6;
    let mesh = terrain(n);
    let structures = all_hits_structures(&mesh);
    let directions = [
        Vec3::X,
        -Vec3::X,
        Vec3::Y,
        -Vec3::Y,
        Vec3::Z,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(0.0, -1.0, 1.0),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let mut rays = 0;
    for i in 1..n {
        for j in 1..n {
            for z in [0.5f32, 0.75] {
                let origin = Vec3::new(i as f32, j as f32, z);
                for direction in directions {
                    let ray = Ray::new(origin, direction);
                    for (name, structure) in &structures {
                        let count = structure.count_hits(&ray);
                        assert_eq!(
                            count % 2,
                            1,
                            "{name}: {count} hits from {origin} along {direction}"
                        );
                    }
                    rays += 1;
                }
            }
        }
    }
    assert_eq!(rays, 500);
}

/// Rays that only touch a surface, at a silhouette vertex or a silhouette edge of the
/// octahedron, or that start exactly on an edge where two faces meet at an angle: a touch is a
/// hit for the closest- and any-hit queries, at its exact `t`, in every structure. (Before the
/// exact edge signs, the f64 fallback's rounding decided these, and missed some.)
#[test]
fn touches_are_hits_for_closest_and_any_hit_queries() {
    let mesh = octahedron();
    let structures = accelerators(&mesh);
    let mut rays = Vec::new();
    // Through the vertex (2, 0, 0), touching only it: along the line (2 + s a, s b, s c),
    // |x| + |y| + |z| = 2 + s a + |s| (|b| + |c|) > 2 for s ≠ 0 when |b| + |c| > |a|.
    for (a, b, c) in [(1, 3, 5), (-1, 2, 1), (2, -3, 4), (0, 1, 7), (-3, -5, 1)] {
        let d = Vec3::new(a as f32, b as f32, c as f32);
        rays.push((Vec3::new(2.0, 0.0, 0.0) - 7.0 * d, d, 7.0));
    }
    // Through points of the edge from (2, 0, 0) to (0, 2, 0), touching only it: along
    // (x0 + s a, y0 + s b, s c), the sum is 2 + s (a + b) + |s c|: a touch when |c| > |a + b|.
    for (k, (a, b, c)) in [(1, 2, 4), (3, -1, -3), (-2, -3, 6), (5, -5, 1)]
        .into_iter()
        .enumerate()
    {
        let on_edge = Vec3::new(2.0 - 0.5 * k as f32, 0.5 * k as f32, 0.0);
        let d = Vec3::new(a as f32, b as f32, c as f32);
        rays.push((on_edge - 3.0 * d, d, 3.0));
    }
    // Starting on that edge, leaving the surface outwards (the ray's `t` is 0).
    for d in [
        Vec3::new(1.0, 1.0, 0.25),
        Vec3::new(3.0, 1.0, -1.0),
        Vec3::new(1.0, 5.0, 0.0),
    ] {
        rays.push((Vec3::new(1.5, 0.5, 0.0), d, 0.0));
    }
    for (origin, direction, t) in rays {
        let ray = Ray::new(origin, direction);
        for (name, structure) in &structures {
            let hit = structure
                .intersect(&ray)
                .unwrap_or_else(|| panic!("{name} misses {origin} + t {direction}"));
            assert_eq!(hit.t, t, "{name}: {origin} + t {direction}");
            assert!(structure.occluded(&ray), "{name}: {origin} + t {direction}");
            assert_eq!(structure.intersect_batch(&[ray])[0], Some(hit), "{name}");
        }
    }
}

/// Random terrains, and rays from random points inside (below the lowest height) and outside
/// (above the highest) aimed exactly at random vertices and edge points: odd counts from
/// inside, even from outside, in every structure.
mod random_terrains {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(crate::common::cases(24))]
        #[test]
        fn crossings_have_the_parity_of_the_origin(
            n in 2u32..6,
            heights in prop::collection::vec(1u32..6, 36),
            origins in prop::collection::vec((any::<u32>(), any::<u32>(), any::<bool>()), 4),
            picks in prop::collection::vec(any::<prop::sample::Index>(), 24),
        ) {
            let mesh = terrain_of_heights(n, |i, j| heights[(i * 6 + j) as usize]);
            let structures = all_hits_structures(&mesh);
            let targets = targets(&mesh);
            for (x, y, inside) in origins {
                // Points at odd sixteenths within the block (so that `target − origin` is exact),
                // strictly below height 1 or above 6.
                let within = |k: u32| ((k % (8 * n)) as f32 + 0.5) / 8.0;
                let (x, y) = (within(x), within(y));
                let origin = Vec3::new(x, y, if inside { 0.5 } else { 7.5 });
                for pick in &picks {
                    let target = targets[pick.index(targets.len())];
                    let ray = Ray::new(origin, target - origin);
                    for (name, structure) in &structures {
                        let count = structure.count_hits(&ray);
                        prop_assert_eq!(
                            count % 2 == 1,
                            inside,
                            "{}: {} hits from {} towards {}", name, count, origin, target
                        );
                    }
                }
            }
        }
    }
}

/// Random small-integer triangles and rays between small-integer points (so that rays through
/// vertices and along edges' lines are common): whatever the half-open rule hits, the closed
/// rule hits too, at the same `t`; the two differ only where the closed rule finds the ray on
/// an edge's line.
mod half_open_within_closed {
    use super::*;
    use hbv::geometry::{EdgeRule, PreparedRay, Triangle};
    use proptest::prelude::*;

    fn small_point() -> impl Strategy<Value = Vec3> {
        (-3i8..=3, -3i8..=3, -3i8..=3).prop_map(|(x, y, z)| Vec3::new(x as f32, y as f32, z as f32))
    }

    proptest! {
        #![proptest_config(crate::common::cases(256))]
        #[test]
        fn half_open_hits_are_closed_hits(
            vertices in [small_point(), small_point(), small_point()],
            from in small_point(),
            other in small_point(),
            aim in 0usize..7,
            scale in prop::sample::select(vec![1.0f32, 0.1, 3.0e5, 1.0e-5]),
        ) {
            let [a, b, c] = vertices.map(|v| v * scale);
            // Aimed at a vertex, an edge's midpoint, or another point.
            let towards = [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5, other * scale][aim];
            let from = from * scale;
            let ray = Ray::new(from, towards - from);
            prop_assume!(ray.is_valid());
            let triangle = Triangle::new(a, b, c);
            let prepared = PreparedRay::new(&ray);
            let closed = triangle.intersect_by(&prepared, EdgeRule::Closed);
            let half_open = triangle.intersect_by(&prepared, EdgeRule::HalfOpen);
            if let Some(h) = half_open {
                prop_assert_eq!(closed.map(|c| c.t), Some(h.t));
            }
        }
    }
}
