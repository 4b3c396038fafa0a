"""radbench.Bench: a warm session on a bench. Its captures equal `radbench capture`'s, a second
session on the same bench is refused, Ctrl-C leaves the bench safe, errors carry the exit
class."""

import _thread
import json
import os
import signal
import threading
from pathlib import Path

import pytest

import radbench
from conftest import run

#: A scene with a fixed noise seed: the first capture of a fresh lab is the same every time.
SCENE = "snr_db = 30.0\nseed = 11\n\n[[targets]]\nrange_m = 1.3\namplitude = 0.5\n"


def without(summary, *keys):
    return {k: v for k, v in summary.items() if k not in keys}


def test_a_capture_equals_radbench_captures_on_the_same_scene_and_seed(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    cli_out = tmp_path / "cli"
    cli = json.loads(run("capture", "--allow-rf", "--json", "--scene", str(scene), "--payload",
                         "warm", "--out", str(cli_out)).stdout)
    py_out = tmp_path / "py"
    with radbench.Bench(scene=scene, allow_rf=True) as b:
        p = b.capture(payload="warm", out=py_out)
    # Ranges, levels, the decoded bits: the same capture, processed the same way.
    assert p.targets == cli["targets"] and p.targets
    assert p.payload == cli["payload"] and p.payload["text"] == "warm"
    # The same files, and the same summary but where the files are.
    assert sorted(f.name for f in py_out.iterdir()) == sorted(f.name for f in cli_out.iterdir())
    assert without(p.summary, "files") == without(cli, "files")
    saved = json.loads((py_out / "summary.json").read_text())
    assert without(saved, "files") == without(cli, "files")
    # Processing the folder again gives what the session returned.
    again = radbench.process(py_out)
    assert again.targets == p.targets


def test_captures_are_warm_and_out_none_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with radbench.Bench(allow_rf=True) as b:
        first = b.capture()
        for _ in range(3):
            p = b.capture()
            assert abs(p.ranges_m[0] - first.ranges_m[0]) < 1e-3
        hann = b.capture(window="hann", min_range=0.3)
        assert hann.options["window"] == "hann" and hann.options["min_range_m"] == 0.3
        ofdm = b.capture("ofdm", repetitions=2)
        assert ofdm.waveform == "OFDM" or ofdm.summary["repetitions"] == 2
        assert ofdm.summary["repetitions"] == 2
    assert list(tmp_path.iterdir()) == []
    assert "files" not in first.summary


def test_a_second_session_on_the_same_bench_is_refused_with_the_reason():
    with radbench.MockLab() as lab:
        with radbench.Bench(lab, allow_rf=True) as b:
            with pytest.raises(radbench.InstrumentError, match="the instruments are in use") as e:
                radbench.Bench(lab)
            assert e.value.exit_code == 3
            # The first one goes on, never interleaved with the refused one.
            assert b.capture().ranges_m
        # Closed: the bench is free again.
        with radbench.Bench(lab) as again:
            assert not again.closed


def test_errors_carry_the_command_lines_exit_class(tmp_path):
    with radbench.Bench() as b:
        with pytest.raises(radbench.InputError, match="allow-rf|allow_rf|permit") as e:
            b.capture()
        assert e.value.exit_code == 2
    with radbench.Bench(allow_rf=True) as b:
        with pytest.raises(radbench.InputError, match="did you mean `window`"):
            b.capture(windw="hann")
        with pytest.raises(radbench.InputError, match="^window: "):
            b.capture(window="hanning")
        with pytest.raises(radbench.InputError, match="repetitions"):
            b.capture(repetitions=0)
        # A refused capture leaves the session usable.
        assert b.capture().ranges_m
    with pytest.raises(radbench.InputError, match="missing.toml"):
        radbench.Bench(tmp_path / "missing.toml")
    with pytest.raises(radbench.InputError, match="scene"):
        radbench.Bench(tmp_path / "bench.toml", scene={"targets": []})
    closed = radbench.Bench()
    closed.close()
    with pytest.raises(radbench.RadbenchError, match="closed"):
        closed.capture()


def last(lines, pred):
    found = [i for i, line in enumerate(lines) if pred(line)]
    return found[-1] if found else -1


@pytest.fixture
def sigint_raises():
    """Ctrl-C raises KeyboardInterrupt in these tests however pytest was started: a background job
    of a non-interactive shell starts Python with SIGINT ignored, and then an interrupt is dropped."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_keyboard_interrupt_in_a_capture_leaves_the_bench_safe(tmp_path, sigint_raises):
    journal = tmp_path / "io.jsonl"
    with radbench.MockLab() as lab, radbench.Bench(lab, allow_rf=True, trace_io=journal) as b:
        before = lab.last_capture()["captures"] or 0

        def interrupt_once_the_scope_captured():
            # Bounded: at most 30 s of polling (the capture takes well under a second).
            for _ in range(3000):
                if (lab.last_capture()["captures"] or 0) > before:
                    break
                threading.Event().wait(0.01)
            _thread.interrupt_main()

        watcher = threading.Thread(target=interrupt_once_the_scope_captured)
        watcher.start()
        with pytest.raises(KeyboardInterrupt):
            # Many repetitions: the interrupt lands while they are captured or processed.
            b.capture(repetitions=200)
        watcher.join(timeout=30)
        assert not watcher.is_alive()
        # The journal: the AWG's outputs and the transmitter were switched off after the
        # last time they were switched on.
        lines = [json.loads(line) for line in journal.read_text().splitlines()]
        texts = [(e["instrument"], e.get("text", "")) for e in lines if e["direction"] == "write"]
        on = last(texts, lambda t: t[0] == "awg" and "OUTP1 ON" in t[1])
        off = last(texts, lambda t: t[0] == "awg" and "OUTP1 OFF" in t[1])
        assert on >= 0 and off > on, "the AWG output is off at the end"
        tx_on = last(texts, lambda t: t[0] == "tx" and t[1].startswith("W 02") and not t[1].startswith("W 02 0000"))
        tx_off = last(texts, lambda t: t[0] == "tx" and t[1].startswith("W 02 0000"))
        assert tx_off > tx_on, "the transmitter is off at the end"
        # The session goes on.
        assert b.capture().ranges_m


def open_descriptors():
    return len(os.listdir("/proc/self/fd"))


def os_threads():
    return len(os.listdir("/proc/self/task"))


def interrupt_during_a_capture(lab, b):
    """Ctrl-C while `b` captures on `lab` (its scope has captured once more)."""
    before = lab.last_capture()["captures"] or 0

    def interrupt_once_the_scope_captured():
        for _ in range(3000):  # at most 30 s
            if (lab.last_capture()["captures"] or 0) > before:
                break
            threading.Event().wait(0.01)
        _thread.interrupt_main()

    watcher = threading.Thread(target=interrupt_once_the_scope_captured)
    watcher.start()
    with pytest.raises(KeyboardInterrupt):
        b.capture(repetitions=200)
    watcher.join(timeout=30)
    assert not watcher.is_alive()


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads in /proc")
def test_sessions_interrupted_or_not_leave_no_thread_or_descriptor_behind(sigint_raises):
    # One session first: what a process sets up once (thread pools, FFT plans) is not a leak.
    with radbench.MockLab() as lab, radbench.Bench(lab, allow_rf=True) as b:
        b.capture()
    fds, threads = open_descriptors(), os_threads()
    for _ in range(3):
        with radbench.MockLab() as lab, radbench.Bench(lab, allow_rf=True) as b:
            b.capture()
            interrupt_during_a_capture(lab, b)
            assert b.capture().ranges_m
    # Threads end a moment after they are told to: look again for at most 10 s.
    for _ in range(1000):
        if (open_descriptors(), os_threads()) <= (fds, threads):
            break
        threading.Event().wait(0.01)
    assert open_descriptors() <= fds and os_threads() <= threads, (fds, threads)


def test_close_with_and_the_doctor():
    b = radbench.Bench(allow_rf=True)
    report = b.doctor()
    assert report["checks"] and {"id", "status", "detail"} <= set(report["checks"][0])
    assert b.capture().ranges_m  # connected again after the doctor
    cal = b.calibrate(1.0)
    assert abs(cal["system_delay_s"] - 2.5e-9) < 0.05e-9 and cal["stored_in"] is None
    assert b.close() is not None
    assert b.closed and b.close() is None


#: A reference pillar at 1 m on the thesis' chain (uneven: its response is worth correcting).
THESIS_REFERENCE = (
    "snr_db = 25.0\nseed = 4\n\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\n"
    "[chain]\npreset = \"thesis-lab\"\n"
)


def test_calibrate_response_equals_the_commands_and_later_captures_correct_with_it(tmp_path):
    scene = tmp_path / "reference.toml"
    scene.write_text(THESIS_REFERENCE)
    cli = json.loads(run("calibrate", "response", "--reference-range", "1.0", "--scene", str(scene),
                         "--allow-rf", "--json", "--out", str(tmp_path / "cli.toml")).stdout)
    with radbench.Bench(scene=scene, allow_rf=True) as b:
        py = b.calibrate_response(1.0, out=tmp_path / "py.toml")
        # The same measurement on a fresh lab of the same scene, the same figures.
        assert py["figures"] == cli["figures"] and py["reference"] == cli["reference"]
        assert py["stored_in"] == str(tmp_path / "py.toml") and py["refused"] is None
        assert (tmp_path / "py.npy").exists()
        corrected = b.capture(calibration=tmp_path / "py.toml")
        assert corrected.options["correction"]["calibration"] == str(tmp_path / "py.toml")
        # Checked before anything radiates, named as the keywords they were given as.
        with pytest.raises(radbench.InputError, match="gate_ns"):
            b.calibrate_response(1.0, gate_ns=0.1)
        with pytest.raises(radbench.InputError, match="reflector.*0.3 m from the reference"):
            b.calibrate_response(1.0, reflector=0.9)
        with pytest.raises(radbench.InputError, match="bandwdth.*bandwidth"):
            b.calibrate_response(1.0, bandwdth=1e9)
        with pytest.raises(radbench.InputError, match="out"):
            b.calibrate_response(1.0, out=tmp_path / "py.txt")
    with radbench.Bench(scene=scene) as b, pytest.raises(radbench.InputError, match="allow"):
        b.calibrate_response(1.0)


def test_calibrate_response_on_a_bench_file_is_stored_beside_it_and_named_in_it(tmp_path):
    scene = tmp_path / "reference.toml"
    scene.write_text(THESIS_REFERENCE)
    with radbench.MockLab(scene) as lab:
        bench = tmp_path / "bench.toml"
        lab.bench_toml(bench, calibrated=True)
        with radbench.Bench(bench, allow_rf=True) as b:
            found = b.calibrate_response(1.0)
            assert found["stored_in"] == str(tmp_path / "bench-response.toml")
            assert 'response = "bench-response.toml"' in bench.read_text()
            # The bench's captures correct with it from now on, in this session too.
            p = b.capture()
            assert p.options["correction"]["calibration"].endswith("bench-response.toml")


def test_the_radbench_bench_fixture(radbench_bench):
    assert radbench_bench.capture().ranges_m


CAMPAIGN = """name = "py-three"
seed = 3
repetitions = 1

[waveform]
kind = "msk-lfm"

[processing]
algorithms = ["correlation"]

[[steps]]
targets = [1.0]

[[steps]]
targets = [1.5]

[[steps]]
targets = [2.0]
"""

#: The same spec as a dict.
CAMPAIGN_DICT = {
    "name": "py-three",
    "seed": 3,
    "repetitions": 1,
    "waveform": {"kind": "msk-lfm"},
    "processing": {"algorithms": ["correlation"]},
    "steps": [{"targets": [1.0]}, {"targets": [1.5]}, {"targets": [2.0]}],
}


def test_a_campaign_equals_radbench_campaign_runs_results(tmp_path):
    spec = tmp_path / "three.toml"
    spec.write_text(CAMPAIGN)
    run("campaign", "run", str(spec), "--allow-rf", "--out", str(tmp_path / "cli"))
    cli = json.loads((tmp_path / "cli" / "results.json").read_text())
    seen = []
    with radbench.Bench(allow_rf=True) as b:
        r = b.campaign(spec, out=tmp_path / "py").run(on_step=seen.append)
        # A dict is the same spec.
        d = b.campaign(CAMPAIGN_DICT, out=tmp_path / "dict").run()
    assert r.results == cli and d.results == cli
    assert "<table>" in r._repr_html_() and "py-three" in r._repr_html_()
    assert r.status == "complete" and len(r.steps) == 3
    # Each step's result as it landed, in order.
    assert [s["index"] for s in seen] == [1, 2, 3]
    assert [s["result"] for s in seen] == cli["steps"]


class Stop(Exception):
    pass


#: Five steps: a stop after the first one's result leaves steps unmeasured.
FIVE = dict(CAMPAIGN_DICT, name="py-five", steps=[{"targets": [1.0 + 0.2 * k]} for k in range(5)])


def test_an_exception_in_on_step_stops_the_run_safely_and_resume_completes_it(tmp_path):
    with radbench.Bench(allow_rf=True) as b:
        c = b.campaign(FIVE, out=tmp_path / "run")

        def stop_after_the_first(step):
            raise Stop(f"enough after step {step['index']}")

        with pytest.raises(Stop):
            c.run(on_step=stop_after_the_first)
        stopped = radbench.read_run(c.dir, captures=False)
        assert stopped.status == "interrupted"
        assert stopped.results is None or len(stopped.results["steps"]) < 5
        # The journal of the run ends with the bench's safe state.
        journal = [json.loads(line) for line in (Path(c.dir) / "io-journal.jsonl").read_text().splitlines()]
        texts = [(e["instrument"], e.get("text", "")) for e in journal if e["direction"] == "write"]
        on = last(texts, lambda t: t[0] == "awg" and "OUTP1 ON" in t[1])
        off = last(texts, lambda t: t[0] == "awg" and "OUTP1 OFF" in t[1])
        assert off > on >= 0
        done = c.resume()
    assert done.status == "complete" and len(done.results["steps"]) == 5


def test_keyboard_interrupt_in_on_step_stops_the_run_and_resume_completes_it(tmp_path):
    with radbench.Bench(allow_rf=True) as b:
        c = b.campaign(FIVE, out=tmp_path / "run")

        def interrupted(step):
            raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            c.run(on_step=interrupted)
        assert radbench.read_run(c.dir, captures=False).status == "interrupted"
        assert c.resume().status == "complete"


def test_jupyter_shows_a_capture_as_svg_and_a_table(radbench_bench):
    p = radbench_bench.capture()
    shown = p._repr_html_()
    assert "<svg" in shown and "<polyline" in shown and "<table>" in shown
    assert f"{p.ranges_m[0]:.3f} m" in shown


def test_plot_draws_with_matplotlib_when_it_is_there(radbench_bench):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    ax = radbench_bench.capture().plot()
    assert ax.get_xlabel() == "range (m)"
