"""A/B of two or more builds of the hbv module in one process, against embreex.

Each DIR holds a copy of the package (DIR/hbv/__init__.py, *.py, *.pyi and the extension as
_hbv.abi3.so, e.g. `cargo build --release -p hbv-py` copied from target/release/lib_hbv.so). All
are loaded into this one process, as packages hbv_0, hbv_1, ... (each extension is its own copy
of the library), and timed in turn, round after round, on the ray sets of python_compare.py,
with embreex in the same rounds. On a virtual machine whose speed drifts by ±25% from minute to
minute, builds timed in separate processes differ by more than most changes do; in one process
the drift hits every contender alike, and the median of the per-round ratios is stable to 1–2%.

    OPENBLAS_NUM_THREADS=1 nice -n -20 python bench/python_ab.py spot,teapot /tmp/ab/old /tmp/ab/new

prints, per mesh and ray set, each build's ratio to embreex and to the first build, after
checking that every build answers alike. `--ray-dir DIR` traces the ray files DIR/MESH/*.npz of
`hbv bench MESH --write-rays DIR/MESH` with their intervals (rays that leave a surface);
`--query intersect_all|count|contains` times the every-hit queries against the first build
(`contains` on python_compare.py's query points, one per ray of the set). `--threads N` (or
`all`) gives hbv's calls `threads=`; embreex stays on one thread.
"""

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import python_compare  # noqa: E402  (its ray sets)


def load_copy(directory, k):
    name = f"hbv_{k}"
    package = Path(directory) / "hbv"
    spec = importlib.util.spec_from_file_location(
        name, package / "__init__.py", submodule_search_locations=[str(package)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


# The every-hit queries, which embreex has no counterpart of: timed against the first build only.
EVERY_HIT = ("intersect_all", "count", "contains")


def ray_sets(args, vertices, mesh_name):
    """{name: (origins, directions, tmin, tmax)}: python_compare.py's sets, or with --ray-dir
    the ray files (../shared/RAYS.md) in RAY_DIR/MESH/, as `hbv bench MESH --write-rays` writes
    them, with their intervals."""
    if args.ray_dir is None:
        return {name: (o, d, None, None)
                for name, (o, d) in python_compare.ray_sets(vertices, args.rays, 1).items()}
    sets = {}
    for path in sorted((Path(args.ray_dir) / mesh_name).glob("*.npz")):
        with np.load(path) as f:
            sets[path.stem] = tuple(np.asarray(f[k]) for k in ("origins", "directions", "tmin", "tmax"))
    return sets


def embree_call(embree, query, o, d, tmin, tmax):
    """EmbreeScene.run on the same rays: embreex starts each ray at t = 0, so a ray [tmin, tmax]
    is given as the origin o + tmin d with dists = tmax - tmin (as embree_compare.py does)."""
    if tmin is None:
        return lambda: embree.run(o, d, output=1 if query == "intersect" else 0)
    origins = np.ascontiguousarray(o + tmin[:, None] * d, dtype=np.float32)
    dists = np.ascontiguousarray(tmax - tmin, dtype=np.float32)
    d = np.ascontiguousarray(d, dtype=np.float32)
    if query == "intersect":
        return lambda: embree.run(origins, d, dists=dists, query="INTERSECT", output=1)
    return lambda: embree.run(origins, d, dists=dists, query="OCCLUDED")


def same_answers(a, b):
    """Whether two builds answered alike: arrays, tuples of arrays or dicts of arrays."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    if isinstance(a, tuple):
        return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    return np.array_equal(a, b)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", help="comma-separated names in --scenes (without .ply)")
    parser.add_argument("builds", nargs="+", help="directories holding a copy of the package")
    parser.add_argument("--scenes", default=str(Path(__file__).parents[1] / ".." / "shared" / "scenes"))
    parser.add_argument("--rays", type=int, default=262144)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--threads", default="1",
                        help="threads= of hbv's calls: a count, or 'all' for None (every core); "
                        "default 1. embreex runs on one thread whatever this says")
    parser.add_argument("--query", choices=["intersect", "occluded", *EVERY_HIT], default="intersect")
    parser.add_argument("--ray-dir", help="trace the ray files RAY_DIR/MESH/*.npz (with their "
                        "intervals) instead of python_compare.py's sets")
    args = parser.parse_args()
    threads = None if args.threads == "all" else int(args.threads)

    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh as EmbreeMesh

    modules = [load_copy(d, k) for k, d in enumerate(args.builds)]
    names = [Path(d).name for d in args.builds]
    for mesh_name in args.meshes.split(","):
        mesh = modules[0].load(str(Path(args.scenes) / f"{mesh_name}.ply"))
        v, f = mesh.vertices, mesh.faces
        embree = rtcore_scene.EmbreeScene()
        EmbreeMesh(embree, v[f])
        bvhs = [m.BVH(m.Mesh(v, f)) for m in modules]
        for set_name, (o, d, tmin, tmax) in ray_sets(args, v, mesh_name).items():
            if args.query == "contains":
                # Points, not rays: python_compare.py's nearest-point queries.
                points = python_compare.query_points(v, len(o), 1)
                query_args, bounds = (points,), {}
            else:
                query_args, bounds = (o, d), {"tmin": tmin, "tmax": tmax}
            calls = {} if args.query in EVERY_HIT else {
                "embreex": embree_call(embree, args.query, o, d, tmin, tmax)}
            for name, bvh in zip(names, bvhs):
                calls[name] = (lambda b: lambda: getattr(b, args.query)(
                    *query_args, **bounds, threads=threads))(bvh)
            answers = {name: call() for name, call in calls.items()}
            for name in names[1:]:
                if not same_answers(answers[names[0]], answers[name]):
                    sys.exit(f"{mesh_name}/{set_name}: {name} answers differently from {names[0]}")
            seconds = {name: [] for name in calls}
            for _ in range(args.rounds):
                for name, call in calls.items():
                    start = time.perf_counter()
                    call()
                    seconds[name].append(time.perf_counter() - start)
            ratio = lambda a, b: statistics.median(x / y for x, y in zip(seconds[a], seconds[b]))
            against = (lambda name: "") if args.query in EVERY_HIT else (
                lambda name: f"{ratio('embreex', name):.3f}x embreex ")
            print(f"{mesh_name}/{set_name}: " + "  ".join(
                f"{name} {against(name)}({ratio(names[0], name):.3f}x {names[0]})"
                for name in names), flush=True)


if __name__ == "__main__":
    main()
