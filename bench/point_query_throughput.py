"""Points a second of one point query of `hbv.BVH` on one thread, for an A/B of two builds of
the module.

    PYTHONPATH=BUILD python bench/point_query_throughput.py contains MESH [MESH ...]
    PYTHONPATH=BUILD python bench/point_query_throughput.py closest_point MESH [MESH ...]

200,000 points uniform in each mesh's box grown by 10 % on every side (python_compare.py's
points for `closest_point`), two warm-up calls, the best of five; prints the rate and a summary
of the answers (the share of points inside, or the mean distance), which two builds must agree
on.
"""

import sys
import time

import numpy as np
import trimesh

import hbv

POINTS = 200_000


def query_points(vertices):
    low, high = vertices.min(0).astype(np.float64), vertices.max(0).astype(np.float64)
    pad = 0.1 * (high - low)
    uniform = np.random.default_rng(2).uniform(size=(POINTS, 3))
    return np.ascontiguousarray(low - pad + (high - low + 2 * pad) * uniform, np.float32)


def summary(query, answer):
    if query == "contains":
        return f"{answer.mean():.4f} inside"
    return f"mean distance {answer['distance'].mean():.9f}"


def main(query, paths):
    for path in paths:
        loaded = trimesh.load(path, force="mesh")
        vertices = np.asarray(loaded.vertices, np.float32)
        bvh = hbv.BVH(hbv.Mesh(vertices, np.asarray(loaded.faces, np.uint32)))
        points = query_points(vertices)
        call = lambda: getattr(bvh, query)(points, threads=1)
        call(), call()
        best = float("inf")
        for _ in range(5):
            start = time.perf_counter()
            answer = call()
            best = min(best, time.perf_counter() - start)
        print(f"{path}: {POINTS / best / 1e6:.3f} M points/s, {summary(query, answer)}")


if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[1] not in ("contains", "closest_point"):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:])
