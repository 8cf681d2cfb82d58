#!/usr/bin/env bash
# Instructions and (modelled) mispredicted branches per ray of hbv and of Embree on the same
# rays, both counted by valgrind's callgrind: a comparison that a drifting machine's clock does
# not blur (two runs give the same counts). hbv: `hbv trace`'s batch query, one thread, as
# bench/count_instructions.sh counts it. Embree (embreex from PyPI): only inside its
# rtcIntersect1 / rtcOccluded1 calls, one per ray (embreex's loop around them and the Python
# around that are not counted), the scene built as bench/embree_compare.py builds it.
#
#   bench/instructions_vs_embree.sh MESH RAYS.npz [--occluded]
#   PYTHON=../py-bench-venv/bin/python bench/instructions_vs_embree.sh ../shared/scenes/teapot.ply rays.npz
#
# PYTHON is an interpreter with numpy, embreex and this repository's `hbv` package (to load the
# mesh as hbv does); default python3. Embree's rays start at the ray file's origins moved to
# tmin, as bench/embree_compare.py gives them (RAYS.md). Counts are not times: an instruction
# of one program is not worth one of the other (their mix of loads, vector operations and
# branches differs), so read the ratios beside the timed ones of bench/embree_compare.py.
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ $# -lt 2 ]]; then
    echo "usage: $0 MESH RAYS.npz [--occluded]" >&2
    exit 2
fi
command -v valgrind >/dev/null || { echo "valgrind is not installed" >&2; exit 2; }
mesh=$1 rays=$2 query=${3:-}
python=${PYTHON:-python3}
hbv_line=$(bash bench/count_instructions.sh "$mesh" "$rays" $query)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat >"$work/embree.py" <<'EOF'
import sys
import numpy as np
import hbv
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh as EmbreeMesh

mesh = hbv.load(sys.argv[1])
rays = np.load(sys.argv[2])
scene = rtcore_scene.EmbreeScene()
EmbreeMesh(scene, np.ascontiguousarray(mesh.vertices.astype(np.float32)[mesh.faces]))
o = np.ascontiguousarray(rays["origins"], np.float32)
d = np.ascontiguousarray(rays["directions"], np.float32)
n = len(o)
# embreex starts every ray at t = 0: a ray [tmin, tmax] is given as o + tmin d, tmax - tmin.
tmin = np.broadcast_to(rays["tmin"] if "tmin" in rays else np.float32(0), (n,)).astype(np.float32)
tmax = np.broadcast_to(rays["tmax"] if "tmax" in rays else np.float32(np.inf), (n,)).astype(np.float32)
o = np.ascontiguousarray(o + tmin[:, None] * d, np.float32)
dists = np.ascontiguousarray(tmax - tmin, np.float32)
if sys.argv[3] == "--occluded":
    scene.run(o, d, dists=dists, query="OCCLUDED")
else:
    scene.run(o, d, dists=dists, query="INTERSECT", output=1)
print(n)
EOF
valgrind --tool=callgrind --branch-sim=yes \
    --toggle-collect='rtcIntersect1' --toggle-collect='rtcOccluded1' \
    --callgrind-out-file="$work/cg.out" \
    "$python" "$work/embree.py" "$mesh" "$rays" "${query:-closest}" >"$work/n.txt" 2>/dev/null
n=$(tail -1 "$work/n.txt")
embree_line=$(callgrind_annotate "$work/cg.out" 2>/dev/null | tr -d ',' | awk -v n="$n" '
    /PROGRAM TOTALS/ { printf "%.0f %.2f", $1 / n, ($5 + $9) / n }')
hbv_counts=$(echo "$hbv_line" | awk '{ print $3, $6 }')
read -r hi hm <<<"$hbv_counts"
read -r ei em <<<"$embree_line"
echo "$(basename "$mesh") $(basename "$rays") ${query:-closest}: $n rays"
echo "  hbv    $hi instructions, $hm mispredicted branches per ray"
echo "  Embree $ei instructions, $em mispredicted branches per ray"
awk -v hi="$hi" -v ei="$ei" -v hm="$hm" -v em="$em" \
    'BEGIN { printf "  hbv / Embree: %.2f x the instructions, %.2f x the mispredictions\n", hi / ei, hm / em }'
