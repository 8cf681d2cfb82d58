#!/usr/bin/env bash
# Instructions and (modelled) branch mispredictions per ray of one `hbv trace`, counted by
# valgrind's cachegrind: deterministic, so two builds can be compared on a busy machine where
# timings are not. Counts only the traversal functions (the wide layouts' *_hit(s)_* kernels),
# not loading, building or writing.
#
#   bench/count_instructions.sh [HBV] MESH RAYS.npz [trace options...]
#   bench/count_instructions.sh target/release/hbv ../shared/scenes/teapot.ply rays/diffuse.npz --occluded
#
# The branch predictor cachegrind models is simpler than a real core's: read its misprediction
# counts as a comparison between builds, not as the hardware's figure.
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
valgrind --tool=cachegrind --cache-sim=no --branch-sim=yes \
    --cachegrind-out-file="$work/cg.out" \
    "$hbv" trace "$mesh" --rays "$rays" --out "$work/hits.npz" --threads 1 --json "$@" \
    >"$work/trace.json" 2>/dev/null
n=$(grep -o '"rays": *[0-9]*' "$work/trace.json" | grep -o '[0-9]*$')
cg_annotate --show-percs=no "$work/cg.out" | awk -v n="$n" '
    /_hits?_(avx|with)/ { ir = $1; bcm = $3; gsub(",", "", ir); gsub(",", "", bcm); i += ir; m += bcm }
    END { printf "%d rays: %.0f instructions and %.2f mispredicted branches per ray\n", n, i / n, m / n }'
