"""hbv.trimesh.RayMeshIntersector against trimesh's own RayMeshIntersector, same rays."""

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("rtree")  # trimesh's ray_triangle intersector needs it

import hbv.trimesh  # noqa: E402
from trimesh.ray.ray_triangle import RayMeshIntersector as TrimeshIntersector  # noqa: E402


@pytest.fixture(scope="module")
def meshes():
    return [
        trimesh.creation.icosphere(subdivisions=3),
        trimesh.creation.torus(major_radius=1.0, minor_radius=0.3),
        trimesh.creation.box(extents=(1.0, 2.0, 0.5)),
    ]


def rays(n=400, seed=7):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-2, 2, (n, 3))
    target = rng.uniform(-0.8, 0.8, (n, 3))
    d = target - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


def test_first_and_any_agree(meshes):
    o, d = rays()
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh)
        theirs = TrimeshIntersector(mesh)
        np.testing.assert_array_equal(ours.intersects_any(o, d), theirs.intersects_any(o, d))
        first_ours, first_theirs = ours.intersects_first(o, d), theirs.intersects_first(o, d)
        assert first_ours.dtype == first_theirs.dtype == np.int64
        np.testing.assert_array_equal(first_ours, first_theirs)


def test_all_hits_agree(meshes):
    o, d = rays(seed=8)
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh)
        theirs = TrimeshIntersector(mesh)
        tri_a, ray_a = ours.intersects_id(o, d)
        tri_b, ray_b = theirs.intersects_id(o, d)
        assert set(zip(ray_a.tolist(), tri_a.tolist())) == set(zip(ray_b.tolist(), tri_b.tolist()))
        loc_a, ray_a, tri_a = ours.intersects_location(o, d)
        loc_b, ray_b, tri_b = theirs.intersects_location(o, d)
        assert loc_a.shape == loc_b.shape and loc_a.dtype == np.float64
        order_a = np.lexsort((tri_a, ray_a))
        order_b = np.lexsort((tri_b, ray_b))
        np.testing.assert_array_equal(ray_a[order_a], ray_b[order_b])
        np.testing.assert_array_equal(tri_a[order_a], tri_b[order_b])
        np.testing.assert_allclose(loc_a[order_a], loc_b[order_b], atol=1e-5)


def test_single_hit_and_max_hits(meshes):
    o, d = rays(seed=9)
    mesh = meshes[1]
    ours = hbv.trimesh.RayMeshIntersector(mesh)
    tri, ray = ours.intersects_id(o, d, multiple_hits=False)
    first = ours.intersects_first(o, d)
    np.testing.assert_array_equal(tri, first[ray])
    tri2, ray2 = ours.intersects_id(o, d, max_hits=2)
    assert np.bincount(ray2, minlength=len(o)).max() <= 2


def test_contains_points_agrees(meshes):
    rng = np.random.default_rng(10)
    points = rng.uniform(-1.5, 1.5, (3000, 3))
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh).contains_points(points)
        theirs = mesh.contains(points)
        assert (ours != theirs).sum() <= 1


def test_plugs_into_trimesh(meshes):
    mesh = meshes[0].copy()
    mesh.ray = hbv.trimesh.RayMeshIntersector(mesh)
    loc, idx_ray, idx_tri = mesh.ray.intersects_location([[0, 0, -5.0]], [[0, 0, 1.0]])
    assert len(loc) == 2 and set(idx_ray) == {0}
