"""trimesh interop: ``RayMeshIntersector(mesh)`` answers the ray queries of
``trimesh.ray.ray_triangle.RayMeshIntersector`` (and of trimesh's Embree one) with an hbv BVH;
``scene(trimesh_scene)`` makes an ``hbv.Scene`` of a ``trimesh.Scene``.

Same methods, arguments and return types; hits are exact (watertight), every hit along a ray is
found in one traversal, and rays run on all cores. trimesh itself is not needed to import this
module: any object with ``vertices`` (V, 3) and ``faces`` (F, 3) works as the mesh.

>>> import trimesh, hbv.trimesh
>>> mesh = trimesh.creation.icosphere()
>>> mesh.ray = hbv.trimesh.RayMeshIntersector(mesh)   # trimesh's own calls now use hbv
"""

from __future__ import annotations

from typing import Any, List, Optional, Tuple, Union

import numpy as np

from ._hbv import BVH, Mesh, Scene

__all__ = ["RayMeshIntersector", "scene", "scene_nodes"]


class RayMeshIntersector:
    """Ray queries on a trimesh mesh with the meaning of trimesh's intersectors.

    Parameters
    ----------
    mesh : trimesh.Trimesh, or any object with ``vertices`` (V, 3) and ``faces`` (F, 3)
    builder, layout, leaf_size : passed to :class:`hbv.BVH`.

    The BVH is built once, here; make a new intersector if the mesh changes.
    """

    def __init__(
        self,
        mesh: Any,
        builder: str = "binned-sah",
        layout: Optional[str] = None,
        leaf_size: Optional[int] = None,
    ) -> None:
        self.mesh = mesh
        self.bvh = BVH(
            Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)),
            builder=builder,
            layout=layout,
            leaf_size=leaf_size,
        )

    def intersects_id(
        self,
        ray_origins: Any,
        ray_directions: Any,
        return_locations: bool = False,
        multiple_hits: bool = True,
        max_hits: Optional[int] = None,
        **kwargs: Any,
    ) -> Union[Tuple[np.ndarray, np.ndarray], Tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Triangles hit by rays (from the origin forward).

        Returns ``(index_tri, index_ray)`` (int64), and the hit ``locations`` (h, 3) float64 as a
        third array with ``return_locations=True``. With ``multiple_hits=True`` every hit along
        each ray (at most ``max_hits`` per ray, nearest first), otherwise the closest one. As in
        trimesh, with ``return_locations=True`` a ray through a shared edge or vertex reports its
        location once.
        """
        origins, directions = _rays(ray_origins, ray_directions)
        if multiple_hits:
            index_ray, t, index_tri = self.bvh.intersect_all(origins, directions)
            if max_hits is not None:
                keep = _rank_within_ray(index_ray) < max_hits
                index_ray, t, index_tri = index_ray[keep], t[keep], index_tri[keep]
        else:
            hits = self.bvh.intersect(origins, directions)
            index_ray = np.flatnonzero(hits["hit"]).astype(np.int64)
            t, index_tri = hits["t"][index_ray], hits["prim"][index_ray]
        if not return_locations:
            return index_tri, index_ray
        locations = origins[index_ray] + directions[index_ray] * t[:, None].astype(np.float64)
        keep = _first_of_coincident(index_ray, locations)
        return index_tri[keep], index_ray[keep], locations[keep]

    def intersects_location(
        self, ray_origins: Any, ray_directions: Any, **kwargs: Any
    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unique hit locations: ``(locations (h, 3) float64, index_ray, index_tri)``."""
        index_tri, index_ray, locations = self.intersects_id(
            ray_origins, ray_directions, return_locations=True, **kwargs
        )
        return locations, index_ray, index_tri

    def intersects_first(self, ray_origins: Any, ray_directions: Any, **kwargs: Any) -> np.ndarray:
        """The triangle each ray hits first (int64), -1 where it hits nothing."""
        origins, directions = _rays(ray_origins, ray_directions)
        return self.bvh.intersect(origins, directions)["prim"]

    def intersects_any(self, ray_origins: Any, ray_directions: Any, **kwargs: Any) -> np.ndarray:
        """Whether each ray hits anything (bool)."""
        origins, directions = _rays(ray_origins, ray_directions)
        return self.bvh.occluded(origins, directions)

    def contains_points(self, points: Any) -> np.ndarray:
        """Whether each point lies inside the (closed) mesh (bool); undefined on the surface."""
        return self.bvh.contains(np.asarray(points, dtype=np.float64).reshape(-1, 3))


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


def _rays(origins: Any, directions: Any) -> Tuple[np.ndarray, np.ndarray]:
    """Rays as float64 (h, 3) arrays (trimesh accepts a single ray as (3,))."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(o) != len(d):
        raise ValueError(
            f"ray_directions: expected {len(o)} rows, as ray_origins has, got {len(d)}"
        )
    return o, d


def _rank_within_ray(index_ray: np.ndarray) -> np.ndarray:
    """0 for each ray's first hit, 1 for its second, ... (hits grouped by ray)."""
    if len(index_ray) == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.flatnonzero(np.r_[True, index_ray[1:] != index_ray[:-1]])
    first_of_group = np.repeat(starts, np.diff(np.r_[starts, len(index_ray)]))
    return np.arange(len(index_ray)) - first_of_group


def _first_of_coincident(index_ray: np.ndarray, locations: np.ndarray) -> np.ndarray:
    """Drops a hit that repeats the previous hit of the same ray at the same place (within
    1e-8 of the scene scale): a ray through an edge or vertex hits every triangle there."""
    if len(index_ray) < 2:
        return np.ones(len(index_ray), dtype=bool)
    scale = max(1.0, float(np.abs(locations).max()))
    same_ray = index_ray[1:] == index_ray[:-1]
    close = np.linalg.norm(locations[1:] - locations[:-1], axis=1) <= 1e-8 * scale
    return np.r_[True, ~(same_ray & close)]
