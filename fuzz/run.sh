#!/usr/bin/env bash
# Runs every fuzz target for a bounded time, one after the other, and fails if any crashes.
#
#   fuzz/run.sh [SECONDS]     (default 120 per target; needs `rustup toolchain install nightly`
#                              and `cargo install cargo-fuzz`)
#
# Targets are the [[bin]]s of fuzz/Cargo.toml (`cargo fuzz list`); each starts from its seeds in
# fuzz/seeds/TARGET/ (committed) plus what earlier runs left in fuzz/corpus/TARGET/ (ignored).
# One libFuzzer process per target, one at a time (no -jobs/-workers: the machine is shared), a 2 GiB memory limit and a 10 s time limit per input, so an
# input that makes a reader allocate what a header declares, or loop, counts as a crash too.
# A crash leaves its input in fuzz/artifacts/TARGET/; keep it as a regression test in
# crates/*/tests/bad_input.rs (see docs/RELIABILITY.md). Prints one summary line per target.
set -uo pipefail
cd "$(dirname "$0")"

seconds="${1:-120}"
targets=$(cargo +nightly fuzz list) || { echo "cargo +nightly fuzz list failed" >&2; exit 2; }
cargo +nightly fuzz build -O >/dev/null || { echo "fuzz build failed" >&2; exit 2; }

failed=()
for target in $targets; do
    mkdir -p "corpus/$target" "artifacts/$target"
    seeds=()
    [ -d "seeds/$target" ] && seeds=("seeds/$target")
    log="artifacts/$target/last-run.log"
    cargo +nightly fuzz run -O "$target" "corpus/$target" "${seeds[@]}" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=2048 \
        -timeout=10 -max_len=65536 -print_final_stats=1 >"$log" 2>&1
    status=$?
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    if [ "$status" -eq 0 ]; then
        echo "$target: ok, ${runs:-?} executions in ${seconds} s"
    else
        echo "$target: CRASH (exit $status), see fuzz/$log and fuzz/artifacts/$target/"
        grep -m1 -E 'panicked at|ERROR: libFuzzer|SUMMARY' "$log" | sed 's/^/    /'
        failed+=("$target")
    fi
done

if [ "${#failed[@]}" -gt 0 ]; then
    echo "crashed: ${failed[*]}" >&2
    exit 1
fi
