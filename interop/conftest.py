"""Shared fixtures: a running `mock-lab serve --json` and a hard per-test time limit."""

import json
import os
import select
import signal
import subprocess
import sys
import tempfile
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


class MockLab:
    """A running `mock-lab serve --json`: its endpoints for the loopback instrument."""

    def __init__(self, *extra_args: str):
        # stderr goes to a file, never to an unread pipe: a full pipe would stall the server.
        # MOCK_LAB_LOG names a file to keep (with RUST_LOG=mock_lab=debug, say) when debugging.
        log_path = os.environ.get("MOCK_LAB_LOG")
        self.log = open(log_path, "w+b") if log_path else tempfile.TemporaryFile()
        self.proc = subprocess.Popen(
            [_binary(), "serve", "--json", *extra_args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
        )
        ready, _, _ = select.select([self.proc.stdout], [], [], STARTUP_LIMIT_S)
        if not ready:
            self.stop()
            raise RuntimeError(f"mock-lab printed no endpoints within {STARTUP_LIMIT_S} s")
        line = self.proc.stdout.readline()
        if not line:
            status = self.proc.wait(timeout=10)
            self.log.seek(0)
            self.error = self.log.read().decode(errors="replace")
            raise RuntimeError(f"mock-lab exited with status {status}: {self.error}")
        listing = json.loads(line)
        self.endpoints = {
            e["transport"]: e for e in listing["endpoints"] if e["instrument"] == "loopback"
        }

    def stop(self):
        # End of stdin asks mock-lab to stop; kill it if it does not.
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)
        self.log.close()


def radbench_binary() -> str:
    path = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))
    if not Path(path).exists():
        pytest.fail(f"radbench binary not found at {path}; run `cargo build -p radbench` or interop/run.sh")
    return path


class ForeignServer:
    """A server script from interop/servers/, run with this interpreter: the first line it
    prints is a JSON description of where it listens. Killed (and waited for) on stop."""

    def __init__(self, script: str):
        self.log = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(
            [sys.executable, str(REPO / "interop" / "servers" / script)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self.log,
        )
        ready, _, _ = select.select([self.proc.stdout], [], [], STARTUP_LIMIT_S)
        line = self.proc.stdout.readline() if ready else b""
        if not line:
            self.stop()
            self.log.seek(0)
            raise RuntimeError(f"{script} did not start: {self.log.read().decode(errors='replace')}")
        self.info = json.loads(line)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)


@pytest.fixture(scope="session")
def endpoints():
    """Starts mock-lab on OS-chosen ports, yields {transport: endpoint dict}."""
    lab = MockLab()
    try:
        yield lab.endpoints
    finally:
        lab.stop()
