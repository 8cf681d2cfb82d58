"""A ``.npy`` file as a dask array whose chunks each worker reads in place (memory map).

``da.from_array(np.load(path, mmap_mode="r"))`` works with Dask's local schedulers, but a
distributed graph would pickle the memory map, that is the whole array; here each task maps the
file on its worker and copies out only its rows, so memory stays bounded by the chunks.
"""

from __future__ import annotations

import os

import dask.array as da
import numpy as np
from dask.base import tokenize


def from_npy(path, rows: int) -> da.Array:
    """The array in ``path`` (a ``.npy`` file every worker reads at that path), chunked every
    ``rows`` rows along its first axis, the other axes whole."""
    path = os.path.abspath(os.fspath(path))
    header = np.load(path, mmap_mode="r")
    if header.ndim == 0:
        raise ValueError(f"{path}: a 0-d array has no rows to chunk")
    if not isinstance(rows, int) or rows < 1:
        raise ValueError(f"rows: expected a positive int, got {rows!r}")
    n = header.shape[0]
    starts = list(range(0, n, rows)) or [0]
    chunks = (tuple(min(rows, n - start) for start in starts), *((size,) for size in header.shape[1:]))
    name = f"hbv-npy-{tokenize(path, os.path.getmtime(path), n, rows)}"
    return da.map_blocks(
        _read_rows, path, rows,
        name=name, chunks=chunks, dtype=header.dtype,
        meta=np.empty((0,) * header.ndim, header.dtype),
    )


def _read_rows(path, rows, block_id=None):
    start = block_id[0] * rows
    return np.array(np.load(path, mmap_mode="r")[start:start + rows])
