"""Loading a structure on every worker before the first graph, so that no graph's first tasks
wait for it (and so that a benchmark times queries, not loads)."""

from __future__ import annotations

from . import worker_cache
from .structure_handle import share

#: A query's one-ray call that makes the layout it walks (the BVH makes layouts on first use:
#: see hbv.BVH's doc).
_RAY = ([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])


def preload(structure, client=None, warm: tuple[str, ...] = ()) -> dict[str, int]:
    """Loads the structure (a BVH, Grid, Scene or handle) on every worker of ``client`` (default:
    the current one), once per process as any task would; ``warm``: queries to call once on one
    ray or point there (``"intersect"``, ``"intersect_all"``, ``"closest_point"``, ...), which
    makes the layouts they walk. Returns {worker address: loads of this checksum there}."""
    if client is None:
        from distributed import get_client

        client = get_client()
    handle = share(structure, client)
    if handle.local:
        raise ValueError("preload: needs a distributed client")
    workers = list(client.scheduler_info()["workers"])
    futures = [
        client.submit(_load_and_warm, handle.spec, handle.payload, warm, workers=[worker],
                      allow_other_workers=False, pure=False)
        for worker in workers
    ]
    return dict(zip(workers, client.gather(futures)))


def _load_and_warm(spec, payload, warm):
    structure = worker_cache.structure_for(spec, payload)
    for query in warm:
        if query in ("contains", "closest_point", "signed_distance"):
            getattr(structure, query)(_RAY[0], threads=1)
        else:
            getattr(structure, query)(*_RAY, threads=1)
    return worker_cache.load_counts()[spec.checksum]


