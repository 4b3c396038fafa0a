"""radbench capture's files read by independent tools: the sigmf package validates the SigMF
recording, numpy reads the .npy range profile, lecroyparser reads the saved .trc traces.

Runs `radbench capture` on the built-in mock lab (127.0.0.1 only) into a temporary folder.
"""

import json
import os
import pathlib
import subprocess

import lecroyparser
import numpy as np
import pytest
import sigmf
from sigmf import sigmffile

REPO = pathlib.Path(__file__).resolve().parent.parent
RADBENCH = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    out = tmp_path_factory.mktemp("capture")
    done = subprocess.run(
        [RADBENCH, "capture", "--allow-rf", "--json", "--payload", "interop", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_sigmf_package_validates_the_recording(capture):
    meta = capture["files"]["sigmf_meta"]
    recording = sigmffile.fromfile(meta)
    recording.validate()
    assert recording.get_global_field("core:datatype") == "ci16_le"
    assert recording.get_global_field("core:sample_rate") == 80e9
    samples = recording.read_samples()
    assert samples.dtype.kind == "c" and samples.size > 0
    # The radbench namespace turns the raw words back into volts.
    gain = recording.get_global_field("radbench:vertical_gain")
    raw = np.fromfile(capture["files"]["sigmf_data"], dtype="<i2").reshape(-1, 2)
    assert raw.shape[0] == samples.size
    assert gain[0] > 0 and gain[1] > 0
    truth = recording.get_global_field("radbench:scene")
    assert truth["targets"][0]["range_m"] == capture["scene"]["targets"][0]["range_m"]


def test_numpy_reads_the_range_profile(capture):
    profile = np.load(capture["files"]["profile_npy"])
    assert profile.ndim == 2 and profile.shape[0] > 100
    ranges = profile[:, 0]
    peak = ranges[np.argmax(profile[:, 1])]
    assert abs(peak - capture["targets"][0]["range_m"]) < 0.01
    csv = np.loadtxt(capture["files"]["profile_csv"], delimiter=",", skiprows=1)
    np.testing.assert_allclose(csv, profile, rtol=1e-12)


def test_lecroyparser_reads_the_saved_traces(capture):
    for path in capture["files"]["trc"]:
        trace = lecroyparser.ScopeData(path)
        assert len(trace.y) > 1000
        assert np.isfinite(trace.y).all()


def test_payload_and_target(capture):
    assert capture["payload"]["text"] == "interop"
    assert len(capture["targets"]) == 1
    assert abs(capture["targets"][0]["range_m"] - capture["scene"]["targets"][0]["range_m"]) < 1e-3
