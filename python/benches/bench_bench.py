"""radbench.Bench against the pyvisa-py + numpy script's warm step (benches/compare_campaign.py's
`PythonStack`) and against a one-shot `radbench capture`, on one `mock-lab serve`, in one run.

    cargo build --release -p radbench --bin radbench -p mock_lab --bin mock-lab
    python python/benches/bench_bench.py --radbench target/release/radbench \\
        --mock-lab target/release/mock-lab [--captures 20] [--turns 5]

The Python environment needs the radbench wheel and interop/requirements.txt (pyvisa, pyvisa-py,
pyvicp, numpy, scipy). Each turn, against the same lab (its bench file):
- warm: `radbench.Bench(bench, allow_rf=True)`, then `--captures` calls of `b.capture()` (no
  files, as the script writes none); the per-capture time is the median of captures 2..N;
- the script: its sessions opened and one step taken first (not counted), then `--captures`
  steps; the median step;
- first capture: a new `radbench.Bench` (opening it included) and its first `b.capture(out=DIR)`
  (the files `radbench capture` writes), against one `radbench capture --bench ... --out DIR`
  (a new process: spawn to exit).
Targets (issue 43): the warm capture at least 1.5x faster than the script's warm step, the first
capture within 1.2x of the one-shot. Prints a table and one JSON line; exit 0 when both hold.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "benches"))

import compare_campaign as cc  # noqa: E402
import pyvisa  # noqa: E402

import radbench  # noqa: E402

WARM_SPEEDUP = 1.5
FIRST_RATIO = 1.2


def warm_captures(bench: Path, n: int):
    """Seconds of each of n captures of one session (the first included) and of opening it."""
    t = time.perf_counter()
    with radbench.Bench(bench, allow_rf=True) as b:
        opened = time.perf_counter() - t
        times = []
        for _ in range(n):
            t = time.perf_counter()
            p = b.capture()
            times.append(time.perf_counter() - t)
        assert p.ranges_m, "the session found no target"
    return opened, times


def first_capture(bench: Path, out: Path) -> float:
    """A new session and its first capture, written as `radbench capture` writes it."""
    t = time.perf_counter()
    with radbench.Bench(bench, allow_rf=True) as b:
        b.capture(out=out)
        took = time.perf_counter() - t
    return took


def script_steps(lab, rm, n: int):
    stack = cc.PythonStack(lab, rm, seed=7)
    try:
        stack.step(1.0, 7)  # warm: the first step (upload) is not counted
        times = []
        for k in range(n):
            t = time.perf_counter()
            stack.step(1.0, 8 + k)
            times.append(time.perf_counter() - t)
    finally:
        stack.close()
    return times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--radbench", required=True)
    ap.add_argument("--mock-lab", required=True)
    ap.add_argument("--captures", type=int, default=20)
    ap.add_argument("--turns", type=int, default=5)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="radbench-bench-bench-"))
    lab = cc.MockLab(args.mock_lab, work)
    rm = pyvisa.ResourceManager("@py")
    warm, script, first, one_shot, opened = [], [], [], [], []
    try:
        for turn in range(args.turns):
            o, times = warm_captures(lab.bench_file, args.captures)
            opened.append(o)
            warm.append(statistics.median(times[1:]))
            script.append(statistics.median(script_steps(lab, rm, args.captures)))
            first.append(first_capture(lab.bench_file, work / f"first-{turn}"))
            one_shot.append(cc.radbench_one_shot(args.radbench, lab.bench_file, work / f"one-shot-{turn}")["wall"])
            for d in (work / f"first-{turn}", work / f"one-shot-{turn}"):
                shutil.rmtree(d, ignore_errors=True)
    finally:
        rm.close()
        lab.stop()
        shutil.rmtree(work, ignore_errors=True)
    med = statistics.median
    speedup = med(script) / med(warm)
    ratio = med(first) / med(one_shot)
    ms = lambda xs: f"{1e3 * min(xs):7.1f} / {1e3 * med(xs):7.1f} ms"  # noqa: E731
    print(f"{args.turns} turns of {args.captures} captures each; min / median")
    print(f"  Bench() opened                         {ms(opened)}")
    print(f"  b.capture(), warm (captures 2..N)      {ms(warm)}")
    print(f"  the script's warm step                 {ms(script)}")
    print(f"  script step / warm capture             {speedup:7.2f}x   target >= {WARM_SPEEDUP}x: "
          f"{'met' if speedup >= WARM_SPEEDUP else 'MISSED'}")
    print(f"  new Bench + first capture (files)      {ms(first)}")
    print(f"  one-shot radbench capture (process)    {ms(one_shot)}")
    print(f"  first capture / one-shot               {ratio:7.2f}x   target <= {FIRST_RATIO}x: "
          f"{'met' if ratio <= FIRST_RATIO else 'MISSED'}")
    print(json.dumps({"warm_s": med(warm), "script_step_s": med(script), "speedup": speedup,
                      "first_s": med(first), "one_shot_s": med(one_shot), "first_ratio": ratio,
                      "opened_s": med(opened)}))
    return 0 if speedup >= WARM_SPEEDUP and ratio <= FIRST_RATIO else 1


if __name__ == "__main__":
    sys.exit(main())
