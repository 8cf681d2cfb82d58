"""The arguments of a query as dask arrays that share one chunking along the rays.

The rays' (or points') first argument sets the row chunks; the 3 columns become one chunk;
every other per-ray array is rechunked to the same rows. Nothing is ever rechunked across rays
differently from the first argument, so chunks of any size pass through as they are.
"""

from __future__ import annotations

import math
import numbers

import dask.array as da
import numpy as np


def vectors(name: str, value, rows=None) -> da.Array:
    """(N, 3) rays' origins, directions or points as a dask array chunked ``(rows, 3)``
    (rows: the first argument's row chunks; None for the first argument itself)."""
    array = value if isinstance(value, da.Array) else da.asarray(value)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name}: expected an array of shape (N, 3), got shape {array.shape}")
    if rows is None:
        rows = array.chunks[0]
        if any(math.isnan(size) for size in rows):
            raise ValueError(
                f"{name}: unknown chunk sizes along the rays; call {name}.compute_chunk_sizes() "
                f"first"
            )
    elif array.shape[0] != sum(rows):
        raise ValueError(f"{name}: {array.shape[0]} rows, the first argument has {sum(rows)}")
    return array.rechunk((rows, 3))


def per_ray(name: str, value, rows):
    """A per-ray argument (tmin, tmax, mask): None and numbers stay as they are (the same for
    every ray); arrays become (N,) dask arrays chunked like the rays."""
    if value is None or isinstance(value, numbers.Number) or np.ndim(value) == 0:
        return value
    array = value if isinstance(value, da.Array) else da.asarray(value)
    if array.ndim != 1 or array.shape[0] != sum(rows):
        raise ValueError(f"{name}: expected a number or an array of shape ({sum(rows)},), got "
                         f"shape {array.shape}")
    return array.rechunk((rows,))

