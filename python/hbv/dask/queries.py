"""The queries over dask arrays: one task per chunk of rays, then one array per answer member.

Each query builds two layers: the answer of each chunk (one task: the in-memory call on that
chunk, with the worker's cached structure), then each member of it as a dask array chunked like
the rays. Computing several members together runs each chunk's query once.
"""

from __future__ import annotations

import dask.array as da
import numpy as np
from dask.base import tokenize

from . import ray_blocks, worker_cache
from .answers import answer_of
from .structure_bytes import kind_of
from .structure_handle import StructureHandle, share


def intersect(structure, origins, directions, tmin=None, tmax=None, mask=None, *, threads=1):
    """The closest hit of each ray: a dict of dask arrays (``hit``, ``t``, ``prim``, ``u``,
    ``v``, ``normal``; a Scene adds ``instance``), as ``structure.intersect``."""
    return _ray_query("intersect", structure, origins, directions, tmin, tmax, mask, threads)


def occluded(structure, origins, directions, tmin=None, tmax=None, mask=None, *, threads=1):
    """Whether anything lies along each ray: a bool dask array, as ``structure.occluded``."""
    return _ray_query("occluded", structure, origins, directions, tmin, tmax, mask, threads)


def count(structure, origins, directions, tmin=None, tmax=None, mask=None, *, threads=1):
    """The number of hits along each ray: an int64 dask array, as ``structure.count``."""
    return _ray_query("count", structure, origins, directions, tmin, tmax, mask, threads)


def intersect_all(structure, origins, directions, tmin=None, tmax=None, mask=None, *, threads=1):
    """Every hit along each ray, as a ragged result: the tuple of ``structure.intersect_all``
    (``ray``, ``t``, ``prim``; a Scene adds ``instance`` and ``normal``) as flat dask arrays,
    one row per hit, with one chunk per chunk of rays (lengths unknown until computed:
    ``compute_chunk_sizes()`` before ``to_zarr``). ``ray`` is the global ray index, rows are
    ordered by ray then as in memory, so the concatenation equals the in-memory answer.
    ``count`` gives the hits per ray (``cumsum``: the offsets)."""
    return _ray_query("intersect_all", structure, origins, directions, tmin, tmax, mask, threads)


def contains(structure, points, mask=None, *, threads=1):
    """Whether each point lies inside the (closed) mesh: a bool dask array."""
    return _point_query("contains", structure, points, mask, threads)


def closest_point(structure, points, mask=None, *, threads=1):
    """The nearest surface point of each point: a dict of dask arrays (``point``, ``distance``,
    ``prim``, ``u``, ``v``; a Scene adds ``instance``). TypeError for a Grid."""
    return _point_query("closest_point", structure, points, mask, threads)


def signed_distance(structure, points, mask=None, *, threads=1):
    """closest_point's distance, negative inside: a float64 dask array. TypeError for a Grid."""
    return _point_query("signed_distance", structure, points, mask, threads)


def _ray_query(query, structure, origins, directions, tmin, tmax, mask, threads):
    handle, form, members = _prepare(query, structure, mask)
    origins = ray_blocks.vectors("origins", origins)
    rows = origins.chunks[0]
    arrays = {"origins": origins, "directions": ray_blocks.vectors("directions", directions, rows)}
    per_ray = {"tmin": tmin, "tmax": tmax, "mask": mask}
    if form == "ragged":
        # The first global ray index of each chunk, read from the chunk's own slice of arange.
        per_ray["row_start"] = da.arange(sum(rows), chunks=(rows,), dtype=np.int64)
    return _build(query, handle, form, members, rows, arrays, per_ray, threads)


def _point_query(query, structure, points, mask, threads):
    handle, form, members = _prepare(query, structure, mask)
    points = ray_blocks.vectors("points", points)
    rows = points.chunks[0]
    return _build(query, handle, form, members, rows, {"points": points}, {"mask": mask}, threads)


def _prepare(query, structure, mask):
    kind = structure.kind if isinstance(structure, StructureHandle) else kind_of(structure)
    form, members = answer_of(query, kind)
    if mask is not None and kind != "scene":
        raise TypeError(f"{query}: mask is a Scene's (instance masks); this structure is a {kind}")
    return share(structure), form, members


def _build(query, handle, form, members, rows, arrays, per_ray, threads):
    """The chunk-answer layer and one dask array per member."""
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int)
                                or threads < 1):
        raise ValueError(f"threads: expected None or a positive int, got {threads!r}")
    names, inputs, scalars = [], [], {}
    for name, array in arrays.items():
        names.append(name)
        inputs += [array, "ij"]
    for name, value in per_ray.items():
        value = ray_blocks.per_ray(name, value, rows)
        if isinstance(value, da.Array):
            names.append(name)
            inputs += [value, "i"]
        elif value is not None:
            scalars[name] = value
    token = tokenize(handle.spec, query, threads, scalars, *inputs[::2])
    task = dict(query=query, array_names=tuple(names), scalars=scalars, spec=handle.spec,
                payload=handle.payload, local=handle.local, threads=threads)
    name = f"hbv-{query}-{token}"
    if form == "array":
        # One array per chunk: the answers are the chunks themselves, no member to pick.
        ((_, dtype, _shape),) = members
        return da.blockwise(_answer_chunk, "i", *inputs, name=name, dtype=dtype,
                            meta=np.empty((0,), dtype), concatenate=True, wrap=False, **task)
    answers = da.blockwise(
        _answer_chunk, "i", *inputs, name=name, dtype=object, meta=np.empty((0,), object),
        concatenate=True, adjust_chunks={"i": 1}, wrap=True, **task,
    )
    chunk_rows = tuple(float("nan") for _ in rows) if form == "ragged" else rows
    picked = {
        member: _member(answers, member if form == "dict" else position, dtype, shape, chunk_rows,
                        f"hbv-{query}-{member}-{token}")
        for position, (member, dtype, shape) in enumerate(members)
    }
    return picked if form == "dict" else tuple(picked.values())


def _member(answers, key, dtype, shape, rows, name):
    """One member of the answers as a dask array: ``rows`` per chunk, then ``shape``."""
    return answers.map_blocks(
        _pick, key,
        name=name,
        chunks=(rows, *[(size,) for size in shape]),
        new_axis=list(range(1, 1 + len(shape))) or None,
        dtype=dtype, meta=np.empty((0,) * (1 + len(shape)), dtype),
    )


def _pick(answers_chunk, key):
    """A member of a chunk's answer (key: its name or position in it)."""
    return answers_chunk[0][key]


def _answer_chunk(*chunks, query, array_names, scalars, spec, payload, local, threads, wrap):
    """One chunk's answer (on a worker): the in-memory query with the process's cached copy of
    the structure; wrap: in a 1-element object array (the chunk of the answers layer)."""
    structure = payload if local else worker_cache.structure_for(spec, payload)
    arrays = dict(zip(array_names, chunks))  # any layout: the compiled module copies if it must
    row_start = arrays.pop("row_start", None)
    positional = [arrays.pop(name) for name in ("origins", "directions", "points") if name in arrays]
    answer = getattr(structure, query)(*positional, threads=threads, **arrays, **scalars)
    if row_start is not None and len(row_start):
        answer = (answer[0] + row_start[0], *answer[1:])
    if not wrap:
        return answer
    out = np.empty(1, object)
    out[0] = answer
    return out
