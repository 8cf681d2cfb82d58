//! Property tests of the point queries: the BVH's nearest surface point equals the f64 brute
//! force's, and the inside test agrees with parity counts and with geometry.

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, InsertionBuilder, InsertionConfig,
};
use hbv::bvh::layout::Wide8Layout;
use hbv::bvh::BuildTree;
use hbv::geometry::Aabb;
use hbv::glam::{DVec3, Vec3};
use hbv::mesh::procedural::{icosphere, torus};
use std::sync::Arc;

use hbv::proximity::{
    closest_point_brute_force, contains, BuildTreeSearch, CandidateGridConfig, ClosestPoint,
    ClosestPointColumns, ClosestPointTree, ClosestPointsOnDemand, FlatPoints, NearestPointSearch,
    QueryPoints, SearchTally, SearchTreeConfig,
};
use hbv::{BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{closed_mesh, order, point, scale, soup};

/// Query points for `mesh`: inside and around its box, exactly on vertices, on edges and on
/// faces, far away, and non-finite.
fn points_for(mesh: &TriangleMesh) -> impl Strategy<Value = Vec<Vec3>> {
    let b = mesh.bounds();
    let (lo, hi) = (b.min, b.max);
    let n = mesh.triangle_count();
    let positions = mesh.positions().to_vec();
    let m = mesh.clone();
    let m2 = mesh.clone();
    let around = move || {
        (-0.5f32..1.5, -0.5f32..1.5, -0.5f32..1.5)
            .prop_map(move |(x, y, z)| lo + (hi - lo) * Vec3::new(x, y, z))
    };
    let one = prop_oneof![
        4 => around(),
        1 => (0..positions.len()).prop_map(move |i| positions[i]),
        1 => (0..n, 0.0f32..1.0).prop_map(move |(i, k)| {
            let t = m.triangle(i);
            t.p0 + (t.p1 - t.p0) * k
        }),
        // A hair off a face: the search's rounding margins decide here.
        1 => (0..n, 0.0f32..1.0, 0.0f32..1.0, -1e-3f32..1e-3).prop_map(move |(i, a, b, off)| {
            let t = m2.triangle(i);
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let n = (t.p1 - t.p0).cross(t.p2 - t.p0).normalize_or_zero();
            let size = (t.p1 - t.p0).length().max((t.p2 - t.p0).length());
            t.p0 + (t.p1 - t.p0) * a + (t.p2 - t.p0) * b + n * (off * size)
        }),
        1 => point(1e9),
        1 => Just(Vec3::new(f32::NAN, 0.0, 0.0)),
        1 => Just(Vec3::new(0.0, f32::INFINITY, 0.0)),
    ];
    // Half the time, a tight cluster around one of them as well: neighbours in the batch's
    // Morton order, each seeded with the previous one's triangle.
    let ext = (hi - lo).max_element();
    (
        prop::collection::vec(one, 1..48),
        any::<bool>(),
        prop::collection::vec(point(1.0), 16),
    )
        .prop_map(move |(mut points, cluster, offsets)| {
            if cluster {
                let centre = points[0];
                points.extend(offsets.iter().map(|o| centre + *o * (1e-3 * ext)));
            }
            points
        })
}

fn mesh_and_points(
    mesh: impl Strategy<Value = TriangleMesh>,
) -> impl Strategy<Value = (TriangleMesh, Vec<Vec3>)> {
    mesh.prop_flat_map(|m| {
        let points = points_for(&m);
        (Just(m), points)
    })
}

/// [`assert_closest_points_agree_with`] with the default search tree: the insertion tree
/// without a candidate grid (batches in Morton order, each point seeded by its neighbour's
/// answer), the SAH tree with the product's grid.
fn assert_closest_points_agree(
    mesh: &TriangleMesh,
    order: hbv::bvh::build::InsertionOrder,
    leaf: usize,
    points: &[Vec3],
) -> Result<(), TestCaseError> {
    let no_grid = CandidateGridConfig {
        cells: 0,
        ..CandidateGridConfig::default()
    };
    assert_closest_points_agree_with(
        mesh,
        order,
        leaf,
        SearchTreeConfig::default(),
        no_grid,
        points,
    )
}

/// Candidate grids of every kind: none, one cell to a few hundred (large cells: few list their
/// triangles, the rest seed tree searches), fine ones, any list length, tight or wide margins.
fn grid_config() -> impl Strategy<Value = CandidateGridConfig> {
    (
        prop_oneof![Just(0usize), 1usize..300, Just(4096)],
        prop_oneof![1usize..4, 4usize..64],
        prop_oneof![Just(0.0f64), Just(0.25), 0.0f64..2.0],
        prop_oneof![Just(0.0f64), Just(0.5)],
        // Made with the tree, or after a few dozen points (between the single queries, or at
        // the batch).
        prop_oneof![Just(0.0f64), 0.0f64..0.05],
    )
        .prop_map(|(cells, max_candidates, margin, min_listing, payback)| {
            CandidateGridConfig {
                cells,
                max_candidates,
                margin,
                min_listing,
                payback,
            }
        })
}

fn assert_closest_points_agree_with(
    mesh: &TriangleMesh,
    order: hbv::bvh::build::InsertionOrder,
    leaf: usize,
    config: SearchTreeConfig,
    grid: CandidateGridConfig,
    points: &[Vec3],
) -> Result<(), TestCaseError> {
    let insertion = InsertionBuilder::new(InsertionConfig {
        order,
        max_leaf_size: leaf,
    })
    .build(mesh);
    let mut sah_config = BinnedSahConfig::default();
    sah_config.leaf.max_leaf_size = leaf;
    let sah = BinnedSahBuilder::new(sah_config).build(mesh);
    // The insertion tree with the grid asked for, the SAH tree with the default one (32,768
    // cells: the product's), made at once.
    let product_grid = CandidateGridConfig {
        payback: 0.0,
        ..CandidateGridConfig::default()
    };
    for (name, tree, grid) in [
        ("insertion", insertion, grid),
        ("binned-sah", sah, product_grid),
    ] {
        let search = ClosestPointTree::with_grid(&tree, mesh, config, grid);
        let walk = BuildTreeSearch::new(&tree, mesh);
        for (i, p) in points.iter().enumerate() {
            let want = closest_point_brute_force(mesh, p.as_dvec3());
            let got = search.closest_point(*p);
            prop_assert_eq!(want, got, "{}: point {} {:?}", name, i, p);
            // The builder's own tree, walked as it is (a fresh BVH's first queries).
            let walked = walk.closest_point(p.as_dvec3());
            prop_assert_eq!(want, walked, "{} walk: point {} {:?}", name, i, p);
        }
        // The batch form (Morton order, each search seeded with its neighbour's triangle):
        // the same answers.
        let as_f64: Vec<_> = points.iter().map(|p| p.as_dvec3()).collect();
        for (i, got) in search.closest_points(&as_f64).into_iter().enumerate() {
            let want = closest_point_brute_force(mesh, as_f64[i]);
            prop_assert_eq!(want, got, "{} batch: point {} {:?}", name, i, points[i]);
        }
        // The column form: the same answers, NaN, +inf, -1, 0, 0 for none (compared as bits:
        // NaN rows must match too).
        let rows = column_rows(&search, as_f64.as_slice());
        for (i, &p) in as_f64.iter().enumerate() {
            let want = match closest_point_brute_force(mesh, p) {
                Some(c) => (c.point.to_array(), c.distance, c.prim as i64, c.u, c.v),
                None => ([f64::NAN; 3], f64::INFINITY, -1, 0.0, 0.0),
            };
            prop_assert_eq!(
                row_bits(want),
                rows[i],
                "{} columns: point {} {:?}",
                name,
                i,
                p
            );
        }
        // A batch longer than one run (answered in Morton order, in parallel or in turn on the
        // calling thread, rather than in the points' order): the points repeated, the same rows.
        if !points.is_empty() {
            let n = points.len();
            let long: Vec<_> = as_f64
                .iter()
                .cycle()
                .take(ClosestPointTree::RUN + 1 + n)
                .copied()
                .collect();
            for (j, row) in column_rows(&search, long.as_slice())
                .into_iter()
                .enumerate()
            {
                prop_assert_eq!(row, rows[j % n], "{} long batch: row {}", name, j);
            }
            // Read in place from the flat rows of f32 and f64 arrays (as from NumPy), one run
            // and several: the same rows.
            let flat32: Vec<f32> = long.iter().flat_map(|p| p.as_vec3().to_array()).collect();
            let flat64: Vec<f64> = long.iter().flat_map(|p| p.to_array()).collect();
            // On demand: walks for the first `n` points (in one run, then in several: the
            // limit is `n + RUN + 1 + n`), then the search tree, made by the batch that passes
            // the limit.
            let on_demand = ClosestPointsOnDemand::with_walk_limit(
                Arc::new(tree.clone()),
                Arc::new(mesh.clone()),
                long.len() + n,
            );
            let by_walks = on_demand_rows(&on_demand, &FlatPoints::new(&flat32[..3 * n]).unwrap());
            let long_walks = on_demand_rows(&on_demand, long.as_slice());
            prop_assert!(
                on_demand.search_tree().is_none(),
                "{}: made too early",
                name
            );
            let by_search = on_demand_rows(&on_demand, long.as_slice());
            prop_assert!(on_demand.search_tree().is_some(), "{}: never made", name);
            for (j, row) in by_walks.into_iter().enumerate() {
                prop_assert_eq!(row, rows[j], "{} walked rows: row {}", name, j);
            }
            for (j, (walked, searched)) in long_walks.into_iter().zip(by_search).enumerate() {
                prop_assert_eq!(walked, rows[j % n], "{} walked long rows: row {}", name, j);
                prop_assert_eq!(searched, rows[j % n], "{} on-demand rows: row {}", name, j);
            }
            for (form, got) in [
                (
                    "f32",
                    column_rows(&search, &FlatPoints::new(&flat32).unwrap()),
                ),
                (
                    "f64",
                    column_rows(&search, &FlatPoints::new(&flat64).unwrap()),
                ),
                (
                    "f32 run",
                    column_rows(&search, &FlatPoints::new(&flat32[..3 * n]).unwrap()),
                ),
                (
                    "calling-thread",
                    column_rows_with(&search, long.as_slice(), true),
                ),
                (
                    "calling-thread f32",
                    column_rows_with(&search, &FlatPoints::new(&flat32).unwrap(), true),
                ),
            ] {
                for (j, row) in got.into_iter().enumerate() {
                    prop_assert_eq!(row, rows[j % n], "{} {} rows: row {}", name, form, j);
                }
            }
        }
    }
    Ok(())
}

/// The rows `on_demand` answers for `points` (flat f32 coordinates or points), on the pool's
/// threads.
fn on_demand_rows<P: QueryPoints + ?Sized>(
    on_demand: &ClosestPointsOnDemand,
    points: &P,
) -> Vec<RowBits> {
    let n = points.count();
    let (mut q, mut d, mut k) = (vec![[0.0; 3]; n], vec![0.0; n], vec![0i64; n]);
    let (mut u, mut v) = (vec![0.0; n], vec![0.0; n]);
    let columns = ClosestPointColumns {
        point: &mut q,
        distance: &mut d,
        prim: &mut k,
        u: &mut u,
        v: &mut v,
    };
    on_demand.closest_points_into(points, columns);
    (0..n)
        .map(|i| row_bits((q[i], d[i], k[i], u[i], v[i])))
        .collect()
}

/// A row of `closest_points_into`'s columns (point, distance, prim, u, v), floats as bits.
type RowBits = ([u64; 3], u64, i64, u64, u64);

fn row_bits((q, d, k, u, v): ([f64; 3], f64, i64, f64, f64)) -> RowBits {
    (
        q.map(f64::to_bits),
        d.to_bits(),
        k,
        u.to_bits(),
        v.to_bits(),
    )
}

/// `search.closest_points_into(points)`, row by row.
fn column_rows<P: QueryPoints + ?Sized>(search: &ClosestPointTree, points: &P) -> Vec<RowBits> {
    column_rows_with(search, points, false)
}

/// [`column_rows`], or with `here` the calling-thread form `closest_points_into_here`.
fn column_rows_with<P: QueryPoints + ?Sized>(
    search: &ClosestPointTree,
    points: &P,
    here: bool,
) -> Vec<RowBits> {
    let n = points.count();
    let (mut point, mut distance) = (vec![[0.0; 3]; n], vec![0.0; n]);
    let (mut prim, mut u, mut v) = (vec![0i64; n], vec![0.0; n], vec![0.0; n]);
    let columns = ClosestPointColumns {
        point: &mut point,
        distance: &mut distance,
        prim: &mut prim,
        u: &mut u,
        v: &mut v,
    };
    if here {
        search.closest_points_into_here(points, columns);
    } else {
        search.closest_points_into(points, columns);
    }
    (0..n)
        .map(|i| row_bits((point[i], distance[i], prim[i], u[i], v[i])))
        .collect()
}

proptest! {
    #![proptest_config(common::cases(200))]

    #[test]
    fn soup_closest_point_equals_brute_force((mesh, points) in mesh_and_points(soup()), order in order(), leaf in 1usize..9) {
        assert_closest_points_agree(&mesh, order, leaf, &points)?;
    }

    /// Any leaf size of the search tree (one triangle to whole subtrees of 20), node boxes in
    /// rotated frames or not.
    #[test]
    fn closest_point_equals_brute_force_at_any_search_leaf_size((mesh, points) in mesh_and_points(soup()), order in order(), leaf in 1usize..9, search_leaf in 1usize..21, rotated_frames in any::<bool>(), grid in grid_config()) {
        let config = SearchTreeConfig { leaf_triangles: search_leaf, rotated_frames };
        assert_closest_points_agree_with(&mesh, order, leaf, config, grid, &points)?;
    }

    /// Rooms of large axis-aligned walls and boxes (the candidate grid's case: most cells list
    /// two to four triangles), with duplicated faces (exact ties: the smallest id wins),
    /// degenerate triangles and points on the grid's cell boundaries, the walls, their edges and
    /// corners.
    #[test]
    fn room_closest_point_equals_brute_force((mesh, points) in room_and_points(), order in order(), grid in grid_config()) {
        assert_closest_points_agree_with(&mesh, order, 4, SearchTreeConfig::default(), grid, &points)?;
    }

    /// Small triangles far from the origin (coordinates around 10⁷, where an f32 step is 1):
    /// the rounding of the f32 bounds and of the f64 test matters most.
    #[test]
    fn closest_point_equals_brute_force_far_from_the_origin((mesh, points) in mesh_and_points(far_soup()), order in order(), leaf in 1usize..9) {
        assert_closest_points_agree(&mesh, order, leaf, &points)?;
    }

    /// Tilted, gently waving sheets of many small triangles: the search tree gives their
    /// nodes rotated frames, whose bounds must stay conservative.
    #[test]
    fn tilted_sheet_closest_point_equals_brute_force((mesh, points) in mesh_and_points(tilted_sheet()), order in order(), leaf in 1usize..9) {
        assert_closest_points_agree(&mesh, order, leaf, &points)?;
    }

    /// A room with one detailed object: grids of every kind, the walls' cells answering from
    /// their lists and the object's seeding searches, against the brute force.
    #[test]
    fn room_with_an_object_closest_point_equals_brute_force((mesh, points) in mesh_and_points(room_with_object()), order in order(), grid in grid_config()) {
        assert_closest_points_agree_with(&mesh, order, 4, SearchTreeConfig::default(), grid, &points)?;
    }

    /// The counted search (`closest_points_tallied`, for profiling) gives the same answers,
    /// and counts at least one exact test for every point with an answer.
    #[test]
    fn tallied_search_gives_the_same_answers((mesh, points) in mesh_and_points(closed_mesh())) {
        let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
        let search = ClosestPointTree::new(&tree, &mesh);
        let as_f64: Vec<_> = points.iter().map(|p| p.as_dvec3()).collect();
        for (i, (got, tally)) in search.closest_points_tallied(&as_f64).into_iter().enumerate() {
            prop_assert_eq!(closest_point_brute_force(&mesh, as_f64[i]), got);
            let mut single = SearchTally::default();
            prop_assert_eq!(search.closest_point_tallied(as_f64[i], &mut single), got);
            if got.is_some() {
                prop_assert!(tally.exact >= 1 && single.exact >= 1 && single.nodes >= 1);
            }
        }
    }

    #[test]
    fn closed_mesh_closest_point_equals_brute_force((mesh, points) in mesh_and_points(closed_mesh()), order in order(), leaf in 1usize..9) {
        assert_closest_points_agree(&mesh, order, leaf, &points)?;
    }

    /// The BVH's vote equals brute force's vote (same rays, same parities), on closed meshes.
    #[test]
    fn closed_mesh_contains_equals_brute_force_parity((mesh, points) in mesh_and_points(closed_mesh())) {
        let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
        let bvh = Wide8Layout::new(&tree, &mesh);
        let reference = BruteForce::new(&mesh);
        for p in &points {
            prop_assert_eq!(contains(&reference, *p), contains(&bvh, *p), "{:?}", p);
        }
    }
}

/// A room of twelve large wall triangles with one detailed object inside (an icosphere of 80 or
/// 320 small triangles, anywhere from the middle to touching a wall), scaled and moved: the
/// candidate grid lists the walls' cells and seeds tree searches near the object.
fn room_with_object() -> impl Strategy<Value = TriangleMesh> {
    (
        prop_oneof![Just(1.0f32), scale()],
        prop_oneof![Just(Vec3::ZERO), point(10.0), point(1e6)],
        (0.05f32..0.95, 0.05f32..0.95, 0.05f32..0.95),
        prop_oneof![0.01f32..0.05, 0.05f32..0.45],
        1u32..3,
    )
        .prop_map(|(s, shift, (x, y, z), radius, subdivisions)| {
            let mut positions: Vec<Vec3> = (0..8)
                .map(|k| Vec3::new((k & 1) as f32, (k >> 1 & 1) as f32, (k >> 2 & 1) as f32))
                .collect();
            let mut faces: Vec<[u32; 3]> = vec![
                [0, 1, 3],
                [0, 3, 2],
                [4, 6, 7],
                [4, 7, 5],
                [0, 4, 5],
                [0, 5, 1],
                [2, 3, 7],
                [2, 7, 6],
                [0, 2, 6],
                [0, 6, 4],
                [1, 5, 7],
                [1, 7, 3],
            ];
            let object = icosphere(Vec3::new(x, y, z), radius, subdivisions);
            let base = positions.len() as u32;
            positions.extend_from_slice(object.positions());
            faces.extend(object.indices().iter().map(|t| t.map(|i| i + base)));
            let positions = positions.into_iter().map(|p| p * s + shift * s).collect();
            TriangleMesh::new(positions, faces).unwrap()
        })
}

/// An `n × n` grid of squares (two triangles each) over the unit square, waving by `wave` along
/// z, turned by a random rotation, scaled and moved.
fn tilted_sheet() -> impl Strategy<Value = TriangleMesh> {
    (
        scale(),
        point(1.0),
        -3.2f32..3.2,
        prop_oneof![Just(0.0f32), 0.0f32..0.05, 0.05f32..0.5],
        4u32..24,
        point(1.0),
    )
        .prop_map(|(s, axis, angle, wave, n, shift)| {
            let rotation =
                hbv::glam::Quat::from_axis_angle(axis.try_normalize().unwrap_or(Vec3::Z), angle);
            let mut positions = Vec::new();
            for i in 0..=n {
                for j in 0..=n {
                    let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                    let z = wave * (7.0 * x).sin() * (5.0 * y).cos();
                    positions.push((rotation * Vec3::new(x, y, z) + shift) * s);
                }
            }
            let at = |i: u32, j: u32| i * (n + 1) + j;
            let mut faces = Vec::new();
            for i in 0..n {
                for j in 0..n {
                    faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
            TriangleMesh::new(positions, faces).unwrap()
        })
}

/// A room as a modelled scene has it: an axis-aligned box of walls (two triangles each), one to
/// three axis-aligned blocks inside, some faces listed twice (exact ties), a degenerate
/// triangle, all scaled and moved (to huge coordinates too); and query points from a lattice
/// of eighths of the room (on walls, edges, corners, and on the boundaries of grids whose cells
/// divide the room evenly), a hair off them, random ones and far ones.
fn room_and_points() -> impl Strategy<Value = (TriangleMesh, Vec<Vec3>)> {
    let block = (point(0.8), 0.05f32..0.4, 0.05f32..0.4, 0.05f32..0.4);
    (
        prop_oneof![Just(1.0f32), scale()],
        prop_oneof![Just(Vec3::ZERO), point(10.0), point(1e7)],
        prop::collection::vec(block, 1..4),
        prop::collection::vec(0usize..40, 0..4),
        prop::collection::vec((0u32..9, 0u32..9, 0u32..9, 0usize..4), 1..40),
        prop::collection::vec(point(1.5), 0..8),
    )
        .prop_map(|(s, shift, blocks, doubled, lattice, random)| {
            let mut tris: Vec<[Vec3; 3]> = Vec::new();
            let mut cuboid = |lo: Vec3, hi: Vec3| {
                let c = |i: u32| {
                    Vec3::new(
                        if i & 1 == 0 { lo.x } else { hi.x },
                        if i & 2 == 0 { lo.y } else { hi.y },
                        if i & 4 == 0 { lo.z } else { hi.z },
                    )
                };
                for [a, b, d, e] in [
                    [0, 1, 3, 2],
                    [4, 6, 7, 5],
                    [0, 4, 5, 1],
                    [2, 3, 7, 6],
                    [0, 2, 6, 4],
                    [1, 5, 7, 3],
                ] {
                    tris.push([c(a), c(b), c(d)]);
                    tris.push([c(a), c(d), c(e)]);
                }
            };
            cuboid(Vec3::splat(-1.0), Vec3::splat(1.0));
            for (centre, x, y, z) in blocks {
                let half = Vec3::new(x, y, z);
                cuboid(centre - half, centre + half);
            }
            for k in doubled {
                let t = tris[k % tris.len()];
                tris.push(t);
            }
            tris.push([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
            let place = |v: Vec3| v * s + shift;
            let positions = tris.iter().flatten().map(|&v| place(v)).collect();
            let faces = (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            let mut points: Vec<Vec3> = lattice
                .into_iter()
                .map(|(i, j, k, nudge)| {
                    let p = place(Vec3::new(i as f32, j as f32, k as f32) * 0.25 - 1.0);
                    match nudge {
                        0 => p,
                        1 => Vec3::new(p.x.next_up(), p.y, p.z.next_down()),
                        2 => p + Vec3::splat(1e-4 * s),
                        _ => place(Vec3::new(i as f32, j as f32, k as f32) * 0.3 - 1.2),
                    }
                })
                .collect();
            points.extend(random.into_iter().map(place));
            points.push(place(Vec3::new(40.0, -3.0, 0.5)));
            (TriangleMesh::new(positions, faces).unwrap(), points)
        })
}

/// A soup of small triangles around `(1e7, -1e7, 3e6)`.
fn far_soup() -> impl Strategy<Value = TriangleMesh> {
    let corner = Vec3::new(1e7, -1e7, 3e6);
    let tri = (point(400.0), point(30.0), point(30.0)).prop_map(move |(a, b, c)| {
        let a = corner + a;
        [a, a + b, a + c]
    });
    prop::collection::vec(tri, 1..40).prop_map(|tris| {
        let positions = tris.iter().flatten().copied().collect();
        let faces = (0..tris.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        TriangleMesh::new(positions, faces).unwrap()
    })
}

/// A hand-made tree whose root has nine children (n-ary builders make such nodes): the search
/// tree groups them in fours and answers as the brute force does.
#[test]
fn closest_point_through_a_node_of_nine_children() {
    let mesh = icosphere(Vec3::new(0.25, 0.5, -1.0), 1.5, 2);
    let n = mesh.triangle_count() as u32;
    let mut tree = BuildTree::new();
    let leaves: Vec<_> = (0..9)
        .map(|k| {
            let prims: Vec<u32> = (k * n / 9..(k + 1) * n / 9).collect();
            let bounds = prims.iter().fold(Aabb::EMPTY, |b, &p| {
                let t = mesh.triangle(p as usize);
                b.union_point(t.p0).union_point(t.p1).union_point(t.p2)
            });
            tree.push_leaf(prims, bounds)
        })
        .collect();
    let root = tree.push_internal(leaves);
    tree.set_root(Some(root));
    for (leaf_triangles, rotated_frames) in [(1, true), (8, false), (8, true), (64, true)] {
        let config = SearchTreeConfig {
            leaf_triangles,
            rotated_frames,
        };
        let search = ClosestPointTree::with_config(&tree, &mesh, config);
        for i in 0..200 {
            let k = i as f32;
            let p = Vec3::new((k * 0.37).sin(), (k * 0.61).cos(), (k * 0.13).sin()) * 3.0;
            assert_eq!(
                search.closest_point(p),
                closest_point_brute_force(&mesh, p.as_dvec3()),
                "{p:?}"
            );
        }
    }
}

/// Points well inside and well outside a sphere (away from the polygonal surface) are
/// classified by geometry.
#[test]
fn contains_matches_a_sphere() {
    let mesh = icosphere(Vec3::new(0.5, -0.25, 2.0), 2.0, 3);
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let bvh = Wide8Layout::new(&tree, &mesh);
    let centre = Vec3::new(0.5, -0.25, 2.0);
    let mut checked = 0;
    for i in 0..20 {
        for j in 0..20 {
            for k in 0..20 {
                let p = centre + (Vec3::new(i as f32, j as f32, k as f32) / 19.0 - 0.5) * 5.0;
                let r = (p - centre).length();
                if r < 1.8 {
                    assert!(contains(&bvh, p), "{p:?} (r = {r}) should be inside");
                    checked += 1;
                } else if r > 2.01 {
                    assert!(!contains(&bvh, p), "{p:?} (r = {r}) should be outside");
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 7000);
}

/// A sphere of radius 1.9 and points around it, and the same scaled by 2^126 (exactly: a radius
/// of 1.6e38, within the range a mesh may have): every point is classified alike. A unit
/// direction meets the big sphere's far side at `t` beyond `f32::MAX` from most of the points;
/// the inside test dropped that crossing, and points outside came out inside (a new user's
/// sweep).
#[test]
fn contains_is_the_same_at_the_top_of_the_f32_range() {
    let scale = 2f32.powi(126);
    let small = icosphere(Vec3::ZERO, 1.9, 2);
    let big = TriangleMesh::new(
        small.positions().iter().map(|&p| p * scale).collect(),
        small.indices().to_vec(),
    )
    .unwrap();
    let layout = |m: &TriangleMesh| {
        Wide8Layout::new(
            &BinnedSahBuilder::new(BinnedSahConfig::default()).build(m),
            m,
        )
    };
    let (small_bvh, big_bvh) = (layout(&small), layout(&big));
    let (mut inside, mut outside) = (0, 0);
    for i in 0..16 {
        for j in 0..16 {
            for k in 0..16 {
                let p = (Vec3::new(i as f32, j as f32, k as f32) / 15.0 - 0.5) * 5.0;
                let expected = contains(&small_bvh, p);
                assert_eq!(contains(&big_bvh, p * scale), expected, "{p:?}");
                if expected {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
    }
    assert!(
        inside > 500 && outside > 1500,
        "{inside} inside, {outside} outside"
    );
}

/// A cube and grid points: rays from the centre and from symmetric points must not be fooled
/// by the diagonals and edges that axis-aligned meshes line up with.
#[test]
fn contains_is_not_fooled_by_a_cube_s_edges() {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let positions = vec![
        v(-1.0, -1.0, -1.0),
        v(1.0, -1.0, -1.0),
        v(1.0, 1.0, -1.0),
        v(-1.0, 1.0, -1.0),
        v(-1.0, -1.0, 1.0),
        v(1.0, -1.0, 1.0),
        v(1.0, 1.0, 1.0),
        v(-1.0, 1.0, 1.0),
    ];
    let faces = vec![
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [2, 3, 7],
        [2, 7, 6],
        [1, 2, 6],
        [1, 6, 5],
        [0, 4, 7],
        [0, 7, 3],
    ];
    let mesh = TriangleMesh::new(positions, faces).unwrap();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let bvh = Wide8Layout::new(&tree, &mesh);
    for i in -4..=4 {
        for j in -4..=4 {
            for k in -4..=4 {
                let p = Vec3::new(i as f32, j as f32, k as f32) * 0.25;
                let on_surface = p.abs().max_element() == 1.0;
                if !on_surface {
                    let inside = p.abs().max_element() < 1.0;
                    assert_eq!(contains(&bvh, p), inside, "{p:?}");
                }
            }
        }
    }
    let far = Vec3::new(3.0, 0.0, 0.0);
    assert!(!contains(&bvh, far));
}

#[test]
fn closest_point_on_a_torus_is_on_its_tube() {
    let mesh = torus(Vec3::ZERO, 2.0, 0.5, 48, 24);
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let search = ClosestPointTree::new(&tree, &mesh);
    let hit = search.closest_point(Vec3::new(5.0, 0.0, 0.0)).unwrap();
    assert!((hit.distance - 2.5).abs() < 0.01, "{hit:?}");
    let t = mesh.triangle(hit.prim as usize);
    let back =
        (1.0 - hit.u - hit.v) * t.p0.as_dvec3() + hit.u * t.p1.as_dvec3() + hit.v * t.p2.as_dvec3();
    assert!((back - hit.point).length() < 1e-12);
    assert!(search.closest_point(Vec3::NAN).is_none());
    let empty = TriangleMesh::new(vec![], vec![]).unwrap();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&empty);
    assert!(ClosestPointTree::new(&tree, &empty)
        .closest_point(DVec3::ZERO)
        .is_none());
}

/// The deterministic runner's first room of [`room_and_points`], and its SAH tree.
fn a_room() -> (TriangleMesh, hbv::bvh::BuildTree) {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let (mesh, _) = room_and_points().new_tree(&mut runner).unwrap().current();
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    (mesh, tree)
}

/// The grid is made once the points asked for reach `payback` per cell, counting the batch
/// that reaches it, and the answers are the brute force's before and after.
#[test]
fn the_grid_is_made_once_enough_points_are_asked_for() {
    let (mesh, tree) = a_room();
    let config = CandidateGridConfig {
        cells: 512,
        payback: 2.0,
        ..CandidateGridConfig::default()
    };
    let search = ClosestPointTree::with_grid(&tree, &mesh, SearchTreeConfig::default(), config);
    let b = mesh.bounds();
    let points: Vec<DVec3> = (0..1100)
        .map(|i| {
            let t = Vec3::new(
                (i % 11) as f32 / 10.0,
                (i / 11 % 10) as f32 / 9.0,
                (i / 110) as f32 / 9.0,
            );
            (b.min - (b.max - b.min) * 0.2 + (b.max - b.min) * 1.4 * t).as_dvec3()
        })
        .collect();
    let agree = |found: Vec<Option<ClosestPoint>>, points: &[DVec3]| {
        for (p, got) in points.iter().zip(found) {
            assert_eq!(got, closest_point_brute_force(&mesh, *p), "{p:?}");
        }
    };
    // 1,000 points of the 1,024 the grid waits for: searched without it.
    agree(search.closest_points(&points[..1000]), &points[..1000]);
    assert_eq!(search.grid_summary(), (0, 0, 0));
    // Single queries count too, and the 24th more makes it.
    for p in &points[1000..1023] {
        agree(vec![search.closest_point(*p)], &[*p]);
    }
    assert_eq!(search.grid_summary(), (0, 0, 0));
    agree(search.closest_points(&points[1023..]), &points[1023..]);
    let (cells, listing, _) = search.grid_summary();
    assert!(
        cells >= 512 && listing > 0,
        "{cells} cells, {listing} listing"
    );
    agree(search.closest_points(&points), &points);
}

/// On a room of large walls most cells of the default grid list their candidates (the fast
/// path is the one exercised), and a lattice of points through walls, edges, corners and
/// cell boundaries gets the brute force's answers.
#[test]
fn room_grid_lists_candidates_and_agrees() {
    let (mesh, tree) = a_room();
    let at_once = CandidateGridConfig {
        payback: 0.0,
        ..CandidateGridConfig::default()
    };
    let search = ClosestPointTree::with_grid(&tree, &mesh, SearchTreeConfig::default(), at_once);
    let (cells, listing, _) = search.grid_summary();
    assert!(
        cells > 20_000 && listing * 10 > cells * 8,
        "{cells} cells, {listing} listing"
    );
    let b = mesh.bounds();
    for i in 0..=32 {
        for j in 0..=32 {
            for k in [0, 5, 16, 31, 32] {
                let t = Vec3::new(i as f32, j as f32, k as f32) / 32.0;
                let p = b.min - (b.max - b.min) * 0.25 + (b.max - b.min) * 1.5 * t;
                assert_eq!(
                    search.closest_point(p),
                    closest_point_brute_force(&mesh, p.as_dvec3()),
                    "{p:?}"
                );
            }
        }
    }
}
