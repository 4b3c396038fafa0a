#!/usr/bin/env bash
# Re-processing throughput: captures per second of `radbench process` on one core and on all cores.
#
# Makes its own captures first (the accuracy campaign on the built-in mock lab, RUNS times: six
# MSK-LFM captures each), then re-processes all of them with their recorded options, once with
# --jobs 1 and once with every core, and prints captures per second for each. Everything stays in
# a temporary folder that is removed at the end.
#
#   cargo build --release && bash benches/process_throughput.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-4}
BIN=${RADBENCH_BIN:-target/release/radbench}
[ -x "$BIN" ] || { echo "build first: cargo build --release" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# A cache of prepared pieces of its own (warmed by making the archive): the shared
# ~/.cache/radbench keeps 16 pieces per kind, and other users' runs evict ours between turns.
export RADBENCH_CACHE_DIR="${RADBENCH_CACHE_DIR:-$work/cache}"
inputs=()
for i in $(seq 1 "$RUNS"); do
    "$BIN" campaign run examples/accuracy.toml --allow-rf --out "$work/run-$i" > /dev/null 2>&1
    inputs+=("$work/run-$i")
done
# The captures just written are still going to the disk: without this, the first timed runs'
# fsyncs wait for that writeback (the archive is meant to be saved captures).
sync
captures=$(find "$work" -name 'capture.sigmf-meta' | wc -l)
cores=$(nproc)
rate() { # jobs -> captures per second (best of 3)
    local best=0
    for _ in 1 2 3; do
        rm -rf "$work/out"
        local t0 t1
        t0=$(date +%s.%N)
        "$BIN" process "${inputs[@]}" --jobs "$1" --out "$work/out" > /dev/null 2>&1
        t1=$(date +%s.%N)
        best=$(python3 -c "print(max($best, $captures / ($t1 - $t0)))")
    done
    printf '%.1f' "$best"
}
one=$(rate 1)
all=$(rate "$cores")
echo "radbench process, $captures MSK-LFM captures of the accuracy campaign, best of 3:"
echo "  1 core:   $one captures/s"
echo "  $cores cores: $all captures/s"
