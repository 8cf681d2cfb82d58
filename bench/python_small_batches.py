#!/usr/bin/env python3
"""One thread against all threads on small batches of `closest_point` and `intersect_all`.

For each mesh and batch size, `--rounds` rounds each call `threads=1` and then `threads=None`
(every core), each call preceded by `--busy` milliseconds of Python arithmetic (the process keeps
its core, as a program that does other work between calls; the pool's threads idle meanwhile).
Prints the median and 90th-percentile time of each, in µs. Points are `python_compare.py`'s
(uniform in the mesh's box grown 10%), rays its random ones.

    ../py-bench-venv/bin/python bench/python_small_batches.py cornell_box spot bunny --query closest_point
    ../py-bench-venv/bin/python bench/python_small_batches.py cornell_box teapot bunny --query intersect_all --sizes 512 2048 8192

Meshes are names in ../shared/scenes or paths. To see how a pool hand-off behaves on a busy
machine, run it while other processes keep the cores busy.
"""

import argparse
import pathlib
import statistics
import sys
import time

import numpy as np

import hbv

BENCH = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))
from python_compare import query_points, ray_sets  # noqa: E402


def mesh_path(name):
    path = pathlib.Path(name)
    return path if path.suffix else BENCH.parent.parent / "shared" / "scenes" / f"{name}.ply"


def busy(milliseconds):
    end = time.perf_counter() + milliseconds / 1000
    while time.perf_counter() < end:
        pass


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("meshes", nargs="+")
    p.add_argument("--query", choices=["closest_point", "intersect_all"], default="closest_point")
    p.add_argument("--sizes", type=int, nargs="+", default=[256, 257, 512, 1024, 2048, 8192])
    p.add_argument("--rounds", type=int, default=60, help="calls of each kind per size (default 60)")
    p.add_argument("--busy", type=float, default=2.0,
                   help="milliseconds of Python arithmetic before each call (default 2)")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    largest = max(args.sizes)
    for name in args.meshes:
        mesh = hbv.load(mesh_path(name))
        bvh = hbv.BVH(mesh)
        if args.query == "closest_point":
            points = query_points(mesh.vertices, largest, args.seed)
            call = lambda n, threads: bvh.closest_point(points[:n], threads=threads)
        else:
            o, d = ray_sets(mesh.vertices, largest, args.seed)["random"]
            call = lambda n, threads: bvh.intersect_all(o[:n], d[:n], threads=threads)
        call(largest, 1)
        call(largest, None)
        for n in args.sizes:
            times = {1: [], None: []}
            for _ in range(args.rounds):
                for threads in (1, None):
                    busy(args.busy)
                    start = time.perf_counter()
                    call(n, threads)
                    times[threads].append(time.perf_counter() - start)
            row = []
            for threads, label in ((1, "one thread"), (None, "all threads")):
                t = np.array(times[threads]) * 1e6
                row.append(f"{label} median {statistics.median(t):.0f} µs, p90 {np.percentile(t, 90):.0f}")
            print(f"{mesh_path(name).name} {args.query} {n}: " + "; ".join(row))


if __name__ == "__main__":
    main()
