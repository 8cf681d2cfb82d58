"""Queries against float64 brute force: closest hit, all hits, counts, inside, closest point."""

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays
from reference import closest_on_triangles, nondegenerate, ray_triangle_t


def triangles_of(v, f):
    return v.astype(np.float32).astype(np.float64)[f]


def rays_and_brute_force(v, f, n, seed=2):
    """`n` random rays (rounded to float32, held as float64) and brute force's t of every ray
    against every non-degenerate triangle (NaN: no hit)."""
    tris = triangles_of(v, f)
    o, d = random_rays(n, seed=seed)
    o, d = o.astype(np.float32).astype(np.float64), d.astype(np.float32).astype(np.float64)
    t_all = ray_triangle_t(tris, o, d)
    t_all[:, ~nondegenerate(tris)] = np.nan
    return tris, o, d, t_all


def test_closest_hit_matches_brute_force(triangle_soup):
    mesh, v, f = triangle_soup
    tris, o, d, t_all = rays_and_brute_force(v, f, 400)
    h = hbv.BVH(mesh).intersect(o, d)
    ref_hit = ~np.all(np.isnan(t_all), axis=1)
    np.testing.assert_array_equal(h["hit"], ref_hit)
    best = np.nanmin(np.where(ref_hit[:, None], t_all, np.inf), axis=1)
    np.testing.assert_allclose(h["t"][ref_hit], best[ref_hit], rtol=1e-5, atol=1e-6)
    # The triangle: brute force's, unless another lies within rounding of the same t.
    second = np.sort(np.where(np.isnan(t_all), np.inf, t_all), axis=1)[:, 1]
    with np.errstate(invalid="ignore"):
        clear = ref_hit & (second - best > 1e-4 * np.abs(best) + 1e-6)
    np.testing.assert_array_equal(h["prim"][clear], np.nanargmin(t_all[clear], axis=1))
    # The barycentrics give the hit point.
    tri = tris[h["prim"][ref_hit]]
    u, vv = h["u"][ref_hit, None], h["v"][ref_hit, None]
    point = (1 - u - vv) * tri[:, 0] + u * tri[:, 1] + vv * tri[:, 2]
    along = o[ref_hit] + d[ref_hit] * h["t"][ref_hit, None]
    assert np.abs(point - along).max() < 1e-4


def test_per_ray_intervals_match_brute_force(triangle_soup):
    # More rays than one run of the batch loop (256), on one thread and on all, with each bound
    # a scalar or per ray, float32 or float64: every ray gets its own interval.
    mesh, v, f = triangle_soup
    tris, o, d, t_all = rays_and_brute_force(v, f, 1500, seed=9)
    rng = np.random.default_rng(3)
    tmin = rng.uniform(0, 2, len(o)).astype(np.float32)
    tmax = (tmin + rng.uniform(0, 3, len(o))).astype(np.float32)
    bvh = hbv.BVH(mesh)
    for lo, hi in [(tmin, tmax), (tmin.astype(np.float64), None), (0.5, tmax.astype(np.float64))]:
        lo_ray = np.broadcast_to(np.float32(0.0 if lo is None else lo), len(o)).astype(np.float64)
        hi_ray = np.broadcast_to(np.float32(np.inf if hi is None else hi), len(o)).astype(np.float64)
        with np.errstate(invalid="ignore"):
            inside = np.where((t_all >= lo_ray[:, None]) & (t_all <= hi_ray[:, None]), t_all, np.nan)
        # Leave out rays with a hit within rounding of either end of their interval.
        with np.errstate(invalid="ignore"):
            near_end = np.any((np.abs(t_all - lo_ray[:, None]) < 1e-4)
                              | (np.abs(t_all - hi_ray[:, None]) < 1e-4), axis=1)
        ref_hit = ~np.all(np.isnan(inside), axis=1)
        for threads in [1, None]:
            h = bvh.intersect(o, d, tmin=lo, tmax=hi, threads=threads)
            np.testing.assert_array_equal(h["hit"][~near_end], ref_hit[~near_end])
            best = np.nanmin(np.where(ref_hit[:, None], inside, np.inf), axis=1)
            ok = ref_hit & ~near_end
            np.testing.assert_allclose(h["t"][ok], best[ok], rtol=1e-5, atol=1e-6)
            np.testing.assert_array_equal(bvh.occluded(o, d, tmin=lo, tmax=hi, threads=threads),
                                          h["hit"])
        assert 0.1 < ref_hit.mean() < 0.9


def test_all_hits_and_counts_match_brute_force(triangle_soup):
    mesh, v, f = triangle_soup
    tris, o, d, t_all = rays_and_brute_force(v, f, 300, seed=5)
    bvh = hbv.BVH(mesh)
    ray, t, prim = bvh.intersect_all(o, d)
    counts = bvh.count(o, d)
    assert counts.sum() == len(ray)
    np.testing.assert_array_equal(np.bincount(ray, minlength=len(o)), counts)
    # Sorted by ray, then by t.
    assert np.all(np.diff(ray) >= 0)
    same = ray[1:] == ray[:-1]
    assert np.all(t[1:][same] >= t[:-1][same])
    # Against brute force: the same set of triangles per ray, away from edges (where the
    # float64 reference may disagree with the exact test about a graze).
    ref = [set(np.flatnonzero(~np.isnan(row))) for row in t_all]
    got = [set() for _ in range(len(o))]
    for r, p in zip(ray, prim):
        got[r].add(int(p))
    differing = sum(a != b for a, b in zip(ref, got))
    assert differing <= 2, differing
    # Each reported hit is where the reference puts it.
    np.testing.assert_allclose(t, t_all[ray, prim], rtol=1e-4, atol=1e-6)
    # Every closest hit is the first of the ray's list.
    first = np.r_[True, ~same]
    h = bvh.intersect(o, d)
    np.testing.assert_array_equal(h["t"][ray[first]], t[first])


def test_contains_matches_a_parity_count_and_geometry(sphere):
    mesh, v, f = sphere
    bvh = hbv.BVH(mesh)
    rng = np.random.default_rng(3)
    points = rng.uniform(-1.3, 1.3, (2000, 3))
    r = np.linalg.norm(points, axis=1)
    far = (r < 0.95) | (r > 1.0)
    inside = bvh.contains(points)
    np.testing.assert_array_equal(inside[far], r[far] < 0.95)
    # A parity count along one generic direction, from the hit counts.
    d = np.tile([0.31, -0.52, 0.79], (len(points), 1))
    parity = bvh.count(points, d) % 2 == 1
    assert (parity != inside).sum() <= 2


def test_contains_on_grid_points_of_a_cube():
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    bvh = hbv.BVH(hbv.Mesh(v, f))
    g = np.linspace(-1.5, 1.5, 13)
    points = np.array(np.meshgrid(g, g, g)).reshape(3, -1).T
    m = np.abs(points).max(1)
    off = m != 1.0
    np.testing.assert_array_equal(bvh.contains(points)[off], m[off] < 1.0)


CUBE_V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
CUBE_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def test_open_edges_count_holes_by_position(sphere):
    mesh, v, f = sphere
    assert mesh.open_edges == 0 and mesh.is_closed
    cube = hbv.Mesh(CUBE_V, CUBE_F)
    assert cube.open_edges == 0 and cube.is_closed
    # One face (two triangles) gone: its square rim is open.
    holed = hbv.Mesh(CUBE_V, CUBE_F[2:])
    assert holed.open_edges == 4 and not holed.is_closed
    # Every triangle with its own three corners (as files with per-face normals have):
    # vertices are compared by position, so the cube is still closed.
    split = hbv.Mesh(CUBE_V[CUBE_F.ravel()], np.arange(36).reshape(12, 3))
    assert len(split.vertices) == 36 and split.is_closed
    # Degenerate triangles are never crossed, and do not open a mesh.
    assert hbv.Mesh(CUBE_V, np.vstack([CUBE_F, [[0, 1, 1]]])).is_closed
    assert hbv.Mesh(np.zeros((0, 3)), np.zeros((0, 3), int)).is_closed


def test_contains_warns_on_open_meshes_only(sphere):
    import warnings

    points = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    closed = hbv.BVH(sphere[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(closed.contains(points), [True, False])
        hbv.Grid(sphere[0]).contains(points)
    holed = hbv.Mesh(CUBE_V, CUBE_F[2:])
    for structure in (hbv.BVH(holed), hbv.Grid(holed)):
        with pytest.warns(RuntimeWarning, match=r"not closed \(4 open edges"):
            structure.contains(points)
    # A bad argument is refused before any warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError):
            hbv.BVH(holed).contains(np.zeros((2, 2)))


def test_closest_point_matches_float64_brute_force(triangle_soup):
    mesh, v, f = triangle_soup
    tris = triangles_of(v, f)
    keep = nondegenerate(tris)
    rng = np.random.default_rng(4)
    points = np.r_[rng.uniform(-2, 2, (150, 3)), v[:20].astype(np.float32), [[50.0, -3.0, 2.0]]]
    got = hbv.BVH(mesh).closest_point(points)
    assert got["point"].dtype == np.float64 and got["prim"].dtype == np.int64
    for i, p in enumerate(points):
        q = closest_on_triangles(p, tris)
        dist = np.where(keep, np.linalg.norm(q - p, axis=1), np.inf)
        j = int(np.argmin(dist))
        assert abs(got["distance"][i] - dist[j]) <= 1e-12 * max(1.0, dist[j]), i
        if np.sort(dist)[1] - dist[j] > 1e-9:
            assert got["prim"][i] == j
            np.testing.assert_allclose(got["point"][i], q[j], atol=1e-12)
    # The barycentrics reproduce the point.
    tri = tris[got["prim"]]
    u, w = got["u"][:, None], got["v"][:, None]
    np.testing.assert_allclose((1 - u - w) * tri[:, 0] + u * tri[:, 1] + w * tri[:, 2], got["point"], atol=1e-12)


def test_closest_point_reads_every_array_layout_alike():
    """float32 and float64, C-ordered (read in place), Fortran-ordered, strided and integer
    points give the same answers, and a wrong shape a clear error."""
    v, f = icosphere(2, radius=1.0)
    bvh = hbv.BVH(hbv.Mesh(v, f))
    rng = np.random.default_rng(9)
    p32 = rng.uniform(-2, 2, (300, 3)).astype(np.float32)
    want = bvh.closest_point(p32.astype(np.float64))
    wide = np.zeros((300, 6), np.float32)
    wide[:, ::2] = p32
    for layout in [p32, np.asfortranarray(p32), wide[:, ::2], p32.astype(np.float64).T.copy().T]:
        got = bvh.closest_point(layout)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
    # float64 points keep their precision whatever the layout (a copy is float64 too).
    p64 = rng.uniform(-2, 2, (300, 3))
    want = bvh.closest_point(p64)
    wide64 = np.zeros((300, 6))
    wide64[:, ::2] = p64
    for layout in [np.asfortranarray(p64), wide64[:, ::2], p64.tolist()]:
        got = bvh.closest_point(layout)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
    whole = np.array([[1, 2, 0], [0, 0, 3]], dtype=np.int32)
    np.testing.assert_array_equal(bvh.closest_point(whole)["prim"], bvh.closest_point(whole.astype(np.float64))["prim"])
    with pytest.raises((TypeError, ValueError)):
        bvh.closest_point(np.zeros((4, 2), np.float32))


def test_closest_point_on_a_sphere():
    v, f = icosphere(4, radius=2.0, center=(1.0, 0.0, -1.0))
    bvh = hbv.BVH(hbv.Mesh(v, f))
    rng = np.random.default_rng(6)
    points = rng.normal(size=(500, 3)) * 3 + [1.0, 0.0, -1.0]
    got = bvh.closest_point(points, threads=2)
    r = np.linalg.norm(points - [1.0, 0.0, -1.0], axis=1)
    assert np.abs(got["distance"] - np.abs(r - 2.0)).max() < 0.01


def test_signed_distance_is_the_distance_negative_inside():
    v, f = icosphere(4, radius=2.0, center=(1.0, 0.0, -1.0))
    bvh = hbv.BVH(hbv.Mesh(v, f))
    rng = np.random.default_rng(8)
    points = rng.normal(size=(3000, 3)) * 2 + [1.0, 0.0, -1.0]
    signed = bvh.signed_distance(points, threads=2)
    assert signed.dtype == np.float64 and signed.shape == (3000,)
    # Its magnitude is closest_point's distance, its sign contains' answer, exactly.
    np.testing.assert_array_equal(np.abs(signed), bvh.closest_point(points)["distance"])
    np.testing.assert_array_equal(signed < 0, bvh.contains(points) & (signed != 0))
    # And close to the sphere's own signed distance (the mesh is an inscribed polyhedron).
    r = np.linalg.norm(points - [1.0, 0.0, -1.0], axis=1)
    assert np.abs(signed - (r - 2.0)).max() < 0.02
    # No answer: a non-finite point; an empty list of points.
    assert bvh.signed_distance(np.array([[np.nan, 0.0, 0.0]]))[0] == np.inf
    assert bvh.signed_distance(np.zeros((0, 3))).shape == (0,)


def test_signed_distance_warns_on_open_meshes(sphere):
    mesh, v, f = sphere
    bvh = hbv.BVH(hbv.Mesh(v, f[1:]))
    with pytest.warns(RuntimeWarning):
        signed = bvh.signed_distance(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]]))
    assert signed[0] < 0 < signed[1]


def test_closest_point_is_the_same_on_any_tree_and_thread_count():
    """Exact answers do not depend on the tree, the thread count or the batch's order: clustered
    points (neighbours in the batch seed each other) and points a hair off the surface, on an
    icosphere, equal across builders, leaf sizes and threads, and the float64 brute force on a
    sample."""
    v, f = icosphere(3, radius=1.5, center=(0.25, -0.5, 2.0))
    mesh = hbv.Mesh(v, f)
    rng = np.random.default_rng(8)
    centre = np.array([0.25, -0.5, 2.0])
    directions = rng.normal(size=(1500, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    near_surface = centre + directions * (1.5 + rng.uniform(-1e-4, 1e-4, (1500, 1)))
    cluster = rng.normal(size=(1500, 3)) * 1e-3 + [1.0, 0.5, 2.5]
    spread = rng.uniform(-3, 3, (1500, 3)) + centre
    points = np.r_[near_surface, cluster, spread]
    want = hbv.BVH(mesh).closest_point(points, threads=1)
    for bvh, threads in [
        (hbv.BVH(mesh), None),
        (hbv.BVH(mesh), 3),
        (hbv.BVH(mesh, builder="insertion", leaf_size=1), None),
        (hbv.BVH(mesh, leaf_size=32), 2),
    ]:
        got = bvh.closest_point(points, threads=threads)
        for key in ("point", "distance", "prim", "u", "v"):
            np.testing.assert_array_equal(got[key], want[key], err_msg=key)
    # A fresh BVH walks its own tree for its first points (32 √triangles: 1,144 here),
    # then makes the search tree in the call that would pass that count: calls of 40 points
    # (on one thread and on all), then the rest; the same answers throughout.
    fresh = hbv.BVH(mesh)
    for start, threads in [(0, 1), (40, None), (80, 1), (120, None)]:
        got = fresh.closest_point(points[start:start + 40], threads=threads)
        for key in ("point", "distance", "prim", "u", "v"):
            np.testing.assert_array_equal(got[key], want[key][start:start + 40], err_msg=key)
    got = fresh.closest_point(points)
    for key in ("point", "distance", "prim", "u", "v"):
        np.testing.assert_array_equal(got[key], want[key], err_msg=key)
    tris = triangles_of(mesh.vertices, f)
    for i in rng.choice(len(points), 100, replace=False):
        dist = np.linalg.norm(closest_on_triangles(points[i], tris) - points[i], axis=1)
        assert abs(want["distance"][i] - dist.min()) <= 1e-12 * max(1.0, dist.min()), i


def test_closest_point_in_a_room_of_large_walls():
    """A room of axis-aligned walls (the candidate grid's case: cells list the few triangles
    that can be nearest), with one face listed twice (exact ties go to the smaller id): lattice
    points on walls, edges, corners and in between, far points and a NaN point, against the
    float64 brute force."""
    corners = np.array([[x, y, z] for z in (-1.0, 1.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    faces = [[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads]
    block = corners * [0.2, 0.3, 0.25] + [0.3, -0.4, 0.1]
    faces += [[i + 8 for i in t] for t in faces]
    faces.append(faces[3])
    v = np.r_[corners, block] * 3.5 + [10.0, -2.0, 0.5]
    mesh = hbv.Mesh(v, np.array(faces))
    lattice = np.stack(np.meshgrid(*[np.linspace(-1.25, 1.25, 11)] * 3), -1).reshape(-1, 3)
    points = np.r_[lattice * 3.5 + [10.0, -2.0, 0.5], [[80.0, 1.0, 2.0], [np.nan, 0.0, 0.0]]]
    tris = triangles_of(v, np.array(faces))
    got = hbv.BVH(mesh).closest_point(points, threads=2)
    assert got["prim"][-1] == -1 and np.isinf(got["distance"][-1]) and np.isnan(got["point"][-1]).all()
    for i, p in enumerate(points[:-1]):
        dist = np.linalg.norm(closest_on_triangles(p, tris) - p, axis=1)
        j = int(np.argmin(dist))
        assert abs(got["distance"][i] - dist[j]) <= 1e-12 * max(1.0, dist[j]), i
        if np.sort(dist)[1] - dist[j] > 1e-9:
            assert got["prim"][i] == j, i
    # Points whose nearest feature is only on the duplicated face never name the copy.
    assert not (got["prim"] == len(faces) - 1).any()
    # The same answers on one thread and on all.
    bvh = hbv.BVH(mesh)
    again = bvh.closest_point(points, threads=1)
    np.testing.assert_array_equal(again["prim"], got["prim"])
    np.testing.assert_array_equal(again["distance"], got["distance"])
    # And once enough points have been asked for that the candidate grid is made (131,072
    # for the default grid, the batch that reaches it included), the same answers from it.
    rng = np.random.default_rng(5)
    bvh.closest_point(v.min(0) - 1.0 + (v.max(0) - v.min(0) + 2.0) * rng.random((140_000, 3)))
    from_grid = bvh.closest_point(points)
    for key in ("point", "distance", "prim", "u", "v"):
        np.testing.assert_array_equal(from_grid[key], got[key])
