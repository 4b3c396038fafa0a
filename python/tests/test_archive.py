"""read_run against results.json, and the Dask example against `radbench process --jobs 2`."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import radbench
from conftest import cli_process, run

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign") / "run"
    spec = Path(__file__).resolve().parents[2] / "examples" / "accuracy.toml"
    run("campaign", "run", str(spec), "--allow-rf", "--out", str(out))
    return out


def test_read_run_gives_the_numbers_of_results_json(campaign):
    r = radbench.read_run(campaign)
    results = json.loads((campaign / "results.json").read_text())
    assert r.results == results and r.status == "complete"
    assert [s.index for s in r.steps] == [s["index"] for s in results["steps"]]
    for step, expected in zip(r.steps, results["steps"]):
        assert step.result == expected
        corr = expected["algorithms"]["correlation"]
        # The step's saved capture processed again gives what the campaign recorded.
        again = radbench.process(step.capture)
        assert [t["range_m"] for t in again.targets] == pytest.approx(
            [t["range_m"] for t in corr["targets"]], abs=1e-9)
        assert again.width_3db_cm == pytest.approx(corr["width_3db_cm"], rel=1e-9)
        assert again.sidelobe_db == pytest.approx(corr["sidelobe_db"], abs=1e-9)
        assert again.payload["bit_errors"] == corr["payload"]["bit_errors"]
        assert step.capture.true_ranges_m == [t["range_m"] for t in expected["truth"]["targets"]]
    assert radbench.read_run(campaign, captures=False).steps[0].capture is None
    with pytest.raises(radbench.InputError, match="read_run"):
        radbench.read_capture(campaign)


def test_captures_lists_what_radbench_process_would(campaign, archive):
    found = radbench.captures(campaign, archive["ofdm"])
    assert list(found)[:6] == [f"step-{k:03d}" for k in range(1, 7)]
    assert len(found) == 7


def test_dask_example_equals_radbench_process_jobs_2(campaign, archive):
    inputs = [str(campaign), *(str(archive[n]) for n in ("msk-lfm", "ofdm", "music"))]
    done = subprocess.run([sys.executable, str(EXAMPLES / "dask_archive.py"), *inputs, "--workers", "2"],
                          capture_output=True, text=True, timeout=170, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    on_dask = json.loads(done.stdout)
    cli = cli_process(inputs, jobs=2)
    assert list(on_dask) == list(cli) and len(cli) == 9
    for name, summary in cli.items():
        assert on_dask[name] == {k: v for k, v in summary.items() if k != "files"}, name


def test_a_running_manifest_nobody_works_on_reads_as_interrupted(campaign, tmp_path):
    import fcntl
    import shutil
    run_dir = tmp_path / "run"
    shutil.copytree(campaign, run_dir)
    manifest = run_dir / "manifest.toml"
    manifest.write_text(manifest.read_text().replace('status = "complete"', 'status = "running"', 1))
    with open(run_dir / ".radbench.lock", "rb") as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        assert radbench.read_run(run_dir, captures=False).status == "running"
    r = radbench.read_run(run_dir, captures=False)
    assert r.status == "interrupted" and r.manifest["reason"] == radbench.STALE_REASON


def test_the_steps_journal_of_a_running_session_is_merged(campaign, tmp_path):
    """A run whose session still runs (or stopped without storing its end) has the steps it
    recorded since its start in manifest-steps.jsonl: read_run merges them, as radbench does."""
    import fcntl
    import shutil
    run_dir = tmp_path / "run"
    shutil.copytree(campaign, run_dir)
    manifest = radbench.read_run(run_dir, captures=False).manifest
    done = manifest["steps"][0]
    assert done["status"] == "done"
    # manifest.toml as the session's start stored it: step 1 pending, the session not ended.
    text = (run_dir / "manifest.toml").read_text()
    text = text.replace('status = "complete"', 'status = "running"', 1)
    text = text.replace('status = "done"', 'status = "pending"', 1)
    text = "\n".join(line for line in text.split("\n") if not line.startswith("ended = "))
    (run_dir / "manifest.toml").write_text(text)
    line = {"session": len(manifest["sessions"]), "updated": "later", "step": done,
            "timing": manifest["sessions"][-1]["timing"]}
    journal = run_dir / radbench.STEPS_JOURNAL
    journal.write_text(json.dumps(line) + "\n" + json.dumps(line)[:40])
    with open(run_dir / ".radbench.lock", "rb") as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        r = radbench.read_run(run_dir, captures=False)
    assert r.status == "running" and r.manifest["updated"] == "later"
    assert r.manifest["steps"][0]["status"] == "done"
    assert r.manifest["steps"][0]["files"] == done["files"]
    # Without the journal, step 1 reads pending: the journal is what recorded it.
    journal.unlink()
    assert radbench.read_run(run_dir, captures=False).manifest["steps"][0]["status"] == "pending"
