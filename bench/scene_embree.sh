#!/usr/bin/env bash
# hbv's two-level scenes against Embree's (BENCHMARKS.md, "Scenes against Embree"): writes the
# scenes (crates/hbv/examples/scene_write_glb.rs), makes rays and Embree's answers with the
# Embree oracle, traces them with hbv (crates/hbv-cli/examples/scene_trace.rs: the scene, and
# hbv's own BVH over the flattened triangles), compares the answers ray by ray, and times
# closest hit and any hit on one thread, Embree's loop and hbv's (a ray a call, and batches) in turn.
#
#   PY=../py-bench-venv/bin/python O=../shared/oracle/embree_oracle.py bench/scene_embree.sh [OUT_DIR]
#
# PY: a Python with numpy, embreex 4.4.0.post1 and trimesh; O: the Embree oracle (not part of
# this repository). OUT_DIR (default .cache/scenes) receives the scenes, rays and answers.
set -euo pipefail
PY=${PY:-../py-bench-venv/bin/python}
O=${O:-../shared/oracle/embree_oracle.py}
OUT=${1:-.cache/scenes}
RAYS=${RAYS:-200000}
[ -f "$O" ] || { echo "scene_embree.sh: no Embree oracle at $O (set O)" >&2; exit 2; }
cargo build --release -q -p hbv --example scene_write_glb
cargo build --release -q -p hbv-cli --example scene_trace
TRACE=target/release/examples/scene_trace
target/release/examples/scene_write_glb "$OUT"
(cd bench && $PY -c "import machine; print(machine.describe(machine.machine()))") || true
for glb in "$OUT"/*.glb; do
  s=${glb%.glb}
  $PY "$O" rays "$glb" --seed 21 --count "$RAYS" -o "${s}_rays.npz" > /dev/null
  $PY "$O" trace "$glb" "${s}_rays.npz" -o "${s}_ref.npz"
  $PY "$O" trace "$glb" "${s}_rays.npz" --mode occluded -o "${s}_occ.npz"
  $PY "$O" flatten "$glb" -o "${s}_flat.ply" --offsets "${s}_offsets.npz"
  $TRACE "$glb" "${s}_rays.npz" --out "${s}_mine.npz" --repeat 1
  $TRACE "$glb" "${s}_rays.npz" --out "${s}_mine_occ.npz" --occluded --repeat 1
  for args in "" "--occluded"; do
    ref=${s}_ref.npz; mine=${s}_mine.npz
    [ -n "$args" ] && { ref=${s}_occ.npz; mine=${s}_mine_occ.npz; }
    $PY "$O" compare "$ref" "$mine" --rays "${s}_rays.npz" --exclude-kinds on_surface_tmin0 \
      --min-agreement 0.9995 | tail -1
    (cd bench && $PY scene_exact_arbiter.py "../$glb" "../${s}_rays.npz" "../$ref" "../$mine" \
      --exclude-kinds on_surface_tmin0 --sample 1000 $args | grep -v "^ray " )
  done
  # Timing: two rounds, each Embree's two-level loop, then hbv's scene and hbv's flattened BVH,
  # one ray a call and as one batch (interleaved), closest hit and any hit.
  for round in 1 2; do
    $PY "$O" bench "$glb" "${s}_rays.npz" --repeat 3
    for input in "$glb" "${s}_flat.ply"; do
      for batch in "" "--batch"; do
        $TRACE "$input" "${s}_rays.npz" --repeat 5 $batch
        $TRACE "$input" "${s}_rays.npz" --repeat 5 --occluded $batch
      done
    done
  done
done
