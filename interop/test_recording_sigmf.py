"""radbench reads SigMF recordings written by the sigmf package (not by radbench): every complex
datatype and byte order it accepts, with and without radbench's `radbench:` namespace.

Each recording holds seeded random samples written with numpy and described with sigmf (which
adds `core:sha512`); sigmf reads it back (autoscale off: the stored values) as the reference.
`radbench recording --json --first N` must print the same first samples, counts, rate, datetime
and statistics. Corruptions (data changed after the hash, a cut data file, a missing data file,
an unsupported datatype) exit 2 naming the file and the field.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
import sigmf
from sigmf import SigMFFile
from sigmf.sigmffile import fromfile

REPO = pathlib.Path(__file__).resolve().parent.parent
RADBENCH = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))
FIRST = 32
SAMPLES = 1000

# SigMF datatype -> numpy dtype of one component.
DATATYPES = {
    "ci8": "i1",
    "cu8": "u1",
    "ci16_le": "<i2",
    "ci16_be": ">i2",
    "ci32_le": "<i4",
    "cu16_be": ">u2",
    "cf32_le": "<f4",
    "cf32_be": ">f4",
    "cf64_le": "<f8",
    "cf64_be": ">f8",
}


def components(datatype, seed):
    """SAMPLES interleaved I/Q components of the datatype, seeded."""
    rng = np.random.default_rng(seed)
    dtype = np.dtype(DATATYPES[datatype])
    if dtype.kind == "f":
        return (rng.standard_normal(2 * SAMPLES) * 0.3).astype(dtype)
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, size=2 * SAMPLES, endpoint=True).astype(dtype)


def write(folder, name, datatype, values, extra=None):
    base = folder / name
    values.tofile(f"{base}.sigmf-data")
    global_info = {sigmf.DATATYPE_KEY: datatype, sigmf.SAMPLE_RATE_KEY: 16e9}
    global_info.update(extra or {})
    meta = SigMFFile(data_file=f"{base}.sigmf-data", global_info=global_info)
    meta.add_capture(0, metadata={sigmf.DATETIME_KEY: "2026-11-21T19:55:00.000Z",
                                  sigmf.FREQUENCY_KEY: 80e9})
    meta.tofile(f"{base}.sigmf-meta")
    return base


def radbench_recording(path, *extra):
    done = subprocess.run(
        [RADBENCH, "recording", "--json", "--first", str(FIRST), str(path), *extra],
        capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )
    return done.returncode, json.loads(done.stdout) if done.stdout else None, done.stderr


def check_stats(ours, samples):
    i, q = samples.real.astype(np.float64), samples.imag.astype(np.float64)
    assert ours["mean_i"] == pytest.approx(i.mean(), rel=1e-9, abs=1e-12)
    assert ours["mean_q"] == pytest.approx(q.mean(), rel=1e-9, abs=1e-12)
    assert ours["rms_i"] == pytest.approx(np.sqrt(np.mean(i * i)), rel=1e-9)
    assert ours["rms_q"] == pytest.approx(np.sqrt(np.mean(q * q)), rel=1e-9)
    assert ours["rms"] == pytest.approx(np.sqrt(np.mean(i * i + q * q)), rel=1e-9)
    assert (ours["min_i"], ours["max_i"]) == (i.min(), i.max())
    assert (ours["min_q"], ours["max_q"]) == (q.min(), q.max())


@pytest.mark.parametrize("datatype", sorted(DATATYPES))
def test_sigmf_recordings_read_in_native_scale(tmp_path, datatype):
    values = components(datatype, seed=len(datatype) * 7919 + ord(datatype[-1]))
    base = write(tmp_path, datatype, datatype, values)
    reference = fromfile(str(base), autoscale=False).read_samples()
    # numpy's own reading of the interleaved components agrees with sigmf's (which hands out
    # complex64 for every type: cf64 and 32-bit integers come back rounded to float32).
    pairs = values.astype(np.float64).reshape(-1, 2)
    eps = np.finfo(reference.real.dtype).eps
    np.testing.assert_allclose(reference.real, pairs[:, 0], rtol=eps, atol=0)
    np.testing.assert_allclose(reference.imag, pairs[:, 1], rtol=eps, atol=0)

    code, doc, err = radbench_recording(f"{base}.sigmf-meta")
    assert code == 0, err
    ours = doc["recordings"][0]
    assert ours["datatype"] == datatype
    assert ours["unit"] == "native"
    assert ours["samples"] == SAMPLES
    assert ours["sample_rate_hz"] == 16e9
    assert ours["frequency_hz"] == 80e9
    assert ours["datetime"] == "2026-11-21T19:55:00.000Z"
    assert ours["sha512_checked"] is True
    np.testing.assert_array_equal(np.asarray(ours["first_samples"]), pairs[:FIRST])
    check_stats(ours["stats"], pairs[:, 0] + 1j * pairs[:, 1])


@pytest.mark.parametrize("datatype", ["ci16_le", "ci16_be", "ci8", "cf32_be"])
def test_radbench_namespace_gives_volts(tmp_path, datatype):
    values = components(datatype, seed=11)
    gain, offset = [2.5e-5, 3.0e-5], [0.01, -0.02]
    base = write(tmp_path, "ours", datatype, values, {
        sigmf.EXTENSIONS_KEY: [{"name": "radbench", "version": "1.0.0", "optional": True}],
        "radbench:vertical_gain": gain,
        "radbench:vertical_offset": offset,
        "radbench:trigger_offset_s": -1.25e-9,
        "radbench:waveform": {"kind": "msk-lfm"},
    })
    fromfile(str(base)).validate()
    code, doc, err = radbench_recording(base)  # the base name works too
    assert code == 0, err
    ours = doc["recordings"][0]
    assert ours["unit"] == "volts"
    assert ours["radbench"]["trigger_offset_s"] == -1.25e-9
    assert ours["radbench"]["waveform"]["kind"] == "msk-lfm"
    assert ours["extensions"] == [{"name": "radbench", "version": "1.0.0", "optional": True}]
    pairs = values.astype(np.float64).reshape(-1, 2)
    volts = gain[0] * pairs[:, 0] - offset[0] + 1j * (gain[1] * pairs[:, 1] - offset[1])
    got = np.asarray(ours["first_samples"])
    np.testing.assert_allclose(got[:, 0], volts.real[:FIRST], rtol=1e-15, atol=1e-18)
    np.testing.assert_allclose(got[:, 1], volts.imag[:FIRST], rtol=1e-15, atol=1e-18)
    check_stats(ours["stats"], volts)


def test_bad_recordings_exit_2_naming_file_and_field(tmp_path):
    values = components("ci16_le", seed=3)
    changed = write(tmp_path, "changed", "ci16_le", values)
    data = pathlib.Path(f"{changed}.sigmf-data")
    raw = bytearray(data.read_bytes())
    raw[0] ^= 0xFF
    data.write_bytes(bytes(raw))
    cut = write(tmp_path, "cut", "ci16_le", values)
    pathlib.Path(f"{cut}.sigmf-data").write_bytes(values.tobytes()[:-3])
    # Without the hash, so the length check speaks.
    meta = json.loads(pathlib.Path(f"{cut}.sigmf-meta").read_text())
    del meta["global"]["core:sha512"]
    pathlib.Path(f"{cut}.sigmf-meta").write_text(json.dumps(meta))
    lonely = write(tmp_path, "lonely", "ci16_le", values)
    pathlib.Path(f"{lonely}.sigmf-data").unlink()
    real = write(tmp_path, "real", "rf32_le", components("cf32_le", seed=4))

    cases = [
        (changed, "changed.sigmf-data", "core:sha512"),
        (cut, "cut.sigmf-data", "not a whole number"),
        (lonely, "lonely.sigmf-data", "cannot be read"),
        (real, "real.sigmf-meta", "core:datatype"),
    ]
    for base, file_name, field in cases:
        done = subprocess.run([RADBENCH, "recording", f"{base}.sigmf-meta"], capture_output=True,
                              text=True, timeout=60, stdin=subprocess.DEVNULL)
        assert done.returncode == 2, (file_name, done.stderr)
        assert file_name in done.stderr and field in done.stderr, done.stderr
