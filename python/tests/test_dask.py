"""hbv.dask on a local cluster of 2 worker processes: every query on BVH, Grid and Scene equal
bit for bit to the in-memory call with uneven chunks, one load per worker, a killed worker's
tasks rerun with the same answers, Zarr and .npy round trips, and the checksum refusal."""

import os
import signal
import time

import numpy as np
import pytest

pytest.importorskip("dask", reason="hbv.dask needs dask: pip install 'hbv[dask]'")
pytest.importorskip("distributed", reason="hbv.dask's tests need dask.distributed: pip install 'hbv[dask]'")

import dask  # noqa: E402
import dask.array as da  # noqa: E402
from distributed import Client, LocalCluster  # noqa: E402

import hbv  # noqa: E402
import hbv.dask  # noqa: E402
from conftest import icosphere, random_rays, soup  # noqa: E402

N = 1008
CHUNKS = (1, 7, 1000)  # uneven, a single ray among them


@pytest.fixture(scope="module")
def client():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as c:
        yield c


def sphere_mesh():
    return hbv.Mesh(*icosphere(3))


def scene():
    s = hbv.Scene()
    mesh = sphere_mesh()
    s.add(mesh, mask=1)
    s.add(mesh, np.array([[0.5, 0, 0, 0.6], [0, 0.5, 0, 0], [0, 0, 0.5, 0]]), mask=2)
    return s


STRUCTURES = {
    "bvh": lambda: hbv.BVH(sphere_mesh()),
    "grid": lambda: hbv.Grid(sphere_mesh()),
    "scene": scene,
}
RAY_QUERIES = ["intersect", "occluded", "count", "intersect_all"]
POINT_QUERIES = ["contains", "closest_point", "signed_distance"]


def rays():
    o, d = random_rays(N, seed=5)
    rng = np.random.default_rng(6)
    return o, d, rng.uniform(0.0, 0.5, N), rng.uniform(0.5, 4.0, N), rng.integers(0, 4, N)


def chunked(a):
    return da.from_array(a, chunks=(CHUNKS,) + a.shape[1:])


def assert_same(got, want):
    """Bit for bit: same type, members, dtypes and bytes."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and list(got) == list(want)
        for key in want:
            assert_same(got[key], want[key])
    elif isinstance(want, tuple):
        assert isinstance(got, tuple) and len(got) == len(want)
        for g, w in zip(got, want):
            assert_same(g, w)
    else:
        got = np.asarray(got)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == want.tobytes()


def supported(kind, query):
    return not (kind == "grid" and query in ("closest_point", "signed_distance"))


@pytest.mark.parametrize("kind", list(STRUCTURES))
@pytest.mark.parametrize("query", RAY_QUERIES)
def test_ray_queries_equal_in_memory(client, kind, query):
    structure = STRUCTURES[kind]()
    o, d, tmin, tmax, mask = rays()
    extra = {"mask": mask} if kind == "scene" else {}
    want = getattr(structure, query)(o, d, tmin, tmax, **extra)
    lazy = getattr(hbv.dask, query)(structure, chunked(o), chunked(d), chunked(tmin), tmax, **extra)
    (got,) = dask.compute(lazy)
    if query == "intersect_all":
        assert np.isnan(lazy[0].chunks[0]).all()  # ragged: lengths unknown until computed
    assert_same(got, want)
    # Scalars for the bounds, no mask.
    want = getattr(structure, query)(o, d, 0.1, 3.0)
    (got,) = dask.compute(getattr(hbv.dask, query)(structure, chunked(o), chunked(d), 0.1, 3.0))
    assert_same(got, want)


@pytest.mark.parametrize("kind", list(STRUCTURES))
@pytest.mark.parametrize("query", POINT_QUERIES)
def test_point_queries_equal_in_memory(client, kind, query):
    structure = STRUCTURES[kind]()
    points = random_rays(N, seed=7)[0]
    if not supported(kind, query):
        with pytest.raises(TypeError, match=query):
            getattr(hbv.dask, query)(structure, chunked(points))
        return
    want = getattr(structure, query)(points)
    (got,) = dask.compute(getattr(hbv.dask, query)(structure, chunked(points)))
    assert_same(got, want)
    if kind == "scene":
        mask = np.random.default_rng(8).integers(0, 4, N)
        want = getattr(structure, query)(points, mask=mask)
        (got,) = dask.compute(getattr(hbv.dask, query)(structure, chunked(points), chunked(mask)))
        assert_same(got, want)


def test_members_and_chunks_before_compute(client):
    bvh = STRUCTURES["bvh"]()
    o, d = random_rays(N)[:2]
    hits = hbv.dask.intersect(bvh, chunked(o), da.from_array(d, chunks=(500, 2)))
    assert hits["t"].dtype == np.float32 and hits["t"].chunks == (CHUNKS,)
    assert hits["normal"].shape == (N, 3) and hits["normal"].chunks == (CHUNKS, (3,))
    scene_hits = hbv.dask.intersect(scene(), chunked(o), chunked(d))
    assert list(scene_hits) == list(scene().intersect(o[:1], d[:1]))


def test_local_scheduler_without_a_cluster():
    bvh = STRUCTURES["bvh"]()
    handle = hbv.dask.share(bvh, client=False)
    assert handle.local
    o, d = random_rays(N)[:2]
    with dask.config.set(scheduler="sync"):
        (got,) = dask.compute(hbv.dask.intersect_all(handle, chunked(o), chunked(d)))
    assert_same(got, bvh.intersect_all(o, d))


def misaligned(block):
    """The chunk as a C-ordered but misaligned, read-only view (what a deserialized chunk can be)."""
    raw = np.frombuffer(b"\0" + block.tobytes(), np.uint8)[1:]
    return raw.view(block.dtype).reshape(block.shape)


def test_nan_empty_and_misaligned_chunks(client):
    structure = scene()
    o, d = random_rays(N, seed=17)[:2]
    o[::5] = np.nan
    d[3::7] = 0.0
    want = structure.intersect(o, d)
    odd = chunked(o).map_blocks(misaligned, dtype=o.dtype)
    (got,) = dask.compute(hbv.dask.intersect(structure, odd, chunked(d)))
    assert_same(got, want)
    empty = np.zeros((0, 3))
    for query in RAY_QUERIES:
        (got,) = dask.compute(getattr(hbv.dask, query)(structure, da.from_array(empty), empty))
        assert_same(got, getattr(structure, query)(empty, empty))


def test_bad_arguments_fail_at_graph_build(client):
    bvh = STRUCTURES["bvh"]()
    o, d = random_rays(10)[:2]
    with pytest.raises(TypeError, match="mask"):
        hbv.dask.intersect(bvh, o, d, mask=1)
    with pytest.raises(ValueError, match="directions"):
        hbv.dask.intersect(bvh, o, d[:5])
    with pytest.raises(ValueError, match="origins"):
        hbv.dask.occluded(bvh, o[:, :2], d)
    with pytest.raises(ValueError, match="tmax"):
        hbv.dask.count(bvh, o, d, tmax=np.ones(3))
    with pytest.raises(TypeError, match="structure"):
        hbv.dask.count(object(), o, d)
    with pytest.raises(TypeError, match="Grid has no closest_point"):
        hbv.dask.closest_point(STRUCTURES["grid"](), o)
    with pytest.raises(ValueError, match="not a .hbv file"):
        path = os.path.join(os.path.dirname(__file__), "conftest.py")
        hbv.dask.open(path)


def test_one_load_per_worker(client, tmp_path):
    bvh = hbv.BVH(hbv.Mesh(*soup(200, seed=11)))
    handle = hbv.dask.share(bvh)
    assert hbv.dask.share(bvh) is handle  # the same bytes are not scattered again
    o, d = random_rays(N)[:2]
    many = da.from_array(o, chunks=(16, 3)), da.from_array(d, chunks=(16, 3))
    for graph in range(3):
        dask.compute(hbv.dask.count(handle, *many), hbv.dask.intersect(bvh, *many))
    counts = client.run(hbv.dask.load_counts)
    per_worker = [c.get(handle.checksum, 0) for c in counts.values()]
    assert sum(per_worker) >= 1 and max(per_worker) == 1
    assert set(hbv.dask.preload(handle).values()) == {1}  # now loaded on both, once each
    hbv.dask.release(handle)  # dropped everywhere: the next graph loads it again
    dask.compute(hbv.dask.count(bvh, *many))
    assert max(c[handle.checksum] for c in client.run(hbv.dask.load_counts).values()) == 2
    # From a shared file: one more load per worker (another source, the same checksum rule).
    path = tmp_path / "soup.hbv"
    bvh.save(path)
    opened = hbv.dask.open(path)
    assert opened.kind == "bvh"
    (got,) = dask.compute(hbv.dask.count(opened, *many))
    assert_same(got, bvh.count(o, d))


def test_zarr_and_npy_round_trip(client, tmp_path):
    zarr = pytest.importorskip("zarr", reason="the Zarr round trip needs zarr")
    structure = scene()
    structure.save(tmp_path / "scene.hbv")
    opened = hbv.dask.open(tmp_path / "scene.hbv")
    assert opened.kind == "scene"
    o, d = random_rays(N, seed=9)[:2]
    store = str(tmp_path / "rays.zarr")
    da.to_zarr(da.from_array(o, chunks=(100, 3)), store, component="origins")
    da.to_zarr(da.from_array(d, chunks=(100, 3)), store, component="directions")
    hits = hbv.dask.intersect(opened, da.from_zarr(store, component="origins"),
                              da.from_zarr(store, component="directions").rechunk((250, 3)))
    out = str(tmp_path / "hits.zarr")
    dask.compute(*[da.to_zarr(hits[k], out, component=k, compute=False) for k in hits])
    group = zarr.open_group(out, mode="r")
    assert_same({k: group[k][...] for k in hits}, structure.intersect(o, d))
    np.save(tmp_path / "o.npy", o)
    np.save(tmp_path / "d.npy", np.asfortranarray(d))
    lazy = hbv.dask.count(structure, hbv.dask.from_npy(tmp_path / "o.npy", 100),
                          hbv.dask.from_npy(tmp_path / "d.npy", 100))
    assert_same(lazy.compute(), structure.count(o, d))


def test_changed_file_is_refused(client, tmp_path):
    path = tmp_path / "changing.hbv"
    hbv.BVH(hbv.Mesh(*soup(50, seed=21))).save(path)
    handle = hbv.dask.open(path)
    hbv.BVH(hbv.Mesh(*soup(50, seed=22))).save(path, overwrite=True)
    o, d = random_rays(20)[:2]
    with pytest.raises(hbv.dask.StructureMismatchError, match="checksum"):
        hbv.dask.count(handle, o, d).compute()


def slow_rays(block, block_id=None):
    time.sleep(0.05)  # a slow ray source, so that the graph is mid-run when a worker dies
    return block


def run_killing(client, lazy, victims):
    """Computes ``lazy`` while SIGKILLing the worker processes ``victims`` ({address: pid}) once
    their first task runs; waits for their replacements. Returns the answer."""
    future = client.compute(lazy)
    deadline = time.time() + 10
    while not all(client.processing().get(w) for w in victims) and time.time() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)
    assert not future.done(), "the graph ended before the worker could be killed"
    for pid in victims.values():
        os.kill(pid, signal.SIGKILL)
    got = future.result(timeout=60)
    deadline = time.time() + 60  # the nanny starts a new process; the scheduler drops the old
    while True:
        now = client.run(os.getpid, on_error="ignore")
        if len(now) == 2 and not set(victims.values()) & set(now.values()):
            return got
        assert time.time() < deadline, f"the killed workers were not replaced: {now}"
        time.sleep(0.2)


def slow_origins(o):
    return chunked(o).rechunk((24, 3)).map_blocks(slow_rays, dtype=o.dtype)


def test_killed_worker_is_replaced_and_answers_are_the_same(client):
    structure = scene()
    handle = hbv.dask.share(structure)
    o, d = random_rays(N, seed=13)[:2]
    lazy = hbv.dask.intersect(handle, slow_origins(o), chunked(d))
    holders = client.who_has([handle.payload])[handle.payload.key]
    victim = sorted(holders)[0]  # a worker holding the structure's bytes
    got = run_killing(client, lazy, {victim: client.run(os.getpid)[victim]})
    assert_same(got, structure.intersect(o, d))
    assert all(c.get(handle.checksum, 1) == 1 for c in client.run(hbv.dask.load_counts).values())


def test_every_worker_killed_the_structure_is_sent_again(client):
    structure = hbv.Grid(hbv.Mesh(*soup(120, seed=31)))
    o, d = random_rays(N, seed=14)[:2]
    lazy = hbv.dask.count(structure, slow_origins(o), chunked(d))
    got = run_killing(client, lazy, client.run(os.getpid))  # every copy of the bytes dies
    assert_same(got, structure.count(o, d))


EXAMPLE = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "dask_trace_zarr.py")


@pytest.mark.skipif(not os.path.exists(EXAMPLE), reason="examples/ is not beside the tests")
def test_zarr_example_traces_and_never_replaces_an_output_unasked(client, tmp_path):
    pytest.importorskip("zarr")
    import subprocess
    import sys

    command = [sys.executable, EXAMPLE, "--rays", "3000", "--chunk", "1000",
               "--scheduler", client.scheduler.address,
               "--store", str(tmp_path / "rays.zarr"), "--out", str(tmp_path / "hits.zarr")]
    first = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    origins = da.from_zarr(str(tmp_path / "rays.zarr"), component="origins").compute()
    directions = da.from_zarr(str(tmp_path / "rays.zarr"), component="directions").compute()
    want = hbv.load_scene(str(tmp_path / "hits.scene.hbv")).intersect(origins, directions)
    for name, array in want.items():
        got = da.from_zarr(str(tmp_path / "hits.zarr"), component=name).compute()
        assert got.dtype == array.dtype and got.tobytes() == array.tobytes(), name
    before = sorted(p.name for p in (tmp_path / "hits.zarr").rglob("*"))
    again = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert again.returncode != 0 and "--force" in again.stderr
    assert sorted(p.name for p in (tmp_path / "hits.zarr").rglob("*")) == before
    forced = subprocess.run(command + ["--force"], capture_output=True, text=True, timeout=120)
    assert forced.returncode == 0, forced.stderr
