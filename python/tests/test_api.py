"""The Python API: construction, argument checking, dtypes, intervals, threads, pickling."""

import doctest
import pickle

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays


def test_mesh_round_trips_its_arrays(sphere):
    mesh, v, f = sphere
    assert mesh.triangle_count == len(f) == len(mesh)
    np.testing.assert_array_equal(mesh.faces, f)
    np.testing.assert_array_equal(mesh.vertices, v.astype(np.float32))
    assert mesh.vertices.dtype == np.float32 and mesh.faces.dtype == np.int64
    lo, hi = mesh.bounds
    assert np.allclose(lo, -1, atol=1e-6) and np.allclose(hi, 1, atol=1e-6)


def test_load_reads_obj_and_names_the_file_on_errors(tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    mesh = hbv.load(path)
    assert mesh.triangle_count == 2
    assert hbv.load(str(path)).triangle_count == 2
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="bad.obj"):
        hbv.load(bad)
    with pytest.raises(OSError, match="missing.ply"):
        hbv.load(tmp_path / "missing.ply")


def test_bad_arguments_raise_clear_errors(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    o, d = random_rays(4)
    with pytest.raises(ValueError, match=r"origins: expected shape \(N, 3\), got \(4, 2\)"):
        bvh.intersect(o[:, :2], d)
    with pytest.raises(ValueError, match="directions: expected 4 rows"):
        bvh.intersect(o, d[:3])
    with pytest.raises(TypeError, match="directions: .*complex128"):
        bvh.intersect(o, d.astype(complex))
    with pytest.raises(ValueError, match="tmax: expected 4 rows"):
        bvh.intersect(o, d, tmax=np.ones(3))
    for bad in (0, -1, 2**70):
        with pytest.raises(ValueError, match=f"threads: expected a positive number of threads.*got {bad}"):
            bvh.occluded(o, d, threads=bad)
    for bad in (1.5, "2", True):
        with pytest.raises(TypeError, match="threads: expected a positive number of threads"):
            bvh.intersect(o, d, threads=bad)
    with pytest.raises(ValueError, match="threads"):
        bvh.closest_point(np.zeros((2, 3)), threads=-2)
    # More threads than any machine has are refused at once (100,000 took minutes to start).
    for bad in (1025, 100_000):
        with pytest.raises(ValueError, match=f"threads: at most 1024, or None for all cores; got {bad}"):
            bvh.intersect(o, d, threads=bad)
    bvh.intersect(o, d, threads=1024)
    with pytest.raises(ValueError, match="points: expected shape"):
        bvh.closest_point(np.zeros((2, 2)))
    with pytest.raises(TypeError, match="mesh: expected an hbv.Mesh"):
        hbv.BVH(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="builder: unknown builder"):
        hbv.BVH(mesh, builder="octree")
    with pytest.raises(ValueError, match="layout: unknown layout"):
        hbv.BVH(mesh, layout="wide16")
    with pytest.raises(ValueError, match="leaf_size"):
        hbv.BVH(mesh, leaf_size=0)
    with pytest.raises(ValueError, match="face 0: vertex index 7 out of range"):
        hbv.Mesh(np.zeros((3, 3)), [[0, 1, 7]])
    with pytest.raises(ValueError, match="faces: row 0: index -1 is negative"):
        hbv.Mesh(np.zeros((3, 3)), [[0, 1, -1]])
    # An unsigned index is shown as it is (2^63 + 5 read as int64 was shown negative).
    with pytest.raises(ValueError, match="faces: row 0: index 9223372036854775813 does not fit 32 bits"):
        hbv.Mesh(np.zeros((3, 3)), np.array([[0, 1, 2**63 + 5]], np.uint64))
    # A ragged list: NumPy's reason, not "expected a NumPy array".
    with pytest.raises(TypeError, match="vertices: .*got a list that it cannot read: .*inhomogeneous"):
        hbv.Mesh([[0, 0, 0], [1, 0]], [[0, 1, 2]])
    with pytest.raises(TypeError, match=r"tmin: expected a number or an array of shape \(N,\), got str"):
        hbv.BVH(hbv.Mesh(np.eye(3), [[0, 1, 2]])).intersect(np.zeros((1, 3)), np.ones((1, 3)), tmin="a")
    with pytest.raises(TypeError, match="faces: expected an integer dtype"):
        hbv.Mesh(np.zeros((3, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="vertex 1: coordinate is not finite"):
        hbv.Mesh([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], [[0, 1, 2]])


def test_dtypes_and_strides_give_the_same_answers(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    o, d = random_rays(500)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    want = bvh.intersect(o32, d32)
    assert want["t"].dtype == np.float32 and want["prim"].dtype == np.int64
    assert want["hit"].dtype == bool and want["u"].dtype == np.float32
    # float64 read in place (C order) or converted (Fortran order, strided), float32 likewise.
    for oo, dd in [(o, d), (np.asfortranarray(o32), d32), (o32, np.repeat(d32, 2, 0)[::2]),
                   (np.asfortranarray(o), np.repeat(d, 2, 0)[::2]), (o32.tolist(), d32.tolist()),
                   (o.astype(">f8"), d32.astype(">f4"))]:
        got = bvh.intersect(oo, dd)
        for k in want:
            np.testing.assert_array_equal(got[k], want[k])
    tmin, tmax = np.linspace(0, 2, 500), np.linspace(3, 9, 500)
    want = bvh.intersect(o32, d32, tmin=tmin.astype(np.float32), tmax=tmax.astype(np.float32))
    got = bvh.intersect(o, d, tmin=tmin, tmax=tmax)
    for k in want:
        np.testing.assert_array_equal(got[k], want[k])
    np.testing.assert_array_equal(bvh.contains(o), bvh.contains(o32))
    # Floats in neither native float32 nor float64 are read as float64: float16 exactly.
    h = o.astype(np.float16)
    for k, column in bvh.intersect(h, d32).items():
        np.testing.assert_array_equal(column, bvh.intersect(h.astype(np.float32), d32)[k])
    for k, column in bvh.closest_point(o.astype(">f8")).items():
        np.testing.assert_array_equal(column, bvh.closest_point(o)[k])


def test_misses_and_invalid_rays_follow_rays_md(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    o = np.array([[0, 0, -5], [0, 0, -5], [np.nan, 0, 0], [0, 0, 0], [5, 5, 5]], np.float32)
    d = np.array([[0, 0, 1], [0, 0, -1], [0, 0, 1], [0, 0, 0], [1, 0, 0]], np.float32)
    h = bvh.intersect(o, d)
    np.testing.assert_array_equal(h["hit"], [True, False, False, False, False])
    assert np.all(np.isinf(h["t"][1:])) and np.all(h["prim"][1:] == -1)
    assert np.all(h["u"][1:] == 0) and np.all(h["v"][1:] == 0)
    np.testing.assert_array_equal(bvh.occluded(o, d), h["hit"])


def test_intervals_scalar_and_per_ray(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    o = np.array([[0.01, 0.02, -5.0]] * 3)
    d = np.array([[0, 0, 1.0]] * 3)
    np.testing.assert_array_equal(bvh.occluded(o, d, tmax=3.0), [False] * 3)
    np.testing.assert_array_equal(bvh.occluded(o, d, tmax=np.array([3.0, 4.5, np.inf])), [False, True, True])
    h = bvh.intersect(o, d, tmin=np.array([0, 4.5, 7.0]))
    np.testing.assert_array_equal(h["hit"], [True, True, False])
    assert abs(h["t"][0] - 4.0) < 0.01 and abs(h["t"][1] - 6.0) < 0.01
    assert list(bvh.count(o, d, tmin=4.5)) == [1, 1, 1]


def test_threads_do_not_change_answers(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    # Batches of at most 2,048 rays stay on the calling thread; larger ones are cut into runs
    # that the calling thread and the pool's threads share (5,000: a shorter last run).
    for n in (300, 5000):
        o, d = random_rays(n)
        want = bvh.intersect(o, d, threads=1)
        for threads in (None, 2, 3):
            got = bvh.intersect(o, d, threads=threads)
            for k in want:
                np.testing.assert_array_equal(got[k], want[k])
            np.testing.assert_array_equal(
                bvh.occluded(o, d, threads=threads), bvh.occluded(o, d, threads=1))
        np.testing.assert_array_equal(bvh.count(o, d, threads=1), bvh.count(o, d))
        # intersect_all on one thread runs on the calling thread, not in a pool: same lists.
        for got, want in zip(bvh.intersect_all(o, d, threads=1), bvh.intersect_all(o, d)):
            np.testing.assert_array_equal(got, want)


def test_structures_made_on_first_use_from_several_threads(sphere):
    # A BVH lays out its ray structure on the first intersect or occluded, and its wide-8 and
    # nearest-point structures on their queries' first calls: a first call made from several
    # Python threads at once makes one, and every thread gets the answers of a BVH that had it.
    from concurrent.futures import ThreadPoolExecutor

    mesh, _, _ = sphere
    o, d = random_rays(3000)
    points = o[:500]
    reference = hbv.BVH(mesh, layout="wide4")
    want = (reference.intersect(o, d), reference.occluded(o, d), reference.count(o, d),
            reference.closest_point(points))
    for layout in ("wide8", "wide4"):
        bvh = hbv.BVH(mesh, layout=layout)
        queries = [lambda: bvh.intersect(o, d), lambda: bvh.occluded(o, d),
                   lambda: bvh.count(o, d), lambda: bvh.closest_point(points)]
        with ThreadPoolExecutor(8) as pool:
            futures = [(k, pool.submit(queries[k])) for k in range(4) for _ in range(2)]
            for k, future in futures:
                got = future.result()
                if isinstance(got, dict):
                    for key in want[k]:
                        np.testing.assert_array_equal(got[key], want[k][key], err_msg=f"{layout} {key}")
                else:
                    np.testing.assert_array_equal(got, want[k], err_msg=layout)


def test_every_builder_and_layout_gives_the_same_answers(triangle_soup):
    mesh, _, _ = triangle_soup
    o, d = random_rays(1000)
    want = hbv.BVH(mesh).intersect(o, d)
    for builder in ["binned-sah", "sweep-sah", "insertion", "median", "lbvh", "ploc"]:
        for layout in ["wide8", "wide4", "ordered", "recursive", "skip"]:
            bvh = hbv.BVH(mesh, builder=builder, layout=layout, leaf_size=4)
            got = bvh.intersect(o, d)
            for k in want:
                np.testing.assert_array_equal(got[k], want[k], err_msg=f"{builder} {layout} {k}")
    bvh = hbv.BVH(mesh, builder="insertion", optimize=True)
    np.testing.assert_array_equal(bvh.intersect(o, d)["prim"], want["prim"])


def test_quality_chooses_builder_and_optimizer_and_explicit_arguments_replace_them(triangle_soup):
    mesh, _, _ = triangle_soup
    o, d = random_rays(1000)
    want = hbv.BVH(mesh).intersect(o, d)
    for quality, builder, optimize in [
        ("low", "lbvh", False),
        ("medium", "binned-sah", False),
        ("high", "binned-sah", True),
    ]:
        # More than 1,024 triangles: no reinsertion unless the quality asks for it.
        big = hbv.BVH(hbv.Mesh(*icosphere(3)), quality=quality)
        assert (big.builder, big.stats()["optimize"]) == (builder, optimize)
        bvh = hbv.BVH(mesh, quality=quality.upper())
        assert bvh.builder == builder
        for k in want:
            np.testing.assert_array_equal(bvh.intersect(o, d)[k], want[k], err_msg=f"{quality} {k}")
    replaced = hbv.BVH(mesh, quality="high", builder="median", optimize=False, leaf_size=2)
    assert replaced.builder == "median"
    assert replaced.stats()["optimize"] is False
    assert replaced.stats()["leaf_size"] == 2
    assert hbv.BVH(mesh).builder == "binned-sah"
    with pytest.raises(ValueError, match="quality: unknown quality \"best\"; expected one of low, medium, high"):
        hbv.BVH(mesh, quality="best")


def room_of_boxes(boxes=6, seed=3):
    """A modelled scene: a room's twelve wall triangles (facing in) around random boxes."""
    rng = np.random.default_rng(seed)
    corners = np.array([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0)])
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    cube = np.array([[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads])
    vertices, faces = [corners * 10.0 - 5.0], [cube[:, ::-1]]
    for k in range(boxes):
        size = rng.uniform(0.3, 2.0, 3)
        vertices.append(corners * size + rng.uniform(-4.0, 4.0 - size))
        faces.append(cube + 8 * (k + 1))
    return np.concatenate(vertices), np.concatenate(faces)


def test_small_meshes_are_optimized_by_default_with_the_same_answers(sphere):
    v, f = room_of_boxes()
    mesh = hbv.Mesh(v, f)
    default, plain = hbv.BVH(mesh), hbv.BVH(mesh, optimize=False)
    assert default.stats()["optimize"] is True and "optimize=True" in repr(default)
    assert plain.stats()["optimize"] is False
    # Reinsertion lifts the walls out of the subtrees whose boxes they stretch.
    assert default.expected_tests() < plain.expected_tests()
    o, d = random_rays(2000, spread=6.0)
    want = plain.intersect(o, d)
    got = default.intersect(o, d)
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)
    np.testing.assert_array_equal(default.count(o, d), plain.count(o, d))
    # Pickled with the choice made, so unpickling builds the same tree.
    again = pickle.loads(pickle.dumps(default))
    assert again.stats()["optimize"] is True and again.expected_tests() == default.expected_tests()
    # Above 1,024 triangles the default is not to optimize (the icosphere has 1,280).
    big, _, big_f = sphere
    assert len(big_f) > 1024 and hbv.BVH(big).stats()["optimize"] is False
    assert hbv.BVH(big, optimize=True).stats()["optimize"] is True


def test_costs_and_stats(sphere):
    mesh, _, f = sphere
    bvh = hbv.BVH(mesh, builder="insertion")
    s = bvh.stats()
    assert s["triangles"] == len(f) and s["builder"] == "insertion" and s["layout"] == "wide8"
    assert s["expected_tests"] == bvh.expected_tests() > 1.0
    assert bvh.sah_cost() > 0 and bvh.sah_cost(2.0, 1.0) > bvh.sah_cost(1.0, 1.0)
    assert s["leaves"] == len(f)  # insertion: one triangle per leaf


def test_pickling_rebuilds_the_same_bvh(sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh, builder="median", layout="ordered", leaf_size=3)
    copy = pickle.loads(pickle.dumps(bvh))
    assert repr(copy) == repr(bvh)
    assert copy.expected_tests() == bvh.expected_tests()
    o, d = random_rays(200)
    for k, v in bvh.intersect(o, d).items():
        np.testing.assert_array_equal(copy.intersect(o, d)[k], v)
    m2 = pickle.loads(pickle.dumps(mesh))
    np.testing.assert_array_equal(m2.faces, mesh.faces)


def test_empty_mesh_answers_misses():
    mesh = hbv.Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    bvh = hbv.BVH(mesh)
    o, d = random_rays(10)
    assert not bvh.intersect(o, d)["hit"].any()
    assert (bvh.count(o, d) == 0).all() and not bvh.contains(o).any()
    cp = bvh.closest_point(o)
    assert (cp["prim"] == -1).all() and np.isinf(cp["distance"]).all()


def test_zero_rays():
    v, f = icosphere(1)
    bvh = hbv.BVH(hbv.Mesh(v, f))
    empty = np.zeros((0, 3), np.float32)
    assert len(bvh.intersect(empty, empty)["t"]) == 0
    assert len(bvh.intersect_all(empty, empty)[0]) == 0
    assert bvh.closest_point(empty)["point"].shape == (0, 3)


def test_docstring_examples_run():
    assert doctest.testmod(hbv, raise_on_error=True).attempted > 0
