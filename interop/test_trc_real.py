"""radbench reads .trc files from real LeCroy scopes as lecroyscope and lecroyparser do.

The files are the ones shipped in the lecroyscope sdist's tests (fetched from PyPI at test time,
cached under .venv-interop/, never committed):

| file | what it is |
|---|---|
| pulse.trc | WaveRunner 64Xi-A, 502 points, 16-bit words (8 nominal bits), LOFIRST |
| pulse_sequence.trc | the same scope in sequence mode: 20 segments of 502 points, TRIGTIME array |
| issue_1.trc | WavePro 254HD, 100 002 points, 16-bit words (14 nominal bits) |
| header.trc | a 200-segment sequence cut after its descriptor (a truncated file) |

From pulse_sequence.trc the tests also derive, with struct and the template's field types, an
8-bit (COMM_TYPE 0) copy, a HIFIRST copy, one behind a `C1:WF ALL,` prefix and one without the
`#9` header, so every variant carries real scope data.

radbench's reading is `radbench trc --json --points N` (the first and last N volts and times of
each segment, each segment's trigger time and offset, statistics of all points).

Reference quirks, checked against the bytes: lecroyscope reads samples and TRIGTIME doubles in the
machine's byte order (so it misreads HIFIRST files: those are compared with its reading of the
LOFIRST original), and it gives every segment the time axis of HORIZ_OFFSET, while LeCroy stores
each segment's own TRIGGER_OFFSET (radbench uses that: the difference is checked to be exactly
the stored offset difference, under one sample interval). lecroyparser ignores segments (one flat
array) and stretches its time axis by N/(N-1).
"""

import datetime
import importlib.metadata
import json
import os
import pathlib
import shutil
import struct
import subprocess
import sys
import tarfile

import lecroyparser
import lecroyscope
import numpy as np
import pytest
from lecroyscope.reading.header import trc_description

REPO = pathlib.Path(__file__).resolve().parent.parent
RADBENCH = os.environ.get("RADBENCH_BIN", str(REPO / "target" / "debug" / "radbench"))
CACHE = REPO / ".venv-interop" / "sdist-cache"
#: Enough points to get every point of the 502-point segments.
POINTS = 600
REAL = ["pulse.trc", "pulse_sequence.trc", "issue_1.trc"]


@pytest.fixture(scope="session")
def real_files(tmp_path_factory):
    """The lecroyscope sdist's tests/files, extracted into a temporary folder."""
    version = importlib.metadata.version("lecroyscope")
    name = f"lecroyscope-{version}.tar.gz"
    sdist = CACHE / name
    if not sdist.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        download = tmp_path_factory.mktemp("sdist")
        done = subprocess.run(
            [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
             "--no-deps", "--no-binary", ":all:", f"lecroyscope=={version}", "-d", str(download)],
            capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL,
        )
        assert done.returncode == 0, f"cannot fetch the lecroyscope sdist from PyPI: {done.stderr}"
        shutil.move(str(download / name), sdist)
    out = tmp_path_factory.mktemp("lecroyscope_files")
    with tarfile.open(sdist) as tar:
        members = [m for m in tar.getmembers()
                   if "/tests/files/" in m.name and m.name.endswith(".trc") and m.isfile()]
        assert len(members) >= 4, [m.name for m in members]
        for m in members:
            (out / pathlib.Path(m.name).name).write_bytes(tar.extractfile(m).read())
    return out


def radbench_trc(*paths, points=POINTS):
    done = subprocess.run(
        [RADBENCH, "trc", "--json", "--points", str(points), *map(str, paths)],
        capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )
    return done.returncode, json.loads(done.stdout) if done.stdout else None, done.stderr


def read_ours(path):
    code, doc, err = radbench_trc(path)
    assert code == 0, err
    assert doc["errors"] == []
    return doc["traces"][0]


def reference(path):
    """lecroyscope's volts (segments x points), time axis, trigger times and header."""
    trace = lecroyscope.Trace(path)
    volts = np.atleast_2d(trace.voltage)
    return trace, volts


def check_against_lecroyscope(ours, trace, volts, compare_trigtime=True):
    h = trace.header
    assert ours["header"]["instrument_name"] == h["instrument_name"]
    assert ours["header"]["wave_array_count"] == h["wave_array_count"]
    assert ours["header"]["vertical_gain"] == h["vertical_gain"]
    assert ours["header"]["vertical_offset"] == h["vertical_offset"]
    assert ours["header"]["horiz_interval"] == h["horiz_interval"]
    assert ours["header"]["horiz_offset"] == h["horiz_offset"]
    assert ours["header"]["nominal_bits"] == h["nominal_bits"]
    assert ours["channel"] == h["wave_source"] + 1
    theirs_time = datetime.datetime.fromisoformat(h["trigger_time"])
    assert datetime.datetime.fromisoformat(ours["trigger_time"]) == theirs_time
    assert ours["segment_count"] == len(trace) == volts.shape[0]
    assert ours["points_per_segment"] == volts.shape[1]
    n = min(POINTS, volts.shape[1])
    for k, seg in enumerate(ours["segments"]):
        v = volts[k]
        # The same arithmetic (f64 gain x code - offset) in both: identical values.
        np.testing.assert_array_equal(seg["first_volts"], v[:n])
        np.testing.assert_array_equal(seg["last_volts"], v[-n:])
        if trace.sequence and compare_trigtime:
            trig_time, trig_offset = trace.trigger_times[0][k], trace.trigger_times[1][k]
            assert seg["trigger_time_s"] == trig_time
            assert seg["trigger_offset_s"] == trig_offset
        # lecroyscope: one axis from HORIZ_OFFSET; radbench: this segment's TRIGGER_OFFSET.
        shift = seg["trigger_offset_s"] - h["horiz_offset"]
        assert abs(shift) < h["horiz_interval"]
        np.testing.assert_allclose(seg["first_times_s"], trace.time[:n] + shift, rtol=0, atol=1e-18)
        np.testing.assert_allclose(seg["last_times_s"], trace.time[-n:] + shift, rtol=0, atol=1e-18)
        stats = seg["stats"]
        assert stats["min_v"] == v.min() and stats["max_v"] == v.max()
        assert stats["mean_v"] == pytest.approx(v.mean(), rel=1e-9, abs=1e-12)
        assert stats["rms_v"] == pytest.approx(np.sqrt(np.mean(v * v)), rel=1e-9)
    flat = volts.ravel()
    assert ours["stats"]["mean_v"] == pytest.approx(flat.mean(), rel=1e-9, abs=1e-12)
    assert ours["stats"]["rms_v"] == pytest.approx(np.sqrt(np.mean(flat * flat)), rel=1e-9)


def check_against_lecroyparser(ours, path):
    data = lecroyparser.ScopeData(str(path))
    seg_len = ours["points_per_segment"]
    assert len(data.y) == ours["points"]
    # lecroyparser scales in float32 (gain x code - offset): a few float32 ulps of the larger term.
    scale = abs(ours["header"]["vertical_offset"]) + np.max(np.abs(data.y))
    atol = 4 * np.finfo(np.float32).eps * scale
    for k, seg in enumerate(ours["segments"]):
        theirs = data.y[k * seg_len:(k + 1) * seg_len]
        n = len(seg["first_volts"])
        np.testing.assert_allclose(seg["first_volts"], theirs[:n], rtol=0, atol=atol)
        np.testing.assert_allclose(seg["last_volts"], theirs[-n:], rtol=0, atol=atol)
    assert data.x[0] == ours["header"]["horiz_offset"] == ours["segments"][0]["first_times_s"][0]
    if ours["segment_count"] == 1:
        n = len(ours["segments"][0]["first_times_s"])
        dt = ours["sample_interval_s"]
        assert np.max(np.abs(data.x[:n] - ours["segments"][0]["first_times_s"])) <= dt


@pytest.mark.parametrize("name", REAL)
def test_real_files_match_lecroyscope(real_files, name):
    path = real_files / name
    trace, volts = reference(path)
    check_against_lecroyscope(read_ours(path), trace, volts)


@pytest.mark.parametrize("name", REAL)
def test_real_files_match_lecroyparser(real_files, name):
    path = real_files / name
    check_against_lecroyparser(read_ours(path), path)


def test_sequence_is_seen_as_segments(real_files):
    ours = read_ours(real_files / "pulse_sequence.trc")
    assert ours["segment_count"] == 20
    assert ours["points_per_segment"] == 502
    assert len(ours["segments"]) == 20
    times = [s["trigger_time_s"] for s in ours["segments"]]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:]))
    text = subprocess.run([RADBENCH, "trc", str(real_files / "pulse_sequence.trc")],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert text.returncode == 0, text.stderr
    assert "10040 in 20 segments of 502" in text.stdout


def test_truncated_file_is_a_clear_error(real_files):
    path = real_files / "header.trc"
    # lecroyscope reads its header: a 200-segment sequence whose arrays are missing.
    header = lecroyscope.Trace(path, header_only=True).header
    assert header["subarray_count"] == 200 and header["wave_array1"] == 800800
    code, doc, err = radbench_trc(path)
    assert code == 2, err
    assert doc["traces"] == []
    assert doc["errors"][0]["file"].endswith("header.trc")
    message = doc["errors"][0]["error"]
    assert "truncated" in message and "TRIGTIME_ARRAY" in message, message
    assert f"holds {path.stat().st_size}" in message, message
    done = subprocess.run([RADBENCH, "trc", str(path)], capture_output=True, text=True,
                          timeout=60, stdin=subprocess.DEVNULL)
    assert done.returncode == 2
    assert "header.trc" in done.stderr and "TRIGTIME_ARRAY" in done.stderr, done.stderr


# Variants of a real file, rewritten field by field from the template's types.

FIELD_OFFSETS = {}
_at = 0
for _name, _fmt in trc_description:
    FIELD_OFFSETS[_name] = (_at, _fmt)
    _at += struct.calcsize("<" + _fmt)
assert _at == 346


def split(path):
    """(descriptor fields as a dict, user text, trigtime doubles, codes) of a LOFIRST word file."""
    raw = path.read_bytes()
    start = raw.find(b"WAVEDESC")
    desc = {n: struct.unpack_from("<" + f, raw, start + o) for n, (o, f) in FIELD_OFFSETS.items()}
    at = start + 346
    text = raw[at:at + desc["user_text"][0]]
    at += len(text)
    trig = np.frombuffer(raw, "<f8", desc["trig_time_array"][0] // 8, at)
    at += desc["trig_time_array"][0]
    codes = np.frombuffer(raw, "<i2", desc["wave_array_count"][0], at)
    assert desc["comm_order"][0] == 1 and desc["comm_type"][0] == 1
    return desc, text, trig, codes


def join(desc, text, trig, codes, order, word):
    d = dict(desc)
    d["comm_order"] = (1 if order == "<" else 0,)
    d["comm_type"] = (1 if word else 0,)
    d["wave_array1"] = (codes.size * (2 if word else 1),)
    block = bytearray(346)
    for name, (offset, fmt) in FIELD_OFFSETS.items():
        struct.pack_into(order + fmt, block, offset, *d[name])
    block += text + trig.astype(order + "f8").tobytes()
    block += codes.astype(order + "i2").tobytes() if word else codes.astype("i1").tobytes()
    return bytes(block)


def trc(block):
    return b"#9%09d" % len(block) + block


@pytest.fixture(scope="module")
def variants(real_files, tmp_path_factory):
    out = tmp_path_factory.mktemp("variants")
    desc, text, trig, codes = split(real_files / "pulse_sequence.trc")
    # 8-bit: the upper byte of each word, as the scope's BYTE format; gain x 256 keeps volts.
    byte_desc = dict(desc)
    byte_desc["vertical_gain"] = (desc["vertical_gain"][0] * 256,)
    files = {
        "byte_lofirst": trc(join(byte_desc, text, trig, codes >> 8, "<", False)),
        "byte_hifirst": trc(join(byte_desc, text, trig, codes >> 8, ">", False)),
        "word_hifirst": trc(join(desc, text, trig, codes, ">", True)),
        "reply_prefix": b"C2:WF ALL," + trc(join(desc, text, trig, codes, "<", True)) + b"\n",
        "no_file_header": join(desc, text, trig, codes, "<", True),
    }
    paths = {}
    for name, content in files.items():
        paths[name] = out / f"{name}.trc"
        paths[name].write_bytes(content)
    return paths


@pytest.mark.parametrize("name", ["reply_prefix", "no_file_header", "word_hifirst"])
def test_variants_read_like_the_original(real_files, variants, name):
    original = read_ours(real_files / "pulse_sequence.trc")
    ours = read_ours(variants[name])
    assert ours["segments"] == original["segments"]
    assert ours["header"]["order"] == ("HiFirst" if "hifirst" in name else "LoFirst")
    trace, volts = reference(real_files / "pulse_sequence.trc")
    check_against_lecroyscope(ours, trace, volts)
    if name != "reply_prefix":  # lecroyparser looks for WAVEDESC in the first 50 bytes only
        check_against_lecroyparser(ours, variants[name])


@pytest.mark.parametrize("name", ["byte_lofirst", "byte_hifirst"])
def test_8_bit_variants(real_files, variants, name):
    ours = read_ours(variants[name])
    assert ours["header"]["comm_type"] == 0
    assert ours["segment_count"] == 20
    check_against_lecroyparser(ours, variants[name])
    lofirst = lecroyscope.Trace(variants["byte_lofirst"])
    assert lofirst.header["comm_type"] == 0
    # lecroyscope reads int8 samples and (little-endian) TRIGTIME right in the LOFIRST copy.
    check_against_lecroyscope(ours, lofirst, np.atleast_2d(lofirst.voltage))
    # The 8-bit volts are the 16-bit volts with the low byte dropped.
    full = read_ours(real_files / "pulse_sequence.trc")
    step = ours["header"]["vertical_gain"]
    for seg8, seg16 in zip(ours["segments"], full["segments"]):
        diff = np.asarray(seg16["first_volts"]) - np.asarray(seg8["first_volts"])
        assert np.all((diff >= -1e-9) & (diff < step + 1e-9))


def test_process_sees_the_segments_of_a_real_sequence_file(real_files, tmp_path):
    """`radbench process` on a real 20-segment sequence .trc (lecroyscope's test file, I and Q
    from the same file) takes every segment as one repetition."""
    seq = str(real_files / "pulse_sequence.trc")
    out = tmp_path / "p"
    proc = subprocess.run(
        [RADBENCH, "process", seq, seq, "--waveform", "msk-lfm", "--sample-rate", "1e9",
         "--bandwidth", "2.5e8", "--pulse-us", "0.5", "--bits-per-pulse", "16",
         "--out", str(out), "--json"],
        capture_output=True, timeout=120, stdin=subprocess.DEVNULL,
    )
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    summary = doc["processed"][0]["summary"]
    assert summary["repetitions"] == 20
    assert len(summary["each_repetition"]) == 20
