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

echo "python: building the wheel (maturin, release profile of python/Cargo.toml)"
"$PYTHON" -m venv "$WORK/build"
"$WORK/build/bin/python" -m pip install --quiet --disable-pip-version-check maturin==1.16.0
started=$SECONDS
"$WORK/build/bin/maturin" build --release --quiet --manifest-path python/Cargo.toml \
    --interpreter "$WORK/build/bin/python" --out "$WORK/wheels"
echo "python: wheel built in $((SECONDS - started)) s: $(ls "$WORK/wheels")"

echo "python: installing it into a fresh venv"
"$PYTHON" -m venv "$WORK/test"
"$WORK/test/bin/python" -m pip install --quiet --disable-pip-version-check \
    "$WORK"/wheels/*.whl -r python/tests/requirements.txt

cargo build --quiet -p radbench --bin radbench
export RADBENCH_BIN="$CARGO_TARGET_DIR/debug/radbench"
# From outside python/, so that the installed package is the one imported.
cd "$WORK"
set +e
"$WORK/test/bin/python" -m pytest -q -p no:cacheprovider "$ROOT/python/tests"
status=$?
set -e
if [ "$status" -eq 5 ]; then
    echo "python: pytest collected no tests; treating that as a failure" >&2
    exit 1
fi
exit "$status"
