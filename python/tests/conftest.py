"""Shared fixtures: the radbench command line (RADBENCH_BIN, else `radbench` on PATH) and
captures it makes on its built-in mock lab (127.0.0.1 only), once per session."""

import json
import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

#: Every test must finish within this many seconds (SIGALRM fails it otherwise).
TEST_LIMIT_S = 180


@pytest.fixture(autouse=True)
def _time_limit():
    def expired(signum, frame):
        raise TimeoutError(f"test exceeded {TEST_LIMIT_S} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(TEST_LIMIT_S)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def radbench_bin() -> str:
    path = os.environ.get("RADBENCH_BIN") or shutil.which("radbench")
    if not path or not Path(path).exists():
        pytest.fail("the radbench binary is needed: set RADBENCH_BIN or put radbench on PATH")
    return path


def run(*args: str, timeout: float = 150) -> subprocess.CompletedProcess:
    done = subprocess.run([radbench_bin(), *args], capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"radbench {' '.join(args)}: {done.stderr}"
    return done


@pytest.fixture(scope="session")
def archive(tmp_path_factory):
    """Captures made by `radbench capture` on the built-in mock lab: MSK-LFM (with a payload),
    OFDM, and OFDM of two close targets processed with MUSIC."""
    root = tmp_path_factory.mktemp("archive")
    scene = root / "two.toml"
    scene.write_text(
        "snr_db = 30.0\nseed = 5\n\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\n"
        "[[targets]]\nrange_m = 1.12\namplitude = 0.4\n"
    )
    made = {
        "msk-lfm": ["--payload", "from python"],
        "ofdm": ["--waveform", "ofdm"],
        "music": ["--waveform", "ofdm", "--algorithm", "music", "--p", "2", "--scene", str(scene)],
    }
    out = {}
    for name, extra in made.items():
        folder = root / name
        run("capture", "--allow-rf", "--json", "--out", str(folder), *extra)
        out[name] = folder
    return out


def cli_process(inputs, *options, jobs=None):
    """`radbench process --json` of `inputs`: {folder name: summary}."""
    import tempfile

    out = Path(tempfile.mkdtemp()) / "out"
    args = ["process", *map(str, inputs), "--out", str(out), "--json", *options]
    if jobs:
        args += ["--jobs", str(jobs)]
    doc = json.loads(run(*args, timeout=600).stdout)
    assert not doc["failed"], doc["failed"]
    return {Path(p["dir"]).name: p["summary"] for p in doc["processed"]}
