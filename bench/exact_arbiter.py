#!/usr/bin/env python3
"""Where two tracers disagree on the same rays (hbv and Embree, say), which one is right, decided
by exact rational arithmetic on the rays' and the mesh's float32 values.

For each disagreeing ray of a sample (closest hit: a different hit flag, or different triangles
at different `t`; occlusion: a different flag), every triangle the ray could plausibly meet (a
float64 Moller-Trumbore test with a generous tolerance) is decided exactly with Python's
`fractions.Fraction`: the line's parameter at the triangle's plane, the closed interval
`[tmin, tmax]`, and the signs of the three sub-triangle areas (edges and vertices count, both
sides). A tracer is right on a ray when its hit flag matches the exact one and, for a hit, its
triangle is among those at the exact nearest `t` (ties on shared edges allow several).

Usage (with the `hbv` Python package installed, and NumPy):

    python bench/exact_arbiter.py MESH RAYS.npz REFERENCE.npz OTHER.npz [--occluded] [--sample N]

REFERENCE and OTHER are hit files of docs/RAYS.md (`hit`, `t`, `prim`; or `occluded` with
`--occluded`), for example Embree's from `../shared/oracle/embree_oracle.py trace` and hbv's from
`hbv trace`. Triangle ids are hbv's (the file's face order, polygons fan-triangulated), as
`hbv.load` reads the mesh. Prints a tally and each ray on which OTHER is wrong.
"""

import argparse
from fractions import Fraction

import numpy as np


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh")
    p.add_argument("rays")
    p.add_argument("reference")
    p.add_argument("other")
    p.add_argument("--occluded", action="store_true", help="compare occlusion flags")
    p.add_argument("--sample", type=int, default=100, help="disagreements decided (default 100)")
    p.add_argument("--seed", type=int, default=0)
    return p.parse_args()


def plausible(tris, o, d, tmin, tmax):
    """Triangles whose float64 hit lies within a generous tolerance of the ray's interval."""
    a, b, c = (tris[:, k].astype(np.float64) for k in range(3))
    o, d = o.astype(np.float64), d.astype(np.float64)
    e1, e2 = b - a, c - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        slack = 1e-3
        scale = np.abs(tris).max() + np.abs(o).max()
        near = (u >= -slack) & (v >= -slack) & (u + v <= 1 + slack)
        near &= (t >= tmin - slack * scale / np.linalg.norm(d)) & (t <= tmax + slack * scale)
    # Rays nearly parallel to a triangle's plane (whose f64 barycentrics mean little) are
    # decided exactly too.
    size = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(d)
    grazing = np.abs(det) <= 1e-9 * size
    return np.nonzero(near | grazing | ~np.isfinite(t))[0]


def exact_hits(tris, candidates, o, d, tmin, tmax, corners=None):
    """(t, prim) of every candidate triangle the ray meets within [tmin, tmax], exactly.
    `corners(k)`, when given, returns triangle k's three vertices as exact `Fraction` lists
    (a scene's world vertices); otherwise they are `tris[k]`'s floats."""
    fr = lambda v: [Fraction(float(x)) for x in v]
    corners = corners or (lambda k: [fr(tris[k, j]) for j in range(3)])
    O, D = fr(o), fr(d)
    lo = Fraction(float(tmin))
    hi = Fraction(float(tmax)) if np.isfinite(tmax) else None
    hits = []
    for k in candidates:
        A, B, C = corners(k)
        e1 = [B[i] - A[i] for i in range(3)]
        e2 = [C[i] - A[i] for i in range(3)]
        n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
        den = sum(n[i] * D[i] for i in range(3))
        if den == 0:  # degenerate triangle, or a ray parallel to its plane: never hit
            continue
        t = sum(n[i] * (A[i] - O[i]) for i in range(3)) / den
        if t < lo or (hi is not None and t > hi):
            continue
        P = [O[i] + t * D[i] for i in range(3)]

        def side(p, q):
            u = [q[i] - p[i] for i in range(3)]
            w = [P[i] - p[i] for i in range(3)]
            m = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            return sum(m[i] * n[i] for i in range(3))

        signs = [side(A, B), side(B, C), side(C, A)]
        if all(x >= 0 for x in signs) or all(x <= 0 for x in signs):
            hits.append((t, int(k)))
    return sorted(hits)


VERDICTS = ("both right (a tie)", "other right", "reference right", "neither")


def verdict(right_a, right_b):
    """The tally's key for a ray on which the reference (a) and the other answer (b) were
    judged against the exact one."""
    return ("both right (a tie)" if right_a and right_b else "other right" if right_b
            else "reference right" if right_a else "neither")


def hit_detail(a, b, ids_a, ids_b, i, name):
    """Both answers to ray `i`, for a line on a ray decided against one of them."""
    return (f"; reference hit={a['hit'][i]} t={a['t'][i]:.9g} {name}={ids_a[i]}"
            f", other hit={b['hit'][i]} t={b['t'][i]:.9g} {name}={ids_b[i]}")


def main():
    import hbv

    args = parse_args()
    mesh = hbv.load(args.mesh)
    tris = mesh.vertices[mesh.faces]
    rays = np.load(args.rays)
    o, d = rays["origins"], rays["directions"]
    n = len(o)
    tmin = rays["tmin"] if "tmin" in rays.files else np.zeros(n, np.float32)
    tmax = rays["tmax"] if "tmax" in rays.files else np.full(n, np.inf, np.float32)
    a, b = np.load(args.reference), np.load(args.other)
    if args.occluded:
        flag = lambda h: h["occluded"] if "occluded" in h.files else h["hit"]
        fa, fb = flag(a), flag(b)
        differ = np.nonzero(fa != fb)[0]
    else:
        fa, fb = a["hit"], b["hit"]
        differ = np.nonzero((fa != fb) | (fa & fb & (a["prim"] != b["prim"]) & (a["t"] != b["t"])))[0]
    sample = np.random.default_rng(args.seed).permutation(differ)[: args.sample]
    print(f"{len(differ)} of {n} rays disagree; deciding {len(sample)} exactly")
    tally = dict.fromkeys(VERDICTS, 0)
    for i in sample:
        hits = exact_hits(tris, plausible(tris, o[i], d[i], tmin[i], tmax[i]), o[i], d[i], tmin[i], tmax[i])
        if args.occluded:
            truth = bool(hits)
            right_a, right_b = bool(fa[i]) == truth, bool(fb[i]) == truth
            exact = f"occluded={truth}"
        elif hits:
            nearest = {k for t, k in hits if t == hits[0][0]}
            right_a = bool(fa[i]) and int(a["prim"][i]) in nearest
            right_b = bool(fb[i]) and int(b["prim"][i]) in nearest
            exact = f"t={float(hits[0][0]):.9g} triangles {sorted(nearest)[:4]}"
        else:
            right_a, right_b = not fa[i], not fb[i]
            exact = "miss"
        key = verdict(right_a, right_b)
        tally[key] += 1
        if not right_b:
            detail = "" if args.occluded else hit_detail(a, b, a["prim"], b["prim"], i, "prim")
            print(f"ray {i}: {key}: exact {exact}{detail}")
    print(tally)


if __name__ == "__main__":
    main()
