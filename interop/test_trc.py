"""lecroyparser reads .trc files saved from mock_lab's LeCroy emulator (WORD little-endian on C1, BYTE
big-endian on C2) and by radbench's LeCroy driver (captured over VICP), and gets the same volts and
times as the emulator recorded and as radbench decoded.

Needs: numpy, lecroyparser, pytest, and cargo on PATH (the example is built on the fly).
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

lecroyparser = pytest.importorskip("lecroyparser")

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def trc_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("trc")
    cargo = os.environ.get("CARGO", "cargo")
    subprocess.run(
        [cargo, "run", "-q", "-p", "mock_lab", "--example", "write_trc", "--", str(out)],
        cwd=ROOT,
        check=True,
        timeout=600,
    )
    return out


@pytest.mark.parametrize("channel", ["C1", "C2"])
def test_lecroyparser_reads_emulator_trc(trc_dir, channel):
    expected = json.loads((trc_dir / "expected.json").read_text())[channel]
    data = lecroyparser.ScopeData(str(trc_dir / f"{channel}.trc"))
    volts = np.asarray(expected["volts"])
    times = np.asarray(expected["times"])
    assert data.templateName.startswith("LECROY_2_3")
    assert data.waveArrayCount == len(volts)
    assert data.nominalBits == 8
    # Volts: identical up to float32 storage of VERTICAL_GAIN / VERTICAL_OFFSET.
    np.testing.assert_allclose(data.y, volts, rtol=1e-6, atol=1e-9)
    # Times: lecroyparser builds its axis with linspace(0, N*dt, N) + HORIZ_OFFSET, which stretches
    # the spacing by N/(N-1); the start is exact and no point is off by more than one interval.
    assert data.x[0] == pytest.approx(times[0], abs=1e-15)
    assert np.max(np.abs(data.x - times)) <= expected["interval"] * 1.001


@pytest.fixture(scope="module")
def radbench_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("radbench_trc")
    cargo = os.environ.get("CARGO", "cargo")
    subprocess.run(
        [cargo, "run", "-q", "--example", "lecroy_trc", "--", str(out)],
        cwd=ROOT,
        check=True,
        timeout=600,
    )
    return out


@pytest.mark.parametrize("channel", ["C1", "C2"])
def test_lecroyparser_and_radbench_agree(radbench_dir, channel):
    """A .trc saved by radbench's LeCroy driver (captured over VICP from the emulator) decodes to the
    same volts and times in lecroyparser as in radbench."""
    ours = json.loads((radbench_dir / "radbench.json").read_text())[channel]
    data = lecroyparser.ScopeData(str(radbench_dir / f"rb_{channel}.trc"))
    volts = np.asarray(ours["volts"])
    times = np.asarray(ours["times"])
    assert len(data.y) == len(volts) == 2000
    np.testing.assert_allclose(data.y, volts, rtol=1e-6, atol=1e-9)
    assert data.x[0] == pytest.approx(times[0], abs=1e-15)
    assert np.max(np.abs(data.x - times)) <= ours["interval"] * 1.001
