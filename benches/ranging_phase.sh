#!/usr/bin/env bash
# What `--ranging phase` adds to a capture's processing (issue 41's bound: at most 10 %).
#
# On docs/metrology.md's realistic scene (thesis-lab chain, clutter, leakage, 1 kHz of LO phase
# noise, 1 ps of trigger jitter, SNR 30 dB): a response calibration on the pillar at 1.0 m, then
# COUNT captures of the pillar near it; then `radbench process` of all of them with the
# calibration, once per ranging mode, best of 5 each, on one core (--jobs 1). Prints the time per
# capture of each mode and their ratio, with the load average around them (the machine is
# shared: read the best with the load). Everything stays in a temporary folder.
#
#   cargo build --release && bash benches/ranging_phase.sh [COUNT]
set -euo pipefail
cd "$(dirname "$0")/.."
COUNT=${1:-10}
BIN=${RADBENCH_BIN:-target/release/radbench}
[ -x "$BIN" ] || { echo "build first: cargo build --release" >&2; exit 2; }
BIN=$(realpath "$BIN")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene() { # range_m seed [with the wall]
    cat <<TOML
snr_db = 30.0
trigger_jitter_s = 1e-12
seed = $2
[[targets]]
range_m = $1
amplitude = 0.5
[[clutter]]
range_m = 0.02
amplitude = 0.02
$( [ "${3:-}" = wall ] && printf '[[clutter]]\nrange_m = 12.5\namplitude = 0.1\n' )
[leakage]
amplitude = 0.03
delay_s = 0.2e-9
[impairments]
phase_noise_linewidth_hz = 1000.0
dc_offset_v = [0.002, -0.001]
iq_gain_db = 0.3
iq_phase_deg = 2.0
[chain]
preset = "thesis-lab"
TOML
}
cd "$work"
scene 1.0 1 > reference.toml
"$BIN" calibrate response --reference-range 1.0 --scene reference.toml --allow-rf \
    --out response.toml --force > /dev/null 2>&1
captures=()
for i in $(seq 1 "$COUNT"); do
    # Steps of 37 um from the calibration's place: farther, the leakage's fitted peak moves with
    # the pillar's residue and some captures keep their envelope range (docs/metrology.md).
    scene "$(python3 -c "print(1.0 + 37e-6 * $i)")" "$((100 + i))" wall > "scene-$i.toml"
    "$BIN" capture --scene "scene-$i.toml" --allow-rf --calibration response.toml \
        --out "c$i" > /dev/null 2>&1
    captures+=("c$i")
done
sync
# The timing means something only if phase ranging ran: no capture may fall back to the envelope.
if "$BIN" process "${captures[@]}" --calibration response.toml --ranging phase --json \
    --out checked 2>&1 | grep -q "envelope's\|keeps its envelope range"; then
    echo "phase ranging fell back to the envelope on this scene: the timing would be wrong" >&2
    exit 1
fi
load() { cut -d' ' -f1 /proc/loadavg; }
best() { # mode -> best seconds per capture of 5
    local b=1e9
    for _ in 1 2 3 4 5; do
        rm -rf out
        local t0 t1
        t0=$(date +%s.%N)
        "$BIN" process "${captures[@]}" --calibration response.toml --ranging "$1" --jobs 1 \
            --out out > /dev/null 2>&1
        t1=$(date +%s.%N)
        b=$(python3 -c "print(min($b, ($t1 - $t0) / $COUNT))")
    done
    echo "$b"
}
before=$(load)
envelope=$(best envelope)
phase=$(best phase)
python3 - "$envelope" "$phase" "$before" "$(load)" "$COUNT" <<'PY'
import sys
envelope, phase, before, after, count = sys.argv[1:]
e, p = float(envelope), float(phase)
print(f"process of {count} captures, one core (load average {before} -> {after}):")
print(f"  envelope {e * 1e3:.1f} ms per capture, phase {p * 1e3:.1f} ms: phase adds {100 * (p / e - 1):+.1f} %")
PY
