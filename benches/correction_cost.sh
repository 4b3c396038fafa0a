#!/usr/bin/env bash
# What the chain correction costs `radbench process` (issue 38: a corrected capture's processing
# at most 1.2x an uncorrected one's). One fresh process per run, as a user re-processes a saved
# capture: the same capture processed with `--correction none` and with `--correction rx` (the
# calibration read, checked and applied), for both waveforms. Prints best and median wall time of
# RUNS runs each and their ratio, with the load average (the machine may be shared: read the best).
#
# The scenes are docs/calibration.md's: a reference pillar at 1.0 m and a pillar at 2.3 m on the
# `thesis-lab` chain, SNR 25 dB. Everything stays in a temporary folder.
#
#   cargo build --release && bash benches/correction_cost.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-11}
BIN=${RADBENCH_BIN:-target/release/radbench}
[ -x "$BIN" ] || { echo "build first: cargo build --release" >&2; exit 2; }
BIN=$(realpath "$BIN")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene() { # range seed
    cat <<EOF
snr_db = 25.0
seed = $2
[[targets]]
range_m = $1
amplitude = 0.5
[chain]
preset = "thesis-lab"
EOF
}
scene 1.0 7 > "$work/reference.toml"
scene 2.3 11 > "$work/pillar.toml"
load() { cut -d' ' -f1 /proc/loadavg; }
stats() { # times... -> "best / median"
    python3 -c 'import sys, statistics as s; t = sorted(map(float, sys.argv[1:])); print(f"{t[0]:.3f} / {s.median(t):.3f}")' "$@"
}
echo "radbench process, none against rx, $RUNS runs each ($(nproc) cores):"
for waveform in msk-lfm ofdm; do
    (cd "$work" && "$BIN" calibrate response --reference-range 1.0 --scene reference.toml \
        --allow-rf --waveform "$waveform" --out "cal-$waveform.toml" > /dev/null 2>&1)
    (cd "$work" && "$BIN" capture --allow-rf --scene pillar.toml --waveform "$waveform" \
        --correction none --out "cap-$waveform" > /dev/null 2>&1)
    before=$(load)
    declare -A times=([none]="" [rx]="")
    for _ in $(seq 1 "$RUNS"); do
        for mode in none rx; do
            rm -rf "$work/out"
            extra=()
            [ "$mode" = rx ] && extra=(--calibration "cal-$waveform.toml")
            t0=$(date +%s.%N)
            (cd "$work" && "$BIN" process "cap-$waveform" --correction "$mode" "${extra[@]}" \
                --out out > /dev/null 2>&1)
            t1=$(date +%s.%N)
            times[$mode]+=" $(python3 -c "print($t1 - $t0)")"
        done
    done
    # shellcheck disable=SC2086
    none=$(stats ${times[none]})
    # shellcheck disable=SC2086
    rx=$(stats ${times[rx]})
    ratio=$(python3 -c "print(f'{float(\"${rx%% *}\") / float(\"${none%% *}\"):.2f}')")
    echo "  $waveform: none $none s, rx $rx s (best / median), rx / none (best) ${ratio}x," \
        "load $before -> $(load)"
done
