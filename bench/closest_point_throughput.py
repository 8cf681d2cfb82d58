"""Points a second of `hbv.BVH.closest_point` on one thread, for an A/B of two builds of the module.

    PYTHONPATH=BUILD python bench/closest_point_throughput.py MESH_NAME [MESH_NAME ...]

Meshes are read from ../shared/scenes; 200,000 points uniform in each mesh's box grown by 10 %
(python_compare.py's points), two warm-up calls, best of five; the mean distance lets two
builds' answers be compared.
"""
import sys, time, numpy as np, hbv, trimesh
for name in sys.argv[1:]:
    m = trimesh.load("/work/shared/scenes/" + name, force="mesh")
    V = np.asarray(m.vertices, np.float32); F = np.asarray(m.faces, np.uint32)
    bvh = hbv.BVH(hbv.Mesh(V, F))
    lo, hi = V.min(0).astype(np.float64), V.max(0).astype(np.float64); pad = 0.1 * (hi - lo)
    pts = np.ascontiguousarray(lo - pad + (hi - lo + 2 * pad) * np.random.default_rng(2).uniform(size=(200000, 3)), np.float32)
    bvh.closest_point(pts, threads=1); bvh.closest_point(pts, threads=1)
    best = 1e9
    for _ in range(5):
        t0 = time.perf_counter(); r = bvh.closest_point(pts, threads=1); best = min(best, time.perf_counter() - t0)
    print(f"{name}: {len(pts)/best/1e6:.3f} M pts/s, mean d {r['distance'].mean():.9f}")
