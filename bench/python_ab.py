"""A/B of two or more builds of the hbv module in one process, against embreex.

Each DIR holds a copy of the package (DIR/hbv/__init__.py, *.py, *.pyi and the extension as
_hbv.abi3.so, e.g. `cargo build --release -p hbv-py` copied from target/release/lib_hbv.so). All
are loaded into this one process, as packages hbv_0, hbv_1, ... (each extension is its own copy
of the library), and timed in turn, round after round, on the ray sets of python_compare.py,
with embreex in the same rounds. On a virtual machine whose speed drifts by ±25% from minute to
minute, builds timed in separate processes differ by more than most changes do; in one process
the drift hits every contender alike, and the median of the per-round ratios is stable to 1–2%.

    OPENBLAS_NUM_THREADS=1 nice -n -20 python bench/python_ab.py spot,teapot /tmp/ab/old /tmp/ab/new

prints, per mesh and ray set, each build's ratio to embreex and to the first build.
"""

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", help="comma-separated names in --scenes (without .ply)")
    parser.add_argument("builds", nargs="+", help="directories holding a copy of the package")
    parser.add_argument("--scenes", default=str(Path(__file__).parents[1] / ".." / "shared" / "scenes"))
    parser.add_argument("--rays", type=int, default=262144)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--query", choices=["intersect", "occluded"], default="intersect")
    args = parser.parse_args()

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
        for set_name, (o, d) in python_compare.ray_sets(v, args.rays, 1).items():
            output = 1 if args.query == "intersect" else 0
            calls = {"embreex": lambda: embree.run(o, d, output=output)}
            for name, bvh in zip(names, bvhs):
                calls[name] = (lambda b: lambda: getattr(b, args.query)(o, d, threads=1))(bvh)
            for call in calls.values():
                call()
            seconds = {name: [] for name in calls}
            for _ in range(args.rounds):
                for name, call in calls.items():
                    start = time.perf_counter()
                    call()
                    seconds[name].append(time.perf_counter() - start)
            ratio = lambda a, b: statistics.median(x / y for x, y in zip(seconds[a], seconds[b]))
            print(f"{mesh_name}/{set_name}: " + "  ".join(
                f"{name} {ratio('embreex', name):.3f}x embreex ({ratio(names[0], name):.3f}x {names[0]})"
                for name in names), flush=True)


if __name__ == "__main__":
    main()
