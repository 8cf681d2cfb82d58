"""The process-wide cache of structures on a worker: one loaded copy per checksum.

Every task that needs a structure asks ``structure_for``; the first one in the process loads it
(from the bytes sent by `share`, or from the shared file after checking its checksum against the one
the client took), every later one, of any graph, gets the same object. ``load_counts`` says how
often each checksum was loaded in this process (1, unless ``drop`` dropped it), for
``client.run``.
"""

from __future__ import annotations

import collections
import socket
import threading

from . import structure_bytes

_lock = threading.Lock()
_loaded: dict[str, object] = {}
_loads: collections.Counter[str] = collections.Counter()


class StructureMismatchError(ValueError):
    """A structure file whose bytes differ from the ones the client opened."""


def structure_for(spec, payload):
    """The structure ``spec`` names, loaded at most once in this process.

    spec: a ``StructureSpec`` (kind, checksum, path, layout); payload: the bytes sent by ``share``, or
    None when the structure is read from ``spec.path``. Raises ``StructureMismatchError`` when
    the bytes do not have the client's checksum: a worker never answers with another structure.
    """
    with _lock:
        structure = _loaded.get(spec.checksum)
        if structure is not None:
            return structure
        data = payload if payload is not None else _read(spec.path)
        found = structure_bytes.checksum(data)
        if found != spec.checksum:
            if spec.path is not None:
                where, why = spec.path, "the file changed or differs between hosts"
            else:
                where, why = "the structure sent by share", "its bytes were damaged on the way"
            raise StructureMismatchError(
                f"{where} on worker host {socket.gethostname()}: checksum {found[:16]}… differs "
                f"from the client's {spec.checksum[:16]}…; {why}: refusing to answer with "
                f"another structure"
            )
        structure = structure_bytes.from_bytes(spec.kind, data, spec.layout)
        _loaded[spec.checksum] = structure
        _loads[spec.checksum] += 1
        return structure


def _read(path: str) -> bytes:
    with open(path, "rb") as file:
        return file.read()


def load_counts() -> dict[str, int]:
    """{checksum: loads in this process}."""
    with _lock:
        return dict(_loads)


def drop(checksum: str | None = None) -> None:
    """Drops one loaded structure (or all of them: None) from this process."""
    with _lock:
        if checksum is None:
            _loaded.clear()
        else:
            _loaded.pop(checksum, None)
