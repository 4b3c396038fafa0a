"""radbench.catalog() against `radbench runs query` over the same catalog (docs/catalog.md)."""

import json
from pathlib import Path

import pytest

import radbench
from conftest import run

SPEC = Path(__file__).resolve().parents[2] / "examples" / "accuracy.toml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two accuracy runs and a capture, registered as they were written, then indexed."""
    root = tmp_path_factory.mktemp("catalog") / "runs"
    for name in ("first", "second"):
        run("campaign", "run", str(SPEC), "--allow-rf", "--out", str(root / name))
    run("capture", "--allow-rf", "--out", str(root / "capture"))
    run("runs", "--catalog", str(root / "catalog.sqlite"), "index", str(root))
    return root


def cli_query(root, *args):
    out = run("runs", "--catalog", str(root / "catalog.sqlite"), "query", "--json", *args)
    return json.loads(out.stdout)


def test_runs_equal_what_runs_query_gives(runs):
    cat = radbench.catalog(runs / "catalog.sqlite")
    want = cli_query(runs, "--kind", "accuracy", "--where", "max_abs_error_m < 1")
    got = cat.runs(kind="accuracy", where="max_abs_error_m < 1")
    assert [r["run_id"] for r in got] == [r["run_id"] for r in want]
    assert len(got) == 2
    assert got[0]["metrics"]["max_abs_error_m"] == pytest.approx(want[0]["max_abs_error_m"])
    same = cat.runs(kind="position", where={"max_abs_error_m": ("<", 1.0), "missed": 0})
    assert [r["run_id"] for r in same] == [r["run_id"] for r in got]
    assert cat.runs(where={"max_abs_error_m": ("<", 0.0)}) == []
    assert cat.runs(since="2000-01-01", status="complete", limit=1)[0]["run_id"] == got[0]["run_id"]
    assert cat.runs(calibration="none", scope="labmaster", waveform="msk-lfm") == got


def test_captures_hold_the_capture_and_every_campaign_step(runs):
    cat = radbench.catalog(runs / "catalog.sqlite")
    [capture] = cat.captures(origin="capture")
    assert capture["dir"] == str((runs / "capture").resolve())
    run_id = cat.runs(limit=1)[0]["run_id"]
    steps = cat.captures(run_id=run_id)
    assert len(steps) == 6 and {s["origin"] for s in steps} == {"campaign"}
    assert len(cat.steps(run_id)) == 6


def test_bad_filters_name_the_field(runs):
    cat = radbench.catalog(runs / "catalog.sqlite")
    with pytest.raises(ValueError, match="where"):
        cat.runs(where="max_abs_error_m < 1; DROP TABLE runs")
    with pytest.raises(ValueError, match="since"):
        cat.runs(since="last week")
    with pytest.raises(ValueError, match="status"):
        cat.runs(status="done")
    with pytest.raises(FileNotFoundError, match="runs index"):
        radbench.catalog(runs / "nothing.sqlite")


def test_to_pandas(runs):
    pytest.importorskip("pandas")
    cat = radbench.catalog(runs / "catalog.sqlite")
    frame = cat.runs(kind="accuracy").to_pandas()
    assert list(frame["name"]) == ["accuracy", "accuracy"]
    assert len(cat.to_pandas("steps")) == 12
