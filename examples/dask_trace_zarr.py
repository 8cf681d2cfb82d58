#!/usr/bin/env python3
"""Trace rays from a Zarr store against a scene on a Dask cluster, answers written to Zarr.

    python examples/dask_trace_zarr.py [SCENE] [--rays 100000000] [--chunk 1000000]
        [--store rays.zarr] [--out hits.zarr] [--force] [--scheduler tcp://host:8786] [--workers 2]

SCENE: a ``.hbv`` file (``BVH.save``, ``Scene.save``, ``hbv build``), a glTF file or a mesh
(.obj, .ply); none: a built-in scene (a field of spheres, tori and boxes on a floor, from this
folder's .obj files). A file other than ``.hbv`` is loaded here and saved as ``.hbv`` beside the
output store, so the workers read it from there (put --out on storage every worker sees).

The ray store is made when it does not exist (``origins`` and ``directions``, float32, chunked
--chunk rays along the first axis), generated chunk by chunk inside the graph: neither making it
nor tracing it holds more than a few chunks per worker. Each member of ``hbv.dask.intersect``'s
answer becomes an array of the output store. Without --scheduler, a local cluster of --workers
processes of one thread each (1 GiB of memory each) runs it. An output store (or the saved scene
beside it) that exists already is left as it is, and the run refused, unless --force is given.
"""

import argparse
import os
import pathlib
import time

import dask
import dask.array as da
import numpy as np
from distributed import Client, LocalCluster

import hbv
import hbv.dask

HERE = pathlib.Path(__file__).resolve().parent


def builtin_scene():
    """A 20 x 20 field of spheres, tori and boxes on a floor."""
    scene = hbv.Scene()
    meshes = [hbv.load(HERE / name) for name in ("icosphere.obj", "torus.obj", "box.obj")]
    scene.add(hbv.load(HERE / "floor.obj"), np.diag([30.0, 1.0, 30.0, 1.0]))
    rng = np.random.default_rng(1)
    for i in range(20):
        for j in range(20):
            angle = rng.uniform(0, 2 * np.pi)
            c, s, size = np.cos(angle), np.sin(angle), rng.uniform(0.3, 0.7)
            transform = np.array([[c * size, 0, s * size, 3 * i - 28.5],
                                  [0, size, 0, size],
                                  [-s * size, 0, c * size, 3 * j - 28.5]])
            scene.add(meshes[(i + j) % 3], transform)
    return scene


def saved_scene_path(scene_arg, out):
    """The .hbv file the workers open: the one given, or the scene's, saved beside the output."""
    if scene_arg and scene_arg.endswith(".hbv"):
        return scene_arg
    return str(pathlib.Path(out).with_suffix(".scene.hbv"))


def structure_file(scene_arg, out, force):
    """Saves the scene where ``saved_scene_path`` says (a .hbv file given is used as it is)."""
    path = saved_scene_path(scene_arg, out)
    if path != scene_arg:
        scene = hbv.load_scene(scene_arg) if scene_arg else builtin_scene()
        scene.save(path, overwrite=force)
    return path


def ray_chunk(lo, hi, count, chunk, part, block_id=None):
    """Chunk ``block_id`` of ``count`` rays from above the scene's box towards its points:
    origins (part 0) or directions (part 1), the same for both parts (one seed per chunk)."""
    start = block_id[0] * chunk
    n = min(chunk, count - start)
    rng = np.random.default_rng([7, block_id[0]])
    lo, hi = np.asarray(lo), np.asarray(hi)
    origins = lo + (hi - lo) * rng.uniform(size=(n, 3)) + [0.0, hi[1] - lo[1] + 1.0, 0.0]
    if part == 0:
        return origins.astype(np.float32)
    targets = lo + (hi - lo) * rng.uniform(size=(n, 3))
    return (targets - origins).astype(np.float32)


def make_ray_store(store, bounds, count, chunk):
    rows = tuple(min(chunk, count - start) for start in range(0, count, chunk))
    for part, name in enumerate(("origins", "directions")):
        rays = da.map_blocks(ray_chunk, *bounds, count, chunk, part, chunks=(rows, (3,)),
                             dtype=np.float32, meta=np.empty((0, 3), np.float32))
        da.to_zarr(rays, store, component=name, overwrite=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scene", nargs="?")
    parser.add_argument("--rays", type=float, default=100e6)
    parser.add_argument("--chunk", type=int, default=1_000_000)
    parser.add_argument("--store", default="rays.zarr")
    parser.add_argument("--out", default="hits.zarr")
    parser.add_argument("--force", action="store_true", help="replace an existing --out store")
    parser.add_argument("--scheduler")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    count = int(args.rays)
    if not args.force:
        for existing in (args.out, saved_scene_path(args.scene, args.out)):
            if existing != args.scene and os.path.exists(existing):
                parser.error(f"{existing} exists: give --force to replace it, or another --out")

    if args.scheduler:
        client = Client(args.scheduler)
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                               memory_limit="1GiB", dashboard_address=":0")
        client = Client(cluster)
    path = structure_file(args.scene, args.out, args.force)
    handle = hbv.dask.open(path)
    print(f"structure: {path} ({handle.kind}, blake2b {handle.checksum[:16]})")
    hbv.dask.preload(handle, client, warm=("intersect",))

    if not os.path.exists(args.store):
        start = time.perf_counter()
        bounds = hbv.load_scene(path).bounds
        make_ray_store(args.store, bounds, count, args.chunk)
        print(f"ray store {args.store}: {count:,} rays in {time.perf_counter() - start:.1f} s")
    origins = da.from_zarr(args.store, component="origins")
    directions = da.from_zarr(args.store, component="directions")

    start = time.perf_counter()
    hits = hbv.dask.intersect(handle, origins, directions)
    writes = [da.to_zarr(array, args.out, component=name, overwrite=args.force, compute=False)
              for name, array in hits.items()]
    dask.compute(*writes)
    seconds = time.perf_counter() - start
    hit = da.from_zarr(args.out, component="hit")
    print(f"{origins.shape[0]:,} rays in {seconds:.1f} s ({origins.shape[0] / seconds / 1e6:.2f} M "
          f"rays/s), {float(hit.mean().compute()):.1%} hit; answers in {args.out}")
    client.close()


if __name__ == "__main__":
    main()
