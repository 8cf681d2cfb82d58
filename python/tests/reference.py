"""Float64 brute-force references in NumPy: every ray against every triangle, every point
against every triangle."""

import numpy as np


def ray_triangle_t(tris, o, d):
    """Möller–Trumbore in float64: (rays, triangles) array of t, NaN where there is no hit."""
    p0, p1, p2 = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = p1 - p0, p2 - p0
    pvec = np.cross(d[:, None, :], e2[None])
    det = np.einsum("rtk,tk->rt", pvec, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tvec = o[:, None, :] - p0[None]
        u = np.einsum("rtk,rtk->rt", tvec, pvec) * inv
        q = np.cross(tvec, e1[None])
        v = np.einsum("rk,rtk->rt", d, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
    ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
    return np.where(ok, t, np.nan)


def closest_on_triangles(p, tris):
    """Ericson's closest point of each triangle to point p, vectorized, float64: (T, 3)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        face = a + ab * (vb * denom)[:, None] + ac * (vc * denom)[:, None]
        e_ab = a + ab * (d1 / (d1 - d3))[:, None]
        e_ac = a + ac * (d2 / (d2 - d6))[:, None]
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        e_bc = b + (c - b) * w[:, None]
    out = face
    # Later assignments take precedence, so go from the last region tested to the first.
    out = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[:, None], e_bc, out)
    out = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[:, None], e_ac, out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    out = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[:, None], e_ab, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    return out


def nondegenerate(tris):
    return np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1) > 0
