"""What each query answers, per kind of structure: the members, their dtypes and shapes.

These are the in-memory calls' answers (``hbv/_hbv.pyi``); a dask answer has the same members,
dtypes and per-ray shapes, so that ``dask.compute`` of it equals the in-memory call bit for bit.
"""

from __future__ import annotations

import numpy as np

_F32, _F64, _I64, _BOOL = np.dtype(np.float32), np.dtype(np.float64), np.dtype(np.int64), np.dtype(bool)

#: (member, dtype, shape per ray) of the dict answers.
_HITS = [("hit", _BOOL, ()), ("t", _F32, ()), ("prim", _I64, ()), ("u", _F32, ()), ("v", _F32, ())]
_CLOSEST = [("point", _F64, (3,)), ("distance", _F64, ()), ("prim", _I64, ()), ("u", _F64, ()),
            ("v", _F64, ())]
_ALL_HITS = [("ray", _I64, ()), ("t", _F32, ()), ("prim", _I64, ())]

#: query -> (form, members by kind); form: "dict" (one array per member, one row per ray),
#: "ragged" (a tuple of flat arrays, one row per hit, chunk lengths unknown until computed) or
#: "array" (one array).
ANSWERS = {
    "intersect": ("dict", {
        "bvh": _HITS + [("normal", _F32, (3,))],
        "grid": _HITS + [("normal", _F32, (3,))],
        "scene": _HITS + [("instance", _I64, ()), ("normal", _F32, (3,))],
    }),
    "closest_point": ("dict", {
        "bvh": _CLOSEST,
        "scene": _CLOSEST + [("instance", _I64, ())],
    }),
    "intersect_all": ("ragged", {
        "bvh": _ALL_HITS,
        "grid": _ALL_HITS,
        "scene": _ALL_HITS + [("instance", _I64, ()), ("normal", _F32, (3,))],
    }),
    "occluded": ("array", {kind: [("", _BOOL, ())] for kind in ("bvh", "grid", "scene")}),
    "count": ("array", {kind: [("", _I64, ())] for kind in ("bvh", "grid", "scene")}),
    "contains": ("array", {kind: [("", _BOOL, ())] for kind in ("bvh", "grid", "scene")}),
    "signed_distance": ("array", {"bvh": [("", _F64, ())], "scene": [("", _F64, ())]}),
}


def answer_of(query: str, kind: str):
    """(form, members) of a query on a kind of structure; TypeError, at graph-build time, when
    that structure has no such query."""
    form, by_kind = ANSWERS[query]
    if kind not in by_kind:
        names = {"bvh": "hbv.BVH", "grid": "hbv.Grid", "scene": "hbv.Scene"}
        hint = " (a grid has no distance-ordered search: use an hbv.BVH)" if kind == "grid" else ""
        raise TypeError(f"{query}: {names[kind]} has no {query}{hint}")
    return form, by_kind[kind]
