"""hbv.open3d.RaycastingScene: every method against a float64 brute force in NumPy, on small
random meshes with one geometry (an hbv.BVH answers) and several (an hbv.Scene answers); its
argument checks; and, where Open3D is installed, call by call against
open3d.t.geometry.RaycastingScene on the same meshes, rays and points."""

import subprocess
import sys

import numpy as np
import pytest

import hbv
from hbv.open3d import INVALID_ID, RaycastingScene

from conftest import icosphere, soup
from reference import closest_on_triangles, nondegenerate

try:
    import open3d as o3d
except ImportError:  # the parity tests skip, with the reason
    o3d = None

needs_open3d = pytest.mark.skipif(
    o3d is None, reason="open3d is not importable (pip install open3d-cpu): parity tests skipped"
)


def lumpy_sphere(seed, center=(0.0, 0.0, 0.0), radius=1.0):
    """A closed, star-shaped mesh: an icosphere with random radii (float32 vertices)."""
    v, f = icosphere(2)
    radii = np.random.default_rng(seed).uniform(0.7, 1.1, (len(v), 1)) * radius
    return (v * radii + np.asarray(center)).astype(np.float32), f


def random_soup(seed, n=120, offset=(0.0, 0.0, 0.0)):
    v, f = soup(n, seed)
    return (v + np.asarray(offset)).astype(np.float32), f


#: Geometry lists: one (a BVH answers) and several (a Scene answers).
OPEN_SETS = {
    "one": lambda: [random_soup(1)],
    "several": lambda: [random_soup(2), lumpy_sphere(3, (0.5, 0.2, 0.1), 0.6), random_soup(4, 60, (0.3, -0.4, 0))],
}
CLOSED_SETS = {
    "one": lambda: [lumpy_sphere(5)],
    "several": lambda: [lumpy_sphere(6, (-0.8, 0, 0), 0.6), lumpy_sphere(7, (0.9, 0.1, 0), 0.7)],
}


def scene_of(geometries):
    scene = RaycastingScene()
    for expected_id, (v, f) in enumerate(geometries):
        assert scene.add_triangles(v, f) == expected_id
    return scene


def rays_and_points(seed, n=300, spread=1.6):
    rng = np.random.default_rng(seed)
    origins = rng.uniform(-spread, spread, (n, 3))
    directions = rng.normal(size=(n, 3))
    rays = np.hstack([origins, directions]).astype(np.float32)
    points = rng.uniform(-spread, spread, (n, 3)).astype(np.float32)
    return rays, points


class BruteRays:
    """Every ray against every triangle of every geometry, in float64 (Möller & Trumbore)."""

    def __init__(self, geometries, rays):
        tris = [v.astype(np.float64)[f] for v, f in geometries]
        self.geometry = np.concatenate([np.full(len(t), g) for g, t in enumerate(tris)])
        self.prim = np.concatenate([np.arange(len(t)) for t in tris])
        tris = np.concatenate(tris)
        o, d = rays[:, :3].astype(np.float64), rays[:, 3:].astype(np.float64)
        p0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
        normal = np.cross(e1, e2)
        det = -np.einsum("rk,tk->rt", d, normal)
        s = o[:, None, :] - p0[None]
        with np.errstate(divide="ignore", invalid="ignore"):
            self.t = np.einsum("rtk,tk->rt", s, normal) / det
            self.u = -np.einsum("rk,rtk->rt", d, np.cross(s, e2[None])) / det
            self.v = -np.einsum("rk,rtk->rt", d, np.cross(e1[None], s)) / det
        w = 1 - self.u - self.v
        margin = np.minimum(np.minimum(self.u, self.v), w)
        self.hit = (det != 0) & (margin >= 0) & (self.t >= 0)
        # Rays that pass within rounding of an edge, or start within rounding of a plane,
        # may go either way: compared only where no triangle is that close.
        near = ((np.abs(margin) < 1e-4) | (np.abs(self.t) < 1e-4)) & (det != 0)
        self.clear = ~near.any(axis=1)
        self.normals = normal / np.linalg.norm(normal, axis=1, keepdims=True).clip(1e-300)

    def closest(self):
        t = np.where(self.hit, self.t, np.inf)
        order = np.argsort(t, axis=1, kind="stable")
        first = order[:, 0]
        rows = np.arange(len(t))
        t_sorted = np.take_along_axis(t, order, axis=1)
        gap = np.full(len(t), np.inf)
        if t.shape[1] > 1:
            second = np.isfinite(t_sorted[:, 1])
            gap[second] = t_sorted[second, 1] - t_sorted[second, 0]
        return first, t[rows, first], gap > 1e-4


def test_import_of_hbv_does_not_import_open3d():
    code = "import sys, hbv; hbv.open3d.RaycastingScene(); assert 'open3d' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("kind", ["one", "several"])
def test_cast_rays_matches_brute_force(kind):
    geometries = OPEN_SETS[kind]()
    scene = scene_of(geometries)
    rays, _ = rays_and_points(10)
    answer = scene.cast_rays(rays)
    brute = BruteRays(geometries, rays)
    first, t, unambiguous = brute.closest()
    hit = np.isfinite(t)
    assert answer["t_hit"].dtype == np.float32 and answer["t_hit"].shape == (len(rays),)
    for key in ("geometry_ids", "primitive_ids"):
        assert answer[key].dtype == np.uint32
    ok = brute.clear
    np.testing.assert_array_equal(np.isfinite(answer["t_hit"])[ok], hit[ok])
    np.testing.assert_allclose(answer["t_hit"][ok & hit], t[ok & hit], rtol=1e-5, atol=1e-6)
    assert np.all(answer["t_hit"][ok & ~hit] == np.inf)
    sure = ok & hit & unambiguous
    assert sure.sum() > 50
    np.testing.assert_array_equal(answer["geometry_ids"][sure], brute.geometry[first[sure]])
    np.testing.assert_array_equal(answer["primitive_ids"][sure], brute.prim[first[sure]])
    rows = np.flatnonzero(sure)
    np.testing.assert_allclose(
        answer["primitive_uvs"][sure],
        np.stack([brute.u[rows, first[sure]], brute.v[rows, first[sure]]], axis=1),
        atol=1e-4,
    )
    np.testing.assert_allclose(answer["primitive_normals"][sure], brute.normals[first[sure]], atol=1e-5)
    missed = ok & ~hit
    assert np.all(answer["geometry_ids"][missed] == INVALID_ID)
    assert np.all(answer["primitive_ids"][missed] == INVALID_ID)
    assert np.all(answer["primitive_uvs"][missed] == 0)
    assert np.all(answer["primitive_normals"][missed] == 0)


@pytest.mark.parametrize("kind", ["one", "several"])
def test_occlusions_counts_and_lists_match_brute_force(kind):
    geometries = OPEN_SETS[kind]()
    scene = scene_of(geometries)
    rays, _ = rays_and_points(11)
    brute = BruteRays(geometries, rays)
    ok = brute.clear
    for tnear, tfar in [(0.0, np.inf), (0.3, 1.2)]:
        occluded = scene.test_occlusions(rays, tnear=tnear, tfar=tfar)
        expected = (brute.hit & (brute.t >= tnear) & (brute.t <= tfar)).any(axis=1)
        away = ok & ~((np.abs(brute.t - tnear) < 1e-4) | (np.abs(brute.t - tfar) < 1e-4)).any(axis=1)
        assert occluded.dtype == np.bool_
        np.testing.assert_array_equal(occluded[away], expected[away])
    counts = scene.count_intersections(rays)
    assert counts.dtype == np.int32
    np.testing.assert_array_equal(counts[ok], brute.hit.sum(axis=1)[ok])

    listed = scene.list_intersections(rays)
    splits = listed["ray_splits"]
    assert splits.dtype == np.uint32 and splits.shape == (len(rays) + 1,)
    assert splits[0] == 0 and splits[-1] == len(listed["t_hit"])
    np.testing.assert_array_equal(np.diff(splits.astype(np.int64)), counts)
    for key in ("ray_ids", "geometry_ids", "primitive_ids"):
        assert listed[key].dtype == np.uint32
    assert listed["primitive_uvs"].shape == (len(listed["t_hit"]), 2)
    for r in np.flatnonzero(ok)[:200]:
        rows = slice(splits[r], splits[r + 1])
        assert np.all(listed["ray_ids"][rows] == r)
        got = sorted(zip(listed["geometry_ids"][rows].tolist(), listed["primitive_ids"][rows].tolist()))
        hits = np.flatnonzero(brute.hit[r])
        assert got == sorted(zip(brute.geometry[hits].tolist(), brute.prim[hits].tolist()))
        key = {(g, p): k for k, (g, p) in enumerate(zip(brute.geometry[hits], brute.prim[hits]))}
        for g, p, t, uv in zip(
            listed["geometry_ids"][rows], listed["primitive_ids"][rows], listed["t_hit"][rows], listed["primitive_uvs"][rows]
        ):
            k = hits[key[(g, p)]]
            assert t == pytest.approx(brute.t[r, k], rel=1e-5, abs=1e-6)
            np.testing.assert_allclose(uv, [brute.u[r, k], brute.v[r, k]], atol=1e-4)


def brute_closest(geometries, points):
    """(distance, geometry, prim, point, gap to the next) of the nearest non-degenerate
    triangle of each point (hbv leaves degenerate ones out of nearest-point queries), float64."""
    best = []
    for p in points.astype(np.float64):
        candidates = []
        for g, (v, f) in enumerate(geometries):
            tris = v.astype(np.float64)[f]
            q = closest_on_triangles(p, tris)
            d = np.where(nondegenerate(tris), np.linalg.norm(q - p, axis=1), np.inf)
            i = int(np.argmin(d))
            candidates.append((d[i], g, i, q[i], np.partition(d, 1)[1] - d[i] if len(d) > 1 else np.inf))
        candidates.sort(key=lambda c: c[0])
        gap = min(candidates[0][4], candidates[1][0] - candidates[0][0] if len(candidates) > 1 else np.inf)
        best.append(candidates[0][:4] + (gap,))
    return best


@pytest.mark.parametrize("kind", ["one", "several"])
def test_closest_points_and_distance_match_brute_force(kind):
    geometries = OPEN_SETS[kind]()
    scene = scene_of(geometries)
    _, points = rays_and_points(12, 150)
    answer = scene.compute_closest_points(points)
    distance = scene.compute_distance(points)
    assert distance.dtype == np.float32 and answer["points"].dtype == np.float32
    for row, (d, g, prim, q, gap) in enumerate(brute_closest(geometries, points)):
        assert distance[row] == pytest.approx(d, rel=1e-5, abs=1e-6)
        if gap > 1e-5:
            assert (answer["geometry_ids"][row], answer["primitive_ids"][row]) == (g, prim)
            np.testing.assert_allclose(answer["points"][row], q, atol=1e-5)
            v, f = geometries[g]
            p0, p1, p2 = v.astype(np.float64)[f[prim]]
            u, w = answer["primitive_uvs"][row]
            np.testing.assert_allclose((1 - u - w) * p0 + u * p1 + w * p2, q, atol=1e-5)
            n = np.cross(p1 - p0, p2 - p0)
            np.testing.assert_allclose(answer["primitive_normals"][row], n / np.linalg.norm(n), atol=1e-5)


def brute_inside(geometries, points):
    """Inside any geometry: the parity of a float64 ray's crossings, per closed geometry."""
    direction = np.array([0.31, 0.52, 0.79])
    rays = np.hstack([points, np.tile(direction, (len(points), 1))]).astype(np.float64)
    inside = np.zeros(len(points), bool)
    for v, f in geometries:
        brute = BruteRays([(v, f)], rays)
        inside |= brute.hit.sum(axis=1) % 2 == 1
    return inside


@pytest.mark.parametrize("kind", ["one", "several"])
def test_signed_distance_and_occupancy_match_brute_force(kind):
    geometries = CLOSED_SETS[kind]()
    scene = scene_of(geometries)
    _, points = rays_and_points(13, 200, spread=1.1)
    inside = brute_inside(geometries, points)
    assert 20 < inside.sum() < 180
    distance = np.array([c[0] for c in brute_closest(geometries, points)])
    away = distance > 1e-4
    occupancy = scene.compute_occupancy(points)
    assert occupancy.dtype == np.float32
    np.testing.assert_array_equal(occupancy[away], inside[away].astype(np.float32))
    signed = scene.compute_signed_distance(points, nsamples=3)
    assert signed.dtype == np.float32
    np.testing.assert_allclose(signed[away], np.where(inside, -distance, distance)[away], rtol=1e-5, atol=1e-6)


def test_scene_signed_distance_matches_brute_force():
    """hbv.Scene.signed_distance: closest_point's distance, negative inside (contains)."""
    geometries = CLOSED_SETS["several"]()
    scene = hbv.Scene()
    shift = np.array([[1, 0, 0, 0.25], [0, 1, 0, -0.5], [0, 0, 1, 0], [0, 0, 0, 1]])
    scene.add(hbv.Mesh(*geometries[0]), mask=1)
    scene.add(hbv.Mesh(*geometries[1]), transform=shift, mask=2)
    _, points = rays_and_points(14, 200, spread=1.1)
    moved = [geometries[0], (geometries[1][0] + np.float32([0.25, -0.5, 0]), geometries[1][1])]
    distance = np.array([c[0] for c in brute_closest(moved, points)])
    inside = brute_inside(moved, points)
    signed = scene.signed_distance(points)
    assert signed.dtype == np.float64
    away = distance > 1e-4
    np.testing.assert_allclose(signed[away], np.where(inside, -distance, distance)[away], rtol=1e-5)
    # Masks: the second instance alone.
    only_second = scene.signed_distance(points, mask=2)
    d2 = np.array([c[0] for c in brute_closest(moved[1:], points)])
    in2 = brute_inside(moved[1:], points)
    np.testing.assert_allclose(only_second[d2 > 1e-4], np.where(in2, -d2, d2)[d2 > 1e-4], rtol=1e-5)
    # Not finite, and nothing seen: +inf.
    odd = scene.signed_distance(np.array([[np.nan, 0, 0], [np.inf, 0, 0], [0, 0, 0]]), mask=[1, 1, 4])
    assert np.all(odd == np.inf)
    with pytest.raises(ValueError, match="points"):
        scene.signed_distance(np.zeros((3, 2)))


def test_scene_inside_grid_answers_as_the_exact_test():
    """Past 32,768 points without a mask, a scene of closed meshes answers inside tests from
    its grid of decided cells (hbv::proximity::InsideCells): the same answers as each mesh's
    own exact test, made again after the scene changes, and not used with a mask."""
    geometries = CLOSED_SETS["several"]()
    bvhs = [hbv.BVH(hbv.Mesh(v, f)) for v, f in geometries]
    # The exact test: a Grid's contains, one ray's parity for every point (no inside grid).
    exact_tests = [hbv.Grid(hbv.Mesh(v, f)) for v, f in geometries]
    scene = hbv.Scene()
    for bvh in bvhs:
        scene.add(bvh)
    rng = np.random.default_rng(17)
    points = rng.uniform(-1.6, 1.6, (40_000, 3))
    # Points on and very near the surface, where the cells must send the point to a ray.
    near = scene.closest_point(points[:4000])["point"]
    points[:2000] = near[:2000] + rng.normal(scale=1e-7, size=(2000, 3))
    # And points 1e-4 from it: in surface cells, decided by a ray or a short segment.
    points[2000:4000] = near[2000:] + rng.normal(scale=1e-4, size=(2000, 3))

    def exact(shift=(0.0, 0.0, 0.0)):
        inside = np.zeros(len(points), bool)
        for k, grid in enumerate(exact_tests):
            moved = points - (np.asarray(shift) if k == 1 else 0)
            inside |= grid.contains(moved)
        return inside

    expected = exact()
    for _ in range(3):  # the first call makes the grid, the later ones use it
        np.testing.assert_array_equal(scene.contains(points), expected)
    signed = scene.signed_distance(points)
    np.testing.assert_array_equal(signed < 0, expected & (signed != 0))
    shift = (0.05, -0.3, 0.2)
    scene.set_transform(1, np.array([[1, 0, 0, shift[0]], [0, 1, 0, shift[1]], [0, 0, 1, shift[2]], [0, 0, 0, 1.0]]))
    for _ in range(2):
        np.testing.assert_array_equal(scene.contains(points), exact(shift))
    np.testing.assert_array_equal(scene.contains(points, mask=1), exact(shift))
    # The drop-in's one closed geometry: its BVH answers its inside tests, with its own grid
    # (test_bvh_inside_grid_answers_as_the_exact_test). Points within rounding of the surface
    # (1e-7 here) may be answered either way, by either test.
    one = scene_of(geometries[:1])
    points = points.astype(np.float32)
    away = bvhs[0].closest_point(points)["distance"] > 1e-5
    assert (~away).sum() > 500
    for _ in range(2):
        inside = one.compute_occupancy(points) == 1
        np.testing.assert_array_equal(inside[away], exact_tests[0].contains(points)[away])


def _points_near_surfaces(bvh, rng, n):
    """`n` points in the box around a unit mesh, a tenth of them within 1e-7 of its surface and
    a tenth 1e-4 from it (in the cells the surface touches)."""
    points = rng.uniform(-1.6, 1.6, (n, 3))
    tenth = n // 10
    near = bvh.closest_point(points[: 2 * tenth])["point"]
    points[:tenth] = near[:tenth] + rng.normal(scale=1e-7, size=(tenth, 3))
    points[tenth : 2 * tenth] = near[tenth:] + rng.normal(scale=1e-4, size=(tenth, 3))
    return points


@pytest.mark.parametrize("calls", [1, 4])
def test_bvh_inside_grid_answers_as_the_exact_test(calls):
    """Past 32,768 points (one call of 40,000, or the fourth of 10,000 each), a BVH over a
    closed mesh answers contains and signed_distance through its inside grid
    (hbv::proximity::InsideCells): the answers of the exact test (a Grid's one ray a point),
    on points in free cells, in surface cells and on the surface, float32 and float64, with any
    threads; NaN and infinite points outside."""
    v, f = lumpy_sphere(21)
    bvh, exact = hbv.BVH(hbv.Mesh(v, f)), hbv.Grid(hbv.Mesh(v, f))
    rng = np.random.default_rng(22)
    points = _points_near_surfaces(bvh, rng, 40_000)
    points[:3] = [[np.nan, 0, 0], [np.inf, 0, 0], [0, -np.inf, 0]]
    expected = exact.contains(points)
    assert 2_000 < expected.sum() < 38_000
    # Within rounding of the surface (the 1e-7 points) a ray and a segment may differ, as any
    # two rays may: "points on the surface may go either way" (BVH.contains).
    off = ~(bvh.closest_point(points)["distance"] <= 1e-6)
    assert off.sum() > 35_000
    for part in np.array_split(np.arange(len(points)), calls):
        got = bvh.contains(points[part])
        np.testing.assert_array_equal(got[off[part]], expected[part][off[part]])
    for dtype, threads in [(np.float64, None), (np.float32, 1), (np.float32, None)]:
        given = points.astype(dtype)
        got, want = bvh.contains(given, threads=threads), exact.contains(given)
        np.testing.assert_array_equal(got[off], want[off])
    signed = bvh.signed_distance(points)
    np.testing.assert_array_equal((signed < 0)[off], expected[off])
    assert np.all(signed[:3] == np.inf)
    # Away from the surface, the float64 brute force agrees.
    away = np.abs(signed) > 1e-4
    away[:3] = False
    check = np.flatnonzero(away)[:300]
    np.testing.assert_array_equal(expected[check], brute_inside([(v, f)], points[check]))


def test_bvh_inside_grid_is_not_made_for_open_or_empty_meshes():
    """An open mesh keeps the majority of three rays past 32,768 points (with its warning), as
    a Grid answers; a mesh of no triangles answers outside everywhere."""
    v, f = lumpy_sphere(23)
    v_open, f_open = v, f[1:]
    bvh, exact = hbv.BVH(hbv.Mesh(v_open, f_open)), hbv.Grid(hbv.Mesh(v_open, f_open))
    points = np.random.default_rng(24).uniform(-1.2, 1.2, (40_000, 3))
    for _ in range(2):
        with pytest.warns(RuntimeWarning, match="not closed"):
            got = bvh.contains(points)
        with pytest.warns(RuntimeWarning, match="not closed"):
            np.testing.assert_array_equal(got, exact.contains(points))
    empty = hbv.BVH(hbv.Mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64)))
    for _ in range(2):
        assert not empty.contains(points).any()


def test_leading_shapes_are_kept():
    scene = scene_of(CLOSED_SETS["one"]())
    rays, points = rays_and_points(15, 24)
    rays, points = rays.reshape(2, 3, 4, 6), points.reshape(4, 6, 3)
    answer = scene.cast_rays(rays)
    assert answer["t_hit"].shape == (2, 3, 4)
    assert answer["primitive_uvs"].shape == (2, 3, 4, 2)
    assert answer["primitive_normals"].shape == (2, 3, 4, 3)
    flat = scene.cast_rays(rays.reshape(-1, 6))
    np.testing.assert_array_equal(answer["t_hit"].reshape(-1), flat["t_hit"])
    assert scene.test_occlusions(rays).shape == (2, 3, 4)
    assert scene.count_intersections(rays).shape == (2, 3, 4)
    assert scene.list_intersections(rays)["ray_splits"].shape == (25,)
    closest = scene.compute_closest_points(points)
    assert closest["points"].shape == (4, 6, 3) and closest["primitive_ids"].shape == (4, 6)
    for method in ("compute_distance", "compute_signed_distance", "compute_occupancy"):
        assert getattr(scene, method)(points).shape == (4, 6)


def test_empty_scene_and_points_not_finite():
    scene = RaycastingScene()
    rays = np.array([[0, 0, -1, 0, 0, 1]], np.float32)
    answer = scene.cast_rays(rays)
    assert answer["t_hit"][0] == np.inf and answer["geometry_ids"][0] == INVALID_ID
    assert scene.count_intersections(rays)[0] == 0 and not scene.test_occlusions(rays)[0]
    assert scene.list_intersections(rays)["ray_splits"].tolist() == [0, 0]
    points = np.array([[0, 0, 0]], np.float32)
    assert scene.compute_distance(points)[0] == np.inf
    assert scene.compute_closest_points(points)["primitive_ids"][0] == INVALID_ID
    assert scene.compute_occupancy(points)[0] == 0

    scene = scene_of(CLOSED_SETS["one"]())
    odd = np.array([[np.nan, 0, 0], [0, np.inf, 0], [0, 0, 0]], np.float32)
    distance = scene.compute_distance(odd)
    assert np.isnan(distance[:2]).all() and distance[2] > 0
    assert np.isnan(scene.compute_signed_distance(odd)[:2]).all()
    closest = scene.compute_closest_points(odd)
    assert np.all(closest["geometry_ids"][:2] == INVALID_ID)
    assert np.all(closest["primitive_normals"][:2] == 0)
    assert scene.compute_occupancy(odd).tolist() == [0, 0, 1]


def test_bad_arguments_name_the_argument():
    scene = scene_of(CLOSED_SETS["one"]())
    with pytest.raises(ValueError, match=r"rays: expected an array of shape \(\.\.\., 6\)"):
        scene.cast_rays(np.zeros((4, 5), np.float32))
    with pytest.raises(ValueError, match="at least 2 dimensions"):
        scene.cast_rays(np.zeros(6, np.float32))
    with pytest.raises(ValueError, match="query_points"):
        scene.compute_distance(np.zeros((4, 6), np.float32))
    with pytest.raises(ValueError, match="nsamples"):
        scene.compute_occupancy(np.zeros((1, 3), np.float32), nsamples=2)
    with pytest.raises(ValueError, match="nsamples"):
        scene.compute_signed_distance(np.zeros((1, 3), np.float32), nsamples=0)
    with pytest.raises(ValueError, match="nthreads"):
        scene.cast_rays(np.zeros((1, 6), np.float32), nthreads=-1)
    with pytest.raises(TypeError, match="add_triangles"):
        scene.add_triangles("not a mesh")
    with pytest.raises(ValueError, match="triangles must have shape"):
        scene.add_triangles(np.zeros((3, 3), np.float32), np.zeros((2, 2), np.int64))
    with pytest.raises(ValueError):  # an index past the vertices: hbv.Mesh's message
        scene.add_triangles(np.zeros((3, 3), np.float32), np.array([[0, 1, 7]]))
    with pytest.raises(ValueError, match="create_rays_pinhole"):
        RaycastingScene.create_rays_pinhole(np.eye(3), np.zeros((4, 4)), 4, 3)
    with pytest.raises(TypeError, match="create_rays_pinhole"):
        RaycastingScene.create_rays_pinhole(60.0, [0, 0, 0], [0, 0, 1])


def test_threads_do_not_change_answers():
    scene = scene_of(OPEN_SETS["several"]())
    rays, points = rays_and_points(16, 3000)
    for method, argument in [("cast_rays", rays), ("compute_closest_points", points)]:
        many, one = getattr(scene, method)(argument), getattr(scene, method)(argument, nthreads=1)
        for key in many:
            np.testing.assert_array_equal(many[key], one[key])


def test_geometry_added_after_a_query_is_seen():
    first, second = CLOSED_SETS["several"]()
    scene = scene_of([first])
    rays = np.array([[-0.8, 0, -5, 0, 0, 1], [0.9, 0.1, -5, 0, 0, 1]], np.float32)
    assert scene.cast_rays(rays)["geometry_ids"].tolist() == [0, INVALID_ID]
    assert scene.add_triangles(*second) == 1
    assert scene.cast_rays(rays)["geometry_ids"].tolist() == [0, 1]
    assert scene.add_triangles(*lumpy_sphere(8, (0, 3, 0), 0.5)) == 2
    rays = np.array([[0, 3, -5, 0, 0, 1]], np.float32)
    assert scene.cast_rays(rays)["geometry_ids"].tolist() == [2]


def test_pinhole_rays_look_where_asked():
    rays = RaycastingScene.create_rays_pinhole(
        fov_deg=90, center=[1, 2, 3], eye=[1, 2, -2], up=[0, 1, 0], width_px=5, height_px=3
    )
    assert rays.shape == (3, 5, 6) and rays.dtype == np.float32
    np.testing.assert_allclose(rays[..., :3], np.broadcast_to([1, 2, -2], (3, 5, 3)))
    np.testing.assert_allclose(rays[1, 2, 3:], [0, 0, 1], atol=1e-6)  # the middle pixel
    # 90 degrees across 5 pixels: the outer pixel centres 2 pixels of a focal length of 2.5 to
    # either side of the middle.
    assert abs(rays[1, 0, 3]) == pytest.approx(0.8, rel=1e-6)
    intrinsic = np.array([[50.0, 0, 20], [0, 40, 10], [0, 0, 1]])
    extrinsic = np.eye(4)
    extrinsic[:3, 3] = [1, 2, 3]
    rays = RaycastingScene.create_rays_pinhole(intrinsic, extrinsic, 40, 20)
    camera_points = rays[..., :3] + rays[..., 3:] + [1, 2, 3]  # world to camera: + t
    pixels = camera_points @ intrinsic.T
    x, y = np.meshgrid(np.arange(40) + 0.5, np.arange(20) + 0.5)
    np.testing.assert_allclose(pixels[..., 0] / pixels[..., 2], x, rtol=1e-5)
    np.testing.assert_allclose(pixels[..., 1] / pixels[..., 2], y, rtol=1e-5)


# -- parity with Open3D ----------------------------------------------------------------------


def assert_t_parity(ours, theirs, exact, maxulp=16):
    """hbv's t within `maxulp` float32 ulps of the float64 brute force, and of Open3D's t
    where Open3D's is that close too (at grazing angles Open3D's t is off by up to ~2,000
    ulps: hbv's then must be at least as close)."""
    ulp = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    ours_off = np.abs(ours.astype(np.float64) - exact) / ulp
    theirs_off = np.abs(theirs.astype(np.float64) - exact) / ulp
    assert ours_off.max(initial=0) <= maxulp
    close = theirs_off <= maxulp
    np.testing.assert_array_max_ulp(ours[close], theirs[close], maxulp=2 * maxulp)
    assert np.all(ours_off <= theirs_off + maxulp)


def open3d_scene_of(geometries):
    scene = o3d.t.geometry.RaycastingScene()
    for v, f in geometries:
        scene.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32)))
    return scene


def as_numpy(answer):
    if isinstance(answer, dict):
        return {key: value.numpy() for key, value in answer.items()}
    return answer.numpy()


@needs_open3d
@pytest.mark.parametrize("kind", ["one", "several"])
def test_parity_with_open3d_rays(kind):
    geometries = OPEN_SETS[kind]()
    ours, theirs = scene_of(geometries), open3d_scene_of(geometries)
    rays, _ = rays_and_points(20, 400)
    brute = BruteRays(geometries, rays)
    _, exact, unambiguous = brute.closest()
    clear = brute.clear & unambiguous
    a, b = ours.cast_rays(rays), as_numpy(theirs.cast_rays(o3d.core.Tensor(rays)))
    assert set(a) == set(b)
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
    hit = clear & np.isfinite(exact)
    assert_t_parity(a["t_hit"][hit], b["t_hit"][hit], exact[hit])
    np.testing.assert_array_equal(a["t_hit"][clear & ~hit], b["t_hit"][clear & ~hit])
    for key in ("geometry_ids", "primitive_ids"):
        np.testing.assert_array_equal(a[key][clear], b[key][clear])
    np.testing.assert_allclose(a["primitive_uvs"][clear], b["primitive_uvs"][clear], atol=1e-4)
    np.testing.assert_allclose(a["primitive_normals"][clear], b["primitive_normals"][clear], atol=1e-5)

    occluded = theirs.test_occlusions(o3d.core.Tensor(rays), tnear=0.2, tfar=1.5).numpy()
    away = brute.clear & ~((np.abs(brute.t - 0.2) < 1e-4) | (np.abs(brute.t - 1.5) < 1e-4)).any(axis=1)
    np.testing.assert_array_equal(ours.test_occlusions(rays, tnear=0.2, tfar=1.5)[away], occluded[away])
    counts = theirs.count_intersections(o3d.core.Tensor(rays)).numpy()
    assert ours.count_intersections(rays).dtype == counts.dtype
    np.testing.assert_array_equal(ours.count_intersections(rays)[brute.clear], counts[brute.clear])

    a, b = ours.list_intersections(rays), as_numpy(theirs.list_intersections(o3d.core.Tensor(rays)))
    assert set(a) == set(b)
    for key in a:
        assert a[key].dtype == b[key].dtype, key
    for r in np.flatnonzero(brute.clear):
        mine = slice(a["ray_splits"][r], a["ray_splits"][r + 1])
        other = slice(b["ray_splits"][r], b["ray_splits"][r + 1])
        key_a = np.lexsort((a["primitive_ids"][mine], a["geometry_ids"][mine]))
        key_b = np.lexsort((b["primitive_ids"][other], b["geometry_ids"][other]))
        for key in ("geometry_ids", "primitive_ids"):
            np.testing.assert_array_equal(a[key][mine][key_a], b[key][other][key_b])
        # The brute force's t of the same hits, in the same order.
        hits = np.flatnonzero(brute.hit[r])
        hits = hits[np.lexsort((brute.prim[hits], brute.geometry[hits]))]
        assert_t_parity(a["t_hit"][mine][key_a], b["t_hit"][other][key_b], brute.t[r, hits])
        np.testing.assert_allclose(a["primitive_uvs"][mine][key_a], b["primitive_uvs"][other][key_b], atol=1e-4)


@needs_open3d
@pytest.mark.parametrize("kind", ["one", "several"])
def test_parity_with_open3d_points(kind):
    geometries = CLOSED_SETS[kind]()
    ours, theirs = scene_of(geometries), open3d_scene_of(geometries)
    _, points = rays_and_points(21, 400)
    tensor = o3d.core.Tensor(points)
    a, b = ours.compute_closest_points(points), as_numpy(theirs.compute_closest_points(tensor))
    assert set(a) == set(b)
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
    distance = ours.compute_distance(points)
    np.testing.assert_allclose(distance, theirs.compute_distance(tensor).numpy(), rtol=1e-5, atol=1e-6)
    brute = brute_closest(geometries, points)
    sure = np.array([gap > 1e-5 for *_, gap in brute])
    for key in ("geometry_ids", "primitive_ids"):
        np.testing.assert_array_equal(a[key][sure], b[key][sure])
    np.testing.assert_allclose(a["points"][sure], b["points"][sure], atol=1e-5)
    np.testing.assert_allclose(a["primitive_uvs"][sure], b["primitive_uvs"][sure], atol=1e-4)
    np.testing.assert_allclose(a["primitive_normals"][sure], b["primitive_normals"][sure], atol=1e-5)
    away = distance > 1e-4
    occupancy = theirs.compute_occupancy(tensor, nsamples=3).numpy()
    np.testing.assert_array_equal(ours.compute_occupancy(points)[away], occupancy[away])
    signed = theirs.compute_signed_distance(tensor, nsamples=3).numpy()
    np.testing.assert_allclose(ours.compute_signed_distance(points)[away], signed[away], rtol=1e-5, atol=1e-6)


@needs_open3d
def test_parity_with_open3d_meshes_tensors_and_cameras():
    box = o3d.geometry.TriangleMesh.create_box()
    ours = RaycastingScene()
    assert ours.add_triangles(box) == 0  # legacy
    assert ours.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(box).translate([3, 0, 0])) == 1
    v, f = lumpy_sphere(9, (0, 3, 0), 0.5)
    assert ours.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32))) == 2
    theirs = o3d.t.geometry.RaycastingScene()
    theirs.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(box))
    theirs.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(box).translate([3, 0, 0]))
    theirs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32)))
    for fov, center, eye, up in [(60, [1.5, 1, 0.5], [-2, -3, 4], [0, 0, 1]), (35, [0, 3, 0], [0.3, 3.2, 4], [0, 1, 0])]:
        rays = theirs.create_rays_pinhole(fov, o3d.core.Tensor(np.float32(center)), o3d.core.Tensor(np.float32(eye)),
                                          o3d.core.Tensor(np.float32(up)), 32, 24)
        mine = ours.create_rays_pinhole(fov_deg=fov, center=center, eye=eye, up=up, width_px=32, height_px=24)
        np.testing.assert_allclose(mine, rays.numpy(), atol=1e-6)
        a, b = ours.cast_rays(rays), as_numpy(theirs.cast_rays(rays))  # a tensor, read as NumPy
        hit = np.isfinite(b["t_hit"])
        assert hit.sum() > 20
        np.testing.assert_array_equal(np.isfinite(a["t_hit"]), hit)
        np.testing.assert_array_max_ulp(a["t_hit"][hit], b["t_hit"][hit], maxulp=64)
        np.testing.assert_array_equal(a["geometry_ids"], b["geometry_ids"])
    intrinsic = o3d.core.Tensor(np.array([[40.0, 0, 16], [0, 40, 12], [0, 0, 1]]))
    extrinsic = np.eye(4)
    extrinsic[:3, 3] = [-0.5, -0.5, 5]
    rays = theirs.create_rays_pinhole(intrinsic, o3d.core.Tensor(extrinsic), 32, 24)
    np.testing.assert_allclose(ours.create_rays_pinhole(intrinsic, extrinsic, 32, 24), rays.numpy(), atol=1e-6)
