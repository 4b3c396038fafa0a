"""radbench.dask over the run catalog: with a LocalCluster of 2 worker processes, one SIGKILLed
halfway, the output set is byte-identical to `radbench process --from-catalog --jobs 2`'s, and
nothing is computed twice beyond the killed worker's in-flight unit (each computation leaves a
marker file)."""

import os
import signal
import sqlite3
import time
from pathlib import Path

import pytest

import radbench
from conftest import run

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")
import radbench.dask as rd  # noqa: E402

CAPTURES = 10
#: Slow enough per unit for a kill to land mid-run (MUSIC of a high order).
OPTIONS = {"algorithm": "music", "m": 96}
CLI_OPTIONS = ["--algorithm", "music", "--m", "96"]


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    root = tmp_path_factory.mktemp("catalog")
    for k in range(CAPTURES):
        run("capture", "--allow-rf", "--waveform", "ofdm", "--seed", str(k + 1),
            "--out", str(root / "runs" / f"c{k}"))
    run("runs", "--catalog", str(root / "runs" / "catalog.sqlite"), "index", str(root / "runs"))
    return root / "runs" / "catalog.sqlite"


def tree(folder: Path):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_units_name_every_capture_and_a_bad_query(catalog):
    found = rd.units(catalog, "all")
    assert len(found) == CAPTURES and len({u["input_sha256"] for u in found}) == CAPTURES
    # The Python catalog's records select the same units.
    records = radbench.catalog(catalog).captures(origin="capture")
    assert sorted(map(str, (u["input_dir"] for u in rd.units(catalog, captures=records)))) == \
        sorted(u["input_dir"] for u in found)
    with pytest.raises(radbench.InputError, match="wavefrm"):
        rd.units(catalog, "wavefrm = ofdm")


def test_the_bag_is_one_task_per_unit(catalog, tmp_path):
    # Dask does not fuse a bag's from_sequence and map: two tasks a unit, and a wait between.
    bag = rd.process_bag(catalog, "all", tmp_path / "out")
    assert bag.npartitions == CAPTURES
    assert len(dict(bag.__dask_graph__())) == CAPTURES


def test_two_workers_one_killed_give_the_bytes_of_the_command(catalog, tmp_path):
    from distributed import Client, LocalCluster

    reference = tmp_path / "cli"
    run("process", "--from-catalog", "all", "--catalog", str(catalog), "--jobs", "2",
        "--out", str(reference), *CLI_OPTIONS, timeout=600)
    out, markers = tmp_path / "dask", tmp_path / "markers"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        assert len(pids) == 2
        future = client.compute(rd.process_bag(catalog, "all", out, markers=markers, **OPTIONS))
        # Halfway: once half the units have started, one worker process is killed.
        deadline = time.monotonic() + 120
        while len(list(markers.glob("*"))) < CAPTURES // 2 and time.monotonic() < deadline:
            assert not future.done() or future.status != "error", future.exception()
            time.sleep(0.005)
        killed_early = not future.done()
        os.kill(pids[0], signal.SIGKILL)
        done = future.result(timeout=300)
    assert killed_early, "every unit was done before the kill: nothing was tested"
    assert sorted(d["input_sha256"] for d in done) == sorted(
        u["input_sha256"] for u in rd.units(catalog, "all"))
    rd.register(catalog, out, done, **OPTIONS)
    # No half-written folder left, and the command's bytes.
    assert tree(out) == tree(reference)
    # Each unit computed once, and at most the killed worker's one in-flight unit again.
    computed = [m.name.rsplit(".", 2)[0] for m in markers.iterdir()]
    assert set(computed) == {p.name for p in out.iterdir()}
    assert CAPTURES <= len(computed) <= CAPTURES + 1, computed
    # Registered like the command's outputs (one row per output folder).
    with sqlite3.connect(catalog) as conn:
        rows = conn.execute("SELECT out_dir FROM processed WHERE out_dir LIKE ?",
                            [str(out) + "%"]).fetchall()
    assert len(rows) == CAPTURES


def test_process_bag_without_dask_says_what_to_install(monkeypatch, catalog):
    import builtins

    real = builtins.__import__

    def no_dask(name, *args, **kwargs):
        if name.startswith("dask"):
            raise ImportError("No module named 'dask'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(ImportError, match="pip install"):
        rd.process_bag(catalog, "all")


def test_worker_environment_replaces_dasks_malloc_trim_threshold_in_the_workers():
    from distributed import Client, LocalCluster

    def trim_threshold():
        return os.environ.get("MALLOC_TRIM_THRESHOLD_")

    # Dask's default, which an earlier cluster of this process also left in os.environ.
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        assert list(client.run(trim_threshold).values()) == ["65536"]
    with rd.worker_environment(), LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:
        assert list(client.run(trim_threshold).values()) == [str(512 << 20)]
        # The rest of WORKER_CONFIG reaches the workers too (the profiler off).
        profiling = client.run(lambda: dask.config.get("distributed.worker.profile.enabled"))
        assert list(profiling.values()) == [False]
