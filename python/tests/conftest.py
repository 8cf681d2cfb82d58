"""Shared meshes and rays of the Python tests: generated in code (no files needed)."""

import numpy as np
import pytest

import hbv


def icosphere(subdivisions=3, radius=1.0, center=(0.0, 0.0, 0.0)):
    """A closed sphere mesh (vertices float64, faces int64), without trimesh."""
    t = (1.0 + 5.0**0.5) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = f
    for _ in range(subdivisions):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = new
    return np.array(verts) * radius + np.asarray(center), np.array(faces, dtype=np.int64)


def soup(n=300, seed=1):
    """Random triangles, small and large, with a few degenerate ones."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-1, 1, (n, 1, 3))
    sizes = rng.choice([0.02, 0.2, 1.0], (n, 1, 1))
    tris = centers + rng.normal(size=(n, 3, 3)) * sizes
    tris[:5, 2] = tris[:5, 0]  # degenerate: coincident vertices
    return tris.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3)


def random_rays(n, seed=2, spread=1.5):
    """Rays from inside and around the [-1, 1] box in random directions, plus axis rays."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(-spread, spread, (n, 3))
    d = rng.normal(size=(n, 3))
    d[: n // 10] = np.eye(3)[rng.integers(0, 3, n // 10)] * rng.choice([-1, 1], (n // 10, 1))
    return o, d


@pytest.fixture(scope="session")
def sphere():
    v, f = icosphere(3)
    return hbv.Mesh(v, f), v, f


@pytest.fixture(scope="session")
def triangle_soup():
    v, f = soup()
    return hbv.Mesh(v, f), v, f
