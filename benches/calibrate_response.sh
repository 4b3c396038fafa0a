#!/usr/bin/env bash
# `radbench calibrate response` end to end, as a user runs it (one fresh process each time: the
# built-in mock lab started, 16 repetitions with the transmitter on and 16 off captured, the
# response measured and checked, the calibration written), for both waveforms. Target (issue 22):
# under 2 s with 16 repetitions.
#
# The scene is docs/calibration.md's: one pillar at 1.0 m on the `thesis-lab` chain, SNR 25 dB. Prints
# the best and median wall time of RUNS runs per waveform and the load average around them
# (the machine is shared: read the best with the load). Everything stays in a temporary folder.
#
#   cargo build --release && bash benches/calibrate_response.sh [RUNS] [REPETITIONS]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-5}
REPS=${2:-16}
BIN=${RADBENCH_BIN:-target/release/radbench}
[ -x "$BIN" ] || { echo "build first: cargo build --release" >&2; exit 2; }
BIN=$(realpath "$BIN")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/reference.toml" <<'EOF'
snr_db = 25.0
[[targets]]
range_m = 1.0
amplitude = 0.5
[chain]
preset = "thesis-lab"
EOF
load() { cut -d' ' -f1 /proc/loadavg; }
echo "radbench calibrate response, $REPS repetitions, $RUNS runs per waveform ($(nproc) cores):"
for waveform in msk-lfm ofdm; do
    before=$(load)
    times=()
    for _ in $(seq 1 "$RUNS"); do
        t0=$(date +%s.%N)
        (cd "$work" && "$BIN" calibrate response --reference-range 1.0 --scene reference.toml \
            --allow-rf --waveform "$waveform" --repetitions "$REPS" --out response.toml \
            > /dev/null 2>&1)
        t1=$(date +%s.%N)
        times+=("$(python3 -c "print($t1 - $t0)")")
    done
    python3 - "$waveform" "$before" "$(load)" "${times[@]}" <<'EOF'
import statistics, sys
waveform, before, after, *runs = sys.argv[1:]
t = sorted(float(x) for x in runs)
print(f"  {waveform:8} best {t[0]:.2f} s, median {statistics.median(t):.2f} s, worst {t[-1]:.2f} s"
      f" (load average {before} -> {after})")
EOF
done
