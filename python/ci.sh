#!/usr/bin/env bash
# CI of the Python package (python/): lints its Rust crate, builds the wheel with maturin in a
# fresh venv, installs it into another fresh venv and runs python/tests (the pyvisa-py scripts
# against MockLab and the mock_lab fixture, process against `radbench process`, read_run, the
# Dask example). Called by .ci/run after the interop checks; prints how long the wheel took.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
# One target folder with the workspace: the Python crate's checks reuse its dependencies.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
PYTHON=${PYTHON:-python3}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

echo "python: cargo fmt and clippy of python/"
(cd python && cargo fmt -- --check && cargo clippy --all-targets --quiet -- -D warnings)

# The dev profile, as the workspace's tests: it reuses their optimised dependencies from the
# shared target folder instead of a second, release build of radbench and everything under it
# (minutes on 2 cores). The code is the same; users' `pip install ./python` builds the release
# profile, whose speed docs/python.md measures.
echo "python: building the wheel (maturin, dev profile of python/Cargo.toml)"
"$PYTHON" -m venv "$WORK/build"
"$WORK/build/bin/python" -m pip install --quiet --disable-pip-version-check maturin==1.16.0
started=$SECONDS
"$WORK/build/bin/maturin" build --profile dev --quiet --manifest-path python/Cargo.toml \
    --interpreter "$WORK/build/bin/python" --out "$WORK/wheels"
echo "python: wheel built in $((SECONDS - started)) s: $(ls "$WORK/wheels")"

# The binary the tests build (see interop/run.sh): nothing to compile after them (.ci/run
# gives its path).
if [ -z "${RADBENCH_BIN:-}" ]; then
    cargo test --workspace --no-run --quiet
    export RADBENCH_BIN="$CARGO_TARGET_DIR/debug/radbench"
fi

# python/tests with one venv's Python, its output into a file ($2); pytest's "no tests
# collected" counts as a failure.
run_tests() {
    local status
    # From outside python/, so that the installed package is the one imported.
    (cd "$WORK" && "$1" -m pytest -q -p no:cacheprovider "$ROOT/python/tests") >"$2" 2>&1 && return 0
    status=$?
    [ "$status" -eq 5 ] && echo "python: pytest collected no tests; treating that as a failure" >>"$2"
    return 1
}

# The oldest Python the package supports (requires-python >= 3.9; the wheel is abi3-py39), when
# this machine has it (on PATH or from pyenv): the same wheel and tests, with the newest releases
# of the test tools that still install there. The two ends, 3.9 and the venv's own (3.11 here),
# stand for the versions between them (one abi3 wheel; 3.10 ran the same 43 tests green until
# 2026-12-06, and cost CI two minutes). pyenv's own copy first: its shim on PATH fails unless
# that version is selected.
older=$(ls -d "${PYENV_ROOT:-$HOME/.pyenv}/versions/3.9".*/bin/python 2>/dev/null |
    tail -n 1 || command -v python3.9 || true)
if [ -n "$older" ] && ! "$older" -c "" 2>/dev/null; then
    older=""
fi

# Both versions side by side: the tests wait on their simulated benches and subprocesses more
# than they compute (a load of about 1 on 2 cores), so together they take little more than one.
echo "python: installing it into a fresh venv${older:+ and one of Python 3.9 ($older)}"
"$PYTHON" -m venv "$WORK/test"
"$WORK/test/bin/python" -m pip install --quiet --disable-pip-version-check \
    "$WORK"/wheels/*.whl -r python/tests/requirements.txt &
installs=($!)
if [ -n "$older" ]; then
    "$older" -m venv "$WORK/test-3.9"
    "$WORK/test-3.9/bin/python" -m pip install --quiet --disable-pip-version-check \
        "$WORK"/wheels/*.whl -r python/tests/requirements-older-python.txt &
    installs+=($!)
fi
for pid in "${installs[@]}"; do wait "$pid"; done

echo "python: python/tests${older:+ on $("$PYTHON" -V) and on Python 3.9, side by side}"
run_tests "$WORK/test/bin/python" "$WORK/tests.log" &
runs=($!)
if [ -n "$older" ]; then
    run_tests "$WORK/test-3.9/bin/python" "$WORK/tests-3.9.log" &
    runs+=($!)
else
    echo "python: no Python 3.9 on this machine: its run of python/tests is skipped"
fi
failed=0
for pid in "${runs[@]}"; do wait "$pid" || failed=1; done
for log in "$WORK"/tests*.log; do
    echo "python: $(basename "$log" .log):"
    cat "$log"
done
[ "$failed" -eq 0 ]

echo "python: the example notebook python/examples/bench.ipynb, executed headless (nbclient)"
"$WORK/test/bin/python" -m pip install --quiet --disable-pip-version-check \
    -r python/tests/requirements-notebook.txt
(cd "$WORK" && "$WORK/test/bin/python" - "$ROOT/python/examples/bench.ipynb" <<'EOF'
import sys

import nbformat
from nbclient import NotebookClient

nb = nbformat.read(sys.argv[1], as_version=4)
NotebookClient(nb, timeout=300, kernel_name="python3").execute()
print(f"python: the notebook ran its {len(nb.cells)} cells")
EOF
)
