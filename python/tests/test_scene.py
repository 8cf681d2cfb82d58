"""hbv.Scene against a float64 brute force over the flattened world triangles; load_scene on a
glTF file against the same scene built by hand; masks, live changes, bad input."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays, soup
from scene_reference import Flattened, as_matrix, trs_matrix, write_gltf


def cube(center=(0.0, 0.0, 0.0), size=1.0):
    """A closed axis-aligned cube, outward faces."""
    c = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
    v = (c - 0.5) * size + np.asarray(center)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def rotation(axis, angle):
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def affine(linear=np.eye(3), offset=(0, 0, 0)):
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = offset
    return m


def mixed_scene():
    """A sphere placed three times (plain, rotated and non-uniformly scaled, mirrored), a soup
    and a cube; masks 1, 2, 4, 8, 3. Returns the scene, its instances for brute force, and the
    sphere mesh object."""
    sv, sf = icosphere(2, radius=0.5)
    tv, tf = soup(60, seed=5)
    tv = tv * 0.4
    cv, cf = cube(size=0.6)
    sphere = hbv.Mesh(sv, sf)
    placed = [
        (sphere, sv, sf, affine(offset=(-1.0, 0.0, 0.0)), 1),
        (sphere, sv, sf, affine(rotation((1, 2, 3), 0.7) @ np.diag([1.5, 0.5, 1.0]),
                                (1.0, 0.2, 0.0)), 2),
        (sphere, sv, sf, affine(np.diag([1.0, -1.0, 1.0]), (0.0, 1.2, 0.3)), 4),
        (hbv.Mesh(tv, tf), tv, tf, affine(rotation((0, 0, 1), 0.3), (0.0, -1.0, 0.2))[:3], 8),
        (hbv.BVH(hbv.Mesh(cv, cf)), cv, cf, affine(2.0 * rotation((1, 1, 0), 1.0),
                                                   (0.2, 0.1, -1.2)), 3),
    ]
    scene = hbv.Scene()
    for k, (mesh, _, _, transform, mask) in enumerate(placed):
        assert scene.add(mesh, transform, mask=mask) == k
    return scene, [(v, f, t, m) for _, v, f, t, m in placed], sphere


def scene_rays(n, seed):
    o, d = random_rays(n, seed=seed, spread=2.0)
    return o.astype(np.float32).astype(np.float64), d.astype(np.float32).astype(np.float64)


def check_closest(hits, flat, o, d, masks):
    """The closest hits agree with brute force: hit or miss, t, and where no other triangle is
    near the same t, the (instance, prim) and the normal."""
    t_all = flat.ts(o, d, masks)
    ref_hit = ~np.all(np.isnan(t_all), axis=1)
    np.testing.assert_array_equal(hits["hit"], ref_hit)
    assert np.all(hits["instance"][~ref_hit] == -1) and np.all(hits["prim"][~ref_hit] == -1)
    assert np.all(hits["normal"][~ref_hit] == 0)
    best = np.nanmin(np.where(ref_hit[:, None], t_all, np.inf), axis=1)
    np.testing.assert_allclose(hits["t"][ref_hit], best[ref_hit], rtol=1e-5, atol=1e-5)
    second = np.sort(np.where(np.isnan(t_all), np.inf, t_all), axis=1)[:, 1]
    with np.errstate(invalid="ignore"):
        clear = ref_hit & (second - best > 1e-4 * np.abs(best) + 1e-5)
    face = np.nanargmin(np.where(ref_hit[:, None], t_all, 0), axis=1)[clear]
    np.testing.assert_array_equal(hits["instance"][clear], flat.instance[face])
    np.testing.assert_array_equal(hits["prim"][clear], flat.prim[face])
    np.testing.assert_allclose(hits["normal"][clear], flat.normals(face), atol=2e-5)
    # The barycentrics of the instance's triangle give the world hit point.
    hit_faces = flat.face(hits["instance"][ref_hit], hits["prim"][ref_hit])
    tri = flat.tris[hit_faces]
    u, v = hits["u"][ref_hit, None], hits["v"][ref_hit, None]
    point = (1 - u - v) * tri[:, 0] + u * tri[:, 1] + v * tri[:, 2]
    along = o[ref_hit] + d[ref_hit] * hits["t"][ref_hit, None]
    assert np.abs(point - along).max() < 1e-4
    return clear


@pytest.mark.parametrize("threads", [1, None])
def test_closest_hits_match_brute_force(threads):
    scene, instances, _ = mixed_scene()
    flat = Flattened(instances)
    # More rays than the calling thread keeps (2,048): runs cut across threads.
    o, d = scene_rays(3000, seed=11)
    hits = scene.intersect(o, d, threads=threads)
    assert hits["t"].dtype == np.float32 and hits["instance"].dtype == np.int64
    assert hits["normal"].shape == (3000, 3) and hits["normal"].dtype == np.float32
    clear = check_closest(hits, flat, o, d, np.full(len(o), 0xFFFFFFFF))
    assert clear.sum() > 500
    assert set(hits["instance"][clear]) == {0, 1, 2, 3, 4}
    np.testing.assert_array_equal(scene.occluded(o, d, threads=threads), hits["hit"])


def test_masks_choose_the_instances_seen():
    scene, instances, _ = mixed_scene()
    flat = Flattened(instances)
    o, d = scene_rays(1500, seed=12)
    rng = np.random.default_rng(4)
    masks = rng.integers(0, 16, len(o)).astype(np.uint32)
    hits = scene.intersect(o, d, mask=masks)
    check_closest(hits, flat, o, d, masks)
    np.testing.assert_array_equal(scene.occluded(o, d, mask=masks), hits["hit"])
    assert not hits["hit"][masks == 0].any()
    # One mask for every ray; a list of Python ints; a strided uint32 array.
    only_soup = scene.intersect(o, d, mask=8)
    check_closest(only_soup, flat, o, d, np.full(len(o), 8))
    assert set(only_soup["instance"][only_soup["hit"]]) == {3}
    listed = scene.intersect(o, d, mask=[int(m) for m in masks])
    np.testing.assert_array_equal(listed["prim"], hits["prim"])
    strided = np.repeat(masks, 2)[::2]
    np.testing.assert_array_equal(scene.intersect(o, d, mask=strided)["prim"], hits["prim"])


def test_every_hit_and_counts_match_brute_force():
    scene, instances, _ = mixed_scene()
    flat = Flattened(instances)
    o, d = scene_rays(600, seed=13)
    masks = np.random.default_rng(5).integers(1, 16, len(o)).astype(np.uint32)
    ray, t, prim, instance, normal = scene.intersect_all(o, d, mask=masks)
    counts = scene.count(o, d, mask=masks)
    np.testing.assert_array_equal(np.bincount(ray, minlength=len(o)), counts)
    t_all = flat.ts(o, d, masks)
    ref_counts = (~np.isnan(t_all)).sum(axis=1)
    # A ray through an edge shared by two triangles counts once here, twice in brute force.
    assert (counts != ref_counts).sum() <= 2
    same = np.flatnonzero(counts == ref_counts)
    assert len(same) > 590
    for r in same[:200]:
        mine = ray == r
        assert np.all(np.diff(t[mine]) >= 0)
        faces = flat.face(instance[mine], prim[mine])
        np.testing.assert_allclose(t[mine], t_all[r, faces], rtol=1e-5, atol=1e-5)
        np.testing.assert_array_equal(np.sort(faces), np.flatnonzero(~np.isnan(t_all[r])))
        np.testing.assert_allclose(normal[mine], flat.normals(faces), atol=2e-5)


def test_closest_point_matches_brute_force():
    scene, instances, _ = mixed_scene()
    flat = Flattened(instances)
    rng = np.random.default_rng(6)
    points = rng.uniform(-2.5, 2.5, (150, 3))
    masks = rng.integers(1, 16, len(points)).astype(np.uint32)
    near = scene.closest_point(points, mask=masks)
    for i, p in enumerate(points):
        dist, face = flat.closest(p, masks[i])
        assert near["distance"][i] == pytest.approx(dist, rel=1e-6, abs=1e-6)
        f = flat.face([near["instance"][i]], [near["prim"][i]])[0]
        tri = flat.tris[f]
        u, v = near["u"][i], near["v"][i]
        np.testing.assert_allclose((1 - u - v) * tri[0] + u * tri[1] + v * tri[2],
                                   near["point"][i], atol=1e-5)
    bad = scene.closest_point(np.array([[np.nan, 0, 0], [0, 0, 0]]), mask=np.array([1, 0], np.uint32))
    assert np.isnan(bad["point"]).all() and np.isinf(bad["distance"]).all()
    np.testing.assert_array_equal(bad["instance"], [-1, -1])
    np.testing.assert_array_equal(bad["prim"], [-1, -1])


def test_contains_counts_closed_instances():
    # Two closed instances apart: a point is inside the scene where it is inside one of them.
    sv, sf = icosphere(3)
    cv, cf = cube(size=1.0)
    scene = hbv.Scene()
    scene.add(hbv.Mesh(sv, sf), affine(np.diag([2.0, 1.0, 1.0]), (-3, 0, 0)), mask=1)
    scene.add((cv, cf), affine(rotation((0, 1, 1), 0.4), (3, 0, 0)), mask=2)
    rng = np.random.default_rng(7)
    points = rng.uniform(-5, 5, (400, 3)) * [1, 0.3, 0.3]
    ellipsoid = ((points[:, 0] + 3) / 2) ** 2 + points[:, 1] ** 2 + points[:, 2] ** 2
    local = (points - [3, 0, 0]) @ rotation((0, 1, 1), 0.4)
    in_cube = np.all(np.abs(local) < 0.5, axis=1)
    in_ellipsoid = ellipsoid < 1
    # Off the surface by a margin (the sphere is a polyhedron within 1% of the unit sphere).
    clear = (np.abs(ellipsoid - 1) > 0.03) & (np.abs(np.abs(local).max(1) - 0.5) > 1e-3)
    inside = scene.contains(points)
    np.testing.assert_array_equal(inside[clear], (in_cube | in_ellipsoid)[clear])
    np.testing.assert_array_equal(scene.contains(points, mask=2)[clear], in_cube[clear])
    np.testing.assert_array_equal(scene.contains(points, mask=1)[clear], in_ellipsoid[clear])


def test_live_changes_answer_the_new_scene():
    scene, instances, sphere = mixed_scene()
    o, d = scene_rays(800, seed=14)
    everyone = np.full(len(o), 0xFFFFFFFF)
    moved = affine(rotation((0, 1, 0), 1.1) * 0.8, (0.3, -0.4, 0.5))
    scene.set_transform(1, moved)
    scene.set_mask(3, 0)
    scene.remove(0)
    instances = [None, (instances[1][0], instances[1][1], moved, 2), instances[2],
                 (instances[3][0], instances[3][1], instances[3][2], 0), instances[4]]
    check_closest(scene.intersect(o, d), Flattened(instances), o, d, everyone)
    assert len(scene) == 4 and scene.instance_count == 5
    # A new instance after a removal gets a new id; the removed id stays refused.
    assert scene.add(sphere, affine(offset=(0, 0, 1.5))) == 5
    instances.append((instances[2][0], instances[2][1], affine(offset=(0, 0, 1.5)), 0xFFFFFFFF))
    assert scene.mesh_count == 3
    hits = scene.intersect(o, d)
    check_closest(hits, Flattened(instances), o, d, everyone)
    assert 0 not in set(hits["instance"])
    for call in (lambda: scene.remove(0), lambda: scene.set_mask(0, 1),
                 lambda: scene.set_transform(0, np.eye(4))):
        with pytest.raises(ValueError, match="instance: id 0 was removed"):
            call()


def test_one_object_is_one_mesh():
    v, f = cube()
    mesh = hbv.Mesh(v, f)
    scene = hbv.Scene()
    scene.add(mesh)
    scene.add(mesh, affine(offset=(2, 0, 0)))
    assert scene.mesh_count == 1
    scene.add(hbv.Mesh(v, f))
    assert scene.mesh_count == 2
    pair = (v, f)
    scene.add(pair)
    scene.add((v, f), affine(offset=(0, 2, 0)))  # the same arrays: the same mesh
    assert scene.mesh_count == 3
    bvh = hbv.BVH(mesh)
    scene.add(bvh)
    scene.add(bvh)
    assert scene.mesh_count == 4 and len(scene) == 7
    assert "4 meshes, 7 instances" in repr(scene)


def test_far_from_the_origin_float64_meshes_keep_their_precision():
    # A 1 m cube at UTM-like coordinates, off float32's grid there (0.5 m apart at 5e6).
    corner = np.array([500000.137, 5000000.291, 10.113])
    v, f = cube(center=corner + 0.5, size=1.0)
    scene = hbv.Scene()
    scene.add((v, f))
    rng = np.random.default_rng(8)
    # Rays into the +y face (at 5e6) and the +x face (at 5e5), from random distances, their
    # float64 origins kept.
    far = rng.uniform(1.0, 5.0, 200)
    inner = rng.uniform(0.05, 0.95, (200, 2))
    o = np.empty((200, 3))
    o[:100] = corner + np.c_[inner[:100, 0], 1.0 + far[:100], inner[:100, 1]]
    o[100:] = corner + np.c_[1.0 + far[100:], inner[100:]]
    d = np.vstack([np.tile([0.0, -1.0, 0.0], (100, 1)), np.tile([-1.0, 0.0, 0.0], (100, 1))])
    expected = np.r_[o[:100, 1] - (corner[1] + 1.0), o[100:, 0] - (corner[0] + 1.0)]
    hits = scene.intersect(o, d)
    assert hits["hit"].all()
    # float32 of the cube's size, not of 5e6 (0.5 m apart there).
    np.testing.assert_allclose(hits["t"], expected, atol=2e-5)
    np.testing.assert_allclose(hits["normal"], np.vstack([np.tile([0, 1, 0], (100, 1)),
                                                          np.tile([1, 0, 0], (100, 1))]), atol=1e-6)
    ray, t, prim, instance, normal = scene.intersect_all(o, d)
    assert np.all(np.bincount(ray, minlength=200) == 2)
    np.testing.assert_allclose(t[::2], expected, atol=2e-5)
    np.testing.assert_allclose(t[1::2], expected + 1.0, atol=2e-5)
    near = scene.closest_point([corner + [0.5, 0.5, 1.25], corner + [0.2, 0.3, 0.4]])
    np.testing.assert_allclose(near["distance"], [0.25, 0.2], atol=2e-5)
    np.testing.assert_array_equal(scene.contains([corner + [0.5, 0.5, 0.999],
                                                  corner + [0.5, 0.5, 1.001],
                                                  corner + [0.001, 0.5, 0.5],
                                                  corner + [-0.001, 0.5, 0.5]]),
                                  [True, False, True, False])


def test_bad_arguments_are_refused_with_their_name():
    scene, _, sphere = mixed_scene()
    o, d = scene_rays(10, seed=1)
    singular = np.diag([1.0, 1.0, 0.0, 1.0])
    bad_transforms = [
        (singular, ValueError, "singular"),
        (np.full((4, 4), np.nan), ValueError, "finite"),
        (np.eye(3), ValueError, r"\(4, 4\) or \(3, 4\)"),
        (np.vstack([np.eye(4)[:3], [0, 0, 1, 1]]), ValueError, "bottom row"),
        ("identity", ValueError, "transform"),
        (np.eye(4, dtype=bool), TypeError, "transform"),
    ]
    for transform, error, words in bad_transforms:
        with pytest.raises(error, match=words):
            scene.add(sphere, transform)
        with pytest.raises(error, match=words):
            scene.set_transform(0, transform)
    for mask, error in [(-1, ValueError), (2**32, ValueError), (1.5, TypeError),
                        (True, TypeError), ("1", TypeError)]:
        with pytest.raises(error, match="mask"):
            scene.add(sphere, mask=mask)
        with pytest.raises(error, match="mask"):
            scene.set_mask(0, mask)
    for instance, error in [(-1, ValueError), (99, ValueError), (2**40, ValueError),
                            (1.0, TypeError), (True, TypeError), ("0", TypeError)]:
        with pytest.raises(error, match="instance"):
            scene.remove(instance)
        with pytest.raises(error, match="instance"):
            scene.set_mask(instance, 1)
    for mask, error in [(np.ones(10, np.float32), TypeError), (np.ones(9, np.uint32), ValueError),
                        (np.ones((10, 1), np.uint32), ValueError),
                        (np.full(10, 2**33), ValueError), (np.full(10, -1), ValueError)]:
        for query in (scene.intersect, scene.occluded, scene.intersect_all, scene.count):
            with pytest.raises(error, match="mask"):
                query(o, d, mask=mask)
        for query in (scene.contains, scene.closest_point):
            with pytest.raises(error, match="mask"):
                query(o, mask=mask)
    with pytest.raises(TypeError, match="mesh"):
        scene.add(42)
    with pytest.raises(ValueError, match="face 0: vertex index 5 out of range"):
        scene.add((np.zeros((3, 3)), np.array([[0, 1, 5]])))
    with pytest.raises(ValueError, match="directions"):
        scene.intersect(o, d[:5])
    with pytest.raises(ValueError, match="points"):
        scene.closest_point(np.zeros((4, 2)))
    # Nothing changed by the refusals: the scene still answers.
    assert len(scene) == 5 and scene.intersect(o, d)["hit"].dtype == np.bool_


def test_empty_scene_misses():
    scene = hbv.Scene()
    o, d = scene_rays(5, seed=1)
    assert not scene.intersect(o, d)["hit"].any()
    assert not scene.occluded(o, d).any()
    assert scene.count(o, d).sum() == 0
    assert np.isinf(scene.closest_point(o)["distance"]).all()


def gltf_scene(tmp_path):
    """A glTF file of two meshes, one placed by three nodes (a matrix, a TRS child of a
    translated parent, a mirroring scale) and one once; with the world transforms of its
    instances in the order RAYS.md gives (depth-first, pre-order)."""
    sv, sf = icosphere(2, radius=0.5)
    tv, tf = soup(40, seed=3)
    m0 = affine(rotation((1, 0, 1), 0.5) * 1.3, (0.5, -0.5, 0.2))
    parent = trs_matrix(translation=(-1.0, 0.5, 0.0))
    q = np.array([0.1, 0.2, 0.3, 0.9])
    q /= np.linalg.norm(q)
    child = trs_matrix((0.2, 0.0, 0.4), q, (1.0, 0.7, 1.2))
    mirror = trs_matrix((1.0, 1.0, -0.5), (0, 0, 0, 1), (1.0, -1.0, 1.0))
    nodes = [
        {"mesh": 0, "matrix": m0.tolist()},
        {"translation": [-1.0, 0.5, 0.0], "children": [2]},
        {"mesh": 0, "translation": [0.2, 0.0, 0.4], "rotation": q.tolist(),
         "scale": [1.0, 0.7, 1.2]},
        {"mesh": 1, "scale": [0.5, 0.5, 0.5]},
        {"mesh": 0, "translation": [1.0, 1.0, -0.5], "scale": [1.0, -1.0, 1.0]},
    ]
    path = tmp_path / "scene.gltf"
    write_gltf(path, [(sv, sf), (tv, tf)], nodes, roots=[0, 1, 3, 4])
    placed = [((sv, sf), m0), ((sv, sf), parent @ child), ((tv, tf), np.diag([0.5, 0.5, 0.5, 1])),
              ((sv, sf), mirror)]
    return path, placed


def test_load_scene_equals_the_scene_built_by_hand(tmp_path):
    path, placed = gltf_scene(tmp_path)
    loaded = hbv.load_scene(str(path))
    assert loaded.mesh_count == 2 and len(loaded) == 4
    by_hand = hbv.Scene()
    meshes = {}
    for (v, f), transform in placed:
        mesh = meshes.setdefault(id(v), hbv.Mesh(v, f))
        by_hand.add(mesh, transform)
    o, d = scene_rays(1500, seed=15)
    a, b = loaded.intersect(o, d), by_hand.intersect(o, d)
    np.testing.assert_array_equal(a["hit"], b["hit"])
    np.testing.assert_array_equal(a["instance"], b["instance"])
    np.testing.assert_array_equal(a["prim"], b["prim"])
    # The file's node matrices multiplied in the loader's order, the hand's in NumPy's.
    np.testing.assert_allclose(a["t"], b["t"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(a["normal"], b["normal"], atol=1e-6)
    flat = Flattened([(v, f, m, 0xFFFFFFFF) for (v, f), m in placed])
    clear = check_closest(a, flat, o, d, np.full(len(o), 0xFFFFFFFF))
    assert set(a["instance"][clear]) == {0, 1, 2, 3}
    np.testing.assert_array_equal(loaded.count(o, d), by_hand.count(o, d))


def test_load_scene_errors_name_the_file(tmp_path):
    with pytest.raises(OSError, match="missing.gltf"):
        hbv.load_scene(str(tmp_path / "missing.gltf"))
    broken = tmp_path / "broken.gltf"
    broken.write_text("{ not json")
    with pytest.raises(ValueError, match="broken.gltf"):
        hbv.load_scene(str(broken))
    path, _ = gltf_scene(tmp_path)
    text = path.read_text().replace('"scale": [0.5, 0.5, 0.5]', '"scale": [0.5, 0.0, 0.5]')
    singular = tmp_path / "singular.gltf"
    singular.write_text(text)
    with pytest.raises(ValueError, match="singular"):
        hbv.load_scene(str(singular))


def test_bvh_hits_carry_the_normal(sphere):
    mesh, v, f = sphere
    o, d = scene_rays(500, seed=16)
    hits = hbv.BVH(mesh).intersect(o, d)
    tri = v.astype(np.float32).astype(np.float64)[f[hits["prim"][hits["hit"]]]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    np.testing.assert_allclose(hits["normal"][hits["hit"]],
                               n / np.linalg.norm(n, axis=1, keepdims=True), atol=1e-6)
    assert np.all(hits["normal"][~hits["hit"]] == 0)
    grid = hbv.Grid(mesh).intersect(o, d)
    np.testing.assert_array_equal(grid["normal"], hits["normal"])


def test_interpolate_vertex_attributes(sphere):
    mesh, v, f = sphere
    o, d = scene_rays(400, seed=17)
    hits = hbv.BVH(mesh).intersect(o, d)
    # Linear attributes interpolate to their value at the hit point.
    colours = (v * [1.0, 2.0, 3.0] + 4.0).astype(np.float32)
    at_hit = hbv.interpolate(mesh, colours, hits["prim"], hits["u"], hits["v"])
    assert at_hit.dtype == np.float32 and at_hit.shape == (len(o), 3)
    h = hits["hit"]
    point = o + d * np.where(h, hits["t"], 0)[:, None].astype(np.float64)
    np.testing.assert_allclose(at_hit[h], point[h] * [1, 2, 3] + 4, atol=1e-4)
    assert np.isnan(at_hit[~h]).all()
    heights = hbv.interpolate(f, v[:, 2].copy(), hits["prim"], hits["u"], hits["v"])
    assert heights.dtype == np.float64 and heights.shape == (len(o),)
    np.testing.assert_allclose(heights[h], point[h, 2], atol=1e-5)
    uv8 = np.zeros((len(v), 2), np.uint8) + 7
    np.testing.assert_allclose(hbv.interpolate(hbv.BVH(mesh), uv8, hits["prim"], hits["u"],
                                               hits["v"])[h], 7.0)
    with pytest.raises(ValueError, match="prim"):
        hbv.interpolate(mesh, colours, np.array([len(f)]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="prim"):
        hbv.interpolate(mesh, colours, np.array([-2]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="attribute"):
        hbv.interpolate(mesh, colours[:-1], hits["prim"], hits["u"], hits["v"])
    with pytest.raises(ValueError, match="u"):
        hbv.interpolate(mesh, colours, hits["prim"], hits["u"][:-1], hits["v"])
    with pytest.raises(TypeError, match="prim"):
        hbv.interpolate(mesh, colours, hits["prim"].astype(float), hits["u"], hits["v"])
    with pytest.raises(TypeError, match="mesh"):
        hbv.interpolate(object(), colours, hits["prim"], hits["u"], hits["v"])


def test_trimesh_scene_converts_with_node_transforms():
    trimesh = pytest.importorskip("trimesh")
    import hbv.trimesh as ht

    box = trimesh.creation.box(extents=(1.0, 0.5, 0.8))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    tm = trimesh.Scene()
    m1 = affine(rotation((0, 0, 1), 0.6), (1.0, 0.0, 0.0))
    m2 = affine(np.diag([1.0, 2.0, 1.0]), (-1.0, 0.5, 0.0))
    m3 = affine(offset=(0.0, -1.0, 0.3))
    tm.add_geometry(box, node_name="a", geom_name="box", transform=m1)
    tm.add_geometry(ball, node_name="b", geom_name="ball", transform=m2)
    tm.add_geometry(box, node_name="c", geom_name="box", transform=m3)
    scene = ht.scene(tm)
    nodes = ht.scene_nodes(tm)
    assert sorted(nodes) == ["a", "b", "c"] and len(scene) == 3
    assert scene.mesh_count == 2
    instances = []
    for node in nodes:
        transform, name = tm.graph[node]
        g = tm.geometry[name]
        instances.append((g.vertices, g.faces, transform, 0xFFFFFFFF))
    o, d = scene_rays(800, seed=18)
    hits = scene.intersect(o, d)
    clear = check_closest(hits, Flattened(instances, exact=True), o, d, np.full(len(o), 0xFFFFFFFF))
    assert set(hits["instance"][clear]) == {0, 1, 2}
    dumped = tm.to_geometry() if hasattr(tm, "to_geometry") else tm.dump(concatenate=True)
    assert hits["hit"].sum() == hbv.BVH(hbv.Mesh(dumped.vertices, dumped.faces)).intersect(
        o, d)["hit"].sum()


def test_transforms_given_as_3x4_and_4x4_agree():
    v, f = cube()
    m = affine(rotation((1, 2, 0), 0.3) * 1.7, (0.1, 0.2, 0.3))
    a, b = hbv.Scene(), hbv.Scene()
    a.add((v, f), m)
    b.add((v, f), m[:3].tolist())
    o, d = scene_rays(300, seed=19)
    np.testing.assert_array_equal(a.intersect(o, d)["t"], b.intersect(o, d)["t"])
    assert as_matrix(m[:3]).shape == (4, 4)


def test_contains_warns_on_open_meshes():
    v, f = cube()
    scene = hbv.Scene()
    scene.add((v, f))
    scene.add((v, f[:-1]), affine(offset=(3, 0, 0)))  # a cube missing a face
    with pytest.warns(RuntimeWarning, match=r"1 of the scene's 2 meshes are not closed \(mesh ids \[1\]"):
        inside = scene.contains([[0.0, 0.0, 0.0], [0.0, 5.0, 0.0]])
    np.testing.assert_array_equal(inside, [True, False])


def test_queries_and_changes_from_several_threads():
    # Queries run with the GIL released while other threads change the scene: each answers a
    # whole scene (before or after a change), none fails.
    import threading

    v, f = icosphere(2, radius=0.4)
    mesh = hbv.Mesh(v, f)
    scene = hbv.Scene()
    for k in range(20):
        scene.add(mesh, affine(offset=(k % 5, k // 5, 0)))
    o = np.c_[np.repeat(np.arange(5.0), 800), np.tile(np.arange(4.0), 1000), np.full(4000, 5.0)]
    d = np.tile([0.0, 0.0, -1.0], (4000, 1))
    errors = []

    def query():
        try:
            for _ in range(5):
                hits = scene.intersect(o, d)
                assert hits["hit"].all()
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=query) for _ in range(3)]
    for t in threads:
        t.start()
    for k in range(20):
        scene.set_transform(k, affine(offset=(k % 5, k // 5, 0.1 * (k % 3))))
        scene.set_mask(k, 1 + k)
    for t in threads:
        t.join()
    assert not errors
    np.testing.assert_allclose(scene.intersect(o, d)["t"], 5.0 - 0.4 - 0.1 * (
        (o[:, 0] + 5 * o[:, 1]).astype(int) % 3), atol=2e-2)


def hbv_command():
    """The `hbv` command line named by HBV_CLI, else the newer of the repository's builds
    (`cargo test --workspace`, which scripts/test.sh runs first, builds the debug one); None
    when there is none."""
    named = os.environ.get("HBV_CLI")
    if named:
        return named
    root = pathlib.Path(__file__).resolve().parents[2]
    built = [root / "target" / b / "hbv" for b in ("release", "debug")]
    built = [p for p in built if p.exists()]
    return str(max(built, key=lambda p: p.stat().st_mtime)) if built else None


def test_hbv_trace_answers_as_load_scene_and_the_scene_built_by_hand(tmp_path):
    command = hbv_command()
    if command is None:
        pytest.skip("the hbv command line is not built (cargo build -p hbv-cli)")
    path, placed = gltf_scene(tmp_path)
    o, d = (a.astype(np.float32) for a in scene_rays(1500, seed=16))
    rays = tmp_path / "rays.npz"
    np.savez(rays, origins=o, directions=d)
    out = tmp_path / "hits.npz"
    subprocess.run([command, "trace", str(path), "--rays", str(rays), "--out", str(out),
                    "--builder", "binned-sah", "--layout", "wide8"], check=True,
                   capture_output=True)
    traced = np.load(out)
    loaded = hbv.load_scene(str(path)).intersect(o, d)
    by_hand = hbv.Scene()
    meshes = {}
    for (v, f), transform in placed:
        by_hand.add(meshes.setdefault(id(v), hbv.Mesh(v, f)), transform)
    hand = by_hand.intersect(o, d)
    # The command line and load_scene read the same file with the same library: bit for bit.
    for key in ("hit", "t", "prim", "u", "v", "instance", "normal"):
        np.testing.assert_array_equal(traced[key], loaded[key], err_msg=key)
    # The scene built by hand multiplies the node matrices in NumPy's order.
    np.testing.assert_array_equal(traced["instance"], hand["instance"])
    np.testing.assert_array_equal(traced["prim"], hand["prim"])
    np.testing.assert_allclose(traced["t"], hand["t"], rtol=1e-6, atol=1e-6)


def kept_scene():
    """The mixed scene, with a float64 cube at UTM coordinates added, two instances removed, a
    mask changed and an instance moved (a change the top level has not seen yet); rays at every
    instance, near and far, with masks; points near both."""
    scene, _, sphere = mixed_scene()
    corner = np.array([500000.137, 5000000.291, 10.113])
    v, f = cube(center=corner + 0.5, size=1.0)
    assert scene.add((v, f), mask=0b1001) == 5
    scene.remove(0)
    scene.remove(3)
    scene.set_mask(1, 0b110)
    scene.set_transform(2, affine(rotation((0, 1, 0), 0.4), (0.1, 1.1, 0.2)))
    o, d = scene_rays(1500, seed=31)
    rng = np.random.default_rng(32)
    far_o = corner + 0.5 + rng.uniform(-3, 3, (300, 3))
    far_d = corner + 0.5 + rng.uniform(-0.4, 0.4, (300, 3)) - far_o
    o, d = np.vstack([o, far_o]), np.vstack([d, far_d])
    masks = rng.choice(np.array([0xFFFFFFFF, 1, 2, 6, 8, 9], np.uint32), len(o))
    points = np.vstack([rng.uniform(-2, 2, (200, 3)), corner + rng.uniform(-1, 2, (100, 3))])
    return scene, sphere, (o, d, masks, points)


def every_answer(scene, o, d, masks, points):
    """Every query of the scene on the rays and points, with their masks and without."""
    answers = []
    for m in (None, masks):
        answers += [scene.intersect(o, d, mask=m), scene.occluded(o, d, mask=m),
                    scene.intersect_all(o, d, mask=m), scene.count(o, d, mask=m),
                    scene.closest_point(points, mask=None if m is None else m[:len(points)])]
    return answers


def assert_same_answers(got, want):
    """Equal bit for bit: every array of every answer (NaN equal to NaN)."""
    if isinstance(want, dict):
        assert got.keys() == want.keys()
        for k in want:
            assert_same_answers(got[k], want[k])
    elif isinstance(want, (list, tuple)):
        assert len(got) == len(want)
        for g, w in zip(got, want):
            assert_same_answers(g, w)
    else:
        assert np.asarray(got).dtype == np.asarray(want).dtype
        np.testing.assert_array_equal(got, want)


def test_pickle_keeps_ids_masks_holes_and_answers():
    import copy
    import pickle

    scene, sphere, queries = kept_scene()
    want = every_answer(scene, *queries)
    assert (want[0]["instance"] == 5).sum() > 20, "rays reach the far cube"
    for back in (pickle.loads(pickle.dumps(scene)), copy.deepcopy(scene)):
        assert type(back) is hbv.Scene
        assert (back.instance_count, len(back), back.mesh_count) == (6, 4, 4)
        assert back.bounds == scene.bounds
        assert_same_answers(every_answer(back, *queries), want)
        # Removed ids stay refused, new ones follow the last.
        with pytest.raises(ValueError, match="instance: id 3 was removed"):
            back.set_mask(3, 1)
        # What is not kept: which Python objects were added. The sphere added again is a new
        # mesh of the unpickled scene, and the same mesh of the original.
        assert back.add(sphere) == 6 and back.mesh_count == 5
        assert scene.mesh_count == 4
    # The original is unchanged by its copies' changes.
    assert_same_answers(every_answer(scene, *queries), want)


def test_save_and_load_scene_round_trip(tmp_path):
    scene, _, queries = kept_scene()
    want = every_answer(scene, *queries)
    path = tmp_path / "kept.hbv"
    scene.save(path)
    assert sorted(os.listdir(tmp_path)) == ["kept.hbv"]  # no temporary file left behind
    loaded = hbv.load_scene(path)
    assert (loaded.instance_count, len(loaded), loaded.mesh_count) == (6, 4, 4)
    assert_same_answers(every_answer(loaded, *queries), want)
    # Told by its content, whatever its name; saving the loaded scene gives the same bytes.
    renamed = tmp_path / "kept.glb"
    loaded.save(renamed)
    assert renamed.read_bytes() == path.read_bytes()
    assert_same_answers(every_answer(hbv.load_scene(str(renamed)), *queries), want)
    # A scene file is not a BVH's.
    with pytest.raises(ValueError, match="kept.hbv.*holds a scene"):
        hbv.load_bvh(path)


def test_scene_save_never_overwrites_unless_asked(tmp_path):
    scene, _, _ = mixed_scene()
    path = tmp_path / "scene.hbv"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="scene.hbv.*overwrite=True"):
        scene.save(path)
    assert path.read_bytes() == b"precious"
    scene.save(path, overwrite=True)
    assert len(hbv.load_scene(path)) == 5
    assert sorted(os.listdir(tmp_path)) == ["scene.hbv"]
    with pytest.raises(FileNotFoundError, match="cannot save the scene: .*no_such_dir"):
        scene.save(tmp_path / "no_such_dir" / "s.hbv")
    with pytest.raises(IsADirectoryError, match="it is a directory"):
        scene.save(tmp_path, overwrite=True)


def test_load_scene_reads_a_bvh_file_as_one_instance(tmp_path, sphere):
    mesh, _, _ = sphere
    bvh = hbv.BVH(mesh, builder="sweep-sah", leaf_size=2)
    path = tmp_path / "tree.hbv"
    bvh.save(path)
    scene = hbv.load_scene(path)
    assert (len(scene), scene.mesh_count, scene.instance_count) == (1, 1, 1)
    o, d = random_rays(1000, seed=33)
    a, b = scene.intersect(o, d), bvh.intersect(o, d)
    assert a["hit"].sum() > 100
    for k in ("hit", "t", "prim", "u", "v", "normal"):
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    np.testing.assert_array_equal(a["instance"], np.where(a["hit"], 0, -1))


def test_corrupt_scene_files_raise_value_error_naming_the_file(tmp_path):
    scene, _, _ = mixed_scene()
    path = tmp_path / "good.hbv"
    scene.save(path)
    data = path.read_bytes()
    truncated = tmp_path / "truncated.hbv"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="truncated.hbv: .*the file is truncated"):
        hbv.load_scene(truncated)
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0x40
    damaged = tmp_path / "damaged.bin"  # told by its magic number, whatever its name
    damaged.write_bytes(bytes(flipped))
    with pytest.raises(ValueError, match="damaged.bin: .*corrupted"):
        hbv.load_scene(damaged)
    empty = tmp_path / "empty.hbv"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match="empty.hbv: not an hbv BVH file"):
        hbv.load_scene(empty)
    with pytest.raises(FileNotFoundError, match="missing.hbv"):
        hbv.load_scene(tmp_path / "missing.hbv")
    with pytest.raises(ValueError, match="<pickled hbv.Scene>: not an hbv BVH file"):
        hbv._hbv._scene_from_bytes(b"not a scene")
