"""A structure as bytes and back: what travels to the workers.

A ``BVH`` travels as its ``.hbv`` file (the tree is read, not built again), a ``Scene`` as its
``.hbv`` scene file (what pickling it gives), a ``Grid`` as its pickle (mesh arrays and density:
the grid is rebuilt, deterministically, the same grid). The checksum that names a structure
everywhere is the BLAKE2b digest of these bytes.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile

from .. import _hbv

#: The first 8 bytes of every ``.hbv`` file (crates/hbv/src/bvh/file/format.rs).
HBV_MAGIC = b"\x89HBV\r\n\x1a\n"
#: The format version (bytes 8..12, little-endian) of each kind of ``.hbv`` file.
_KIND_OF_VERSION = {1: "bvh", 2: "scene"}


def kind_of(structure) -> str:
    """``"bvh"``, ``"grid"`` or ``"scene"``; TypeError for anything else."""
    if isinstance(structure, _hbv.BVH):
        return "bvh"
    if isinstance(structure, _hbv.Grid):
        return "grid"
    if isinstance(structure, _hbv.Scene):
        return "scene"
    raise TypeError(
        f"structure: expected an hbv.BVH, hbv.Grid, hbv.Scene or a handle from hbv.dask.open / "
        f"hbv.dask.share, got {type(structure).__name__}"
    )


def to_bytes(structure) -> tuple[str, bytes]:
    """(kind, bytes) of a structure; ``from_bytes(kind, bytes)`` answers identically."""
    kind = kind_of(structure)
    if kind == "grid":
        return kind, pickle.dumps(structure, protocol=pickle.HIGHEST_PROTOCOL)
    with tempfile.TemporaryDirectory(prefix="hbv-dask-") as folder:
        path = os.path.join(folder, "structure.hbv")
        structure.save(path)
        with open(path, "rb") as file:
            return kind, file.read()


def from_bytes(kind: str, data: bytes, layout: str | None = None):
    """The structure that ``to_bytes`` (or a ``.hbv`` file of that kind) gave these bytes."""
    if kind == "bvh":
        # The compiled module's unpickling entry of a loaded BVH: the .hbv file's bytes.
        return _hbv._bvh_from_bytes(data, layout)
    if kind == "scene":
        return _hbv._scene_from_bytes(data)
    if kind == "grid":
        return pickle.loads(data)
    raise ValueError(f"unknown structure kind {kind!r}")


def checksum(data: bytes) -> str:
    """BLAKE2b (32-byte digest) of the bytes, as hex."""
    return hashlib.blake2b(data, digest_size=32).hexdigest()


def file_checksum(path: str) -> str:
    """``checksum`` of a file's bytes, read in 4 MiB pieces."""
    digest = hashlib.blake2b(digest_size=32)
    with open(path, "rb") as file:
        for piece in iter(lambda: file.read(1 << 22), b""):
            digest.update(piece)
    return digest.hexdigest()


def file_kind(path: str) -> str:
    """The kind a ``.hbv`` file holds, told by its header; ValueError naming the file if it is
    not one (other formats: load them, then ``hbv.dask.share``)."""
    with open(path, "rb") as file:
        head = file.read(12)
    if len(head) < 12 or head[:8] != HBV_MAGIC:
        raise ValueError(
            f"{path}: not a .hbv file (no .hbv magic number); save the structure with "
            f"BVH.save / Scene.save or `hbv build`, or send it from the client with "
            f"hbv.dask.share"
        )
    version = int.from_bytes(head[8:12], "little")
    if version not in _KIND_OF_VERSION:
        raise ValueError(f"{path}: .hbv format version {version}, this hbv reads 1 and 2")
    return _KIND_OF_VERSION[version]
