"""radbench.process against `radbench process`, per capture, on the same archive.

    python benches/bench_process.py --radbench target/release/radbench [--captures 24]
        [--waveform msk-lfm|ofdm] [--algorithm NAME] [--jobs 1 2] [--repeat 5] [--keep DIR]

Makes the archive with `radbench capture` on the built-in mock lab (unless --keep names one
made before), then measures, alternately, --repeat times each (the best kept):
- the command line: `radbench process ARCHIVE --jobs J --json`: its own reported `seconds` (from
  its start of processing to the last file written), and its CPU time;
- Python: radbench.process over the same captures in a fresh interpreter (its start-up and
  import not counted), on J threads (the calls release the GIL): wall and CPU time.
Per capture, two ways: wall time / N, and the marginal CPU time of a capture, (CPU of N captures
- CPU of 1) / (N - 1), which leaves out process start-up and the pipeline's build (once per
worker on both sides) and does not depend on what else the machine runs. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import radbench


def make_archive(radbench_bin: str, root: Path, n: int, waveform: str) -> None:
    for k in range(n):
        subprocess.run([radbench_bin, "capture", "--allow-rf", "--waveform", waveform, "--seed", str(k + 1),
                        "--out", str(root / f"c{k:03d}")], check=True, capture_output=True, timeout=300)


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def cli_run(radbench_bin: str, inputs: list, jobs: int, options: list):
    """(wall seconds as it reports them, CPU seconds of the whole process)."""
    out = Path(tempfile.mkdtemp()) / "out"
    before = _children_cpu()
    done = subprocess.run([radbench_bin, "process", *map(str, inputs), "--jobs", str(jobs), "--json",
                           "--out", str(out), *options], check=True, capture_output=True, text=True, timeout=1800)
    cpu = _children_cpu() - before
    doc = json.loads(done.stdout)
    assert not doc["failed"], doc["failed"]
    return doc["seconds"], cpu


_TIMED = """
import concurrent.futures, json, sys, time
import radbench
inputs, jobs, kwargs = json.loads(sys.argv[1]), int(sys.argv[2]), json.loads(sys.argv[3])
files = list(radbench.captures(*inputs).values())
wall, cpu = time.perf_counter(), time.process_time()
if jobs == 1:
    for f in files:
        radbench.process(f, **kwargs)
else:
    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        list(pool.map(lambda f: radbench.process(f, **kwargs), files))
print(json.dumps([time.perf_counter() - wall, time.process_time() - cpu]))
"""


def python_run(inputs: list, jobs: int, kwargs: dict):
    """(wall, CPU seconds) of the calls, in a fresh interpreter (as the command line is a fresh
    process: no pipeline built yet), its import not counted."""
    done = subprocess.run([sys.executable, "-c", _TIMED, json.dumps([str(i) for i in inputs]), str(jobs),
                           json.dumps(kwargs)], check=True, capture_output=True, text=True, timeout=1800)
    return tuple(json.loads(done.stdout))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--radbench", required=True, help="the radbench binary (a release build)")
    p.add_argument("--captures", type=int, default=24)
    p.add_argument("--waveform", default="msk-lfm")
    p.add_argument("--algorithm")
    p.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    p.add_argument("--repeat", type=int, default=5, help="runs of each; the best is kept")
    p.add_argument("--keep", help="archive folder to make once and reuse")
    a = p.parse_args()
    root = Path(a.keep) if a.keep else Path(tempfile.mkdtemp()) / "archive"
    if not root.exists():
        make_archive(a.radbench, root, a.captures, a.waveform)
    every = [root]
    first = [sorted(p for p in root.iterdir() if p.is_dir())[0]]
    n = len(radbench.captures(root))
    options = ["--algorithm", a.algorithm] if a.algorithm else []
    kwargs = {"algorithm": a.algorithm} if a.algorithm else {}
    report = {"captures": n, "waveform": a.waveform, "algorithm": a.algorithm, "runs": []}
    for jobs in a.jobs:
        best = {k: float("inf") for k in ("cli_wall", "cli_cpu", "cli_cpu1", "py_wall", "py_cpu", "py_cpu1")}
        for _ in range(a.repeat):
            for side, run in (("cli", lambda i: cli_run(a.radbench, i, jobs, options)),
                              ("py", lambda i: python_run(i, jobs, kwargs))):
                wall, cpu = run(every)
                _, cpu1 = run(first)
                best[f"{side}_wall"] = min(best[f"{side}_wall"], wall)
                best[f"{side}_cpu"] = min(best[f"{side}_cpu"], cpu)
                best[f"{side}_cpu1"] = min(best[f"{side}_cpu1"], cpu1)
        cli_marginal = (best["cli_cpu"] - best["cli_cpu1"]) / (n - 1)
        py_marginal = (best["py_cpu"] - best["py_cpu1"]) / (n - 1)
        report["runs"].append({
            "jobs": jobs,
            "cli_wall_ms_per_capture": 1e3 * best["cli_wall"] / n,
            "python_wall_ms_per_capture": 1e3 * best["py_wall"] / n,
            "wall_python_over_cli": best["py_wall"] / best["cli_wall"],
            "cli_cpu_ms_per_capture": 1e3 * cli_marginal,
            "python_cpu_ms_per_capture": 1e3 * py_marginal,
            "cpu_python_over_cli": py_marginal / cli_marginal,
        })
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
