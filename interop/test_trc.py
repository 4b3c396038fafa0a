"""lecroyparser reads .trc files saved from mock_lab's LeCroy emulator and gets the emulator's volts
and times (WORD little-endian on C1, BYTE big-endian on C2).

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
