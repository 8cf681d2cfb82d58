#!/usr/bin/env python3
"""Writes the fuzzers' seed inputs (small valid files of each format) into seeds/TARGET/.

Standard library only. Run from anywhere: python3 fuzz/seeds/make_seeds.py
"""
import base64
import io
import json
import os
import struct
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))

# A tetrahedron and a quad: closed mesh, polygons, shared vertices.
VERTS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TRIS = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def put(target, name, data):
    os.makedirs(os.path.join(HERE, target), exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, target, name), "wb") as f:
        f.write(data)


def obj():
    v = "".join(f"v {x} {y} {z}\n" for x, y, z in VERTS)
    put("obj", "tetra.obj", v + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in TRIS))
    put("obj", "forms.obj",
        "# comments, groups, texture and normal indices, relative indices, a quad\n"
        "mtllib m.mtl\no a\ng b\n" + v + "vt 0 0\nvn 0 0 1\nv 1 1 0 0.5 0.5 0.5\nv 1 1 1 2\n"
        "f 1/1 2/1 3/1\nf 1//1 2//1 4//1\nf -1 -2 -3 -4\nusemtl x\nf 1/1/1 3/1/1 4/1/1 2/1/1\nl 1 2\n")


def ply_header(fmt, nv, nf, extra=""):
    return (f"ply\nformat {fmt} 1.0\ncomment seed\nelement vertex {nv}\n"
            "property float x\nproperty float y\nproperty float z\n" + extra +
            f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n")


def ply():
    body = "".join(f"{x} {y} {z}\n" for x, y, z in VERTS)
    body += "".join(f"3 {a} {b} {c}\n" for a, b, c in TRIS)
    put("ply", "ascii.ply", ply_header("ascii", 4, 4) + body)
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        data = b"".join(struct.pack(e + "3f", *p) for p in VERTS)
        data += b"".join(struct.pack(e + "B3i", 3, *t) for t in TRIS)
        put("ply", fmt + ".ply", ply_header(fmt, 4, 4).encode() + data)
    # An extra vertex property, an extra element and a quad.
    head = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
            "property double z\nproperty uchar red\nelement edge 1\nproperty int a\n"
            "element face 1\nproperty list ushort uint vertex_index\nend_header\n")
    put("ply", "quad.ply", head + "0 0 0 9\n1 0 0 9\n1 1 0 9\n0 1 0 9\n7\n4 0 1 2 3\n")


def gltf_parts():
    pos = b"".join(struct.pack("<3f", *p) for p in VERTS)
    idx = b"".join(struct.pack("<3H", *t) for t in TRIS) + b"\0\0"
    blob = pos + idx
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "children": [1]}, {"mesh": 0, "translation": [2, 0, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": 24},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"},
        ],
    }
    return doc, blob


def gltf():
    doc, blob = gltf_parts()
    embedded = json.loads(json.dumps(doc))
    embedded["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                     + base64.b64encode(blob).decode())
    put("gltf", "embedded.gltf", json.dumps(embedded))
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    glb = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    put("gltf", "binary.glb", struct.pack("<4sII", b"glTF", 2, 12 + len(glb)) + glb)


def npy(descr, shape, values, fmt):
    header = "{'descr': '%s', 'fortran_order': False, 'shape': %s, }" % (
        descr, "(%d,)" % shape[0] if len(shape) == 1 else str(tuple(shape)))
    header += " " * (-(10 + len(header) + 1) % 64) + "\n"
    return (b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode()
            + b"".join(struct.pack(fmt, v) for v in values))


def ray_file():
    n = 3
    origins = [0.1, 0.2, -5, 0.2, 0.1, 5, 5, 0.3, 0.3]
    dirs = [0, 0, 1, 0, 0, -1, -1, 0, 0]
    for name, compression, members in (
        ("f32.npz", zipfile.ZIP_STORED, {
            "origins.npy": npy("<f4", (n, 3), origins, "<f"),
            "directions.npy": npy("<f4", (n, 3), dirs, "<f"),
            "tmin.npy": npy("<f4", (n,), [0, 0, 0], "<f"),
            "tmax.npy": npy("<f4", (n,), [1e30, 1e30, 1e30], "<f")}),
        ("f64_compressed.npz", zipfile.ZIP_DEFLATED, {
            "origins.npy": npy("<f8", (n, 3), origins, "<d"),
            "dirs": npy("<f8", (n, 3), dirs, "<d")}),
    ):
        out = io.BytesIO()
        with zipfile.ZipFile(out, "w", compression) as z:
            for member, data in members.items():
                z.writestr(member, data)
        put("ray_file", name, out.getvalue())


if __name__ == "__main__":
    obj(); ply(); gltf(); ray_file()
