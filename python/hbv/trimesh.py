"""trimesh interop: ``RayMeshIntersector(geometry)`` answers the ray queries of trimesh's Embree
intersector (``trimesh.ray.ray_pyembree.RayMeshIntersector``) with an hbv BVH, ``install()`` makes
it trimesh's Embree backend for every new mesh, and ``scene(trimesh_scene)`` makes an
``hbv.Scene`` of a ``trimesh.Scene``.

Same methods, keywords, return types and orders; hits are exact (watertight), every hit along a
ray is found in one traversal, hit locations come from the hit triangle's plane in float64, and
rays run on all cores. trimesh itself is not needed to import this module: any object with
``vertices`` (V, 3) and ``faces`` (F, 3) works as the mesh.

>>> import trimesh, hbv.trimesh
>>> mesh = trimesh.creation.icosphere()
>>> mesh.ray = hbv.trimesh.RayMeshIntersector(mesh)   # this mesh's ray calls now use hbv
>>> hbv.trimesh.install()                              # every new mesh's, too
"""

from __future__ import annotations

import sys
import types
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from ._hbv import BVH, Mesh, Scene, trimesh_hits

__all__ = ["RayMeshIntersector", "install", "uninstall", "scene", "scene_nodes"]


class RayMeshIntersector:
    """Ray queries on a trimesh mesh with the meaning of trimesh's Embree intersector.

    Parameters
    ----------
    geometry : trimesh.Trimesh, or any object with ``vertices`` (V, 3) and ``faces`` (F, 3)
    scale_to_box : bool
        As trimesh's keyword, for float32's sake: True (the default) traces a mesh that lies
        farther from the origin than its own size moved to its box's centre, so that the mesh
        keeps float32's precision of its size rather than of its distance from the origin.
        Answers are in the mesh's own coordinates either way. (trimesh also scales the mesh;
        floating point needs no scaling, so hbv does not.)
    builder, layout, leaf_size, quality : keywords of :class:`hbv.BVH`.

    Nothing is read from the mesh here: the BVH is built on the first query, as trimesh's
    intersectors do (trimesh makes its intersector inside ``Trimesh.__init__``, before a
    primitive has vertices), and built again by the first query after the mesh changed
    (``apply_scale``, ``apply_transform``, vertices edited in place), told by the hash of
    trimesh's tracked arrays, ``geometry.__hash__()``, the key of trimesh's own caches. An object
    that is not a trimesh geometry is read once: make a new intersector when it changes.
    """

    def __init__(
        self,
        geometry: Any,
        scale_to_box: bool = True,
        *,
        builder: Optional[str] = None,
        layout: Optional[str] = None,
        leaf_size: Optional[int] = None,
        quality: str = "medium",
    ) -> None:
        self.mesh = geometry
        self._scale_to_box = bool(scale_to_box)
        self._options: Dict[str, Any] = dict(
            builder=builder, layout=layout, leaf_size=leaf_size, quality=quality
        )
        self._traced: Optional[_TracedMesh] = None
        self._traced_key: Any = None

    @property
    def bvh(self) -> BVH:
        """The BVH of the mesh as it is now (built on first use, and again after a change)."""
        return self._current().bvh

    def intersects_id(
        self,
        ray_origins: Any,
        ray_directions: Any,
        multiple_hits: bool = True,
        max_hits: Optional[int] = 100,
        return_locations: bool = False,
        **kwargs: Any,
    ) -> Union[Tuple[np.ndarray, np.ndarray], Tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Triangles hit by rays (from the origin forward), trimesh's Embree order of arguments.

        Returns ``(index_tri, index_ray)`` (int64), and the hit ``locations`` (h, 3) float64 as a
        third array with ``return_locations=True``. With ``multiple_hits=True`` every hit along
        each ray, at most ``max_hits`` per ray (the nearest; None: all), in trimesh's Embree
        order: every ray's first hit (by ray), then every ray's second hit, and so on; otherwise
        each ray's closest hit, by ray. A ray crossing the surface through an edge or vertex
        hits one of the triangles there (decided exactly), and coincident faces hit at one place
        are one hit (within 1e-6 of the mesh's size plus the distance), as trimesh reports a
        place once. Locations are where the ray meets the hit triangle's plane, in float64
        from the mesh's float64 vertices.
        """
        traced = self._current()
        origins, directions = _rays(ray_origins, ray_directions)
        traced_origins = traced.placed(origins)
        max_hits = None if max_hits is None else int(max_hits)
        if max_hits is not None and max_hits < 1:
            index_ray, t, index_tri = _no_hits()
        elif multiple_hits:
            index_ray, t, index_tri = traced.bvh.intersect_all(traced_origins, directions)
        else:
            hits = traced.bvh.intersect(traced_origins, directions)
            index_ray = np.flatnonzero(hits["hit"])
            t, index_tri = hits["t"][index_ray], hits["prim"][index_ray]
            if not return_locations:
                return index_tri, index_ray
        planes = (traced.vertices, traced.faces) if return_locations else (None, None)
        index_tri, index_ray, locations = trimesh_hits(
            index_ray, t, index_tri, origins, directions, traced.size, max_hits, *planes
        )
        if locations is None:
            return index_tri, index_ray
        return index_tri, index_ray, locations

    def intersects_location(
        self,
        ray_origins: Any,
        ray_directions: Any,
        multiple_hits: bool = True,
        **kwargs: Any,
    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hit locations: ``(locations (h, 3) float64, index_ray, index_tri)``, as
        ``intersects_id(..., return_locations=True)`` finds them."""
        index_tri, index_ray, locations = self.intersects_id(
            ray_origins,
            ray_directions,
            multiple_hits=multiple_hits,
            return_locations=True,
            **kwargs,
        )
        return locations, index_ray, index_tri

    def intersects_first(self, ray_origins: Any, ray_directions: Any, **kwargs: Any) -> np.ndarray:
        """The triangle each ray hits first (int64), -1 where it hits nothing."""
        traced = self._current()
        origins, directions = _rays(ray_origins, ray_directions)
        return traced.bvh.intersect(traced.placed(origins), directions)["prim"]

    def intersects_any(self, ray_origins: Any, ray_directions: Any, **kwargs: Any) -> np.ndarray:
        """Whether each ray hits anything (bool)."""
        traced = self._current()
        origins, directions = _rays(ray_origins, ray_directions)
        return traced.bvh.occluded(traced.placed(origins), directions)

    def contains_points(self, points: Any) -> np.ndarray:
        """Whether each point lies inside the (closed) mesh (bool): one ray's exact parity;
        undefined on the surface. A RuntimeWarning when the mesh is not closed."""
        traced = self._current()
        return traced.bvh.contains(traced.placed(_points(points)))

    def _current(self) -> "_TracedMesh":
        """The traced mesh for the mesh as it is now, built when there is none or the mesh
        changed since."""
        key = _mesh_key(self.mesh)
        if self._traced is None or key != self._traced_key:
            self._traced = _TracedMesh(self.mesh, self._scale_to_box, self._options)
            self._traced_key = key
        return self._traced

    def __getstate__(self) -> Dict[str, Any]:
        # The mesh and the options: the BVH is built again on the first query after loading.
        return {"mesh": self.mesh, "scale_to_box": self._scale_to_box, "options": self._options}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.__init__(state["mesh"], state["scale_to_box"], **state["options"])  # type: ignore[misc]

    def __copy__(self) -> "RayMeshIntersector":
        # As trimesh's: a new intersector on the same mesh. The traced mesh is shared (it is
        # never changed, only replaced), so the copy does not build again.
        other = RayMeshIntersector(self.mesh, self._scale_to_box, **self._options)
        other._traced, other._traced_key = self._traced, self._traced_key
        return other

    def __deepcopy__(self, memo: Any = None) -> "RayMeshIntersector":
        return self.__copy__()


class _TracedMesh:
    """One state of the mesh as hbv traces it: its BVH, and the float64 vertices and int64 faces
    that hit locations are computed from."""

    def __init__(self, mesh: Any, scale_to_box: bool, options: Dict[str, Any]) -> None:
        self.vertices = np.array(mesh.vertices, dtype=np.float64, order="C").reshape(-1, 3)
        self.faces = np.array(mesh.faces, dtype=np.int64, order="C").reshape(-1, 3)
        finite = self.vertices[np.isfinite(self.vertices).all(axis=1)]
        if len(finite):
            low, high = finite.min(axis=0), finite.max(axis=0)
        else:
            low = high = np.zeros(3)
        #: The box's diagonal (trimesh's ``mesh.scale``), the unit of the location tolerance.
        self.size = max(float(np.linalg.norm(high - low)), np.finfo(np.float64).tiny)
        centre = (low + high) / 2
        #: Subtracted from vertices, rays and points before hbv sees them, or None.
        self.offset = None
        if scale_to_box and np.abs(centre).max() > (high - low).max():
            self.offset = centre
        traced = self.vertices if self.offset is None else self.vertices - self.offset
        self.bvh = BVH(Mesh(traced, self.faces), **options)

    def placed(self, points: np.ndarray) -> np.ndarray:
        """Points (ray origins) in the traced mesh's frame."""
        return points if self.offset is None else points - self.offset


def install() -> None:
    """Makes hbv trimesh's Embree intersector: ``trimesh.ray.ray_pyembree.RayMeshIntersector``
    becomes :class:`RayMeshIntersector` and ``trimesh.ray.has_embree`` True, so every mesh made
    from now on (``Trimesh(..., use_embree=True)``, the default) traces with hbv. Works whether
    or not embreex is installed; ``uninstall()`` puts back exactly what was there. Calling it
    again changes nothing."""
    import trimesh.ray

    if _installed:
        return
    module = trimesh.ray.ray_pyembree
    _installed["has_embree"] = trimesh.ray.has_embree
    _installed["ray_pyembree"] = module
    _installed["sys.modules"] = sys.modules.get("trimesh.ray.ray_pyembree", _ABSENT)
    if isinstance(module, types.ModuleType):
        # embreex is installed: its module stays, with hbv's intersector in it.
        _installed["RayMeshIntersector"] = module.__dict__.get("RayMeshIntersector", _ABSENT)
        module.RayMeshIntersector = RayMeshIntersector  # type: ignore[attr-defined]
    else:
        # trimesh holds the import error in its place: a module of hbv's intersector instead.
        module = types.ModuleType("trimesh.ray.ray_pyembree", "hbv's intersector (hbv.trimesh)")
        module.RayMeshIntersector = RayMeshIntersector  # type: ignore[attr-defined]
        trimesh.ray.ray_pyembree = module
        sys.modules["trimesh.ray.ray_pyembree"] = module
    trimesh.ray.has_embree = True


def uninstall() -> None:
    """Undoes ``install()``: trimesh's Embree module (or the import error in its place),
    ``has_embree`` and ``sys.modules`` as they were. Meshes made meanwhile keep hbv."""
    import trimesh.ray

    if not _installed:
        return
    module = _installed["ray_pyembree"]
    if isinstance(module, types.ModuleType):
        if _installed["RayMeshIntersector"] is _ABSENT:
            del module.RayMeshIntersector
        else:
            module.RayMeshIntersector = _installed["RayMeshIntersector"]
    trimesh.ray.ray_pyembree = module
    if _installed["sys.modules"] is _ABSENT:
        sys.modules.pop("trimesh.ray.ray_pyembree", None)
    else:
        sys.modules["trimesh.ray.ray_pyembree"] = _installed["sys.modules"]
    trimesh.ray.has_embree = _installed["has_embree"]
    _installed.clear()


#: What ``install()`` replaced, to be put back by ``uninstall()``; empty when not installed.
_installed: Dict[str, Any] = {}
_ABSENT = object()


def scene(trimesh_scene: Any) -> Scene:
    """An ``hbv.Scene`` of a ``trimesh.Scene``, placed by its node transforms.

    Each node of the scene graph that carries a triangle mesh becomes an instance, in the order
    of ``trimesh_scene.graph.nodes_geometry``, placed by the node's world transform
    (``trimesh_scene.graph[node][0]``, float64); a geometry shared by several nodes is one mesh
    of the hbv scene, built once and instanced. Vertices (float64 in trimesh) are kept relative
    to each mesh's centre, so that scenes far from the origin keep float32's precision of each
    mesh's size. Nodes whose geometry has no faces (point clouds, paths) are passed over, so
    instance ``i`` is the ``i``-th node of ``scene_nodes(trimesh_scene)``.
    """
    out = Scene()
    for node in scene_nodes(trimesh_scene):
        transform, geometry_name = trimesh_scene.graph[node]
        out.add(trimesh_scene.geometry[geometry_name], transform)
    return out


def scene_nodes(trimesh_scene: Any) -> List[str]:
    """The nodes of a ``trimesh.Scene`` that ``scene`` makes instances of, in instance order:
    those of ``graph.nodes_geometry`` whose geometry has faces."""
    nodes = []
    for node in trimesh_scene.graph.nodes_geometry:
        _, geometry_name = trimesh_scene.graph[node]
        if getattr(trimesh_scene.geometry[geometry_name], "faces", None) is not None:
            nodes.append(node)
    return nodes


def _mesh_key(mesh: Any) -> Any:
    """What tells a mesh's states apart: trimesh geometry hashes its data (``_data``, arrays that
    mark themselves changed when written), the key of trimesh's own caches; other objects are
    read once."""
    if hasattr(mesh, "_data"):
        return mesh.__hash__()
    return None


def _rays(origins: Any, directions: Any) -> Tuple[np.ndarray, np.ndarray]:
    """Rays as (n, 3) arrays, float32 or float64 as given (trimesh accepts a single ray as
    (3,))."""
    o = _rows3("ray_origins", origins)
    d = _rows3("ray_directions", directions)
    if len(o) != len(d):
        raise ValueError(
            f"ray_directions: expected {len(o)} rows, as ray_origins has, got {len(d)}"
        )
    return o, d


def _points(points: Any) -> np.ndarray:
    return _rows3("points", points)


def _rows3(name: str, values: Any) -> np.ndarray:
    """``values`` as a float32 or float64 (n, 3) array (others converted to float64), (3,) read
    as one row; a ValueError naming the argument for any other shape."""
    a = np.asarray(values)
    if a.dtype != np.float32 and a.dtype != np.float64:
        a = a.astype(np.float64)
    if a.shape == (3,):
        return a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (n, 3) or (3,), got {a.shape}")
    return a


def _no_hits() -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    empty = np.zeros(0, dtype=np.int64)
    return empty, np.zeros(0, dtype=np.float32), empty.copy()
