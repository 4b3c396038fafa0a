"""`radbench export` read by numpy (allow_pickle=False) and h5py, and a campaign's results.csv read
by the csv module: the arrays have the documented names, shapes and units, and equal what radbench
itself wrote (summary.json, profile.npy, results.json).

Runs `radbench capture` and `radbench campaign run` on the built-in mock lab (127.0.0.1 only) into
temporary folders.
"""

import csv
import json
import os
import pathlib
import subprocess

import h5py
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
RADBENCH = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))
C0 = 299_792_458.0

SCENE = """snr_db = 30.0
[[targets]]
range_m = 1.0
amplitude = 0.5
[[targets]]
range_m = 2.0
amplitude = 0.3
"""


def radbench(*args, cwd):
    done = subprocess.run(
        [RADBENCH, *args],
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
        cwd=cwd,
    )
    assert done.returncode == 0, f"radbench {args}: {done.stderr}"
    return done


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A two-target capture of two repetitions carrying a payload, exported both ways."""
    d = tmp_path_factory.mktemp("export")
    (d / "scene.toml").write_text(SCENE)
    radbench("capture", "--allow-rf", "--scene", "scene.toml", "--repetitions", "2",
             "--payload", "interop", "--out", "cap", cwd=d)
    radbench("export", "cap", "--npz", cwd=d)
    radbench("export", "cap", "--hdf5", cwd=d)
    summary = json.loads((d / "cap" / "summary.json").read_text())
    return d, summary


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The accuracy campaign, exported both ways."""
    d = tmp_path_factory.mktemp("run")
    radbench("campaign", "run", str(REPO / "examples" / "accuracy.toml"), "--allow-rf",
             "--out", "run", cwd=d)
    radbench("export", "run", "--npz", cwd=d)
    radbench("export", "run", "--hdf5", cwd=d)
    results = json.loads((d / "run" / "results.json").read_text())
    return d, results


def test_the_npz_loads_without_pickles_with_the_documented_names(capture):
    d, summary = capture
    data = np.load(d / "cap.npz", allow_pickle=False)
    for name in ["iq", "iq_rate_hz", "iq_t0_s", "iq_processed", "range_m", "profile",
                 "profile_amplitude", "profile_label", "targets", "reference", "bits", "payload",
                 "metadata"]:
        assert name in data.files, name
    meta = json.loads(str(data["metadata"]))
    assert meta["format"] == "radbench export"
    assert meta["processing"] == summary["processing"]
    assert meta["units"]["iq"] == "V" and meta["units"]["range_m"] == "m"


def test_the_decimated_iq_has_its_length_and_rate(capture):
    d, summary = capture
    data = np.load(d / "cap.npz", allow_pickle=False)
    iq = data["iq"]
    rate = float(data["iq_rate_hz"])
    scope = summary["applied"]["scope"]
    # 80 GSa/s decimated to the waveform's 16 GSa/s: one period per repetition.
    assert iq.dtype == np.complex128
    assert rate == summary["transmission"]["sample_rate_hz"] == 16e9
    assert iq.shape == (2, scope["points"] * rate / scope["sample_rate_hz"])
    assert iq.shape[1] == summary["applied"]["segment"]["padded_samples"]
    assert data["iq_t0_s"].shape == (2,)
    assert data["iq_processed"].shape == (iq.shape[1],)
    # Volts at the scope: well inside its range, not codes.
    assert 0 < np.abs(iq).max() < 1.0


def test_the_profile_peaks_at_the_scene_targets_within_a_cell(capture):
    d, summary = capture
    data = np.load(d / "cap.npz", allow_pickle=False)
    r, z = data["range_m"], data["profile"]
    cell = r[1] - r[0]
    assert z.dtype == np.complex128 and z.shape == r.shape
    np.testing.assert_allclose(np.abs(z), data["profile_amplitude"], rtol=1e-12)
    truth = sorted(t["range_m"] for t in summary["scene"]["targets"])
    # The strongest cell is the strongest target's; the other target has its local peak near it.
    assert abs(r[np.argmax(np.abs(z))] - truth[0]) <= cell
    for t in truth:
        near = np.abs(r - t) <= 2 * cell
        peak = r[near][np.argmax(np.abs(z[near]))]
        assert abs(peak - t) <= cell, (t, peak)


def test_the_arrays_equal_radbenchs_own_files(capture):
    d, summary = capture
    data = np.load(d / "cap.npz", allow_pickle=False)
    table = np.load(d / "cap" / "profile.npy")
    np.testing.assert_array_equal(data["range_m"], table[:, 0])
    np.testing.assert_allclose(20 * np.log10(np.maximum(data["profile_amplitude"], 1e-300)),
                               table[:, 1], rtol=1e-12, atol=1e-12)
    targets = data["targets"]
    assert list(targets["range_m"]) == [t["range_m"] for t in summary["targets"]]
    assert list(targets["level_db"]) == [t["level_db"] for t in summary["targets"]]
    # What was sent: every bit, the payload's bytes, one repetition of the reference.
    assert data["bits"].dtype == np.uint8
    assert data["bits"].shape == (summary["transmission"]["bits"],)
    assert set(np.unique(data["bits"])) <= {0, 1}
    assert bytes(data["payload"]) == b"interop"
    assert data["reference"].shape == (summary["transmission"]["samples_per_repetition"],)


def test_h5py_reads_the_same_arrays(capture):
    d, _ = capture
    data = np.load(d / "cap.npz", allow_pickle=False)
    with h5py.File(d / "cap.h5", "r") as f:
        assert set(f.keys()) == set(data.files)
        for name in data.files:
            a, b = data[name], f[name][()]
            if a.dtype.kind == "U":
                assert b.decode() == str(a), name
            elif a.dtype.names:
                # A table: column by column (NaN, an absent value, equals NaN there).
                assert b.dtype == a.dtype, name
                for column in a.dtype.names:
                    np.testing.assert_array_equal(b[column], a[column], err_msg=column)
            else:
                assert b.dtype == a.dtype, name
                np.testing.assert_array_equal(b, a, err_msg=name)
        assert f["iq"].attrs["units"] == b"V"
        assert f["range_m"].attrs["units"] == b"m"


def test_results_csv_rows_are_results_json(run):
    d, results = run
    with open(d / "run" / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(results["steps"])
    for row, step in zip(rows, results["steps"]):
        a = step["algorithms"][row["algorithm"]]
        assert int(row["step"]) == step["index"]
        assert float(row["nominal_m"]) == step["nominal"]["targets"][0]["range_m"]
        assert float(row["truth_m"]) == step["truth"]["targets"][0]["range_m"]
        assert float(row["range_m"]) == a["targets"][0]["range_m"]
        assert float(row["on_grid_m"]) == a["targets"][0]["on_grid_m"]
        assert float(row["error_m"]) == a["error_m"]
        assert float(row["truth_error_m"]) == a["truth_error_m"]
        for key in ["width_3db_cm", "sidelobe_db", "snr_db"]:
            assert float(row[key]) == a[key], key
        assert int(row["bit_errors"]) == a["payload"]["bit_errors"]
        assert float(row["ber"]) == a["payload"]["ber"]
        assert row["missed"] == "false"


def test_a_run_exports_a_group_per_step(run):
    d, results = run
    data = np.load(d / "run.npz", allow_pickle=False)
    meta = json.loads(str(data["metadata"]))
    assert meta["steps"] == [f"step-{s['index']:03d}" for s in results["steps"]]
    with h5py.File(d / "run.h5", "r") as f:
        for step in results["steps"]:
            group = f"step-{step['index']:03d}"
            found = [t["range_m"] for t in step["algorithms"]["correlation"]["targets"]]
            assert list(data[f"{group}/targets"]["range_m"]) == found
            assert list(f[group]["targets"]["range_m"]) == found
            np.testing.assert_array_equal(f[group]["iq"][()], data[f"{group}/iq"])
            cell = C0 / (2 * float(data[f"{group}/iq_rate_hz"]))
            r, z = data[f"{group}/range_m"], data[f"{group}/profile"]
            truth = step["truth"]["targets"][0]["range_m"]
            assert abs(r[np.argmax(np.abs(z))] - truth) <= cell
