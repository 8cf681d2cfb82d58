"""Float64 brute force over a scene's flattened world-space triangles, and a glTF writer: what
the scene tests compare ``hbv.Scene`` with."""

import base64
import json

import numpy as np

from reference import closest_on_triangles, nondegenerate, ray_triangle_t


def as_matrix(transform):
    """A (4, 4) float64 matrix of None (identity), a (4, 4) or a (3, 4) transform."""
    if transform is None:
        return np.eye(4)
    m = np.asarray(transform, dtype=np.float64)
    return m if m.shape == (4, 4) else np.vstack([m, [0.0, 0.0, 0.0, 1.0]])


class Flattened:
    """The world triangles of instances ``(vertices, faces, transform, mask)`` (``None`` for a
    removed one), instance by instance. Vertices are rounded to float32 (as ``hbv.Mesh``
    stores them) unless ``exact``, then mapped by the transform in float64."""

    def __init__(self, instances, exact=False):
        tris, owner, prim, masks = [], [], [], []
        for i, instance in enumerate(instances):
            if instance is None:
                masks.append(0)
                continue
            v, f, transform, mask = instance
            v = np.asarray(v, np.float64 if exact else np.float32).astype(np.float64)
            m = as_matrix(transform)
            world = v @ m[:3, :3].T + m[:3, 3]
            tris.append(world[np.asarray(f)])
            owner.append(np.full(len(f), i))
            prim.append(np.arange(len(f)))
            masks.append(mask)
        self.tris = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.instance = np.concatenate(owner) if owner else np.zeros(0, np.int64)
        self.prim = np.concatenate(prim) if prim else np.zeros(0, np.int64)
        self.masks = np.array(masks, dtype=np.uint64)
        self.ok = nondegenerate(self.tris)

    def seen(self, ray_masks):
        """(rays, triangles): whether each ray's mask sees each triangle's instance."""
        ray_masks = np.asarray(ray_masks, dtype=np.uint64).reshape(-1, 1)
        return (ray_masks & self.masks[self.instance][None]) != 0

    def ts(self, o, d, ray_masks):
        """t of every ray against every triangle it sees (NaN: no hit)."""
        with np.errstate(invalid="ignore"):
            t = ray_triangle_t(self.tris, o, d)
        t[:, ~self.ok] = np.nan
        t[~self.seen(ray_masks)] = np.nan
        return t

    def normals(self, faces):
        """normalize(cross(p1 - p0, p2 - p0)) of flattened faces ``faces``."""
        tri = self.tris[faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def face(self, instance, prim):
        """The flattened face of (instance, prim) pairs."""
        starts = {}
        for k, i in enumerate(self.instance):
            starts.setdefault(int(i), k)
        return np.array([starts[int(i)] + int(p) for i, p in zip(instance, prim)], dtype=np.int64)

    def closest(self, p, mask):
        """The nearest distance of point p to the triangles its mask sees, and the face."""
        keep = self.ok & self.seen([mask])[0]
        q = closest_on_triangles(p, self.tris[keep])
        dist = np.linalg.norm(q - p, axis=1)
        k = int(np.argmin(dist))
        return dist[k], np.flatnonzero(keep)[k]


def write_gltf(path, meshes, nodes, roots):
    """A .gltf file with its buffer inline (a data URI).

    meshes: list of (vertices, faces); nodes: list of dicts with optional "mesh", "matrix"
    (4x4 row-major, written column-major), "translation", "rotation" (x, y, z, w), "scale",
    "children"; roots: the scene's root nodes."""
    blob = bytearray()
    accessors, views, gltf_meshes = [], [], []

    def add_view(data, target):
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                      "target": target})
        blob.extend(data)
        return len(views) - 1

    for v, f in meshes:
        v = np.asarray(v, np.float32)
        f = np.asarray(f, np.uint32)
        pos = add_view(v.tobytes(), 34962)
        idx = add_view(f.tobytes(), 34963)
        accessors.append({"bufferView": pos, "componentType": 5126, "count": len(v),
                          "type": "VEC3", "min": v.min(0).tolist(), "max": v.max(0).tolist()})
        accessors.append({"bufferView": idx, "componentType": 5125, "count": f.size,
                          "type": "SCALAR"})
        gltf_meshes.append({"primitives": [{"attributes": {"POSITION": len(accessors) - 2},
                                            "indices": len(accessors) - 1}]})
    out_nodes = []
    for node in nodes:
        n = {k: v for k, v in node.items() if k != "matrix"}
        if "matrix" in node:
            n["matrix"] = np.asarray(node["matrix"], np.float64).T.reshape(-1).tolist()
        out_nodes.append(n)
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": out_nodes,
        "meshes": gltf_meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(bytes(blob)).decode()}],
    }
    with open(path, "w") as f:
        json.dump(doc, f)


def trs_matrix(translation=(0, 0, 0), rotation=(0, 0, 0, 1), scale=(1, 1, 1)):
    """T · R · S of a glTF node, float64 (rotation a unit quaternion x, y, z, w)."""
    x, y, z, w = rotation
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(scale, np.float64)[None, :]
    m[:3, 3] = translation
    return m
