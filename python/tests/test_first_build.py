"""A BVH built straight into its wide layout (binned SAH without optimization, the default on
meshes of 8,192 triangles or more) answers as one laid out from a build tree, and builds that
same tree when a later call needs it (closest_point, save, stats, pickle, Scene.add)."""

import functools
import pickle
import warnings

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays, soup


@functools.cache
def shapes():
    """Meshes of more than 8,192 triangles (built straight into wide nodes) with ties: a
    sphere, a soup with degenerate triangles, a soup's triangles twice (every hit tied between
    two ids), a flat grid of coplanar triangles."""
    sphere = icosphere(5)
    v, f = soup(9000)
    doubled_v, doubled_f = soup(4200, seed=5)
    xs, ys = np.meshgrid(np.linspace(-1, 1, 70), np.linspace(-1, 1, 70))
    grid_v = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    k = np.arange(70 * 69).reshape(69, 70)[:, :69].ravel()
    grid_f = np.vstack([np.column_stack([k, k + 1, k + 70]), np.column_stack([k + 1, k + 71, k + 70])])
    meshes = {"sphere": sphere, "soup": (v, f), "doubled": (doubled_v, np.vstack([doubled_f] * 2)),
              "grid": (grid_v, grid_f)}
    assert all(len(f) >= 8192 for _, f in meshes.values())
    return meshes


def rays(n=2000):
    o, d = random_rays(n)
    d[:50] = np.nan  # invalid rays miss
    d[50:60] = 0.0
    o[60:70] = [0.1, 0.2, 3.0]  # straight down onto the grid
    d[60:70] = [0.0, 0.0, -1.0]
    return o, d


def assert_same_hits(got, want, label):
    for key in want:
        np.testing.assert_array_equal(got[key], want[key], err_msg=f"{label} {key}")


@pytest.mark.parametrize("name", ["sphere", "soup", "doubled", "grid"])
@pytest.mark.parametrize("layout", ["wide8", "wide4"])
@pytest.mark.parametrize("leaf_size", [None, 1, 4, 64])
def test_straight_build_answers_as_the_tree_laid_out(name, layout, leaf_size):
    v, f = shapes()[name]
    mesh = hbv.Mesh(v, f)
    o, d = rays()
    # optimize=False: the straight build at any size; "ordered" lays out the same tree.
    direct = hbv.BVH(mesh, layout=layout, optimize=False, leaf_size=leaf_size)
    through_tree = hbv.BVH(mesh, layout="ordered", optimize=False, leaf_size=leaf_size)
    label = f"{name} {layout} {leaf_size}"
    assert_same_hits(direct.intersect(o, d), through_tree.intersect(o, d), label)
    np.testing.assert_array_equal(direct.occluded(o, d), through_tree.occluded(o, d), label)
    np.testing.assert_array_equal(direct.count(o, d), through_tree.count(o, d), label)
    for got, want in zip(direct.intersect_all(o, d), through_tree.intersect_all(o, d)):
        np.testing.assert_array_equal(got, want, label)
    with warnings.catch_warnings():  # open meshes: the majority of three rays, in both
        warnings.simplefilter("ignore", RuntimeWarning)
        np.testing.assert_array_equal(direct.contains(o), through_tree.contains(o), label)
    assert_same_hits(direct.closest_point(o[:300]), through_tree.closest_point(o[:300]), label)


def test_the_tree_built_later_is_the_tree_built_first():
    v, f = shapes()["sphere"]
    mesh = hbv.Mesh(v, f)
    through_tree = hbv.BVH(mesh, layout="ordered")
    want = {k: x for k, x in through_tree.stats().items() if k not in ("layout", "build_seconds")}
    # Each of these calls is the first to need the tree of a BVH built straight into wide nodes.
    for first_call in (
        lambda b: b.stats(),
        lambda b: b.expected_tests(),
        lambda b: b.sah_cost(2.0, 1.0),
        lambda b: b.closest_point(v[:10]),
        lambda b: pickle.loads(pickle.dumps(b)),
    ):
        bvh = hbv.BVH(mesh)
        first_call(bvh)
        got = {k: x for k, x in bvh.stats().items() if k not in ("layout", "build_seconds")}
        assert got == want
        assert bvh.expected_tests() == through_tree.expected_tests()
        assert bvh.sah_cost(2.0, 1.0) == through_tree.sah_cost(2.0, 1.0)


def test_saved_and_loaded_straight_build_answers_the_same(tmp_path):
    v, f = shapes()["soup"]
    mesh = hbv.Mesh(v, f)
    o, d = rays()
    bvh = hbv.BVH(mesh, optimize=False)
    want = bvh.intersect(o, d)
    bvh.save(tmp_path / "soup.hbv")
    loaded = hbv.load_bvh(tmp_path / "soup.hbv")
    assert loaded.builder == "binned-sah"
    assert_same_hits(loaded.intersect(o, d), want, "loaded")
    assert loaded.stats()["nodes"] == hbv.BVH(mesh, optimize=False, layout="ordered").stats()["nodes"]
    copy = pickle.loads(pickle.dumps(bvh))
    assert_same_hits(copy.intersect(o, d), want, "pickled")


def test_scene_of_a_straight_build_answers_as_one_of_its_mesh():
    v, f = shapes()["sphere"]
    mesh = hbv.Mesh(v, f)
    o, d = rays()
    of_bvh, of_mesh = hbv.Scene(), hbv.Scene()
    of_bvh.add(hbv.BVH(mesh))
    of_mesh.add(mesh)
    assert_same_hits(of_bvh.intersect(o, d), of_mesh.intersect(o, d), "scene")


def test_straight_build_of_empty_and_degenerate_meshes_answers_misses():
    o, d = rays(100)
    empty = hbv.BVH(hbv.Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), optimize=False)
    flat = hbv.BVH(hbv.Mesh(np.zeros((3, 3)), np.zeros((9000, 3), np.int64)), optimize=False)
    for bvh in (empty, flat):
        assert not bvh.intersect(o, d)["hit"].any()
        assert not bvh.occluded(o, d).any()
        assert (bvh.count(o, d) == 0).all()
        assert bvh.stats()["triangles"] in (0, 9000)
        assert (bvh.closest_point(o[:5])["prim"] == -1).all()
