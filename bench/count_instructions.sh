#!/usr/bin/env bash
# Instructions and (modelled) branch mispredictions per ray of one `hbv trace`, counted by
# valgrind's callgrind: deterministic, so two builds can be compared on a busy machine where
# timings are not. Counts everything inside the query `hbv trace` times (the batch call, or
# each single-ray call with --one-by-one: ray checks, setup, traversal, triangle tests), not
# loading, building or writing.
#
#   bench/count_instructions.sh [HBV] MESH RAYS.npz [trace options...]
#   bench/count_instructions.sh target/release/hbv ../shared/scenes/teapot.ply rays/diffuse.npz --occluded
#
# The branch predictor callgrind models is simpler than a real core's: read its misprediction
# counts as a comparison between builds, not as the hardware's figure (and a build with fewer
# modelled mispredictions can still be slower: time both before keeping a change).
set -euo pipefail
hbv=target/release/hbv
if [[ $# -ge 1 && -x "$1" && ! "$1" =~ \.(ply|obj|gltf|glb|hbv)$ ]]; then hbv=$1; shift; fi
if [[ $# -lt 2 ]]; then
    echo "usage: $0 [HBV] MESH RAYS.npz [trace options...]" >&2
    exit 2
fi
command -v valgrind >/dev/null || { echo "valgrind is not installed" >&2; exit 2; }
mesh=$1 rays=$2; shift 2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
valgrind --tool=callgrind --branch-sim=yes \
    --toggle-collect='*Accelerator::intersect_batch' --toggle-collect='*Accelerator::occluded_batch' \
    --toggle-collect='*Accelerator>::intersect' --toggle-collect='*Accelerator>::occluded' \
    --toggle-collect='*Accelerator>::intersect_coherent' \
    --callgrind-out-file="$work/cg.out" \
    "$hbv" trace "$mesh" --rays "$rays" --out "$work/hits.npz" --threads 1 --json "$@" \
    >"$work/trace.json" 2>/dev/null
n=$(grep -o '"rays": *[0-9]*' "$work/trace.json" | grep -o '[0-9]*$')
# Totals line: Ir Bc Bcm Bi Bim (conditional and indirect branches, executed and mispredicted).
callgrind_annotate "$work/cg.out" 2>/dev/null | tr -d ',' | awk -v n="$n" '
    /PROGRAM TOTALS/ { printf "%d rays: %.0f instructions and %.2f mispredicted branches per ray\n", n, $1 / n, ($5 + $9) / n }'
