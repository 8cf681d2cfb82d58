"""hbv: fast, exact ray queries on triangle meshes.

Build a bounding volume hierarchy over a mesh once, then ask it, for whole NumPy arrays of rays
or points at a time (all cores, GIL released):

- ``intersect``: the closest hit of each ray (``hit``, ``t``, ``prim``, ``u``, ``v``,
  ``normal``);
- ``occluded``: whether anything lies along each ray;
- ``intersect_all`` / ``count``: every hit along each ray, in one traversal;
- ``contains``: whether points lie inside a closed mesh (``Mesh.is_closed``; a RuntimeWarning
  otherwise);
- ``closest_point``: the nearest surface point, its distance, triangle and barycentrics;
- ``signed_distance``: that distance, negative inside the mesh.

Answers are exact (watertight ray/triangle test, checked against brute force) and deterministic
(equal ``t``: the smaller triangle id wins).

Rays and points are arrays of shape (N, 3), float32 or float64: read in place when C-ordered,
converted otherwise (strided, integer, lists); ``tmin`` / ``tmax`` a number or an (N,) array.
``threads``: ``None`` (every core) or a positive count; batches of up to 2,048 rays stay on the
calling thread, where waking other threads would cost more than the work.

>>> import numpy as np, hbv
>>> mesh = hbv.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
>>> bvh = hbv.BVH(mesh)
>>> hits = bvh.intersect(np.array([[0.2, 0.2, -1.0]]), np.array([[0.0, 0.0, 1.0]]))
>>> bool(hits["hit"][0]), float(hits["t"][0]), int(hits["prim"][0])
(True, 1.0, 0)

``hbv.Grid(mesh)`` (a uniform grid) answers the same ray queries, identically. ``bvh.save(path)``
writes the tree with its mesh to a ``.hbv`` file; ``hbv.load_bvh(path)`` reads it back without
building again.

``hbv.Scene()`` holds many meshes placed by instances (``add(mesh, transform, mask)``), in one
two-level BVH: the same queries, answering with the ``instance`` hit and its world ``normal``;
``hbv.load_scene(path)`` reads a glTF file as one, or a ``.hbv`` scene file that
``scene.save(path)`` wrote (scenes pickle too). ``hbv.interpolate`` gives per-vertex
attributes (normals, uv, colours) at hits.

``hbv.trimesh.RayMeshIntersector`` answers trimesh's ray queries with the same meaning;
``hbv.trimesh.scene`` converts a ``trimesh.Scene``. ``hbv.open3d.RaycastingScene`` answers
the queries of Open3D's ``open3d.t.geometry.RaycastingScene``.
"""

from ._hbv import BVH, Grid, Mesh, Scene, __version__, load, load_bvh, load_scene
from .vertex_attributes import interpolate
from . import open3d, trimesh

__all__ = [
    "BVH",
    "Grid",
    "Mesh",
    "Scene",
    "interpolate",
    "load",
    "load_bvh",
    "load_scene",
    "open3d",
    "trimesh",
    "__version__",
]
