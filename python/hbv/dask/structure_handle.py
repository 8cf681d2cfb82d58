"""How a graph names its structure: a handle that travels once per worker, never per task.

``share(structure)`` sends the structure's bytes to every worker of the current Dask client (as
a task's result, which the scheduler can make again if the workers holding it die; a replacement
worker fetches them from a peer);
``open(path)`` names a ``.hbv`` file every worker can read (shared storage) and takes its checksum
on the client. Tasks carry only the small ``StructureSpec`` and the shared bytes' future; each
worker process loads one copy per checksum (``worker_cache``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from . import structure_bytes, worker_cache


@dataclass(frozen=True)
class StructureSpec:
    """What each task carries: kind (``"bvh"``, ``"grid"``, ``"scene"``), checksum (BLAKE2b of
    the bytes), path (a shared ``.hbv`` file, or None when ``share`` sent the bytes) and the BVH
    layout to load with."""

    kind: str
    checksum: str
    path: str | None = None
    layout: str | None = None


class StructureHandle:
    """A structure as the workers see it; pass it wherever a BVH, Grid or Scene is taken.

    ``payload`` is the future of the bytes (``share`` with a distributed client), the
    structure itself (``share`` without one: the threaded scheduler shares memory), or None
    (``open``: each worker reads ``spec.path``).
    """

    def __init__(self, spec: StructureSpec, payload=None, local: bool = False):
        self.spec = spec
        self.payload = payload
        self.local = local

    @property
    def kind(self) -> str:
        return self.spec.kind

    @property
    def checksum(self) -> str:
        return self.spec.checksum

    def __repr__(self) -> str:
        source = self.spec.path or ("in memory" if self.local else "shared")
        return f"hbv.dask.StructureHandle({self.kind}, {source}, blake2b {self.checksum[:12]}…)"


# Handles of structures already shared, by (client id, checksum): the same structure passed
# again is not sent again.
_shared: dict[tuple[str, str], StructureHandle] = {}


def share(structure, client=None) -> StructureHandle:
    """Sends a BVH, Grid or Scene's bytes to every worker once, recoverably (see below).

    client: a ``distributed.Client`` (default: the current one); False, or no client at all:
    the handle holds the structure itself, for Dask's local schedulers (threads, synchronous).
    """
    if isinstance(structure, StructureHandle):
        return structure
    kind, data = structure_bytes.to_bytes(structure)
    layout = structure.layout if kind == "bvh" else None
    spec = StructureSpec(kind, structure_bytes.checksum(data), None, layout)
    if client is None:
        client = _current_client()
    if client is None or client is False:
        return StructureHandle(spec, structure, local=True)
    key = (client.id, spec.checksum)
    if key not in _shared:
        _shared[key] = StructureHandle(spec, _recoverable_bytes(client, data, spec.checksum))
    return _shared[key]


def _recoverable_bytes(client, data: bytes, checksum: str):
    """The bytes as a task's result (the task holds them, the scheduler keeps the task), sent to
    every worker. Unlike ``client.scatter``, whose data is lost for good when the workers holding
    it die (the active memory manager keeps one replica between graphs), a lost result is made
    again from the task: a killed worker never takes the structure with it."""
    import warnings

    with warnings.catch_warnings():
        # The size warning is for graphs that carry data by accident; here it is the point.
        warnings.filterwarnings("ignore", message=".*[Ll]arge.*")
        future = client.submit(_the_bytes, data, key=f"hbv-structure-{checksum}", pure=False)
    client.replicate([future])
    return future


def _the_bytes(data: bytes) -> bytes:
    return data


def open(path, layout: str | None = None) -> StructureHandle:  # noqa: A001 (hbv.dask.open)
    """Names a ``.hbv`` file (``BVH.save``, ``Scene.save``, ``hbv build``) on storage every
    worker reads at the same path. Its checksum is taken here; a worker whose file differs
    refuses with ``StructureMismatchError``. layout: the BVH layout to load with (BVH files)."""
    path = os.path.abspath(os.fspath(path))
    kind = structure_bytes.file_kind(path)
    if layout is not None and kind != "bvh":
        raise TypeError(f"layout: only a BVH file takes a layout, {path} holds a scene")
    return StructureHandle(StructureSpec(kind, structure_bytes.file_checksum(path), path, layout))


def release(handle: StructureHandle, client=None) -> None:
    """Frees a structure on the cluster: every worker drops its loaded copy, the client its
    bytes (a later query loads or sends it again)."""
    if client is None:
        client = _current_client()
    if handle.local or client is None:
        return
    _shared.pop((client.id, handle.checksum), None)
    client.run(worker_cache.drop, handle.checksum)


def _current_client():
    try:
        from distributed import get_client
    except ImportError:
        return None
    try:
        return get_client()
    except ValueError:
        return None
