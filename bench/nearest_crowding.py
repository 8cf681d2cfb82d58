#!/usr/bin/env python3
"""How many triangles a nearest-point query must decide whatever its bounds: for points drawn as
bench/python_compare.py draws them (uniform in the mesh's box grown by 10 % on each side), the
mean number of triangles whose exact distance is within (1 + e) of the nearest one's.

A search that bounds each triangle's distance from below to within a factor (1 + e) cannot rule
out those triangles, and must decide each of them exactly; e = 0 counts the ties (a nearest
point on a shared vertex or edge). Distances by a float64 brute force over every triangle
(Ericson, Real-Time Collision Detection, 5.1.5, vectorized with NumPy).

    PYTHONPATH=<hbv> python bench/nearest_crowding.py [MESH.ply ...] [--points 300] [--seed 3]

Default meshes: every ../shared/scenes/*.ply, smallest first.
"""
import argparse
import pathlib
import sys

import numpy as np

import hbv

FACTORS = (0.0, 1e-3, 1e-2, 5e-2, 1e-1)


def distances(p, a, b, c):
    """Distances from point `p` to every triangle (a[i], b[i], c[i]), float64."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    q = np.empty_like(a)
    done = np.zeros(len(a), bool)

    def take(mask, point):
        mask &= ~done
        q[mask] = point[mask]
        done[mask] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        take((d1 <= 0) & (d2 <= 0), a)
        take((d3 >= 0) & (d4 <= d3), b)
        take((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab)
        take((d6 >= 0) & (d5 <= d6), c)
        take((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac)
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        take((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + w[:, None] * (c - b))
        inv = 1.0 / (va + vb + vc)
        take(np.ones(len(a), bool), a + ab * (vb * inv)[:, None] + ac * (vc * inv)[:, None])
    d = np.sqrt(((q - p) ** 2).sum(1))
    # Degenerate triangles have no face to be nearest to (as in hbv); NaN from them is dropped.
    return d[np.isfinite(d)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", type=pathlib.Path)
    parser.add_argument("--points", type=int, default=300)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    meshes = args.meshes
    if not meshes:
        scenes = pathlib.Path(__file__).resolve().parent.parent.parent / "shared" / "scenes"
        if not scenes.is_dir():
            sys.exit(f"no meshes given and {scenes} does not exist")
        meshes = sorted(scenes.glob("*.ply"), key=lambda p: p.stat().st_size)
    print("| mesh | " + " | ".join(f"e = {e:g}" for e in FACTORS) + " |")
    print("| --- |" + " ---: |" * len(FACTORS))
    for path in meshes:
        mesh = hbv.load(path)
        v, f = mesh.vertices.astype(np.float64), mesh.faces
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        lo, hi = v.min(0), v.max(0)
        rng = np.random.default_rng(args.seed)
        points = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (args.points, 3))
        counts = np.zeros(len(FACTORS))
        for p in points:
            d = distances(p, a, b, c)
            nearest = d.min()
            counts += [np.count_nonzero(d <= nearest * (1 + e)) for e in FACTORS]
        means = counts / len(points)
        print(f"| {path.stem} | " + " | ".join(f"{m:.2f}" for m in means) + " |")


if __name__ == "__main__":
    main()
