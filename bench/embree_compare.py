#!/usr/bin/env python3
"""hbv against Embree on the same rays: single-thread speed, and the answers ray by ray.

For each mesh:

1. `hbv bench MESH --write-rays DIR` writes the three ray sets of `hbv bench` (camera, diffuse,
   shadow; see crates/hbv-cli/src/ray_sets.rs), so that both tools trace exactly the same rays.
2. Embree 4 (through `embreex`) traces each set single-threaded: `--repeat` timed calls of
   `EmbreeScene.run` after one untimed call (which also builds Embree's BVH), before hbv's runs
   and again after them; the median of all of them is reported.
3. `hbv trace MESH --rays R --out O --threads 1 --json --layout L --repeat N [--occluded]`
   traces the same set `--repeat` times per layout in one process; it times the trace alone (not
   loading or building), and the median of its runs is reported.
4. Every hbv answer is checked against Embree's: the same hit flag (closest hit) or occlusion
   flag (any hit), and for rays both hit, `|t - t_embree| <= t_rel * max(|t_embree|, D / |d|)`
   with D the mesh's box diagonal: 1e-4 relative, or 1e-4 of the mesh's size near the origin.

embreex fixes each ray's start at t = 0, so a ray `[tmin, tmax]` is given to it as the origin
`o + tmin d` with `dists = tmax - tmin` (both in units of `d`), and its `t` is shifted back by
`tmin`.

Usage (from the repository root; setup in bench/README.md):

    cargo build --release -p hbv-cli
    ../bench-venv/bin/python bench/embree_compare.py                 # every ../shared/scenes/*.ply
    ../bench-venv/bin/python bench/embree_compare.py MESH.ply --rays 100000 --layout wide8

Exit status 1 when some (mesh, set, query, layout) disagrees with Embree on more than
`--max-mismatch` of its rays.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np

from machine import describe, machine

REPO = pathlib.Path(__file__).resolve().parent.parent

# (ray set, query) pairs, as `hbv bench` measures them.
CASES = [
    ("primary", "closest"),
    ("diffuse", "closest"),
    ("diffuse", "occluded"),
    ("shadow", "occluded"),
]

LAYOUTS = ["recursive", "skip", "ordered", "wide4", "wide8"]
# A layout name ending in "-1by1" traces one call per ray (`hbv trace --one-by-one`) instead of the
# interleaved batch: the speed of single-ray calls, as Embree's `rtcIntersect1` is called here.
ONE_BY_ONE = "-1by1"


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "meshes",
        nargs="*",
        type=pathlib.Path,
        help="mesh files (default: every *.ply in ../shared/scenes beside the repository)",
    )
    p.add_argument(
        "--hbv",
        type=pathlib.Path,
        default=REPO / "target" / "release" / "hbv",
        help="the hbv binary (default: target/release/hbv)",
    )
    p.add_argument(
        "--builder",
        default="binned-sah",
        help="hbv builder for the traced tree (default binned-sah, the fastest to trace)",
    )
    p.add_argument("--rays", type=int, default=1 << 18, help="rays per set (default 262144)")
    p.add_argument("--ray-seed", type=int, default=1, help="seed of the diffuse and shadow rays")
    p.add_argument("--repeat", type=int, default=3, help="timed runs per measurement (median)")
    p.add_argument(
        "--layout",
        action="append",
        choices=LAYOUTS + [l + ONE_BY_ONE for l in LAYOUTS],
        help="hbv layout to compare, or LAYOUT-1by1 for one call per ray; repeat for several (default: every layout, batched)",
    )
    p.add_argument(
        "--work",
        type=pathlib.Path,
        default=REPO / ".cache" / "embree_compare",
        help="folder for ray and hit files (default: .cache/embree_compare)",
    )
    p.add_argument(
        "--t-rel",
        type=float,
        default=1e-4,
        help="tolerance on t, relative to the larger of t and the mesh's diagonal",
    )
    p.add_argument(
        "--max-mismatch",
        type=float,
        default=1e-3,
        help="largest fraction of disagreeing rays before the exit status is 1",
    )
    p.add_argument("--json", type=pathlib.Path, help="also write every figure to this JSON file")
    return p.parse_args()


def default_meshes():
    scenes = REPO.parent / "shared" / "scenes"
    meshes = sorted(scenes.glob("*.ply")) if scenes.is_dir() else []
    if not meshes:
        sys.exit(f"no mesh given and no *.ply in {scenes}")
    return meshes


def load_mesh(path):
    """Vertices (V, 3) float32 and faces (F, 3) int32 in file order (polygons fanned)."""
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    return vertices, faces


def load_rays(path):
    with np.load(path) as f:
        return {k: np.asarray(f[k]) for k in ("origins", "directions", "tmin", "tmax")}


class Embree:
    """One mesh in an Embree scene (robust flag, embreex's defaults)."""

    def __init__(self, vertices, faces):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, vertices, faces)

    def trace(self, rays, query, repeat):
        """Answers and Mrays/s of each timed run.

        Closest: {"hit", "t"}; occluded: {"occluded"}.
        """
        tmin = rays["tmin"].astype(np.float32)
        d = np.ascontiguousarray(rays["directions"], dtype=np.float32)
        o = np.ascontiguousarray(rays["origins"] + tmin[:, None] * d, dtype=np.float32)
        dists = np.ascontiguousarray(rays["tmax"] - tmin, dtype=np.float32)
        if query == "closest":

            def call():
                return self.scene.run(o, d, dists=dists, query="INTERSECT", output=1)

        else:

            def call():
                return self.scene.run(o, d, dists=dists, query="OCCLUDED")

        result = call()  # warm-up; the first call also builds Embree's BVH
        runs = []
        for _ in range(repeat):
            start = time.perf_counter()
            call()
            runs.append(len(o) / (time.perf_counter() - start) / 1e6)
        if query == "closest":
            hit = result["primID"] != -1
            t = np.where(hit, result["tfar"] + tmin, np.float32(np.inf)).astype(np.float32)
            return {"hit": hit, "t": t}, runs
        # embreex answers OCCLUDED with -1 for a free ray, 0 (the geometry id) for a blocked one.
        return {"occluded": result != -1}, runs


def hbv_trace(hbv, mesh, rays_path, out_path, layout, query, repeat, builder):
    """Answers of `hbv trace` and the Mrays/s of each of its `repeat` runs."""
    cmd = [str(hbv), "trace", str(mesh), "--rays", str(rays_path), "--out", str(out_path), "--force"]
    single = layout.endswith(ONE_BY_ONE)
    layout = layout.removesuffix(ONE_BY_ONE)
    cmd += ["--threads", "1", "--json", "--layout", layout, "--builder", builder]
    if single:
        cmd.append("--one-by-one")
    if query == "occluded":
        cmd.append("--occluded")
    # One process tracing `repeat` times, as Embree's calls are timed in this one: a fresh
    # process's first trace also pays for cold caches and the first touch of its answers' pages.
    cmd += ["--repeat", str(repeat)]
    out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    runs = [out["rays"] / seconds / 1e6 for seconds in out["trace_seconds_each"]]
    with np.load(out_path) as f:
        if query == "closest":
            answers = {"hit": np.asarray(f["hit"]), "t": np.asarray(f["t"])}
        else:
            answers = {"occluded": np.asarray(f["occluded"])}
    return answers, runs


def mismatches(reference, mine, rays, query, t_rel, diagonal):
    """Rays whose answers differ: {"flag": hit or occlusion differs, "t": both hit, t differs}.

    `t` agrees within `t_rel` relative to the larger of `|t|` and the mesh's diagonal (in units
    of `d`): near the origin a relative bound is tighter than the rounding of f32 coordinates.
    """
    if query == "occluded":
        return {"flag": int(np.count_nonzero(reference["occluded"] != mine["occluded"])), "t": 0}
    flag = reference["hit"] != mine["hit"]
    both = reference["hit"] & mine["hit"]
    t_ref = reference["t"][both].astype(np.float64)
    t = mine["t"][both].astype(np.float64)
    length = np.linalg.norm(rays["directions"][both].astype(np.float64), axis=1)
    far = np.abs(t - t_ref) > t_rel * np.maximum(np.abs(t_ref), diagonal / length)
    return {"flag": int(np.count_nonzero(flag)), "t": int(np.count_nonzero(far))}


def compare_mesh(mesh, args, layouts):
    """Every (set, query) on one mesh: a list of rows for the tables and the JSON file."""
    work = args.work / mesh.stem
    work.mkdir(parents=True, exist_ok=True)
    subprocess.run(
        [str(args.hbv), "bench", str(mesh), "--rays", str(args.rays)]
        + ["--ray-seed", str(args.ray_seed), "--write-rays", str(work), "--force"],
        check=True,
        capture_output=True,
    )
    vertices, faces = load_mesh(mesh)
    used = vertices[faces.reshape(-1)] if len(faces) else np.zeros((1, 3), np.float32)
    diagonal = float(np.linalg.norm(used.max(axis=0).astype(np.float64) - used.min(axis=0)))
    start = time.perf_counter()
    embree = Embree(vertices, faces)
    print(f"{mesh.name}: {len(faces)} triangles, Embree scene made in "
          f"{time.perf_counter() - start:.3f} s", file=sys.stderr)

    rows = []
    for ray_set, query in CASES:
        rays_path = work / f"{ray_set}.npz"
        rays = load_rays(rays_path)
        reference, embree_runs = embree.trace(rays, query, args.repeat)
        flag = reference["hit" if query == "closest" else "occluded"]
        row = {
            "mesh": mesh.name,
            "triangles": len(faces),
            "ray_set": ray_set,
            "query": query,
            "rays": len(rays["tmin"]),
            "hit_fraction": float(np.mean(flag)) if len(flag) else 0.0,
            "hbv": {},
        }
        for layout in layouts:
            out_path = work / f"hits_{ray_set}_{query}_{layout}.npz"
            answers, runs = hbv_trace(args.hbv, mesh, rays_path, out_path, layout, query,
                                      args.repeat, args.builder)
            row["hbv"][layout] = {
                "mrays_per_second": statistics.median(runs),
                "runs": runs,
                "mismatches": mismatches(reference, answers, rays, query, args.t_rel, diagonal),
            }
        # Embree timed again after hbv, and the median taken over both sets of runs: on a
        # machine whose speed drifts from minute to minute, Embree's runs then bracket hbv's.
        embree_runs += embree.trace(rays, query, args.repeat)[1]
        row["embree_mrays_per_second"] = statistics.median(embree_runs)
        row["embree_runs"] = embree_runs
        print(f"  {ray_set} {query}: Embree {row['embree_mrays_per_second']:.3f} Mrays/s, "
              + ", ".join(f"{l} {v['mrays_per_second']:.3f}" for l, v in row["hbv"].items()),
              file=sys.stderr)
        rows.append(row)
    return rows


def print_tables(rows, layouts):
    head = f"{'mesh':<16} {'set':<8} {'query':<9} {'hit %':>6} {'Embree':>8}"
    head += "".join(f" {l:>9}" for l in layouts) + f" {'best':>9} {'best/Embree':>11}"
    print("Mrays/s, one thread (median of runs)")
    print(head)
    for r in rows:
        speeds = {l: r["hbv"][l]["mrays_per_second"] for l in layouts}
        best = max(speeds, key=speeds.get)
        line = (f"{r['mesh']:<16} {r['ray_set']:<8} {r['query']:<9} "
                f"{100 * r['hit_fraction']:>6.1f} {r['embree_mrays_per_second']:>8.3f}")
        line += "".join(f" {speeds[l]:>9.3f}" for l in layouts)
        line += f" {best:>9} {speeds[best] / r['embree_mrays_per_second']:>10.2f}x"
        print(line)
    print()
    print("Rays disagreeing with Embree: hit (or occlusion) flag + t, of all rays")
    head = f"{'mesh':<16} {'set':<8} {'query':<9} {'rays':>8}"
    print(head + "".join(f" {l:>9}" for l in layouts))
    for r in rows:
        line = f"{r['mesh']:<16} {r['ray_set']:<8} {r['query']:<9} {r['rays']:>8}"
        for l in layouts:
            m = r["hbv"][l]["mismatches"]
            line += f" {str(m['flag']) + '+' + str(m['t']):>9}"
        print(line)


def main():
    args = parse_args()
    if not args.hbv.exists():
        sys.exit(f"{args.hbv} not found: build it with `cargo build --release -p hbv-cli`, "
                 "or give --hbv")
    layouts = args.layout or LAYOUTS
    meshes = args.meshes or default_meshes()
    rows = []
    for mesh in meshes:
        rows += compare_mesh(mesh, args, layouts)
    print(f"Machine: {describe(machine(packages=('numpy', 'embreex')))}")
    print_tables(rows, layouts)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))

    failed = [
        (r["mesh"], r["ray_set"], r["query"], l)
        for r in rows
        for l in layouts
        if sum(r["hbv"][l]["mismatches"].values()) > args.max_mismatch * r["rays"]
    ]
    if failed:
        print(f"\nmore than {args.max_mismatch:g} of the rays disagree with Embree in: "
              + ", ".join(" ".join(f) for f in failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
