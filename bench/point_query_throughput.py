"""Points a second of one point query of `hbv.BVH` on one thread, for an A/B of two builds of
the module.

    PYTHONPATH=BUILD python bench/point_query_throughput.py QUERY MESH [MESH ...] [--open3d]

QUERY: contains, closest_point or signed_distance. 200,000 points uniform in each mesh's box
grown by 10 % on every side (python_compare.py's points for `closest_point`), two warm-up calls,
the best of five; prints the rate and a summary of the answers (the share of points inside, the
mean distance, or the mean signed distance and the share negative), which two builds must agree
on. With --open3d, also Open3D's counterpart on the same points and one thread
(`compute_occupancy`, `compute_closest_points`, `compute_signed_distance`; package open3d-cpu),
its summary and the ratio.
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


QUERIES = ("contains", "closest_point", "signed_distance")


def summary(query, answer):
    if query == "contains":
        return f"{np.asarray(answer).mean():.4f} inside"
    if query == "closest_point":
        return f"mean distance {np.asarray(answer['distance']).mean():.9f}"
    answer = np.asarray(answer)
    return f"mean signed distance {answer.mean():.9f}, {(answer < 0).mean():.4f} negative"


def best_rate(call):
    """Points a second of the best of five calls after two warm-up calls, and the last answer."""
    call(), call()
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        answer = call()
        best = min(best, time.perf_counter() - start)
    return POINTS / best, answer


def open3d_call(query, vertices, faces, points):
    """Open3D's counterpart of `query` on one thread (its RaycastingScene takes `nthreads`)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32)))
    tensor = o3d.core.Tensor(points)
    if query == "contains":
        return lambda: scene.compute_occupancy(tensor, nthreads=1).numpy() > 0.5
    if query == "closest_point":
        return lambda: {"distance": scene.compute_distance(tensor, nthreads=1).numpy()}
    return lambda: scene.compute_signed_distance(tensor, nthreads=1).numpy()


def main(query, paths, open3d):
    for path in paths:
        loaded = trimesh.load(path, force="mesh")
        vertices = np.asarray(loaded.vertices, np.float32)
        faces = np.asarray(loaded.faces, np.uint32)
        bvh = hbv.BVH(hbv.Mesh(vertices, faces))
        points = query_points(vertices)
        rate, answer = best_rate(lambda: getattr(bvh, query)(points, threads=1))
        line = f"{path}: {rate / 1e6:.3f} M points/s, {summary(query, answer)}"
        if open3d:
            other, other_answer = best_rate(open3d_call(query, vertices, faces, points))
            line += (f"; Open3D {other / 1e6:.3f} M points/s, {summary(query, other_answer)}"
                     f"; hbv / Open3D {rate / other:.2f}x")
        print(line, flush=True)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--open3d"]
    if len(args) < 2 or args[0] not in QUERIES:
        sys.exit(__doc__)
    main(args[0], args[1:], "--open3d" in sys.argv[1:])
