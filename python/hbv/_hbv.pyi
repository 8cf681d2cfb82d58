"""Type stubs of the compiled module (crates/hbv-py)."""

from os import PathLike
from typing import Any, Optional, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Floats = npt.ArrayLike
_Bound = Union[None, float, npt.ArrayLike]

_Mask = Union[None, int, npt.ArrayLike]

class Hits(TypedDict):
    hit: npt.NDArray[np.bool_]
    t: npt.NDArray[np.float32]
    prim: npt.NDArray[np.int64]
    u: npt.NDArray[np.float32]
    v: npt.NDArray[np.float32]
    normal: npt.NDArray[np.float32]

class SceneHits(TypedDict):
    hit: npt.NDArray[np.bool_]
    t: npt.NDArray[np.float32]
    prim: npt.NDArray[np.int64]
    u: npt.NDArray[np.float32]
    v: npt.NDArray[np.float32]
    instance: npt.NDArray[np.int64]
    normal: npt.NDArray[np.float32]

class SceneClosestPoints(TypedDict):
    point: npt.NDArray[np.float64]
    distance: npt.NDArray[np.float64]
    prim: npt.NDArray[np.int64]
    u: npt.NDArray[np.float64]
    v: npt.NDArray[np.float64]
    instance: npt.NDArray[np.int64]

class ClosestPoints(TypedDict):
    point: npt.NDArray[np.float64]
    distance: npt.NDArray[np.float64]
    prim: npt.NDArray[np.int64]
    u: npt.NDArray[np.float64]
    v: npt.NDArray[np.float64]

class Mesh:
    """A triangle mesh: vertices (V, 3) float32/float64, faces (F, 3) integer."""

    def __init__(self, vertices: _Floats, faces: npt.ArrayLike) -> None: ...
    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def faces(self) -> npt.NDArray[np.int64]: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def degenerate_count(self) -> int: ...
    @property
    def open_edges(self) -> int:
        """Edges shared by an odd number of triangles (vertices compared by position); 0 if closed."""
    @property
    def is_closed(self) -> bool:
        """No open edges: the mesh bounds a volume and ``contains`` is defined."""
    @property
    def bounds(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]: ...
    def __len__(self) -> int: ...

def load(path: Union[str, PathLike[str]]) -> Mesh:
    """Reads .obj, .ply, .gltf or .glb; OSError / ValueError naming file, place and reason."""

def trimesh_hits(
    index_ray: npt.NDArray[np.int64],
    t: npt.NDArray[np.float32],
    prim: npt.NDArray[np.int64],
    origins: _Floats,
    directions: _Floats,
    size: float,
    max_hits: Optional[int] = None,
    vertices: Optional[npt.NDArray[np.float64]] = None,
    faces: Optional[npt.NDArray[np.int64]] = None,
    threads: Optional[int] = None,
) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], Optional[npt.NDArray[np.float64]]]:
    """hbv's hit list (``intersect_all``'s, or one hit a ray) in trimesh's Embree order: every
    ray's first hit, then every ray's second, ..., at most ``max_hits`` a ray, a hit at the
    place of the ray's previous one (within 2^-20 of distance + ``size``) left out. Returns
    ``(index_tri, index_ray, locations)``; locations (H, 3) float64 where the ray meets the hit
    triangle's plane, from ``vertices`` (V, 3) float64 and ``faces`` (F, 3) int64, when given
    (else None). Indices out of range raise ValueError naming the argument and the row."""

class BVH:
    """A bounding volume hierarchy over a mesh, answering ray and point queries.

    quality: ``"low"`` (LBVH: the fastest build, for rebuilding often), ``"medium"`` (default:
    binned SAH) or ``"high"`` (binned SAH + reinsertion optimization: the fastest rays);
    ``builder``, ``optimize`` and ``leaf_size`` given with it replace its choices.
    builder: ``"binned-sah"``, ``"sweep-sah"``, ``"insertion"``, ``"median"``, ``"lbvh"`` or
    ``"ploc"`` (default: the quality's).
    optimize: reinsertion optimization (Bittner et al. 2013) after building; None (default):
    the quality's choice, and at any quality for meshes of at most 1,024 triangles, where it
    costs about a millisecond and makes modelled scenes (walls around furniture) up to 1.4x
    faster to trace. ``stats()["optimize"]`` says which was chosen.
    leaf_size: most triangles per leaf, 1 to 255 (default: the builder's).

    The tree is built at once (``stats()["build_seconds"]``); what each kind of query walks is
    made from it on that kind's first call: the layout on the first ``intersect`` or
    ``occluded``, the wide-8 layout on the first ``intersect_all``, ``count`` or ``contains``.
    ``closest_point`` and ``signed_distance`` walk the tree itself for their first points
    (32 √triangles of them, all calls together), then make a nearest-point tree,
    faster per point, in the call that would pass that count; the answers are the same.
    """

    def __init__(
        self,
        mesh: Mesh,
        builder: Optional[str] = None,
        layout: Optional[str] = None,
        optimize: Optional[bool] = None,
        leaf_size: Optional[int] = None,
        quality: str = "medium",
    ) -> None: ...
    @property
    def mesh(self) -> Mesh: ...
    @property
    def builder(self) -> str: ...
    @property
    def layout(self) -> str: ...
    def intersect(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> Hits: ...
    def occluded(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.bool_]: ...
    def intersect_all(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32], npt.NDArray[np.int64]]: ...
    def count(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.int64]: ...
    def contains(self, points: _Floats, threads: Optional[int] = None) -> npt.NDArray[np.bool_]: ...
    def closest_point(self, points: _Floats, threads: Optional[int] = None) -> ClosestPoints: ...
    def signed_distance(
        self, points: _Floats, threads: Optional[int] = None
    ) -> npt.NDArray[np.float64]:
        """closest_point's distance, negative inside the mesh (contains): Open3D's sign, the
        opposite of trimesh's signed_distance."""
    def expected_tests(self) -> float: ...
    def sah_cost(self, traversal: float = 1.0, intersection: float = 1.0) -> float: ...
    def stats(self) -> dict[str, Any]: ...
    def save(self, path: Union[str, PathLike[str]], overwrite: bool = False) -> None:
        """Writes the tree and its mesh to a .hbv file, atomically; FileExistsError if the file
        exists and overwrite is False."""
    def __reduce__(self) -> Any: ...

def load_bvh(path: Union[str, PathLike[str]], layout: Optional[str] = None) -> BVH:
    """Reads a .hbv file (BVH.save or `hbv build`) without building again. FileNotFoundError /
    OSError if it cannot be read; ValueError naming the file and the reason if it is not a valid
    .hbv file (magic number, version, truncation, checksum, a tree that does not fit its mesh)."""

class Grid:
    """A uniform grid over a mesh (lam: density, lam * N^(1/3) cells on the longest axis;
    default 2). Same answers as BVH for the ray queries and contains; no closest_point (a grid
    has no distance-ordered search: use BVH)."""

    def __init__(self, mesh: Mesh, lam: Optional[float] = None) -> None: ...
    @property
    def mesh(self) -> Mesh: ...
    @property
    def lam(self) -> float: ...
    def intersect(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> Hits: ...
    def occluded(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.bool_]: ...
    def intersect_all(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32], npt.NDArray[np.int64]]: ...
    def count(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.int64]: ...
    def contains(self, points: _Floats, threads: Optional[int] = None) -> npt.NDArray[np.bool_]: ...
    def stats(self) -> dict[str, Any]: ...
    def __reduce__(self) -> Any: ...

class Scene:
    """Meshes placed by instances (id, transform, mask) in one two-level BVH.

    ``add`` returns the instance id (0, 1, 2, ... in call order, never reused); the same mesh
    object added twice is one mesh, instanced twice. A ray or point with mask m sees instance i
    only if ``m & mask_i != 0``. Answers carry ``instance`` (-1 on a miss) and the unit world
    ``normal``; ``prim``, ``u``, ``v`` are those of the instance's mesh.
    """

    def __init__(self) -> None: ...
    def add(
        self, mesh: Any, transform: Optional[npt.ArrayLike] = None, mask: Optional[int] = None
    ) -> int:
        """mesh: an hbv.Mesh, an hbv.BVH, a (vertices, faces) pair or an object with vertices
        and faces (trimesh); float64 vertices are kept relative to their centre. transform: a
        (4, 4) or (3, 4) matrix (float64), finite, affine and invertible."""
    def set_transform(self, instance: int, transform: npt.ArrayLike) -> None: ...
    def set_mask(self, instance: int, mask: int) -> None: ...
    def remove(self, instance: int) -> None: ...
    @property
    def instance_count(self) -> int:
        """Ids handed out, removed ones included."""
    @property
    def mesh_count(self) -> int: ...
    @property
    def bounds(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]: ...
    def __len__(self) -> int:
        """Instances not removed."""
    def intersect(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        mask: _Mask = None,
        threads: Optional[int] = None,
    ) -> SceneHits: ...
    def occluded(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        mask: _Mask = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.bool_]: ...
    def intersect_all(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        mask: _Mask = None,
        threads: Optional[int] = None,
    ) -> Tuple[
        npt.NDArray[np.int64],
        npt.NDArray[np.float32],
        npt.NDArray[np.int64],
        npt.NDArray[np.int64],
        npt.NDArray[np.float32],
    ]:
        """(ray, t, prim, instance, normal (H, 3)), by ray, then t, instance, prim."""
    def count(
        self,
        origins: _Floats,
        directions: _Floats,
        tmin: _Bound = None,
        tmax: _Bound = None,
        mask: _Mask = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.int64]: ...
    def contains(
        self, points: _Floats, mask: _Mask = None, threads: Optional[int] = None
    ) -> npt.NDArray[np.bool_]:
        """Inside any instance the point's mask sees (the union); meshes must be closed."""
    def closest_point(
        self, points: _Floats, mask: _Mask = None, threads: Optional[int] = None
    ) -> SceneClosestPoints: ...
    def signed_distance(
        self, points: _Floats, mask: _Mask = None, threads: Optional[int] = None
    ) -> npt.NDArray[np.float64]:
        """closest_point's distance, negative inside (contains), as BVH.signed_distance; +inf
        for a point that is not finite or sees no triangle."""
    def save(self, path: Union[str, PathLike[str]], overwrite: bool = False) -> None:
        """A .hbv scene file, written atomically; FileExistsError unless overwrite=True."""
    def __reduce__(self) -> Any:
        """Pickled as its .hbv scene file's bytes: ids, masks, removed holes and answers kept;
        which Python objects were added is not."""

def load_scene(path: Union[str, PathLike[str]]) -> Scene:
    """Reads a .hbv scene file (Scene.save, `hbv build SCENE.glb`; told by its content), a .hbv
    mesh file as one instance, a glTF file (.gltf, .glb) as a scene (docs/RAYS.md "Scenes
    (glTF)"), or .obj / .ply as one instance. OSError / ValueError naming file, place and
    reason."""
