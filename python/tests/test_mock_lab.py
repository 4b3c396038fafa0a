"""MockLab and the `mock_lab` fixture with a pyvisa-py script written as a user would write it:
upload radbench's waveform to the AWG, switch the front ends on, capture on the scope, read
the traces (and process them with radbench); nothing of the lab outlives its context."""

import importlib.metadata
import os

import numpy as np
import pytest

import radbench

pyvisa = pytest.importorskip("pyvisa")


def user_script(resources, tmp_path):
    """What a lab's own instrument script does, on any bench: returns the two traces saved as
    .trc files."""
    w = radbench.waveform.msk_lfm()
    rm = pyvisa.ResourceManager("@py")
    try:
        awg = rm.open_resource(resources["awg"])
        awg.timeout = 10_000
        awg.read_termination = awg.write_termination = "\n"
        assert awg.query("*IDN?").split(",")[1].startswith("M8195A")
        for c in [":ABOR", ":INST:DACM DCM", ":INST:MEM:EXT:RDIV DIV4", ":TRAC1:MMOD EXT",
                  ":TRAC2:MMOD EXT", ":FREQ:RAST 64000000000", ":TRAC1:DEL:ALL",
                  f":TRAC1:DEF 1,{len(w.i)}"]:
            awg.write(c)
        # Channel 1 interleaves each I code with its marker byte (sample marker on bit 0 and 1).
        pairs = np.empty(2 * len(w.i), dtype=np.int8)
        pairs[0::2] = w.i
        pairs[1::2] = w.marker().astype(np.int8) * 3
        awg.write_binary_values(":TRAC1:DATA 1,0,", pairs, datatype="b")
        awg.write_binary_values(":TRAC2:DATA 1,0,", w.q, datatype="b")
        assert awg.query("*OPC?") == "1"
        for c in [":TRAC1:SEL 1", ":TRAC2:SEL 1", ":VOLT1 0.5", ":VOLT2 0.5", ":VOLT3:AMPL 0.5",
                  ":VOLT3:OFFS 0.25", ":OUTP1 ON", ":OUTP2 ON", ":OUTP3 ON", ":INIT:IMM"]:
            awg.write(c)
        assert awg.query(":SYST:ERR?") == '0,"No error"'
        for name in ("rx", "tx"):
            fe = rm.open_resource(resources[name])
            fe.timeout = 5_000
            fe.read_termination = fe.write_termination = "\n"
            assert fe.query("W 02 000F") == "OK"  # enable
            assert fe.query("W 03 0000") == "OK"  # no attenuation
            fe.close()
        scope = rm.open_resource(resources["scope"])
        scope.timeout = 20_000
        scope.read_termination = "\n"
        for c in ["CHDR OFF", "CFMT DEF9,WORD,BIN", "CORD LO", "C1:TRA ON", "C1:VDIV 0.05",
                  "C2:TRA ON", "C2:VDIV 0.05",
                  "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'",
                  "VBS 'app.Acquisition.Horizontal.SampleRate = 80000000000'",
                  "VBS 'app.Acquisition.Horizontal.HorScale = 0.000001'",
                  "TRSE EDGE,SR,EX,HT,OFF", "EX:TRLV 0.25", "EX:TRSL POS", "TRDL -0.000005"]:
            scope.write(c)
        assert scope.query("TRMD SINGLE;ARM;WAIT 10;*OPC?") == "1"
        scope.read_termination = None
        files = []
        for ch in ("C1", "C2"):
            scope.write(f"{ch}:WF? ALL")
            raw = scope.read_raw()
            start = raw.index(b"#9")
            n = int(raw[start + 2:start + 11])
            assert raw[start + 11:start + 19] == b"WAVEDESC" and n > 1_000_000
            path = tmp_path / f"{ch}.trc"
            path.write_bytes(raw[start:start + 11 + n])
            files.append(str(path))
        for c in [":OUTP1 OFF", ":OUTP2 OFF", ":OUTP3 OFF", ":ABOR"]:
            awg.write(c)
        scope.close()
        awg.close()
        return files
    finally:
        rm.close()


def check_traces(lab, files):
    assert lab.last_capture()["captures"] == 1
    truth = lab.last_capture()["scene"]
    r = radbench.process(files, waveform="msk-lfm", system_delay=truth["system_delay_s"])
    assert r.payload["bit_errors"] == 0
    assert abs(r.ranges_m[0] - truth["targets"][0]["range_m"]) < 1e-3


def test_pyvisa_script_against_mock_lab(tmp_path):
    with radbench.MockLab() as lab:
        assert set(lab.resources) >= {"awg", "scope", "tx", "rx"}
        lab.move(0, 1.5)
        files = user_script(lab.resources, tmp_path)
        check_traces(lab, files)
        assert lab.last_capture()["scene"]["targets"][0]["range_m"] == 1.5


def test_pyvisa_script_against_the_fixture(mock_lab, tmp_path):
    files = user_script(mock_lab.resources, tmp_path)
    check_traces(mock_lab, files)


@pytest.mark.mock_lab(scene={"snr_db": 20.0, "targets": [{"range_m": 2.0, "amplitude": 0.3}]})
def test_fixture_takes_a_scene_from_its_marker(mock_lab):
    assert mock_lab.scene["targets"][0]["range_m"] == 2.0
    assert mock_lab.scene["snr_db"] == 20.0


def pytest11_entry_points():
    """The installed `pytest11` entry points (Python 3.9's `entry_points()` takes no `group`)."""
    points = importlib.metadata.entry_points()
    if hasattr(points, "select"):
        return points.select(group="pytest11")
    return points.get("pytest11", [])


def test_the_plugin_is_registered_under_pytest11():
    found = [e for e in pytest11_entry_points() if e.name == "radbench"]
    assert found and found[0].value == "radbench.pytest_plugin"


def test_control_channel_and_its_errors(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text("snr_db = 25.0\n\n[[targets]]\nrange_m = 0.8\namplitude = 0.5\n")
    with radbench.MockLab(scene) as lab:
        assert lab.scene["targets"][0]["range_m"] == 0.8
        assert lab.add_target(3.0, 0.2) == 1
        lab.set_snr(10.0)
        lab.set_scene({"targets": [{"range_m": 1.2, "amplitude": 0.5}]})
        assert [t["range_m"] for t in lab.scene["targets"]] == [1.2]
        with pytest.raises(radbench.InputError, match="target"):
            lab.move(5, 1.0)
        assert "[simulation]" in lab.bench_toml(tmp_path / "bench.toml")
    with pytest.raises(radbench.RadbenchError, match="not running"):
        lab.resources
    with pytest.raises(radbench.InputError):
        radbench.MockLab(tmp_path / "missing.toml")


def _threads():
    return len(os.listdir("/proc/self/task"))


def _fds():
    out = {}
    for fd in os.listdir("/proc/self/fd"):
        try:
            out[fd] = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            pass
    return out


def test_mock_lab_leaves_no_thread_socket_or_pty_behind(tmp_path):
    # tokio keeps one socket pair per process for its signal driver, made by the first runtime
    # (a process-wide static, never more): start one lab first so that it is there.
    with radbench.MockLab():
        pass
    threads, fds = _threads(), _fds()
    for _ in range(3):
        with radbench.MockLab() as lab:
            assert _threads() > threads
            during = _fds()
            assert any("ptmx" in v or "/dev/pts" in v for v in during.values())
            assert sum(v.startswith("socket:") for v in during.values()) > 5
            rm = pyvisa.ResourceManager("@py")
            inst = rm.open_resource(lab.resources["awg"])
            assert inst.query("*IDN?").startswith("MOCK_LAB")
            inst.close()
            rm.close()
    assert _threads() == threads
    after = _fds()
    assert after == fds, {k: v for k, v in after.items() if fds.get(k) != v}


def test_bench_file_of_mock_lab_serves_radbench_capture(tmp_path):
    import json
    import subprocess

    from conftest import radbench_bin

    with radbench.MockLab() as lab:
        lab.move(0, 1.7)
        bench = tmp_path / "bench.toml"
        lab.bench_toml(bench)
        done = subprocess.run([radbench_bin(), "capture", "--bench", str(bench), "--allow-rf", "--json",
                               "--out", str(tmp_path / "cap")], capture_output=True, text=True,
                              timeout=150, stdin=subprocess.DEVNULL)
        assert done.returncode == 0, done.stderr
        summary = json.loads(done.stdout)
        assert summary["scene"]["targets"][0]["range_m"] == 1.7
        # No [calibration] in the bench file: ranges include the scene's system delay.
        expected = 1.7 + 299_792_458.0 * lab.scene["system_delay_s"] / 2
        assert any(abs(t["range_m"] - expected) < 0.01 for t in summary["targets"]), summary["targets"]
        # ... and the capture says so in its warnings, naming what to run.
        assert any("radbench calibrate" in w for w in summary["warnings"]), summary["warnings"]

        # With the lab's calibration written, ranges are true ranges and nothing is warned of.
        text = lab.bench_toml(bench, calibrated=True)
        assert f"system_delay_s = {lab.scene['system_delay_s']!r}" in text
        done = subprocess.run([radbench_bin(), "capture", "--bench", str(bench), "--allow-rf", "--json",
                               "--out", str(tmp_path / "cap-calibrated")], capture_output=True,
                              text=True, timeout=150, stdin=subprocess.DEVNULL)
        assert done.returncode == 0, done.stderr
        summary = json.loads(done.stdout)
        assert summary["system_delay_s"] == lab.scene["system_delay_s"]
        assert any(abs(t["range_m"] - 1.7) < 0.01 for t in summary["targets"]), summary["targets"]
        assert not any("radbench calibrate" in w for w in summary["warnings"]), summary["warnings"]
