"""Open3D interop: ``RaycastingScene()`` answers the queries of
``open3d.t.geometry.RaycastingScene`` with hbv.

Same methods, arguments, result keys, dtypes and shapes (any leading shape of the rays or
points is kept); the results are NumPy arrays instead of Open3D tensors. Open3D itself is not
needed: vertex and index arrays work everywhere, and Open3D meshes and tensors (legacy or
``open3d.t``) are read through their NumPy views when Open3D is installed.

>>> import hbv.open3d
>>> scene = hbv.open3d.RaycastingScene()      # in place of open3d.t.geometry.RaycastingScene()

What differs is exactness and speed. Open3D decides inside and outside (``compute_occupancy``,
the sign of ``compute_signed_distance``) by the parity of one ray's hits (or a vote of
``nsamples`` rays), which miscounts where the ray passes through an edge or a vertex; hbv's
parity test counts such a ray as a ray moved by an infinitesimal amount would cross, so its
answer is exact on closed meshes whatever ``nsamples`` says. A ray through a shared edge is hit
once (closest hit, ``list_intersections``, ``count_intersections``). On a mesh that is not
closed, where inside is not defined, hbv takes the majority of three rays' exact parities with
one geometry, and one ray's exact parity with several.

One geometry is answered by an :class:`hbv.BVH`, several by an :class:`hbv.Scene` whose
instance ids are the geometry ids; both are made on the first query after a geometry is added.
Inside tests of a closed geometry answer repeated calls' points away from the surface without
a ray, through the inside grid that ``hbv.BVH.contains`` and ``hbv.Scene.contains`` make.
"""

from __future__ import annotations

import contextlib
import math
import sys
import warnings
from typing import Any, Dict, Iterator, List, Optional, Tuple

import numpy as np

from ._hbv import BVH, Mesh, Scene

__all__ = ["RaycastingScene"]

#: The id of no geometry and no triangle (Open3D's ``RaycastingScene.INVALID_ID``).
INVALID_ID = 4294967295


def _numpy(value: Any) -> np.ndarray:
    """An array or an Open3D tensor (``.numpy()``) as a NumPy array, without a copy where it
    allows."""
    if not isinstance(value, np.ndarray) and hasattr(value, "numpy"):
        value = value.numpy()
    return np.asarray(value)


def _last_axis(value: Any, name: str, width: int) -> Tuple[np.ndarray, Tuple[int, ...]]:
    """`value` as float32 rows of `width` (a view where it allows) and its leading shape."""
    array = _numpy(value)
    if array.ndim < 2 or array.shape[-1] != width:
        raise ValueError(
            f"{name}: expected an array of shape (..., {width}) with at least 2 dimensions, "
            f"got shape {array.shape}"
        )
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"{name}: expected a float32 array, got dtype {array.dtype}")
    lead = array.shape[:-1]
    return np.asarray(array, dtype=np.float32).reshape(-1, width), lead


def _threads(nthreads: Any) -> Optional[int]:
    """Open3D's ``nthreads`` (0: every core) as hbv's ``threads`` (None: every core)."""
    count = int(nthreads)
    if count < 0:
        raise ValueError(f"nthreads: expected 0 (every core) or a positive count, got {count}")
    return count or None


def _check_samples(nsamples: Any) -> None:
    """Open3D's rule for ``nsamples`` (odd and >= 1); hbv's answer needs one ray."""
    count = int(nsamples)
    if count < 1 or count % 2 == 0:
        raise ValueError(f"nsamples: must be odd and >= 1, got {count}")


def _mesh_arrays(mesh: Any, triangle_indices: Any) -> Tuple[np.ndarray, np.ndarray]:
    """The vertices (float32) and triangles (int64) of what ``add_triangles`` was given."""
    if triangle_indices is not None:
        vertices, triangles = _numpy(mesh), _numpy(triangle_indices)
    elif hasattr(mesh, "vertex") and hasattr(mesh, "triangle"):  # open3d.t TriangleMesh
        vertices = _numpy(mesh.vertex["positions"])
        triangles = (
            _numpy(mesh.triangle["indices"])
            if "indices" in mesh.triangle
            else np.zeros((0, 3), np.int64)
        )
    elif hasattr(mesh, "vertices") and hasattr(mesh, "triangles"):  # legacy TriangleMesh
        vertices, triangles = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    elif isinstance(mesh, Mesh) or (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
        vertices, triangles = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    else:
        raise TypeError(
            "add_triangles: expected a triangle mesh (open3d.t.geometry.TriangleMesh, "
            "open3d.geometry.TriangleMesh, hbv.Mesh) or vertex and index arrays, got "
            f"{type(mesh).__name__}"
        )
    vertices = np.asarray(vertices, dtype=np.float32)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"add_triangles: vertices must have shape (N, 3), got {vertices.shape}")
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise ValueError(f"add_triangles: triangles must have shape (M, 3), got {triangles.shape}")
    if triangles.size and not np.issubdtype(triangles.dtype, np.integer):
        raise ValueError(f"add_triangles: triangles must be integers, got dtype {triangles.dtype}")
    return vertices, triangles.astype(np.int64, copy=False)


def _unit_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """normalize(cross(p1 - p0, p2 - p0)) of each triangle in float64, as float32 (0 for a
    degenerate one): the normal hbv's hits carry and Open3D's ``primitive_normals``."""
    p = vertices.astype(np.float64)[triangles]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return np.divide(normal, length, out=np.zeros_like(normal), where=length > 0).astype(
        np.float32
    )


class _Geometry:
    """One added mesh: its arrays, its hbv mesh and its triangles' unit normals."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray) -> None:
        self.vertices = vertices
        self.triangles = triangles
        self.mesh = Mesh(vertices, triangles)
        self.normals = _unit_normals(vertices, triangles)
        self.closed = self.mesh.is_closed


class RaycastingScene:
    """Ray and point queries on triangle meshes, with the methods and results of
    ``open3d.t.geometry.RaycastingScene``.

    Parameters
    ----------
    nthreads : int
        Threads of the queries' default (0: every core); a query's own ``nthreads`` wins.
    device : ignored (hbv runs on the CPU).
    """

    INVALID_ID = INVALID_ID

    def __init__(self, nthreads: int = 0, device: Any = None) -> None:
        self._default_threads = _threads(nthreads)
        self._geometries: List[_Geometry] = []
        self._structure: Any = None
        #: Every geometry's triangle normals in one table, made on first use (``_normal_table``).
        self._normals: Optional[Tuple[np.ndarray, np.ndarray]] = None

    # -- geometry ----------------------------------------------------------------------------

    def add_triangles(self, mesh: Any, triangle_indices: Any = None) -> int:
        """Adds a triangle mesh and returns its geometry id (0, 1, 2, ... in call order).

        ``add_triangles(mesh)`` with an Open3D mesh (``open3d.t`` or legacy) or an hbv.Mesh, or
        ``add_triangles(vertex_positions, triangle_indices)`` with (N, 3) and (M, 3) arrays or
        tensors. Vertices are used in float32, as Open3D does.
        """
        vertices, triangles = _mesh_arrays(mesh, triangle_indices)
        geometry = _Geometry(vertices, triangles)
        self._geometries.append(geometry)
        self._normals = None
        if isinstance(self._structure, Scene):
            self._structure.add(geometry.mesh)
        else:
            self._structure = None
        return len(self._geometries) - 1

    def _answerer(self) -> Any:
        """The BVH (one geometry) or Scene (none, or several) that answers, made on first use."""
        if self._structure is None:
            if len(self._geometries) == 1:
                self._structure = BVH(self._geometries[0].mesh)
            else:
                scene = Scene()
                for geometry in self._geometries:
                    scene.add(geometry.mesh)
                self._structure = scene
        return self._structure

    def _normal_table(self) -> Tuple[np.ndarray, np.ndarray]:
        """(normals, offsets): geometry j's triangle i has row ``offsets[j] + i`` of normals."""
        if self._normals is None:
            sizes = [len(g.triangles) for g in self._geometries]
            offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
            normals = [g.normals for g in self._geometries] or [np.zeros((0, 3), np.float32)]
            self._normals = (np.concatenate(normals), offsets)
        return self._normals

    def _ids(self, answer: Dict[str, np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
        """(geometry ids, primitive ids) as uint32, INVALID_ID where there is none."""
        primitive_ids = _low_words(answer["prim"])
        if "instance" in answer:
            return _low_words(answer["instance"]), primitive_ids
        # One geometry: 0 where a triangle was found (prim >= 0), INVALID_ID where not (-1):
        # the high words of prim.
        return _high_words(answer["prim"]), primitive_ids

    def _rays(self, rays: Any) -> Tuple[np.ndarray, np.ndarray, Tuple[int, ...]]:
        """Origins and directions: the two halves of the (N, 6) float32 rows, views that the
        compiled module reads in place (rows a stride of 6 apart), not copies."""
        flat, lead = _last_axis(rays, "rays", 6)
        return flat[:, :3], flat[:, 3:], lead

    def _run_threads(self, nthreads: Any) -> Optional[int]:
        return _threads(nthreads) if int(nthreads) else self._default_threads

    # -- rays --------------------------------------------------------------------------------

    def cast_rays(self, rays: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """The first hit of each ray ``[ox, oy, oz, dx, dy, dz]`` (shape (..., 6)) over
        ``[0, inf)``, ``t`` in units of the direction's length: ``t_hit`` (float32, inf on a
        miss), ``geometry_ids``, ``primitive_ids`` (uint32, INVALID_ID on a miss),
        ``primitive_uvs`` (..., 2) float32 (hit = (1-u-v) p0 + u p1 + v p2) and
        ``primitive_normals`` (..., 3) float32 (unit ``cross(p1 - p0, p2 - p0)``; 0 on a miss).
        """
        origins, directions, lead = self._rays(rays)
        hits = self._answerer().intersect(origins, directions, threads=self._run_threads(nthreads))
        geometry_ids, primitive_ids = self._ids(hits)
        return {
            "t_hit": hits["t"].reshape(lead),
            "geometry_ids": geometry_ids.reshape(lead),
            "primitive_ids": primitive_ids.reshape(lead),
            "primitive_uvs": _pairs(hits["u"], hits["v"]).reshape(lead + (2,)),
            "primitive_normals": hits["normal"].reshape(lead + (3,)),
        }

    def test_occlusions(
        self, rays: Any, tnear: float = 0.0, tfar: float = math.inf, nthreads: int = 0
    ) -> np.ndarray:
        """Whether each ray hits anything with ``tnear <= t <= tfar`` (bool, shape (...))."""
        origins, directions, lead = self._rays(rays)
        occluded = self._answerer().occluded(
            origins, directions, tmin=float(tnear), tmax=float(tfar),
            threads=self._run_threads(nthreads),
        )
        return occluded.reshape(lead)

    def count_intersections(self, rays: Any, nthreads: int = 0) -> np.ndarray:
        """The number of triangles each ray crosses over ``[0, inf)`` (int32, shape (...)); a
        ray through an edge or vertex shared by triangles counts it once."""
        origins, directions, lead = self._rays(rays)
        counts = self._answerer().count(origins, directions, threads=self._run_threads(nthreads))
        return counts.astype(np.int32).reshape(lead)

    def list_intersections(self, rays: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """Every hit of every ray (rays flattened in C order): ``ray_splits`` (uint32, rays + 1:
        ray i's hits are ``ray_splits[i]:ray_splits[i + 1]``), ``ray_ids``, ``geometry_ids``,
        ``primitive_ids`` (uint32), ``primitive_uvs`` (H, 2) float32 and ``t_hit`` float32;
        a ray's hits sorted by ``t`` (Open3D lists them in no set order)."""
        origins, directions, _ = self._rays(rays)
        structure = self._answerer()
        found = structure.intersect_all(origins, directions, threads=self._run_threads(nthreads))
        ray_ids, t_hit, prims = found[0], found[1], found[2]
        if isinstance(structure, Scene):
            geometries = found[3]
        else:
            geometries = np.zeros(len(ray_ids), np.int64)
        counts = np.bincount(ray_ids, minlength=len(origins))
        ray_splits = np.zeros(len(origins) + 1, np.uint32)
        np.cumsum(counts, out=ray_splits[1:])
        uvs = self._crossing_uvs(origins[ray_ids], directions[ray_ids], geometries, prims)
        return {
            "ray_splits": ray_splits,
            "ray_ids": ray_ids.astype(np.uint32),
            "geometry_ids": geometries.astype(np.uint32),
            "primitive_ids": prims.astype(np.uint32),
            "primitive_uvs": uvs,
            "t_hit": t_hit,
        }

    def _crossing_uvs(
        self, origins: np.ndarray, directions: np.ndarray, geometries: np.ndarray, prims: np.ndarray
    ) -> np.ndarray:
        """Barycentrics (u, v) where each ray crosses its triangle's plane, in float64 (the
        triple products of Moller & Trumbore 1997: u = (s x e2)... written with e1 = p1 - p0,
        e2 = p2 - p0, s = o - p0: u = d.(s x e2) / d.(e1 x e2), v = d.(e1 x s) / d.(e1 x e2)),
        as float32."""
        corners = np.empty((len(prims), 3, 3), np.float64)
        for g, geometry in enumerate(self._geometries):
            rows = np.flatnonzero(geometries == g)
            corners[rows] = geometry.vertices[geometry.triangles[prims[rows]]]
        d = directions.astype(np.float64)
        e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
        s = origins.astype(np.float64) - corners[:, 0]
        det = np.einsum("ij,ij->i", d, np.cross(e1, e2))
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("ij,ij->i", d, np.cross(s, e2)) / det
            v = np.einsum("ij,ij->i", d, np.cross(e1, s)) / det
        return np.stack([u, v], axis=-1).astype(np.float32)

    # -- points ------------------------------------------------------------------------------

    def _points(self, query_points: Any) -> Tuple[np.ndarray, Tuple[int, ...]]:
        return _last_axis(query_points, "query_points", 3)

    def compute_closest_points(self, query_points: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """The nearest surface point of each point (shape (..., 3)), exact: ``points`` (..., 3)
        float32, ``geometry_ids``, ``primitive_ids`` (uint32, INVALID_ID for a point that is
        not finite or an empty scene), ``primitive_uvs`` (..., 2) float32 (point = (1-u-v) p0
        + u p1 + v p2) and ``primitive_normals`` (..., 3) float32 (the triangle's unit normal);
        ties go to the smaller geometry id, then the smaller triangle id."""
        points, lead = self._points(query_points)
        found = self._answerer().closest_point(points, threads=self._run_threads(nthreads))
        geometry_ids, primitive_ids = self._ids(found)
        valid = found["prim"] >= 0
        normals = np.zeros((len(points), 3), np.float32)
        geometry = geometry_ids[valid].astype(np.int64)
        table, offsets = self._normal_table()
        normals[valid] = table[offsets[geometry] + found["prim"][valid]]
        return {
            "points": found["point"].astype(np.float32).reshape(lead + (3,)),
            "geometry_ids": geometry_ids.reshape(lead),
            "primitive_ids": primitive_ids.reshape(lead),
            "primitive_uvs": _pairs(found["u"], found["v"]).reshape(lead + (2,)),
            "primitive_normals": normals.reshape(lead + (3,)),
        }

    def compute_distance(self, query_points: Any, nthreads: int = 0) -> np.ndarray:
        """The distance of each point to the nearest surface (float32, shape (...)), exact;
        NaN for a point that is not finite, inf in an empty scene."""
        points, lead = self._points(query_points)
        found = self._answerer().closest_point(points, threads=self._run_threads(nthreads))
        return _nan_where_not_finite(found["distance"], points).reshape(lead)

    def compute_signed_distance(
        self, query_points: Any, nthreads: int = 0, nsamples: int = 1
    ) -> np.ndarray:
        """``compute_distance``, negative inside a closed surface (float32, shape (...)). The
        sign is hbv's exact inside test; ``nsamples`` (odd, >= 1) is checked and not needed."""
        _check_samples(nsamples)
        points, lead = self._points(query_points)
        with self._quiet_if_open():
            signed = self._answerer().signed_distance(points, threads=self._run_threads(nthreads))
        return _nan_where_not_finite(signed, points).reshape(lead)

    def compute_occupancy(self, query_points: Any, nthreads: int = 0, nsamples: int = 1) -> np.ndarray:
        """1.0 where a point lies inside a closed surface, else 0.0 (float32, shape (...)), by
        hbv's exact inside test; ``nsamples`` (odd, >= 1) is checked and not needed."""
        _check_samples(nsamples)
        points, lead = self._points(query_points)
        with self._quiet_if_open():
            inside = self._answerer().contains(points, threads=self._run_threads(nthreads))
        return inside.astype(np.float32).reshape(lead)

    def _quiet_if_open(self) -> Any:
        """A context that silences hbv's RuntimeWarning on open meshes where there is one
        (Open3D does not warn: its inside tests assume closed meshes, as its callers do)."""
        return _silenced_runtime_warnings(not all(g.closed for g in self._geometries))

    # -- cameras -----------------------------------------------------------------------------

    @staticmethod
    def create_rays_pinhole(*args: Any, **kwargs: Any) -> np.ndarray:
        """The rays of a pinhole camera, shape (height_px, width_px, 6) float32, one through
        the centre of each pixel; the direction has depth 1 along the camera's axis.

        ``create_rays_pinhole(intrinsic_matrix, extrinsic_matrix, width_px, height_px)`` with
        the (3, 3) intrinsic matrix and the (4, 4) world-to-camera matrix, or
        ``create_rays_pinhole(fov_deg, center, eye, up, width_px, height_px)`` with the
        horizontal field of view in degrees, the point looked at, the camera's position and its
        up vector.
        """
        names = ("intrinsic_matrix", "extrinsic_matrix", "width_px", "height_px")
        if "fov_deg" in kwargs or (args and np.ndim(_numpy(args[0])) == 0):
            names = ("fov_deg", "center", "eye", "up", "width_px", "height_px")
        given = dict(zip(names, args))
        overlap = set(given) & set(kwargs)
        if overlap or len(args) > len(names) or set(kwargs) - set(names):
            raise TypeError(
                "create_rays_pinhole: expected (intrinsic_matrix, extrinsic_matrix, width_px, "
                "height_px) or (fov_deg, center, eye, up, width_px, height_px)"
            )
        given.update(kwargs)
        missing = [name for name in names if name not in given]
        if missing:
            raise TypeError(f"create_rays_pinhole: missing {', '.join(missing)}")
        width, height = int(given["width_px"]), int(given["height_px"])
        if width <= 0 or height <= 0:
            raise ValueError(f"create_rays_pinhole: width_px and height_px must be positive, got {width}, {height}")
        if "fov_deg" in given:
            intrinsic, extrinsic = _look_at(
                float(given["fov_deg"]), given["center"], given["eye"], given["up"], width, height
            )
        else:
            intrinsic = _matrix(given["intrinsic_matrix"], "intrinsic_matrix", (3, 3))
            extrinsic = _matrix(given["extrinsic_matrix"], "extrinsic_matrix", (4, 4))
        return _pinhole_rays(intrinsic, extrinsic, width, height)


@contextlib.contextmanager
def _silenced_runtime_warnings(active: bool) -> Iterator[None]:
    if not active:
        yield
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def _low_words(ids: np.ndarray) -> np.ndarray:
    """int64 ids (-1: none) as uint32 (INVALID_ID: none): their low 32 bits."""
    if sys.byteorder == "little":
        return np.ascontiguousarray(ids.view(np.uint32)[0::2])
    return ids.astype(np.uint32)


def _high_words(ids: np.ndarray) -> np.ndarray:
    """0 where an int64 id in [0, 2^32) is given, INVALID_ID where it is -1: the high 32 bits."""
    if sys.byteorder == "little":
        return np.ascontiguousarray(ids.view(np.uint32)[1::2])
    return (ids >> 32).astype(np.uint32)


def _pairs(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 2) float32 rows (u, v)."""
    pairs = np.empty((len(u), 2), np.float32)
    pairs[:, 0], pairs[:, 1] = u, v
    return pairs


def _nan_where_not_finite(distance: np.ndarray, points: np.ndarray) -> np.ndarray:
    """float32 distances, NaN for a point with a NaN or infinite coordinate (as Open3D's)."""
    distance = distance.astype(np.float32)
    if not np.isfinite(distance).all():
        distance[~np.isfinite(points).all(axis=1)] = np.nan
    return distance


def _matrix(value: Any, name: str, shape: Tuple[int, int]) -> np.ndarray:
    matrix = _numpy(value).astype(np.float64)
    if matrix.shape != shape or not np.isfinite(matrix).all():
        raise ValueError(f"create_rays_pinhole: {name} must be a finite {shape} matrix, got shape {matrix.shape}")
    return matrix


def _vector(value: Any, name: str) -> np.ndarray:
    vector = _numpy(value).astype(np.float64).reshape(-1)
    if vector.shape != (3,) or not np.isfinite(vector).all():
        raise ValueError(f"create_rays_pinhole: {name} must be 3 finite numbers, got {value!r}")
    return vector


def _look_at(
    fov_deg: float, center: Any, eye: Any, up: Any, width: int, height: int
) -> Tuple[np.ndarray, np.ndarray]:
    """The intrinsic and world-to-camera matrices of a camera at `eye` looking at `center`
    with a horizontal field of view of `fov_deg`, as Open3D makes them: the camera's x axis
    along up x forward, its y axis along forward x (up x forward) and z forward, so that row 0
    of the image is its side away from `up`; equal to Open3D's up to float32 rounding."""
    if not 0 < fov_deg < 180:
        raise ValueError(f"create_rays_pinhole: fov_deg must lie in (0, 180), got {fov_deg}")
    center, eye, up = _vector(center, "center"), _vector(eye, "eye"), _vector(up, "up")
    focal = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    intrinsic = np.array([[focal, 0, 0.5 * width], [0, focal, 0.5 * height], [0, 0, 1]])
    forward = center - eye
    x_axis = np.cross(up, forward)
    y_axis = np.cross(forward, x_axis)
    lengths = [np.linalg.norm(axis) for axis in (x_axis, y_axis, forward)]
    if min(lengths) == 0:
        raise ValueError("create_rays_pinhole: eye equals center, or up is parallel to the view")
    rotation = np.stack([x_axis / lengths[0], y_axis / lengths[1], forward / lengths[2]])
    extrinsic = np.eye(4)
    extrinsic[:3, :3] = rotation
    extrinsic[:3, 3] = -rotation @ eye
    return intrinsic, extrinsic


def _pinhole_rays(intrinsic: np.ndarray, extrinsic: np.ndarray, width: int, height: int) -> np.ndarray:
    """Rays from the camera's centre through pixel centres (x + 0.5, y + 0.5): direction
    R^-1 K^-1 (x + 0.5, y + 0.5, 1), origin -R^-1 t, for the extrinsic [R t]."""
    try:
        to_world = np.linalg.inv(extrinsic)
        pixel_to_camera = np.linalg.inv(intrinsic)
    except np.linalg.LinAlgError as error:
        raise ValueError(f"create_rays_pinhole: the camera matrices are singular ({error})") from None
    x, y = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    pixels = np.stack([x, y, np.ones_like(x)], axis=-1)
    directions = pixels @ (to_world[:3, :3] @ pixel_to_camera).T
    rays = np.empty((height, width, 6), np.float32)
    rays[..., :3] = to_world[:3, 3]
    rays[..., 3:] = directions
    return rays
