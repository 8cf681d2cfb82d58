"""hbv.trimesh.RayMeshIntersector against trimesh's own intersectors, call by call on the same
rays: the pure-Python one (ray_triangle) always, the Embree one where embreex is installed."""

import copy
import pickle
import sys

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("rtree")  # trimesh's ray_triangle intersector needs it

import hbv  # noqa: E402
import hbv.trimesh  # noqa: E402
from trimesh.ray.ray_triangle import RayMeshIntersector as TrimeshIntersector  # noqa: E402

try:  # trimesh's Embree intersector, as it was before any install()
    from trimesh.ray.ray_pyembree import RayMeshIntersector as EmbreeIntersector
except ImportError:
    EmbreeIntersector = None

needs_embree = pytest.mark.skipif(
    EmbreeIntersector is None, reason="embreex is not installed: trimesh has no Embree intersector"
)


@pytest.fixture(scope="module")
def meshes():
    return [
        trimesh.creation.icosphere(subdivisions=3),
        trimesh.creation.torus(major_radius=1.0, minor_radius=0.3),
        trimesh.creation.box(extents=(1.0, 2.0, 0.5)),
    ]


def rays(n=400, seed=7, scale=1.0, offset=0.0):
    """Random rays from around the mesh towards its middle (none through an edge)."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(-2, 2, (n, 3)) * scale + offset
    target = rng.uniform(-0.8, 0.8, (n, 3)) * scale + offset
    d = target - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


def adversarial_rays(mesh):
    """Rays through vertices and edge midpoints, from outside through the middle of the mesh and
    from its middle outwards, and along the axes from the middle: each crosses the surface exactly
    at a vertex or an edge (the meshes are star-shaped about their middle, so no ray only touches
    the surface)."""
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    if mesh.contains([centre])[0] == 0:  # the torus: the middle of its tube
        centre = np.array([1.0, 0.0, 0.0])
    targets = np.vstack([v[:40], (v[f[:40, 0]] + v[f[:40, 1]]) / 2])
    radial = targets - centre
    outside = centre + 3.0 * radial
    o = np.vstack([outside, np.repeat(centre[None], len(targets) + 6, axis=0)])
    d = np.vstack([-radial, radial, np.eye(3), -np.eye(3)])
    return o, d


def by_ray(index_ray, values, decimals=None):
    """{ray: sorted list of rows of values}: hit lists compared whatever their order."""
    out = {}
    values = np.asarray(values)
    if decimals is not None:
        values = np.round(values, decimals)
    for r, v in zip(index_ray.tolist(), values.tolist()):
        out.setdefault(r, []).append(tuple(v) if isinstance(v, list) else v)
    return {r: sorted(v) for r, v in out.items()}


def assert_locations_match(ours, theirs, scale, tolerance=1e-9):
    """Same rays, same number of hits per ray, and each location within tolerance · scale."""
    loc_a, ray_a, _ = ours
    loc_b, ray_b, _ = theirs
    rays = 1 + max(ray_a.max(initial=0), ray_b.max(initial=0))
    np.testing.assert_array_equal(
        np.bincount(ray_a, minlength=rays), np.bincount(ray_b, minlength=rays)
    )
    order_a = np.lexsort((*loc_a.T[::-1], ray_a))
    order_b = np.lexsort((*loc_b.T[::-1], ray_b))
    gap = np.abs(loc_a[order_a] - loc_b[order_b]).max(initial=0.0)
    assert gap <= tolerance * scale, f"locations differ by {gap / scale:.3g} of the mesh's size"


def test_first_and_any_agree(meshes):
    o, d = rays()
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh)
        theirs = TrimeshIntersector(mesh)
        np.testing.assert_array_equal(ours.intersects_any(o, d), theirs.intersects_any(o, d))
        first_ours, first_theirs = ours.intersects_first(o, d), theirs.intersects_first(o, d)
        assert first_ours.dtype == first_theirs.dtype == np.int64
        np.testing.assert_array_equal(first_ours, first_theirs)


def test_all_hits_agree(meshes):
    o, d = rays(seed=8)
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh)
        theirs = TrimeshIntersector(mesh)
        tri_a, ray_a = ours.intersects_id(o, d)
        tri_b, ray_b = theirs.intersects_id(o, d)
        assert tri_a.dtype == ray_a.dtype == np.int64
        assert set(zip(ray_a.tolist(), tri_a.tolist())) == set(zip(ray_b.tolist(), tri_b.tolist()))
        a, b = ours.intersects_location(o, d), theirs.intersects_location(o, d)
        assert a[0].dtype == np.float64 and a[0].shape == b[0].shape
        assert_locations_match(a, b, mesh.scale)
        assert by_ray(a[1], a[2]) == by_ray(b[1], b[2])


def test_adversarial_rays_agree_on_locations(meshes):
    """Rays through vertices and edges: trimesh reports each place once (unique locations), hbv
    each crossing once; the places agree. Each triangle hbv names contains its location."""
    for mesh in meshes:
        o, d = adversarial_rays(mesh)
        ours = hbv.trimesh.RayMeshIntersector(mesh).intersects_location(o, d)
        theirs = TrimeshIntersector(mesh).intersects_location(o, d)
        assert_locations_match(ours, theirs, mesh.scale)
        locations, _, tri = ours
        closest = trimesh.triangles.closest_point(mesh.triangles[tri], locations)
        assert np.abs(closest - locations).max(initial=0.0) <= 1e-9 * mesh.scale


def test_multiple_hits_nearest_first_and_max_hits(meshes):
    o, d = rays(seed=9)
    mesh = meshes[1]  # the torus: up to four hits a ray
    ours = hbv.trimesh.RayMeshIntersector(mesh)
    locations, index_ray, _ = ours.intersects_location(o, d)
    theirs = TrimeshIntersector(mesh).intersects_location(o, d)
    assert_locations_match((locations, index_ray, None), theirs, mesh.scale)
    distance = np.einsum("ij,ij->i", locations - o[index_ray], d[index_ray])
    for k in (1, 2, 3):
        tri_k, ray_k, loc_k = ours.intersects_id(o, d, max_hits=k, return_locations=True)
        assert np.bincount(ray_k).max() <= k
        # each ray's k nearest hits of the full list
        for r in np.unique(index_ray):
            nearest = np.sort(distance[index_ray == r])[:k]
            mine = np.sort(np.einsum("ij,j->i", loc_k[ray_k == r] - o[r], d[r]))
            np.testing.assert_allclose(mine, nearest, atol=1e-9 * mesh.scale)
        tri_ids, ray_ids = ours.intersects_id(o, d, max_hits=k)
        np.testing.assert_array_equal(ray_ids, ray_k)
        np.testing.assert_array_equal(tri_ids, tri_k)
    assert all(len(a) == 0 for a in ours.intersects_id(o, d, max_hits=0, return_locations=True))
    assert len(ours.intersects_id(o, d, max_hits=None)[0]) == len(ours.intersects_id(o, d)[0])


def test_depth_major_order_as_embree():
    """Every ray's first hit by ray, then every ray's second: trimesh's Embree order."""
    mesh = trimesh.creation.icosphere()
    o = np.array([[0, 0, -5.0], [0, 0, -5], [0.3, 0.2, -5], [9, 9, 9]])
    d = np.array([[0, 0, 1.0], [0, 0, 1], [0, 0, 1], [1, 0, 0]])
    ours = hbv.trimesh.RayMeshIntersector(mesh)
    tri, ray, loc = ours.intersects_id(o, d, return_locations=True)
    np.testing.assert_array_equal(ray, [0, 1, 2, 0, 1, 2])
    assert (loc[:3, 2] < 0).all() and (loc[3:, 2] > 0).all()
    tri1, ray1 = ours.intersects_id(o, d, multiple_hits=False)
    np.testing.assert_array_equal(ray1, [0, 1, 2])
    np.testing.assert_array_equal(tri1, ours.intersects_first(o, d)[:3])
    # keywords in trimesh's Embree positions: (origins, directions, multiple_hits, max_hits,
    # return_locations)
    assert len(ours.intersects_id(o, d, False, 100, True)) == 3


def test_depth_major_order_on_many_rays(meshes):
    """Enough hits to be ordered on several threads: the order is NumPy's stable sort of
    intersect_all's hits by their rank within the ray."""
    o, d = rays(n=6000, seed=12)
    ours = hbv.trimesh.RayMeshIntersector(meshes[1])
    index_ray, t, prim = ours.bvh.intersect_all(o, d)
    assert len(index_ray) > 3 * 2048
    starts = np.searchsorted(index_ray, index_ray, side="left")
    rank = np.arange(len(index_ray)) - starts
    for max_hits in (None, 1, 2, 3):
        kept = np.ones(len(rank), bool) if max_hits is None else rank < max_hits
        order = np.flatnonzero(kept)[np.argsort(rank[kept], kind="stable")]
        traced = ours._current()
        planes = (traced.vertices, traced.faces)
        answers = [ours.intersects_id(o, d, max_hits=max_hits)]
        answers += [
            hbv._hbv.trimesh_hits(index_ray, t, prim, o, d, traced.size, max_hits, *planes,
                                  threads=threads)
            for threads in (1, 2, 3)
        ]
        for tri_k, ray_k, *_ in answers:
            np.testing.assert_array_equal(ray_k, index_ray[order])
            np.testing.assert_array_equal(tri_k, prim[order])
        for _, _, locations in answers[2:]:
            np.testing.assert_array_equal(locations, answers[1][2])


def test_single_hit(meshes):
    o, d = rays(seed=9)
    mesh = meshes[1]
    ours = hbv.trimesh.RayMeshIntersector(mesh)
    tri, ray = ours.intersects_id(o, d, multiple_hits=False)
    first = ours.intersects_first(o, d)
    np.testing.assert_array_equal(tri, first[ray])
    np.testing.assert_array_equal(ray, np.flatnonzero(first >= 0))
    loc, ray_l, tri_l = ours.intersects_location(o, d, multiple_hits=False)
    theirs = TrimeshIntersector(mesh).intersects_location(o, d, multiple_hits=False)
    assert_locations_match((loc, ray_l, tri_l), theirs, mesh.scale)


@pytest.mark.parametrize("size, offset", [(1.0, 1e5), (1e-3, 0.0), (1.0, 0.0), (1e3, -3e7)])
@pytest.mark.parametrize("scale_to_box", [True, False])
def test_locations_exact_at_any_scale_and_offset(size, offset, scale_to_box):
    """A cube hit from afar: every location on a face's plane within 1e-9 of the cube's size
    (a float32 t would be off by 1e-5 of the distance)."""
    mesh = trimesh.creation.box(extents=(size, size, size))
    mesh.apply_translation([offset, offset, offset])
    o, d = rays(n=300, seed=3, scale=size, offset=offset)
    o = o + np.array([0.0, 0.0, 100.0]) * size
    d = (offset + np.random.default_rng(4).uniform(-0.45, 0.45, (300, 3)) * size) - o
    ours = hbv.trimesh.RayMeshIntersector(mesh, scale_to_box=scale_to_box)
    locations, index_ray, _ = ours.intersects_location(o, d)
    assert np.bincount(index_ray, minlength=300).min() == 2  # in and out, every ray
    off_plane = np.abs(np.abs(locations - offset) - size / 2).min(axis=1)
    assert off_plane.max() <= 1e-9 * size
    theirs = TrimeshIntersector(mesh).intersects_location(o, d)
    assert_locations_match((locations, index_ray, None), theirs, mesh.scale)


def test_scale_to_box_moves_far_meshes_only():
    far = trimesh.creation.box(extents=(1, 1, 1))
    far.apply_translation([1e5, 0, 0])
    assert hbv.trimesh.RayMeshIntersector(far)._current().offset is not None
    assert hbv.trimesh.RayMeshIntersector(far, scale_to_box=False)._current().offset is None
    near = trimesh.creation.box(extents=(1, 1, 1))
    assert hbv.trimesh.RayMeshIntersector(near)._current().offset is None
    # hit decisions: float32 of the cube's size, not of 1e5 (whose spacing is 0.008)
    o = np.array([[1e5 + 0.4999, 0.0, 5.0]])
    d = np.array([[0.0, 0.0, -1.0]])
    assert hbv.trimesh.RayMeshIntersector(far).intersects_any(o, d).all()
    assert hbv.trimesh.RayMeshIntersector(far).contains_points([[1e5 + 0.4999, 0, 0]]).all()


def test_contains_points_agrees(meshes):
    rng = np.random.default_rng(10)
    points = rng.uniform(-1.5, 1.5, (3000, 3))
    for mesh in meshes:
        ours = hbv.trimesh.RayMeshIntersector(mesh).contains_points(points)
        theirs = mesh.contains(points)
        assert ours.dtype == bool and ours.shape == (3000,)
        assert (ours != theirs).sum() <= 1


@needs_embree
def test_agrees_with_embree(meshes):
    for seed, mesh in enumerate(meshes):
        o, d = rays(n=500, seed=20 + seed)
        ours = hbv.trimesh.RayMeshIntersector(mesh)
        theirs = EmbreeIntersector(mesh)
        np.testing.assert_array_equal(ours.intersects_first(o, d), theirs.intersects_first(o, d))
        np.testing.assert_array_equal(ours.intersects_any(o, d), theirs.intersects_any(o, d))
        a = ours.intersects_id(o, d, return_locations=True)
        b = theirs.intersects_id(o, d, return_locations=True)
        np.testing.assert_array_equal(a[1], b[1])  # the same depth-major order of rays
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_allclose(a[2], b[2], rtol=0, atol=1e-9 * mesh.scale)
        for k in (1, 2):
            np.testing.assert_array_equal(
                ours.intersects_id(o, d, max_hits=k)[1], theirs.intersects_id(o, d, max_hits=k)[1]
            )
        single_a = ours.intersects_location(o, d, multiple_hits=False)
        single_b = theirs.intersects_location(o, d, multiple_hits=False)
        np.testing.assert_array_equal(single_a[1], single_b[1])
        np.testing.assert_allclose(single_a[0], single_b[0], rtol=0, atol=1e-9 * mesh.scale)
        points = np.random.default_rng(seed).uniform(-1.5, 1.5, (2000, 3))
        assert (ours.contains_points(points) != theirs.contains_points(points)).sum() <= 1


def test_plugs_into_trimesh(meshes):
    mesh = meshes[0].copy()
    mesh.ray = hbv.trimesh.RayMeshIntersector(mesh)
    loc, idx_ray, idx_tri = mesh.ray.intersects_location([[0, 0, -5.0]], [[0, 0, 1.0]])
    assert len(loc) == 2 and set(idx_ray) == {0}
    assert mesh.contains([[0, 0, 0], [0, 0, 2]]).tolist() == [True, False]


def test_follows_mesh_changes():
    """Never an answer on a stale mesh: apply_scale, apply_transform, apply_translation and
    vertices edited in place are seen by the next query."""
    mesh = trimesh.creation.box(extents=(1, 1, 1))
    ray = hbv.trimesh.RayMeshIntersector(mesh)
    o, d = np.array([[0.0, 0.0, 10.0]]), np.array([[0.0, 0.0, -1.0]])

    def top():
        return ray.intersects_location(o, d, multiple_hits=False)[0][0, 2]

    assert top() == 0.5
    mesh.apply_scale(2.0)
    assert top() == 1.0
    mesh.apply_transform(trimesh.transformations.translation_matrix([0, 0, 3.0]))
    assert top() == 4.0
    mesh.apply_translation([0, 0, -4.0])
    assert top() == 0.0
    mesh.vertices[:, 2] += 1.0  # in place: trimesh's tracked array notes the change
    assert top() == 1.0
    top_vertices = mesh.vertices[:, 2] > 0
    mesh.vertices[top_vertices, 2] = 3.0  # an item assignment
    assert top() == 3.0
    vertices = mesh.vertices.copy()
    vertices[:, :2] += 50.0  # moved away sideways: the ray misses
    mesh.vertices = vertices
    assert ray.intersects_first(o, d).tolist() == [-1]
    assert ray.contains_points([[50.0, 50.0, 0.5], [0.0, 0.0, 0.5]]).tolist() == [True, False]
    assert ray.intersects_id(o, d)[0].size == 0


def test_built_lazily_on_first_query():
    mesh = trimesh.creation.icosphere()
    ray = hbv.trimesh.RayMeshIntersector(mesh)
    assert ray._traced is None
    ray.intersects_any([[0, 0, -5.0]], [[0, 0, 1.0]])
    built = ray._traced
    ray.intersects_first([[0, 0, -5.0]], [[0, 0, 1.0]])
    assert ray._traced is built  # the same mesh: not built again


def test_pickle_and_copy():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    ray = hbv.trimesh.RayMeshIntersector(mesh, scale_to_box=False, leaf_size=2)
    o, d = rays(n=50, seed=11)
    expected = ray.intersects_id(o, d, return_locations=True)
    back = pickle.loads(pickle.dumps(ray))
    assert back._scale_to_box is False and back._options["leaf_size"] == 2
    assert back._traced is None
    for other in (back, copy.copy(ray), copy.deepcopy(ray)):
        assert isinstance(other, hbv.trimesh.RayMeshIntersector)
        got = other.intersects_id(o, d, return_locations=True)
        for a, b in zip(got, expected):
            np.testing.assert_array_equal(a, b)
    copied = copy.copy(ray)
    assert copied.mesh is ray.mesh  # as trimesh's: a new intersector on the same mesh
    mesh.apply_scale(3.0)
    assert copied.intersects_location(o, d)[0].shape != expected[2].shape or not np.allclose(
        copied.intersects_location(o, d)[0], expected[2]
    )
    # a whole mesh pickled with hbv as its intersector
    mesh.ray = hbv.trimesh.RayMeshIntersector(mesh)
    again = pickle.loads(pickle.dumps(mesh))
    assert isinstance(again.ray, hbv.trimesh.RayMeshIntersector)
    assert again.ray.mesh is again


@pytest.fixture
def installed():
    hbv.trimesh.install()
    try:
        yield
    finally:
        hbv.trimesh.uninstall()


def test_install_makes_every_new_mesh_use_hbv(installed):
    assert trimesh.ray.has_embree
    mesh = trimesh.creation.icosphere()
    assert isinstance(mesh.ray, hbv.trimesh.RayMeshIntersector)
    assert mesh.contains([[0, 0, 0]]).tolist() == [True]
    # primitives make their intersector in Trimesh.__init__, before they have vertices
    box = trimesh.primitives.Box(extents=(1.0, 2.0, 3.0))
    assert isinstance(box.ray, hbv.trimesh.RayMeshIntersector)
    assert box.ray.intersects_location([[0, 0, 10.0]], [[0, 0, -1.0]])[0][:, 2].tolist() == [
        1.5,
        -1.5,
    ]
    box.apply_transform(trimesh.transformations.translation_matrix([0, 0, 1.0]))
    assert box.ray.intersects_location([[0, 0, 10.0]], [[0, 0, -1.0]], multiple_hits=False)[0][
        0, 2
    ] == 2.5
    bounding = mesh.bounding_box
    assert isinstance(bounding.ray, hbv.trimesh.RayMeshIntersector)
    assert bounding.contains([[0, 0, 0], [0, 0, 1.5]]).tolist() == [True, False]
    # trimesh's own switch still picks its pure-Python intersector
    plain = trimesh.Trimesh(mesh.vertices, mesh.faces, use_embree=False)
    assert isinstance(plain.ray, TrimeshIntersector)


def test_install_uninstall_round_trip():
    import trimesh.ray as tray

    before = (tray.has_embree, tray.ray_pyembree, sys.modules.get("trimesh.ray.ray_pyembree"))
    held = getattr(tray.ray_pyembree, "RayMeshIntersector", None) if EmbreeIntersector else None
    hbv.trimesh.install()
    hbv.trimesh.install()  # twice: still undone by one uninstall
    assert tray.ray_pyembree.RayMeshIntersector is hbv.trimesh.RayMeshIntersector
    from trimesh.ray.ray_pyembree import RayMeshIntersector as imported

    assert imported is hbv.trimesh.RayMeshIntersector
    hbv.trimesh.uninstall()
    hbv.trimesh.uninstall()
    after = (tray.has_embree, tray.ray_pyembree, sys.modules.get("trimesh.ray.ray_pyembree"))
    assert after[0] == before[0] and after[1] is before[1] and after[2] is before[2]
    if EmbreeIntersector is not None:
        assert tray.ray_pyembree.RayMeshIntersector is held is EmbreeIntersector
    mesh = trimesh.creation.icosphere()
    assert not isinstance(mesh.ray, hbv.trimesh.RayMeshIntersector)


def test_bad_input_is_refused_with_the_argument_named():
    ray = hbv.trimesh.RayMeshIntersector(trimesh.creation.icosphere())
    with pytest.raises(ValueError, match="ray_directions"):
        ray.intersects_id(np.zeros((4, 3)), np.ones((5, 3)))
    with pytest.raises(ValueError, match="ray_origins"):
        ray.intersects_first(np.zeros((6, 2)), np.ones((4, 3)))
    with pytest.raises(ValueError, match="points"):
        ray.contains_points(np.zeros((4, 2)))
    # a single ray as (3,), as trimesh takes it
    assert ray.intersects_first([0, 0, -5.0], [0, 0, 1.0]).shape == (1,)
    # NaN, zero and infinite rays miss; they never fail the batch
    o = np.array([[np.nan, 0, -5], [0, 0, -5], [0, 0, -5], [0, 0, -5]])
    d = np.array([[0, 0, 1.0], [0, 0, 0], [0, 0, np.inf], [0, 0, 1]])
    assert ray.intersects_any(o, d).tolist() == [False, False, False, True]
    tri, index_ray, loc = ray.intersects_id(o, d, return_locations=True)
    assert set(index_ray.tolist()) == {3} and np.isfinite(loc).all()
    # grazing: along an edge, in the planes of both its triangles, which it does not hit
    mesh = ray.mesh
    edge = mesh.vertices[mesh.faces[0, 1]] - mesh.vertices[mesh.faces[0, 0]]
    start = mesh.vertices[mesh.faces[0, 0]] - 2 * edge
    tri, index_ray, loc = ray.intersects_id([start], [edge], return_locations=True)
    assert np.isfinite(loc).all() and len(tri) <= 2
    # no rays
    empty = ray.intersects_id(np.zeros((0, 3)), np.zeros((0, 3)), return_locations=True)
    assert [a.shape for a in empty] == [(0,), (0,), (0, 3)]


def test_empty_mesh():
    mesh = trimesh.Trimesh()
    ray = hbv.trimesh.RayMeshIntersector(mesh)
    o, d = rays(n=20)
    assert (ray.intersects_first(o, d) == -1).all()
    assert [a.shape for a in ray.intersects_id(o, d, return_locations=True)] == [
        (0,),
        (0,),
        (0, 3),
    ]


def test_trimesh_hits_checks_its_arguments():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2]], dtype=np.int64)
    o, d = np.array([[0.2, 0.2, 1.0]]), np.array([[0.0, 0.0, -1.0]])
    zero, t = np.zeros(1, np.int64), np.ones(1, np.float32)

    def call(index_ray=zero, t=t, prim=zero, origins=o, directions=d, vertices=v, faces=f):
        return hbv._hbv.trimesh_hits(index_ray, t, prim, origins, directions, 1.0, None,
                                     vertices, faces)

    tri, ray, loc = call()
    assert tri.tolist() == [0] and ray.tolist() == [0]
    np.testing.assert_array_equal(loc, [[0.2, 0.2, 0.0]])
    assert hbv._hbv.trimesh_hits(zero, t, zero, o, d, 1.0)[2] is None
    with pytest.raises(ValueError, match="prim: row 0"):
        call(prim=zero + 1)
    with pytest.raises(ValueError, match="index_ray: row 0"):
        call(index_ray=zero - 1)
    with pytest.raises(ValueError, match="faces: row 0"):
        call(faces=f + 1)
    with pytest.raises(TypeError, match="faces"):
        call(faces=f.astype(np.float64))
    with pytest.raises(ValueError, match="t: expected 1 rows"):
        call(t=np.ones(2, np.float32))
    with pytest.raises(ValueError, match="prim: expected shape"):
        call(prim=np.zeros(2, np.int64))
    # other dtypes and layouts are read too, with the same answers
    np.testing.assert_array_equal(
        call(vertices=v.astype(np.float32), faces=f.astype(np.uint16), t=t.astype(np.float64))[2],
        [[0.2, 0.2, 0.0]],
    )
    misaligned = np.frombuffer(b"\0" + v.tobytes(), dtype=np.float64, offset=1).reshape(3, 3)
    np.testing.assert_array_equal(call(vertices=misaligned)[2], [[0.2, 0.2, 0.0]])
    with pytest.raises(ValueError, match="directions"):
        call(directions=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="give both"):
        hbv._hbv.trimesh_hits(zero, t, zero, o, d, 1.0, None, v)
    # a ray in the triangle's plane: no finite plane point, so o + t·d
    _, _, inplane = call(origins=np.array([[-1, 0.2, 0.0]]), directions=np.array([[1.0, 0, 0]]),
                         t=np.full(1, 1.2, np.float32))
    np.testing.assert_allclose(inplane, [[0.2, 0.2, 0.0]], atol=1e-7)
    # depth-major order, max_hits, a repeat of a place left out
    index_ray = np.array([0, 0, 0, 1, 2, 2], np.int64)
    ts = np.array([1.0, 1.0, 2.0, 5.0, 1.0, 3.0], np.float32)
    prims = np.arange(6, dtype=np.int64)
    rays3 = np.zeros((3, 3)), np.tile([0.0, 0.0, 1.0], (3, 1))
    tri, ray, _ = hbv._hbv.trimesh_hits(index_ray, ts, prims, *rays3, 1.0)
    assert ray.tolist() == [0, 1, 2, 0, 2] and tri.tolist() == [0, 3, 4, 2, 5]
    tri, ray, _ = hbv._hbv.trimesh_hits(index_ray, ts, prims, *rays3, 1.0, 1)
    assert ray.tolist() == [0, 1, 2] and tri.tolist() == [0, 3, 4]
    # a ray of 300 hits (ranks past a byte) among rays of 1 to 3, on one thread and several
    counts = np.r_[np.random.default_rng(5).integers(1, 4, 3000), 300, [2] * 500]
    index_ray = np.repeat(np.arange(len(counts)), counts)
    ts = np.concatenate([np.arange(1, c + 1) for c in counts]).astype(np.float32)
    prims = np.arange(len(index_ray), dtype=np.int64)
    rays_n = np.zeros((len(counts), 3)), np.tile([0.0, 0.0, 1.0], (len(counts), 1))
    rank = ts.astype(np.int64) - 1
    for max_hits in (None, 2, 280):
        kept = np.ones(len(rank), bool) if max_hits is None else rank < max_hits
        order = np.flatnonzero(kept)[np.argsort(rank[kept], kind="stable")]
        for threads in (1, 2):
            tri, ray, _ = hbv._hbv.trimesh_hits(index_ray, ts, prims, *rays_n, 1.0, max_hits,
                                                threads=threads)
            np.testing.assert_array_equal(ray, index_ray[order])
            np.testing.assert_array_equal(tri, order)
