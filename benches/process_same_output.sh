#!/usr/bin/env bash
# Before/after check of a speed change: two radbench binaries must give the same files.
#
#   bash benches/process_same_output.sh OLD_BINARY NEW_BINARY [RUNS]
#
# 1. `radbench process`: makes an archive with OLD (the accuracy campaign on the built-in mock
#    lab, RUNS times: six MSK-LFM captures each, as benches/process_throughput.sh), processes all of
#    it with OLD (`--jobs 1`) and with NEW (`--jobs 1` and `--jobs` every core), each into the same
#    output path in turn, and compares every file byte for byte. Only `written_at` in each
#    `manifest.toml` may differ (the time it was written).
# 2. `radbench campaign run` of the same campaign with OLD and with NEW: every file that does not
#    carry the time of the run (profiles, plots, result.json, results, reports) byte for byte.
#    Skipped: the raw files and summaries that record when they were taken (`.trc`,
#    `capture.sigmf-meta`, `summary.json`, `manifest.toml`, `io-journal.jsonl`); the reports
#    are compared with the binary's commit (40 hex digits), the run's date and its duration
#    masked.
#
# Exits 0 when everything matches, 1 with the differing files listed otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
# What a report may differ in: the binary's commit, the run's date (RFC 3339, to the ms) and
# how long it took.
MASK='s/[0-9a-f]{40}/COMMIT/g; s/[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9:.]+Z/DATE/g; s/(Duration[^0-9]*)[0-9.]+ s/\1T s/g'
OLD=$(realpath "${1:?usage: process_same_output.sh OLD_BINARY NEW_BINARY [RUNS]}")
NEW=$(realpath "${2:?usage: process_same_output.sh OLD_BINARY NEW_BINARY [RUNS]}")
RUNS=${3:-2}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
inputs=()
for i in $(seq 1 "$RUNS"); do
    "$OLD" campaign run examples/accuracy.toml --allow-rf --out "$work/archive/run-$i" > /dev/null 2>&1
    inputs+=("$work/archive/run-$i")
done
captures=$(find "$work/archive" -name 'capture.sigmf-meta' | wc -l)

# Every file of two folders, byte for byte; `written_at = ...` lines of manifests left out.
status=0
compare() { # a b what
    local a=$1 b=$2 what=$3 skip=${4:-}
    if ! diff <(cd "$a" && find . -type f | sort) <(cd "$b" && find . -type f | sort) > /dev/null; then
        echo "DIFFERENT FILE LISTS ($what):"
        diff <(cd "$a" && find . -type f | sort) <(cd "$b" && find . -type f | sort) || true
        status=1
    fi
    local n=0 bad=0
    while IFS= read -r f; do
        [ -f "$b/$f" ] || continue
        if [ -n "$skip" ] && [[ "$(basename "$f")" =~ $skip ]]; then
            continue
        fi
        n=$((n + 1))
        case "$(basename "$f")" in
            manifest.toml)
                cmp -s <(grep -v '^written_at = ' "$a/$f") <(grep -v '^written_at = ' "$b/$f") && continue ;;
            report.md | report.html) # they name the commit of the binary
                cmp -s <(sed -E "$MASK" "$a/$f") <(sed -E "$MASK" "$b/$f") && continue ;;
            *) cmp -s "$a/$f" "$b/$f" && continue ;;
        esac
        echo "DIFFERENT ($what): $f"
        bad=$((bad + 1))
        status=1
    done < <(cd "$a" && find . -type f | sort)
    echo "$what: $n files compared, $bad different"
}

cores=$(nproc)
run_process() { # binary jobs -> output folder renamed to $work/$3
    rm -rf "$work/out"
    "$1" process "${inputs[@]}" --jobs "$2" --out "$work/out" > "$work/$3.stdout"
    mv "$work/out" "$work/$3"
}
run_process "$OLD" 1 old
run_process "$NEW" 1 new1
run_process "$NEW" "$cores" new-all
echo "radbench process of $captures captures:"
compare "$work/old" "$work/new1" "process, new --jobs 1"
compare "$work/old" "$work/new-all" "process, new --jobs $cores"

"$OLD" campaign run examples/accuracy.toml --allow-rf --out "$work/campaign-old" > /dev/null 2>&1
"$NEW" campaign run examples/accuracy.toml --allow-rf --out "$work/campaign-new" > /dev/null 2>&1
echo "radbench campaign run examples/accuracy.toml:"
compare "$work/campaign-old" "$work/campaign-new" "campaign" \
    '^(C[12]\.trc|capture\.sigmf-meta|summary\.json|manifest\.toml|io-journal\.jsonl)$'

if [ "$status" = 0 ]; then
    echo "SAME: every compared file is byte-identical"
else
    echo "NOT THE SAME"
fi
exit "$status"
