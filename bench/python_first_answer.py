#!/usr/bin/env python3
"""Time to the first answer from Python: a structure made from a mesh's arrays and one closest-hit
query of 10,000 random rays on it, as a script that builds once and asks once waits for.

Contenders, each starting from the same NumPy arrays (float32 vertices, int faces) and ending
with the hits in NumPy arrays:

- hbv: `hbv.BVH(hbv.Mesh(v, f), quality=Q)` then `intersect(o, d)` (all cores), for each
  `BuildQuality` asked (`--qualities`, default low and medium);
- embreex: `EmbreeScene()` and `TriangleMesh(scene, v[f])`, then `run(o, d, output=1)` (Embree 4
  commits its scene on the first query);
- Open3D: `RaycastingScene()`, `add_triangles`, then `cast_rays` (all cores; it builds on the
  first query);
- trimesh: `Trimesh(v, f, process=False)` and its Embree intersector, then `intersects_first`.

Each round runs every contender once, interleaved (in the listed order, then in the reverse
order the next round, so that none always follows the same one), on a structure made anew; the
first round is discarded (imports, first-touch of the libraries' code); the median of `--repeat` rounds is
reported, and each ratio is the median of the rounds' ratios. Rays: `python_compare.py`'s
`random` set (from a sphere about the mesh towards points of its box).

`--baseline DIR` adds another build of hbv (DIR: the folder holding its `hbv` package, e.g. a
copy of `python/` with that commit's extension) to the same rounds, each quality as
`base <quality>`, and a last column: each quality's baseline time over this build's (the
median of the rounds' ratios; above 1: this build answers sooner).

    ../py-bench-venv/bin/python bench/python_first_answer.py [MESH.ply ...] [--rays 10000] [--repeat 7] [--baseline DIR]
"""

import argparse
import importlib.util
import os
import pathlib
import statistics
import sys
import time

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import hbv  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from python_compare import ray_sets  # noqa: E402

SCENES = pathlib.Path(__file__).resolve().parent.parent.parent / "shared/scenes"


def load_baseline(folder):
    """The `hbv` package in `folder`, imported as `hbv_baseline` beside this build's."""
    package = pathlib.Path(folder).resolve() / "hbv"
    spec = importlib.util.spec_from_file_location(
        "hbv_baseline", package / "__init__.py", submodule_search_locations=[str(package)])
    module = importlib.util.module_from_spec(spec)
    sys.modules["hbv_baseline"] = module
    spec.loader.exec_module(module)
    return module


def contenders(v, f, o, d, qualities, baseline):
    import open3d as o3d
    import trimesh
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh as EmbreeMesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector as TrimeshEmbree

    def hbv_answer(quality, package=hbv):
        return lambda: package.BVH(package.Mesh(v, f), quality=quality).intersect(o, d)["prim"]

    def embreex_answer():
        scene = rtcore_scene.EmbreeScene()
        EmbreeMesh(scene, v[f])
        return scene.run(o, d, output=1)["primID"]

    def open3d_answer():
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32)))
        return scene.cast_rays(o3d.core.Tensor(np.hstack([o, d])))["primitive_ids"].numpy()

    def trimesh_answer():
        mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
        return TrimeshEmbree(mesh).intersects_first(o, d)

    run = {f"hbv {q}": hbv_answer(q) for q in qualities}
    if baseline is not None:
        run.update({f"base {q}": hbv_answer(q, baseline) for q in qualities})
    run.update({"embreex": embreex_answer, "open3d": open3d_answer, "trimesh": trimesh_answer})
    return run


def measure(path, args):
    mesh = hbv.load(str(path))
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    o, d = ray_sets(v, args.rays, args.seed)["random"]
    run = contenders(v, f, o, d, args.qualities, args.baseline_package)
    seconds = {name: [] for name in run}
    for round_ in range(args.repeat + 1):
        order = list(run.items())
        for name, call in order if round_ % 2 else reversed(order):
            start = time.perf_counter()
            call()
            if round_:
                seconds[name].append(time.perf_counter() - start)
    return len(f), seconds


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("meshes", nargs="*", type=pathlib.Path)
    p.add_argument("--rays", type=int, default=10_000)
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--qualities", nargs="+", default=["low", "medium"])
    p.add_argument("--baseline", type=pathlib.Path, help="folder holding another build's hbv")
    args = p.parse_args()
    args.baseline_package = load_baseline(args.baseline) if args.baseline else None
    base_names = [f"base {q}" for q in args.qualities] if args.baseline else []
    meshes = args.meshes or sorted(SCENES.glob("*.ply"), key=lambda m: m.stat().st_size)
    print("| mesh (triangles) | " + " | ".join(f"hbv {q}" for q in args.qualities)
          + "".join(f" | {n}" for n in base_names)
          + " | embreex | Open3D | trimesh | best hbv against each (×) |"
          + (" baseline over this build, each quality (×) |" if base_names else ""))
    print("| --- |" + " ---: |" * (len(args.qualities) + len(base_names) + 4 + bool(base_names)))
    for path in meshes:
        triangles, seconds = measure(path, args)
        ms = {name: statistics.median(s) * 1e3 for name, s in seconds.items()}
        hbv_names = [f"hbv {q}" for q in args.qualities]
        best = [min(seconds[n][r] for n in hbv_names) for r in range(args.repeat)]
        ratio = {other: statistics.median(seconds[other][r] / best[r] for r in range(args.repeat))
                 for other in ("embreex", "open3d", "trimesh")}
        cells = [f"{ms[n]:.1f}" for n in hbv_names + base_names + ["embreex", "open3d", "trimesh"]]
        ratios = " · ".join(f"{ratio[o]:.2f}" for o in ("embreex", "open3d", "trimesh"))
        if base_names:
            gains = [statistics.median(seconds[b][r] / seconds[n][r] for r in range(args.repeat))
                     for b, n in zip(base_names, hbv_names)]
            ratios += " | " + " · ".join(f"{g:.2f}" for g in gains)
        print(f"| {path.stem} ({triangles:,}) | " + " | ".join(cells) + f" | {ratios} |", flush=True)


if __name__ == "__main__":
    main()
