#!/usr/bin/env bash
# Interop checks: independent Python clients (pyvisa + pyvisa-py, pyvicp) against mock_lab, and
# independent readers (sigmf, numpy, h5py, lecroyparser, lecroyscope) of radbench's files, and radbench's
# readers on files other tools and real LeCroy scopes wrote, and the campaign report.html in headless
# Chromium (which .ci/run installs).
# Creates .venv-interop (gitignored) on first use, builds mock-lab, runs pytest on interop/.
# Exits non-zero on any failure, including "no tests collected".
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv-interop
PYTHON=${PYTHON:-python3}
if [ ! -x "$VENV/bin/python" ]; then
    echo "interop: creating $VENV"
    "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r interop/requirements.txt

# The binaries `cargo test --workspace` builds for its own tests (radbench with the `testing`
# feature its dev-dependency turns on: the test doubles, which change no command): after
# .ci/run's test step this compiles nothing. A plain `cargo build -p radbench` would compile
# radbench again without that feature (about 3 minutes of CI on 2 cores). Given both paths
# (MOCK_LAB_BIN, RADBENCH_BIN, as .ci/run gives them), nothing here runs cargo.
if [ -z "${MOCK_LAB_BIN:-}" ] || [ -z "${RADBENCH_BIN:-}" ]; then
    echo "interop: building mock-lab and radbench (as the tests build them)"
    cargo test --workspace --no-run --quiet
    # cargo's own target folder (CARGO_TARGET_DIR when set, as cargo itself does), made absolute.
    target_dir=${CARGO_TARGET_DIR:-target}
    case "$target_dir" in /*) ;; *) target_dir="$PWD/$target_dir" ;; esac
    export MOCK_LAB_BIN="$target_dir/debug/mock-lab"
    export RADBENCH_BIN="$target_dir/debug/radbench"
fi

set +e
"$VENV/bin/python" -m pytest -q -p no:cacheprovider interop
status=$?
set -e
if [ "$status" -eq 5 ]; then
    echo "interop: pytest collected no tests; treating that as a failure" >&2
    exit 1
fi
exit "$status"
