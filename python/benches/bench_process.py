"""radbench.process against `radbench process`, per capture, on the same archive.

    python benches/bench_process.py --radbench target/release/radbench [--captures 12]
        [--waveform msk-lfm|ofdm] [--algorithm NAME] [--keep DIR]

Makes the archive with `radbench capture` on the built-in mock lab (unless --keep names one
made before), then times:
- the command line: `radbench process ARCHIVE --jobs J --json`, its own reported `seconds`
  (from its start of processing to the last file written: process start-up not counted);
- Python: radbench.process over the same captures in a fresh interpreter (its start-up and
  import not counted), on J threads (the calls release the GIL), pipelines built on first use
  as the command line's are.
Prints one JSON object with per-capture milliseconds and the ratio Python / command line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import radbench


def make_archive(radbench_bin: str, root: Path, n: int, waveform: str) -> None:
    for k in range(n):
        subprocess.run([radbench_bin, "capture", "--allow-rf", "--waveform", waveform, "--seed", str(k + 1),
                        "--out", str(root / f"c{k:03d}")], check=True, capture_output=True, timeout=300)


def cli_seconds(radbench_bin: str, root: Path, jobs: int, options: list) -> float:
    out = Path(tempfile.mkdtemp()) / "out"
    done = subprocess.run([radbench_bin, "process", str(root), "--jobs", str(jobs), "--json", "--out", str(out),
                           *options], check=True, capture_output=True, text=True, timeout=1800)
    doc = json.loads(done.stdout)
    assert not doc["failed"], doc["failed"]
    return doc["seconds"]


_TIMED = """
import concurrent.futures, json, sys, time
import radbench
root, jobs, kwargs = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
files = list(radbench.captures(root).values())
started = time.perf_counter()
if jobs == 1:
    for f in files:
        radbench.process(f, **kwargs)
else:
    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        list(pool.map(lambda f: radbench.process(f, **kwargs), files))
print(time.perf_counter() - started)
"""


def python_seconds(root: Path, jobs: int, kwargs: dict) -> float:
    """In a fresh interpreter (as the command line is a fresh process: no pipeline built yet),
    its import not counted."""
    done = subprocess.run([sys.executable, "-c", _TIMED, str(root), str(jobs), json.dumps(kwargs)],
                          check=True, capture_output=True, text=True, timeout=1800)
    return float(done.stdout.strip())


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--radbench", required=True, help="the radbench binary (a release build)")
    p.add_argument("--captures", type=int, default=12)
    p.add_argument("--waveform", default="msk-lfm")
    p.add_argument("--algorithm")
    p.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    p.add_argument("--keep", help="archive folder to make once and reuse")
    a = p.parse_args()
    root = Path(a.keep) if a.keep else Path(tempfile.mkdtemp()) / "archive"
    if not root.exists():
        make_archive(a.radbench, root, a.captures, a.waveform)
    n = len(radbench.captures(root))
    options = ["--algorithm", a.algorithm] if a.algorithm else []
    kwargs = {"algorithm": a.algorithm} if a.algorithm else {}
    report = {"captures": n, "waveform": a.waveform, "algorithm": a.algorithm, "runs": []}
    for jobs in a.jobs:
        # Each measured twice, the better kept (the machine may be shared).
        cli = min(cli_seconds(a.radbench, root, jobs, options) for _ in range(2))
        py = min(python_seconds(root, jobs, kwargs) for _ in range(2))
        report["runs"].append({
            "jobs": jobs,
            "cli_ms_per_capture": 1e3 * cli / n,
            "python_ms_per_capture": 1e3 * py / n,
            "python_over_cli": py / cli,
        })
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
