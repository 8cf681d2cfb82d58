#!/usr/bin/env python3
"""How hbv's `threads=` choice behaves on calls of a few hundred to a few hundred thousand rays.

For each ray set of `python_compare.py` (camera and random rays) and each batch size, the median
time of `BVH.intersect(o, d, threads=1)` and of `BVH.intersect(o, d)` (every core), each call
preceded by `--gap` milliseconds of sleep, as a program that does other work between calls
would (the pool's threads fall asleep in between and must be woken); and the median of the
same all-threads call made back to back (`warm`: its threads still awake).

    ../py-bench-venv/bin/python bench/python_small_calls.py [MESH.ply] [--calls 31] [--gap 2]
"""

import argparse
import pathlib
import statistics
import sys
import time

import hbv

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from python_compare import ray_sets  # noqa: E402

SIZES = (300, 2_000, 5_000, 10_000, 50_000, 200_000)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh", nargs="?", type=pathlib.Path,
                   default=pathlib.Path(__file__).resolve().parent.parent.parent / "shared/scenes/teapot.ply")
    p.add_argument("--calls", type=int, default=31, help="calls per median (default 31)")
    p.add_argument("--gap", type=float, default=2.0, help="milliseconds of sleep before each call (default 2)")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    mesh = hbv.load(args.mesh)
    bvh = hbv.BVH(mesh)
    sets = ray_sets(mesh.vertices, max(SIZES), args.seed)

    def median_call(o, d, threads, gap):
        times = []
        for _ in range(args.calls):
            if gap:
                time.sleep(gap / 1e3)
            start = time.perf_counter()
            bvh.intersect(o, d, threads=threads)
            times.append(time.perf_counter() - start)
        return statistics.median(times)

    print(f"{args.mesh.name}, {args.gap:g} ms before each call, median of {args.calls} calls\n")
    print("| rays | set | 1 thread µs | all threads µs | **1 / all** | all, back to back µs | **1 / all (back to back)** |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: |")
    for name, (o, d) in sets.items():
        for n in SIZES:
            o_n, d_n = o[:n], d[:n]
            one = median_call(o_n, d_n, 1, args.gap)
            every = median_call(o_n, d_n, None, args.gap)
            warm = median_call(o_n, d_n, None, 0)
            print(f"| {n:,} | {name} | {1e6 * one:.0f} | {1e6 * every:.0f} | **{one / every:.2f}×** | "
                  f"{1e6 * warm:.0f} | **{one / warm:.2f}×** |", flush=True)


if __name__ == "__main__":
    main()
