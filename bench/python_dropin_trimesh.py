#!/usr/bin/env python3
"""What `hbv.trimesh.RayMeshIntersector`, trimesh's Embree intersector swapped for hbv's, costs
over the hbv call it wraps, and how it compares with trimesh's own Embree intersector, on the
same rays (1,000,000 by default, float64 as trimesh users pass them).

Pairs, on the tree the drop-in built (`intersector.bvh`), each ratio the drop-in's time over
the native call's:

- `intersects_first` against `BVH.intersect`;
- `intersects_any` against `BVH.occluded`;
- `intersects_id` (every hit, trimesh's Embree order) against `BVH.intersect_all`;
- `intersects_location` (every hit, float64 locations from the hit triangle's plane) against
  `BVH.intersect_all` followed by NumPy's `o + t·d` (locations from float32 `t`: the native way
  to the same arrays, less exact).

Each round runs every call once, the drop-in and the native call of a pair back to back in
alternating order; the first round is discarded; a ratio is the median of the rounds' ratios.
trimesh's Embree intersector (`trimesh.ray.ray_pyembree`, embreex) answers the same calls,
timed over `--embree-repeat` rounds. Rays: `python_compare.py`'s `random` set.

`--clock cpu` times the process's CPU time instead of the wall clock: run with
`RAYON_NUM_THREADS=1` (every call on one thread), it measures what each call costs in work,
steadier than the wall clock on a machine that other jobs share.

    ../py-bench-venv/bin/python bench/python_dropin_trimesh.py [MESH.ply ...] [--rays 1000000] [--repeat 7] [--clock wall|cpu]
"""

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "python"))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import hbv.trimesh  # noqa: E402
from python_compare import ray_sets  # noqa: E402

SCENES = pathlib.Path(__file__).resolve().parent.parent.parent / "shared/scenes"


def pairs(drop, o, d):
    """{query: (drop-in call, native call)} on the drop-in's own tree."""
    bvh = drop.bvh

    def native_locations():
        index_ray, t, prim = bvh.intersect_all(o, d)
        return prim, index_ray, o[index_ray] + t[:, None].astype(np.float64) * d[index_ray]

    return {
        "intersects_first": (lambda: drop.intersects_first(o, d), lambda: bvh.intersect(o, d)),
        "intersects_any": (lambda: drop.intersects_any(o, d), lambda: bvh.occluded(o, d)),
        "intersects_id": (lambda: drop.intersects_id(o, d), lambda: bvh.intersect_all(o, d)),
        "intersects_location": (lambda: drop.intersects_location(o, d), native_locations),
    }


CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCK["wall"]


def seconds_of(call):
    start = clock()
    call()
    return clock() - start


def measure(path, args):
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector as TrimeshEmbree

    mesh = trimesh.load(str(path), process=False)
    o, d = (a.astype(np.float64) for a in ray_sets(np.asarray(mesh.vertices), args.rays, args.seed)["random"])
    drop = hbv.trimesh.RayMeshIntersector(mesh)
    calls = pairs(drop, o, d)
    drop_s = {q: [] for q in calls}
    native_s = {q: [] for q in calls}
    for round_ in range(args.repeat + 1):
        for q, (drop_call, native_call) in calls.items():
            order = [(drop_s, drop_call), (native_s, native_call)]
            for times, call in order if round_ % 2 else order[::-1]:
                s = seconds_of(call)
                if round_:
                    times[q].append(s)
    embree = TrimeshEmbree(mesh)
    embree_calls = {
        "intersects_first": lambda: embree.intersects_first(o, d),
        "intersects_any": lambda: embree.intersects_any(o, d),
        "intersects_id": lambda: embree.intersects_id(o, d),
        "intersects_location": lambda: embree.intersects_location(o, d),
    }
    embree_s = {q: [seconds_of(c) for _ in range(args.embree_repeat + 1)][1:] for q, c in embree_calls.items()}
    return len(mesh.faces), drop_s, native_s, embree_s


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("meshes", nargs="*", type=pathlib.Path)
    p.add_argument("--rays", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--embree-repeat", type=int, default=2)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--clock", choices=sorted(CLOCK), default="wall")
    args = p.parse_args()
    global clock
    clock = CLOCK[args.clock]
    meshes = args.meshes or sorted(SCENES.glob("*.ply"), key=lambda m: m.stat().st_size)
    if not meshes:
        print(f"no meshes given and none in {SCENES}: nothing to measure")
        return
    print("| mesh (triangles) | call | native (ms) | drop-in (ms) | drop-in / native | "
          "trimesh Embree (ms) | Embree / drop-in |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for path in meshes:
        triangles, drop_s, native_s, embree_s = measure(path, args)
        for q in drop_s:
            ratio = statistics.median(a / b for a, b in zip(drop_s[q], native_s[q]))
            drop_ms = statistics.median(drop_s[q]) * 1e3
            native_ms = statistics.median(native_s[q]) * 1e3
            embree_ms = statistics.median(embree_s[q]) * 1e3
            print(f"| {path.stem} ({triangles:,}) | `{q}` | {native_ms:.1f} | {drop_ms:.1f} | "
                  f"{ratio:.3f} | {embree_ms:.0f} | {embree_ms / drop_ms:.1f} |", flush=True)


if __name__ == "__main__":
    main()
