"""hbv over a Dask cluster: the ray and point queries on dask arrays, chunked along the rays.

``pip install hbv[dask]``; ``import hbv`` does not import this module (nor Dask).

>>> import dask.array as da, hbv, hbv.dask                      # doctest: +SKIP
>>> handle = hbv.dask.open("/shared/city.hbv")                  # or hbv.dask.share(bvh)
>>> origins = da.from_zarr("rays.zarr", component="origins")
>>> directions = da.from_zarr("rays.zarr", component="directions")
>>> hits = hbv.dask.intersect(handle, origins, directions)
>>> da.to_zarr(hits["t"], "hits.zarr", component="t")

Every query takes a ``BVH``, ``Grid``, ``Scene`` or a handle and returns dask arrays with the
in-memory call's members and dtypes (``intersect_all``: a ragged tuple of flat arrays, see its
doc). The structure travels once per worker, never per task: ``share`` sends its bytes to every
worker (recoverably: a lost copy is made again), ``open`` names a ``.hbv`` file on shared
storage; each worker process keeps one loaded copy per checksum (BLAKE2b of the bytes;
``load_counts`` through ``client.run``, ``release`` frees it), and a worker whose file differs
from the client's refuses (``StructureMismatchError``). ``threads``: threads per task (default 1: Dask runs one task per
worker thread). docs/DISTRIBUTED.md: real clusters, chunk sizes, costs.
"""

from .queries import (
    closest_point,
    contains,
    count,
    intersect,
    intersect_all,
    occluded,
    signed_distance,
)
from .npy_rays import from_npy
from .preload import preload
from .structure_handle import StructureHandle, StructureSpec, open, release, share
from .worker_cache import StructureMismatchError, load_counts

__all__ = [
    "StructureHandle",
    "StructureMismatchError",
    "StructureSpec",
    "closest_point",
    "contains",
    "count",
    "from_npy",
    "intersect",
    "intersect_all",
    "load_counts",
    "occluded",
    "open",
    "preload",
    "release",
    "share",
    "signed_distance",
]
