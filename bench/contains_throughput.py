"""Points a second of `hbv.BVH.contains` on one thread, for an A/B of two builds of the module.

    PYTHONPATH=BUILD python bench/contains_throughput.py MESH [MESH ...]

200,000 points uniform in each mesh's bounding box (seed 1), the best of five calls after a
warm-up; prints the rate and the share of points inside, which two builds must agree on.
"""

import sys
import time

import numpy as np
import trimesh

import hbv


def best_seconds(call, repeat=5):
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def main(paths):
    for path in paths:
        loaded = trimesh.load(path, force="mesh")
        mesh = hbv.Mesh(np.asarray(loaded.vertices, np.float32), np.asarray(loaded.faces, np.uint32))
        bvh = hbv.BVH(mesh)
        low, high = loaded.bounds
        points = (low + (high - low) * np.random.default_rng(1).random((200_000, 3))).astype(np.float32)
        bvh.contains(points[:1000], threads=1)
        seconds = best_seconds(lambda: bvh.contains(points, threads=1))
        inside = bvh.contains(points, threads=1).mean()
        print(f"{path}: {len(points) / seconds / 1e6:.2f} M points/s, {inside:.4f} inside, open edges {mesh.open_edges}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
