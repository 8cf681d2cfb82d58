"""Per-vertex attributes at hits: ``interpolate(mesh, attribute, prim, u, v)``."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["interpolate"]


def interpolate(mesh: Any, attribute: Any, prim: Any, u: Any, v: Any) -> np.ndarray:
    """A per-vertex attribute (normals, uv, colours) at points of a mesh's triangles.

    Row ``i`` is ``(1 - u[i] - v[i]) * a0 + u[i] * a1 + v[i] * a2``, with ``a0``, ``a1``,
    ``a2`` the attribute's rows at the vertices of triangle ``prim[i]`` in face order: the
    barycentrics of ``intersect`` and ``closest_point`` (of ``hbv.BVH`` and, per instance's
    mesh, of ``hbv.Scene``) give the attribute at the hit.

    Parameters
    ----------
    mesh : an ``hbv.Mesh``, an ``hbv.BVH``, any object with ``faces`` (a trimesh mesh), or the
        faces themselves, an (F, 3) integer array.
    attribute : (V, k) or (V,) array, one row per vertex, of any numeric dtype.
    prim : (N,) integers: triangle ids, -1 for a miss.
    u, v : (N,) barycentrics.

    Returns
    -------
    (N, k) or (N,) array: float32 for a float32 attribute, float64 otherwise. Rows where
    ``prim`` is -1 are NaN (so that a miss cannot pass for a value; ``np.nan_to_num`` makes
    them 0). A ``ValueError`` or ``TypeError`` names the argument that is wrong (shapes, an id
    out of range).
    """
    faces = _faces_of(mesh)
    values = np.asarray(attribute)
    if values.ndim not in (1, 2) or not (
        np.issubdtype(values.dtype, np.number) or values.dtype == np.bool_
    ):
        raise TypeError(
            "attribute: expected a numeric array of shape (V,) or (V, k), got "
            f"dtype {values.dtype} and shape {values.shape}"
        )
    prim = np.asarray(prim)
    if prim.ndim != 1 or not np.issubdtype(prim.dtype, np.integer):
        raise TypeError(
            f"prim: expected an integer array of shape (N,), got dtype {prim.dtype} and "
            f"shape {prim.shape}"
        )
    u = _barycentric("u", u, len(prim))
    v = _barycentric("v", v, len(prim))
    if len(faces) and (faces.min() < 0 or faces.max() >= len(values)):
        raise ValueError(
            f"attribute: {len(values)} rows, but the faces index vertices up to {faces.max()}"
        )
    bad = (prim < -1) | (prim >= len(faces))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"prim: row {i}: {prim[i]} is not a triangle id of a mesh of {len(faces)} "
            "triangles (nor -1, a miss)"
        )
    # A float32 or float64 attribute keeps its precision, in either byte order.
    native = values.dtype.newbyteorder("=")
    dtype = native if native in (np.float32, np.float64) else np.float64
    miss = prim == -1
    if len(faces):
        corners = values[faces[np.where(miss, 0, prim)]].astype(dtype, copy=False)
    else:  # every prim is -1 (checked above)
        corners = np.zeros((len(prim), 3) + values.shape[1:], dtype)
    shape = (-1,) + (1,) * (values.ndim - 1)
    uu, vv = u.astype(dtype).reshape(shape), v.astype(dtype).reshape(shape)
    out = (1 - uu - vv) * corners[:, 0] + uu * corners[:, 1] + vv * corners[:, 2]
    out[miss] = np.nan
    return out


def _faces_of(mesh: Any) -> np.ndarray:
    """The (F, 3) int64 faces of an hbv.Mesh, an hbv.BVH, an object with faces, or an array."""
    mesh = getattr(mesh, "mesh", mesh)  # an hbv.BVH's mesh
    faces = np.asarray(getattr(mesh, "faces", mesh))
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise TypeError(
            "mesh: expected an hbv.Mesh, an hbv.BVH, an object with faces, or an (F, 3) "
            f"integer array, got {type(mesh).__name__}"
        )
    return faces.astype(np.int64, copy=False)


def _barycentric(name: str, values: Any, rows: int) -> np.ndarray:
    values = np.asarray(values)
    if values.shape != (rows,):
        raise ValueError(f"{name}: expected shape ({rows},), as prim has, got {values.shape}")
    if not np.issubdtype(values.dtype, np.floating):
        raise TypeError(f"{name}: expected a float array, got dtype {values.dtype}")
    return values
