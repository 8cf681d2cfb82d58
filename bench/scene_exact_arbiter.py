#!/usr/bin/env python3
"""Where two tracers disagree on the same rays through a glTF scene (hbv's two-level scene and
Embree's, say), which one is right, decided by exact rational arithmetic on the scene as its
file defines it.

The truth is the exact scene: each instance's world vertices are M v with M the exact product of
its node matrices (the file's numbers) and v its mesh's float32 vertices, both as
`fractions.Fraction`; the ray is its float32 origin, direction and interval. For each
disagreeing ray (closest hit: a different hit flag, or a different (instance, prim) at a
different `t`; occlusion: a different flag), every world triangle the ray could plausibly meet
(a float64 test with a generous tolerance over the whole flattened scene) is decided exactly
by `exact_arbiter.exact_hits`. A tracer is right when its flag matches the exact one and, for a
hit, its (instance, prim) is among those at the exact nearest `t` (ties allow several). Where
OTHER is wrong, the exact `t` of its triangle is printed beside the nearest, relative to the
scene's size (the bound of `crates/hbv/src/scene/mod.rs`, "Accuracy", is about 2^-22 of it).

Usage (NumPy only; reads .glb files of docs/RAYS.md, "Scenes (glTF)": float32 positions,
uint8/16/32 or no indices, node `matrix` or TRS, mode-4 primitives):

    python bench/scene_exact_arbiter.py SCENE.glb RAYS.npz REFERENCE.npz OTHER.npz \\
        [--occluded] [--sample N] [--exclude-kinds KIND ...]

REFERENCE and OTHER are hit files with `hit`, `t`, `prim`, `instance` (or `occluded`).
"""

import argparse
import json
import struct
from fractions import Fraction

import numpy as np

from exact_arbiter import VERDICTS, exact_hits, hit_detail, plausible, verdict

COMPONENTS = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC3": 3}


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("rays")
    p.add_argument("reference")
    p.add_argument("other")
    p.add_argument("--occluded", action="store_true", help="compare occlusion flags")
    p.add_argument("--sample", type=int, default=200, help="disagreements decided (default 200)")
    p.add_argument("--exclude-kinds", nargs="*", default=[], help="ray kinds left out")
    p.add_argument("--seed", type=int, default=0)
    return p.parse_args()


def read_glb(path):
    """(meshes, instances): each mesh an (n, 3, 3) float32 array of triangles; each instance
    (mesh, M) with M the 4x4 product of its node matrices as Fractions, in the file's order."""
    data = open(path, "rb").read()
    if data[:4] != b"glTF":
        raise SystemExit(f"{path}: not a .glb file")
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + length])
    binary = data[20 + length + 8 :]

    def accessor(index):
        a = doc["accessors"][index]
        view = doc["bufferViews"][a["bufferView"]]
        dtype, width = COMPONENTS[a["componentType"]], WIDTH[a["type"]]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        stride = view.get("byteStride", 0) or np.dtype(dtype).itemsize * width
        rows = [np.frombuffer(binary, dtype, width, start + i * stride) for i in range(a["count"])]
        return np.array(rows).reshape(a["count"], width)

    meshes = []
    for mesh in doc["meshes"]:
        parts = []
        for prim in mesh["primitives"]:
            if prim.get("mode", 4) != 4:
                continue
            positions = accessor(prim["attributes"]["POSITION"]).astype(np.float32)
            if "indices" in prim:
                faces = accessor(prim["indices"]).reshape(-1, 3).astype(np.int64)
            else:
                faces = np.arange(len(positions)).reshape(-1, 3)
            parts.append(positions[faces])
        meshes.append(np.concatenate(parts) if parts else np.zeros((0, 3, 3), np.float32))

    def local(node):
        if "matrix" in node:
            m = node["matrix"]
            return [[Fraction(m[4 * c + r]) for c in range(4)] for r in range(4)]
        x, y, z, w = (Fraction(q) for q in node.get("rotation", [0, 0, 0, 1]))
        s = [Fraction(v) for v in node.get("scale", [1, 1, 1])]
        t = [Fraction(v) for v in node.get("translation", [0, 0, 0])]
        r = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        return [[r[i][j] * s[j] for j in range(3)] + [t[i]] for i in range(3)] + [[0, 0, 0, 1]]

    def product(a, b):
        return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]

    instances = []
    scene = doc["scenes"][doc.get("scene", 0)]
    stack = [(n, None) for n in reversed(scene["nodes"])]
    while stack:
        index, parent = stack.pop()
        node = doc["nodes"][index]
        m = local(node) if parent is None else product(parent, local(node))
        if "mesh" in node:
            instances.append((node["mesh"], m))
        stack.extend((c, m) for c in reversed(node.get("children", [])))
    return meshes, instances


def edge_gap(a, b, p, d=None):
    """Float64 distance from segment ab to the point p or, with a direction d, to the line
    p + s d (the distance from a + u (b - a) to the line is |c + u e| with c = (a - p) x d̂ and
    e = (b - a) x d̂, least at u = -c.e / |e|^2, clamped to [0, 1])."""
    if d is None:
        ab = b - a
        u = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0)
        return float(np.linalg.norm(a + u * ab - p))
    unit = d / np.linalg.norm(d)
    c, e = np.cross(a - p, unit), np.cross(b - a, unit)
    u = np.clip(-np.dot(c, e) / max(np.dot(e, e), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(c + u * e))


def bound(instance, o, d, t, offsets, tris):
    """The scene's documented bound ε = 2^-22 (κ (|o - b| + t |d|) + S) + 2^-48 κ (|o| + |b|)
    (crates/hbv/src/scene/mod.rs, "Accuracy") for a hit at `t` on `instance`."""
    _, m = instance
    a = np.array([[float(x) for x in row[:3]] for row in m[:3]])
    b = np.array([float(row[3]) for row in m[:3]])
    kappa = np.abs(a).sum(1).max() * np.abs(np.linalg.inv(a)).sum(1).max()
    size = float(np.abs(tris).max())
    o, d = o.astype(np.float64), d.astype(np.float64)
    far = np.abs(o - b).max() + t * np.abs(d).max()
    return 2.0**-22 * (kappa * far + size) + 2.0**-48 * kappa * (np.abs(o).max() + np.abs(b).max())


def main():
    args = parse_args()
    meshes, instances = read_glb(args.scene)
    # The flattened scene in float64 (for the plausibility filter), and where each instance's
    # triangles start in it.
    world, offsets = [], []
    for mesh, m in instances:
        offsets.append(sum(len(w) for w in world))
        a = np.array([[float(x) for x in row[:3]] for row in m[:3]])
        b = np.array([float(row[3]) for row in m[:3]])
        world.append(meshes[mesh].astype(np.float64) @ a.T + b)
    offsets = np.array(offsets + [sum(len(w) for w in world)])
    tris = np.concatenate(world)

    def corners(k):
        i = int(np.searchsorted(offsets, k, side="right") - 1)
        mesh, m = instances[i]
        local = meshes[mesh][k - offsets[i]]
        vs = [[Fraction(float(x)) for x in p] for p in local]
        return [[sum(m[r][c] * v[c] for c in range(3)) + m[r][3] for r in range(3)] for v in vs]

    rays = np.load(args.rays)
    o, d = rays["origins"], rays["directions"]
    n = len(o)
    tmin = rays["tmin"] if "tmin" in rays.files else np.zeros(n, np.float32)
    tmax = rays["tmax"] if "tmax" in rays.files else np.full(n, np.inf, np.float32)
    keep = np.ones(n, bool)
    if "kind" in rays.files and args.exclude_kinds:
        names = [str(k) for k in rays["kind_names"]]
        for kind in args.exclude_kinds:
            keep &= rays["kind"] != names.index(kind)
    a, b = np.load(args.reference), np.load(args.other)
    if args.occluded:
        flag = lambda h: h["occluded"] if "occluded" in h.files else h["hit"]
        fa, fb = flag(a), flag(b)
        differ = np.nonzero(keep & (fa != fb))[0]
    else:
        fa, fb = a["hit"], b["hit"]
        flat = lambda h: np.where(h["hit"], offsets[np.maximum(h["instance"], 0)] + h["prim"], -1)
        ida, idb = flat(a), flat(b)
        differ = np.nonzero(keep & ((fa != fb) | (fa & fb & (ida != idb))))[0]
    sample = np.random.default_rng(args.seed).permutation(differ)[: args.sample]
    size = float(np.abs(tris).max())
    print(f"{len(differ)} of {int(keep.sum())} rays disagree; deciding {len(sample)} exactly")
    tally = dict.fromkeys(VERDICTS, 0)
    for i in sample:
        candidates = plausible(tris, o[i], d[i], tmin[i], tmax[i])
        hits = exact_hits(tris, candidates, o[i], d[i], tmin[i], tmax[i], corners=corners)
        if args.occluded:
            truth = bool(hits)
            right_a, right_b = bool(fa[i]) == truth, bool(fb[i]) == truth
            exact = f"occluded={truth}"
        elif hits:
            nearest = {k for t, k in hits if t == hits[0][0]}
            right_a = bool(fa[i]) and int(ida[i]) in nearest
            right_b = bool(fb[i]) and int(idb[i]) in nearest
            exact = f"t={float(hits[0][0]):.9g}"
            if not right_b:
                # How near the ray's line passes to an edge of a triangle involved (the exact
                # nearest, and OTHER's), over the bound ε: the scene's answers may differ from
                # the exact ones only within ε of an edge (or at a near tie).
                k = min(nearest)
                inst = int(np.searchsorted(offsets, k, side="right") - 1)
                t0 = float(hits[0][0])
                eps = bound(instances[inst], o[i], d[i], t0, offsets, tris)
                line = (o[i].astype(np.float64), d[i].astype(np.float64))
                involved = [k] + ([int(idb[i])] if fb[i] else [])
                gaps = [edge_gap(tris[f, j], tris[f, (j + 1) % 3], *line)
                        for f in involved for j in range(3)]
                exact += f", nearest edge at {min(gaps) / eps:.3g} ε (ε = {eps:.3g})"
        else:
            right_a, right_b = not fa[i], not fb[i]
            exact = "miss"
        key = verdict(right_a, right_b)
        tally[key] += 1
        if not right_b:
            detail = "" if args.occluded else hit_detail(a, b, ida, idb, i, "id")
            kind = str(rays["kind_names"][rays["kind"][i]]) if "kind" in rays.files else ""
            print(f"ray {i} ({key}, {kind}, [{tmin[i]:.9g}, {tmax[i]:.9g}]): exact {exact}{detail}")
    print(tally)


if __name__ == "__main__":
    main()
