"""Writes `bench/python_compare.py`'s ray sets as `hbv trace` ray files, for command-line A/Bs:

    PYTHONPATH=<hbv> python bench/ray_files.py OUTDIR [MESH.ply ...]      # default: ../shared/scenes/*.ply
    python bench/ray_files.py --zero-tmin IN.npz OUT.npz                  # the same rays with tmin = 0

For each mesh, OUTDIR/<stem>_camera512.npz and _camera1024.npz (its pinhole camera, 512^2 and
1024^2 rays in pixel order) and _random.npz (262,144 rays from a sphere about the mesh to points
of its box), seed 1. (`python_compare` imports hbv, hence PYTHONPATH.)
"""
import argparse
import sys
from pathlib import Path

import numpy as np


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="*", type=Path)
    p.add_argument("--zero-tmin", action="store_true", help="copy IN.npz to OUT.npz with tmin = 0")
    args = p.parse_args()
    if args.zero_tmin:
        if len(args.paths) != 2:
            sys.exit("--zero-tmin takes IN.npz OUT.npz")
        with np.load(args.paths[0]) as rays:
            out = {k: rays[k] for k in rays.files}
        out["tmin"] = np.zeros(len(out["origins"]), np.float32)
        np.savez(args.paths[1], **out)
        return
    if not args.paths:
        sys.exit("usage: ray_files.py OUTDIR [MESH ...]")
    sys.path.insert(0, str(Path(__file__).parent))
    import python_compare as pc  # noqa: E402
    import trimesh  # noqa: E402

    out, meshes = args.paths[0], args.paths[1:] or pc.default_meshes()
    out.mkdir(parents=True, exist_ok=True)
    for mesh in meshes:
        v = np.asarray(trimesh.load(mesh, process=False).vertices)
        for n, tag in [(262_144, "512"), (1_048_576, "1024")]:
            sets = pc.ray_sets(v, n, 1)
            np.savez(out / f"{mesh.stem}_camera{tag}.npz", origins=sets["primary"][0], directions=sets["primary"][1])
            if tag == "512":
                np.savez(out / f"{mesh.stem}_random.npz", origins=sets["random"][0], directions=sets["random"][1])
        print(mesh.stem)


if __name__ == "__main__":
    main()
