"""Shared fixtures: a running `mock-lab serve --json` and a hard per-test time limit."""

import json
import os
import select
import signal
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
#: Every test must finish within this many seconds (SIGALRM fails it otherwise).
TEST_LIMIT_S = 120
#: Time allowed for mock-lab to print its endpoints.
STARTUP_LIMIT_S = 60


def _binary() -> str:
    path = os.environ.get("MOCK_LAB_BIN", str(REPO / "target" / "debug" / "mock-lab"))
    if not Path(path).exists():
        pytest.fail(f"mock-lab binary not found at {path}; run `cargo build -p mock_lab --bin mock-lab` "
                    "or interop/run.sh")
    return path


@pytest.fixture(autouse=True)
def _time_limit():
    def expired(signum, frame):
        raise TimeoutError(f"test exceeded {TEST_LIMIT_S} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(TEST_LIMIT_S)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope="session")
def endpoints():
    """Starts mock-lab, yields {transport: endpoint dict} for the loopback instrument."""
    proc = subprocess.Popen(
        [_binary(), "serve", "--json"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=None,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], STARTUP_LIMIT_S)
        if not ready:
            pytest.fail(f"mock-lab printed no endpoints within {STARTUP_LIMIT_S} s")
        line = proc.stdout.readline()
        if not line:
            pytest.fail(f"mock-lab exited before printing endpoints (status {proc.poll()})")
        listing = json.loads(line)
        by_transport = {
            e["transport"]: e for e in listing["endpoints"] if e["instrument"] == "loopback"
        }
        yield by_transport
    finally:
        # End of stdin asks mock-lab to stop; kill it if it does not.
        try:
            proc.stdin.close()
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
