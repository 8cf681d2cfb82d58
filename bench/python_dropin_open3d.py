#!/usr/bin/env python3
"""hbv.open3d.RaycastingScene against open3d.t.geometry.RaycastingScene, and against the native
hbv call it wraps.

1. Inside tests and signed distances: `compute_occupancy` and `compute_signed_distance` of
   `--points` points (uniform in the mesh's box grown by 10 % on each side,
   `python_compare.query_points`) on each shared mesh, hbv's drop-in against Open3D's, all
   cores, `nsamples=1` (Open3D's default and fastest; hbv's answer is exact at any nsamples).
2. The drop-in's cost: `cast_rays` of `--rays` rays (an (N, 6) float32 array, the form Open3D
   takes) against `hbv.BVH.intersect` of the same rays given as C-ordered origins and
   directions (the native call at its cheapest), on the bunny and the dragon; python_compare's
   `random` rays.

Each query is called once untimed (Open3D commits its scene, hbv makes its layouts,
nearest-point tree and inside grid on first use), then `--repeat` interleaved rounds, each timed
call right after an untimed one of the same query; each time is the median of the rounds, each
ratio the median of the rounds' ratios.

    ../py-bench-venv/bin/python bench/python_dropin_open3d.py [MESH.ply ...] [--points 100000]
        [--rays 1000000] [--repeat 5] [--part inside|rays|both]
"""

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import hbv  # noqa: E402
import hbv.open3d  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from machine import describe, machine  # noqa: E402
from python_compare import query_points, ray_sets  # noqa: E402

SCENES = pathlib.Path(__file__).resolve().parent.parent.parent / "shared/scenes"


def rounds(calls, repeat):
    """{name: [seconds of each round]}, after one untimed call of each.

    Each timed call follows an untimed call of the same query, as in python_compare's
    `time_interleaved`: both libraries' thread pools are then awake, and neither call pays
    for waking its workers after the other library's call, or for the other's workers still
    spinning.
    """
    for call in calls.values():
        call()
    seconds = {name: [] for name in calls}
    for _ in range(repeat):
        for name, call in calls.items():
            call()
            start = time.perf_counter()
            call()
            seconds[name].append(time.perf_counter() - start)
    return seconds


def ratio(seconds, slow, fast):
    return statistics.median(s / f for s, f in zip(seconds[slow], seconds[fast]))


def ms(seconds, name):
    return statistics.median(seconds[name]) * 1e3


def mesh_arrays(path):
    mesh = hbv.load(str(path))
    return np.ascontiguousarray(mesh.vertices, np.float32), np.ascontiguousarray(mesh.faces)


def inside_and_distance(path, args):
    import open3d as o3d

    v, f = mesh_arrays(path)
    points = query_points(v, args.points, args.seed)
    ours = hbv.open3d.RaycastingScene()
    ours.add_triangles(v, f)
    theirs = o3d.t.geometry.RaycastingScene()
    theirs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32)))
    tensor = o3d.core.Tensor(points)
    seconds = rounds(
        {
            "open3d sdf": lambda: theirs.compute_signed_distance(tensor),
            "hbv sdf": lambda: ours.compute_signed_distance(points),
            "open3d occupancy": lambda: theirs.compute_occupancy(tensor),
            "hbv occupancy": lambda: ours.compute_occupancy(points),
        },
        args.repeat,
    )
    signed = ours.compute_signed_distance(points)
    occupancy_differs = int((ours.compute_occupancy(points) != theirs.compute_occupancy(tensor).numpy()).sum())
    sign_differs = int(((signed < 0) != (theirs.compute_signed_distance(tensor).numpy() < 0)).sum())
    return len(f), seconds, occupancy_differs, sign_differs


def dropin_cost(path, args):
    v, f = mesh_arrays(path)
    o, d = ray_sets(v, args.rays, args.seed)["random"]
    rays = np.hstack([o, d])
    scene = hbv.open3d.RaycastingScene()
    scene.add_triangles(v, f)
    bvh = hbv.BVH(hbv.Mesh(v, f))
    seconds = rounds(
        {"native": lambda: bvh.intersect(o, d), "drop-in": lambda: scene.cast_rays(rays)},
        args.repeat,
    )
    return len(f), seconds


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("meshes", nargs="*", type=pathlib.Path)
    p.add_argument("--points", type=int, default=100_000)
    p.add_argument("--rays", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--part", choices=("inside", "rays", "both"), default="both",
                   help="1. inside tests and signed distances, 2. the drop-in's cost, or both")
    args = p.parse_args()
    meshes = args.meshes or sorted(SCENES.glob("*.ply"), key=lambda m: m.stat().st_size)
    print(describe(machine()))
    if args.part != "rays":
        inside_table(meshes, args)
    if args.part != "inside":
        rays_table(meshes, args)


def inside_table(meshes, args):
    print(f"\n{args.points:,} points; ms (median of {args.repeat} rounds); ratio: Open3D's time / hbv's")
    print("| mesh (triangles) | closed | signed distance: Open3D | hbv | × | occupancy: Open3D | hbv | × "
          "| points where Open3D's inside differs |")
    print("| --- | --- |" + " ---: |" * 7)
    for path in meshes:
        triangles, s, occupancy_differs, sign_differs = inside_and_distance(path, args)
        closed = "yes" if hbv.load(str(path)).is_closed else "no"
        print(
            f"| {path.stem} ({triangles:,}) | {closed} | {ms(s, 'open3d sdf'):.1f} | {ms(s, 'hbv sdf'):.1f} "
            f"| {ratio(s, 'open3d sdf', 'hbv sdf'):.2f} | {ms(s, 'open3d occupancy'):.1f} "
            f"| {ms(s, 'hbv occupancy'):.1f} | {ratio(s, 'open3d occupancy', 'hbv occupancy'):.2f} "
            f"| {occupancy_differs:,} (sign {sign_differs:,}) |",
            flush=True,
        )


def rays_table(meshes, args):
    print(f"\n{args.rays:,} rays, cast_rays against BVH.intersect; ms (median of {args.repeat} rounds)")
    print("| mesh (triangles) | native | drop-in | drop-in / native |")
    print("| --- | ---: | ---: | ---: |")
    for path in [m for m in meshes if m.stem in ("bunny", "dragon")]:
        triangles, s = dropin_cost(path, args)
        print(
            f"| {path.stem} ({triangles:,}) | {ms(s, 'native'):.1f} | {ms(s, 'drop-in'):.1f} "
            f"| {ratio(s, 'drop-in', 'native'):.3f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
