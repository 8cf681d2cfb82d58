"""hbv.Grid (the uniform grid), BVH.save / hbv.load_bvh (.hbv files) and leaf sizes up to 255."""

import os
import pickle

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays


def assert_same_hits(got, want, what):
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=f"{what} {k}")


# The soup is open (contains warns): the two structures must agree even where inside is undefined.
@pytest.mark.filterwarnings("ignore:contains. the mesh is not closed:RuntimeWarning")
@pytest.mark.parametrize("lam", [None, 0.3, 1.0, 6.0])
def test_grid_answers_what_the_bvh_answers(triangle_soup, sphere, lam):
    for mesh, _, _ in [triangle_soup, sphere]:
        bvh, grid = hbv.BVH(mesh), hbv.Grid(mesh, lam=lam)
        o, d = random_rays(2000, seed=7)
        tmin = np.where(np.arange(len(o)) % 3 == 0, 0.5, 0.0)
        tmax = np.where(np.arange(len(o)) % 4 == 0, 1.0, np.inf)
        assert_same_hits(grid.intersect(o, d), bvh.intersect(o, d), "intersect")
        assert_same_hits(
            grid.intersect(o, d, tmin, tmax), bvh.intersect(o, d, tmin, tmax), "interval"
        )
        np.testing.assert_array_equal(grid.occluded(o, d, tmin, tmax), bvh.occluded(o, d, tmin, tmax))
        for a, b in zip(grid.intersect_all(o, d, tmin, tmax), bvh.intersect_all(o, d, tmin, tmax)):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(grid.count(o, d, threads=1), bvh.count(o, d))
        np.testing.assert_array_equal(grid.contains(o), bvh.contains(o))


def test_grid_stats_pickling_and_errors(sphere):
    mesh, _, f = sphere
    grid = hbv.Grid(mesh)
    s = grid.stats()
    assert s["triangles"] == len(f) and s["lam"] == grid.lam == 2.0
    assert s["cells"] == np.prod(s["resolution"]) > 0 and s["listed"] >= len(f)
    assert s["memory_bytes"] > 0 and s["build_seconds"] >= 0
    copy = pickle.loads(pickle.dumps(hbv.Grid(mesh, lam=1.5)))
    assert copy.lam == 1.5 and repr(copy).startswith("hbv.Grid(")
    o, d = random_rays(100)
    assert_same_hits(copy.intersect(o, d), grid.intersect(o, d), "pickled")
    for bad in [0.0, -1.0, float("nan"), float("inf")]:
        with pytest.raises(ValueError, match="lam"):
            hbv.Grid(mesh, lam=bad)
    with pytest.raises(TypeError, match="mesh: expected an hbv.Mesh"):
        hbv.Grid(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="origins"):
        grid.intersect(o[:, :2], d)
    assert not hasattr(grid, "closest_point")


def test_grid_on_empty_and_degenerate_meshes():
    o, d = random_rays(10)
    for v, f in [(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), (np.eye(3) * [1, 2, 3][0], [[0, 0, 1]])]:
        grid = hbv.Grid(hbv.Mesh(v, f))
        assert not grid.intersect(o, d)["hit"].any() and (grid.count(o, d) == 0).all()
        assert grid.stats()["cells"] == 0


def test_save_and_load_give_the_same_tree(tmp_path, triangle_soup):
    mesh, _, _ = triangle_soup
    bvh = hbv.BVH(mesh, builder="sweep-sah", leaf_size=3, optimize=True)
    path = tmp_path / "soup.hbv"
    bvh.save(path)
    assert sorted(os.listdir(tmp_path)) == ["soup.hbv"]  # no temporary file left behind
    loaded = hbv.load_bvh(path)
    assert loaded.builder == "sweep-sah" and loaded.layout == "wide8"
    s, t = bvh.stats(), loaded.stats()
    for k in ["leaf_size", "optimize", "nodes", "leaves", "depth_max", "expected_tests", "settings"]:
        assert s[k] == t[k], k
    np.testing.assert_array_equal(loaded.mesh.faces, mesh.faces)
    o, d = random_rays(1000)
    assert_same_hits(loaded.intersect(o, d), bvh.intersect(o, d), "loaded")
    assert_same_hits(hbv.load_bvh(str(path), layout="skip").intersect(o, d), bvh.intersect(o, d), "skip")
    copy = pickle.loads(pickle.dumps(loaded))
    assert_same_hits(copy.intersect(o, d), bvh.intersect(o, d), "pickled")


def test_save_never_overwrites_unless_asked(tmp_path, sphere):
    mesh, _, _ = sphere
    path = tmp_path / "tree.hbv"
    path.write_bytes(b"precious")
    bvh = hbv.BVH(mesh)
    with pytest.raises(FileExistsError, match="tree.hbv.*overwrite=True"):
        bvh.save(path)
    assert path.read_bytes() == b"precious"
    bvh.save(path, overwrite=True)
    assert hbv.load_bvh(path).stats()["nodes"] == bvh.stats()["nodes"]
    assert sorted(os.listdir(tmp_path)) == ["tree.hbv"]
    with pytest.raises(FileNotFoundError, match="directory .*no_such_dir does not exist"):
        bvh.save(tmp_path / "no_such_dir" / "t.hbv")
    with pytest.raises(NotADirectoryError, match="tree.hbv is not a directory"):
        bvh.save(path / "t.hbv")
    with pytest.raises(IsADirectoryError, match="it is a directory"):
        bvh.save(tmp_path, overwrite=True)


def test_threads_saving_one_path_at_once_all_succeed(tmp_path, sphere):
    """Each save stages its own temporary file (they were named by the process id alone, so
    two threads saving one path collided): all succeed and one whole file is left."""
    from concurrent.futures import ThreadPoolExecutor

    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    path = tmp_path / "shared.hbv"
    with ThreadPoolExecutor(4) as pool:
        list(pool.map(lambda _: bvh.save(path, overwrite=True), range(16)))
    assert sorted(os.listdir(tmp_path)) == ["shared.hbv"]
    assert hbv.load_bvh(path).stats()["nodes"] == bvh.stats()["nodes"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_save_writes_through_links_and_into_pipes(tmp_path, sphere):
    """A link is written through (the link stays); a pipe or device is written into, never
    renamed over (as root, saving to /dev/null put a regular file in its place)."""
    import stat
    import subprocess
    import sys

    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh)
    target = tmp_path / "target.hbv"
    target.write_bytes(b"old")
    (tmp_path / "link.hbv").symlink_to("target.hbv")
    bvh.save(tmp_path / "link.hbv", overwrite=True)
    assert (tmp_path / "link.hbv").is_symlink()
    assert hbv.load_bvh(target).stats()["nodes"] == bvh.stats()["nodes"]
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    # The reader is another process: save() must not wait on this interpreter.
    reader = subprocess.Popen(
        [sys.executable, "-c", "import sys; sys.stdout.buffer.write(open(sys.argv[1], 'rb').read())", str(pipe)],
        stdout=subprocess.PIPE,
    )
    bvh.save(pipe)
    got, _ = reader.communicate(timeout=60)
    assert stat.S_ISFIFO(os.stat(pipe).st_mode)
    saved = tmp_path / "saved.hbv"
    bvh.save(saved)
    assert got == saved.read_bytes()


def test_loading_bad_files_names_the_file_and_reason(tmp_path, sphere):
    mesh, _, _ = sphere
    good = tmp_path / "good.hbv"
    hbv.BVH(mesh).save(good)
    data = good.read_bytes()
    with pytest.raises(FileNotFoundError, match="missing.hbv"):
        hbv.load_bvh(tmp_path / "missing.hbv")
    cases = {
        "text.hbv": (b"v 0 0 0\n" * 20, "not an hbv BVH file"),
        "short.hbv": (data[: len(data) // 2], "truncated"),
        "flipped.hbv": (data[:-9] + bytes([data[-9] ^ 1]) + data[-8:], "corrupted"),
        "empty.hbv": (b"", ""),
    }
    for name, (content, reason) in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises((ValueError, OSError), match=name) as e:
            hbv.load_bvh(tmp_path / name)
        assert reason in str(e.value), str(e.value)
    with pytest.raises(ValueError, match="layout"):
        hbv.load_bvh(good, layout="wide16")


def test_leaf_sizes_up_to_255_give_the_same_answers():
    v, f = icosphere(4)  # 5120 triangles: leaves of 255 exist
    mesh = hbv.Mesh(v, f)
    o, d = random_rays(1000, seed=5)
    want = hbv.BVH(mesh).intersect(o, d)
    want_all = hbv.BVH(mesh).intersect_all(o, d)
    for builder in ["binned-sah", "median", "lbvh"]:
        for layout in ["wide8", "wide4", "ordered", "recursive", "skip"]:
            bvh = hbv.BVH(mesh, builder=builder, layout=layout, leaf_size=255)
            assert_same_hits(bvh.intersect(o, d), want, f"{builder} {layout}")
            np.testing.assert_array_equal(bvh.occluded(o, d), want["hit"])
        for a, b in zip(bvh.intersect_all(o, d), want_all):
            np.testing.assert_array_equal(a, b)
        cp = bvh.closest_point(o)
        np.testing.assert_array_equal(cp["prim"], hbv.BVH(mesh).closest_point(o)["prim"])
    assert hbv.BVH(mesh, builder="median", leaf_size=255).stats()["leaves"] <= len(f) // 128 + 1
    with pytest.raises(ValueError, match="leaf_size: expected 1 to 255, got 256"):
        hbv.BVH(mesh, leaf_size=256)


def test_readme_python_example_runs(tmp_path, monkeypatch, capsys):
    readme = os.path.join(os.path.dirname(__file__), "..", "..", "README.md")
    if not os.path.exists(readme):
        pytest.skip("README.md not beside the tests")
    text = open(readme, encoding="utf-8").read()
    section = text[text.index("## Python"):]
    code = section[section.index("```python") + len("```python"):]
    code = code[: code.index("```")]
    monkeypatch.chdir(tmp_path)  # it writes cube.hbv
    exec(compile(code, "README.md (Python example)", "exec"), {})
    assert (tmp_path / "cube.hbv").exists()
    assert "[ True False]" in capsys.readouterr().out
