"""Archive processing throughput on one generated archive, and a campaign's step time with the
catalog's registration on and off (docs/catalog.md, "Speed of archive processing").

    python benches/bench_archive.py --radbench target/release/radbench [--captures 24]
        [--repeat 3] [--campaigns 6] [--keep DIR]

Makes the archive with `radbench capture` on the built-in mock lab and indexes it (unless
--keep names one made before), then --repeat times each, in a rotating order, into a fresh output
folder every time (so that every capture is computed):
- `radbench process ARCHIVE/c* --jobs 2` (the reference);
- `radbench process --from-catalog all --jobs 2`;
- radbench.dask.process_bag on a LocalCluster of 2 worker processes (1 thread each), the cluster
  started before the clock starts, in radbench.dask.worker_environment() (--dask-default: not).
Throughput is captures per second of wall time (the best of the repeats); also the median over
the repeats of each path's ratio to `process --jobs 2` in the same repeat. Then --campaigns pairs
of `radbench campaign run examples/accuracy.toml`, registration on and RADBENCH_CATALOG=off
alternating (which goes first alternates too): the mean step time of each (wall time / steps)
and the paired differences. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def sh(*args: str, env=None) -> float:
    """Runs a command; its wall time."""
    t = time.perf_counter()
    subprocess.run(list(args), check=True, capture_output=True, timeout=1800,
                   env={**os.environ, **(env or {})})
    return time.perf_counter() - t


def make_archive(radbench: str, runs: Path, n: int) -> None:
    for k in range(n):
        sh(radbench, "capture", "--allow-rf", "--seed", str(k + 1), "--out", str(runs / f"c{k:03d}"))
    sh(radbench, "runs", "--catalog", str(runs / "catalog.sqlite"), "index", str(runs))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--radbench", required=True)
    p.add_argument("--captures", type=int, default=24)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--campaigns", type=int, default=6)
    p.add_argument("--keep")
    p.add_argument("--dask-default", action="store_true",
                   help="start the Dask workers with Dask's defaults, not WORKER_CONFIG")
    a = p.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="bench-archive-"))
    runs = Path(a.keep) if a.keep else scratch / "runs"
    if not (runs / "catalog.sqlite").exists():
        make_archive(a.radbench, runs, a.captures)
    catalog = runs / "catalog.sqlite"
    inputs = sorted(str(d) for d in runs.iterdir() if d.is_dir())
    n = len(inputs)

    from distributed import Client, LocalCluster

    import radbench.dask as rd

    config = contextlib.nullcontext() if a.dask_default else rd.worker_environment()

    times = {"process --jobs 2": [], "process --from-catalog --jobs 2": [], "dask 2 workers": []}
    with config, LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster, Client(cluster) as client:
        client.run(lambda: __import__("radbench.dask"))
        paths = list(times)
        for r in range(a.repeat):
            out = scratch / f"out{r}"
            # Each repeat starts with the next path: the one after a large write is slowed by
            # its write-back, and no path should always follow the same one.
            for path in paths[r % 3:] + paths[:r % 3]:
                if path == "process --jobs 2":
                    wall = sh(a.radbench, "process", *inputs, "--jobs", "2", "--out", str(out / "plain"))
                elif path == "process --from-catalog --jobs 2":
                    wall = sh(a.radbench, "process", "--from-catalog", "all", "--catalog", str(catalog),
                              "--jobs", "2", "--out", str(out / "catalog"))
                else:
                    t = time.perf_counter()
                    done = client.compute(rd.process_bag(catalog, "all", out / "dask")).result()
                    rd.register(catalog, out / "dask", done)
                    wall = time.perf_counter() - t
                times[path].append(wall)
            # The outputs of a repeat (hundreds of MB with --captures 96) are not needed again.
            shutil.rmtree(out, ignore_errors=True)
    throughput = {k: n / min(v) for k, v in times.items()}
    reference = throughput["process --jobs 2"]
    # The same repeat's paths ran back to back: their ratio is less exposed to the machine's
    # drift than the ratio of bests.
    paired = {k: statistics.median(p / w for p, w in zip(times["process --jobs 2"], v))
              for k, v in times.items()}

    spec = str(ROOT / "examples" / "accuracy.toml")
    steps = None
    step_s = {"on": [], "off": []}
    for k in range(a.campaigns):
        order = ("on", "off") if k % 2 == 0 else ("off", "on")
        for mode in order:
            out = scratch / "campaigns" / f"{k}-{mode}"
            env = {"RADBENCH_CATALOG": "off"} if mode == "off" else {"RADBENCH_CATALOG": ""}
            wall = sh(a.radbench, "campaign", "run", spec, "--allow-rf", "--out", str(out), env=env)
            if steps is None:
                results = json.loads((out / "results.json").read_text())
                steps = len(results["steps"])
            step_s[mode].append(wall / steps)
    diffs = [on - off for on, off in zip(step_s["on"], step_s["off"])]
    # The scratch folder holds the archive (GBs with --captures 96) and every output.
    shutil.rmtree(scratch, ignore_errors=True)
    report = {
        "captures": n,
        "dask_workers": "Dask's defaults" if a.dask_default else "radbench.dask.worker_environment()",
        "captures_per_s": throughput,
        "relative_to_process_jobs_2": {k: v / reference for k, v in throughput.items()},
        "paired_median_relative_to_process_jobs_2": paired,
    }
    if diffs:  # --campaigns 0 times the archive paths only
        report.update({
            "campaign_steps": steps,
            "step_s_median": {m: statistics.median(v) for m, v in step_s.items()},
            "paired_on_minus_off_s": {"median": statistics.median(diffs), "min": min(diffs),
                                      "max": max(diffs)},
        })
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
