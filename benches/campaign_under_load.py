#!/usr/bin/env python3
"""A campaign on a busy PC: `radbench campaign run examples/accuracy.toml --allow-rf` on the
built-in mock lab, quiet and then beside two busy processes, and the ratio (issue 23: at most
3x its quiet time with two busy processes on 2 cores).

The busy processes are `python3 -c "while True: pass"`, started by this script (so they share its
session and autogroup with radbench, as when a shell or a service starts both) and always killed
when it ends: on success, on an error, on Ctrl-C or SIGTERM; they also get SIGKILL from the kernel
should this script die outright (PR_SET_PDEATHSIG).

Besides the wall time it reads each run's I/O journal and manifest, to show that the capture path
(the bench's exchanges) is not delayed by the step worker: per step (steps 2..N: step 1 also
connects and uploads), from the step's first exchange (the AWG state read) to its last (the safe
state),

* `capture`: the whole capture path of the step, instruments included;
* `control`: the control exchanges only (the step minus the scope's arm + acquisition and its
  two waveform transfers, which are the simulated lab's own work): what a reply queued behind
  another thread shows up in;

and the manifest's `wait_s` (how long the run waited for the step worker). Quiet, these must match
those of a worker that never runs while the capture path does (`--compare-idle` runs the old
idle-class worker for that, quiet only: beside two busy processes it barely runs at all).

    python3 benches/campaign_under_load.py [--runs N] [--busy N] [--compare-idle] [--no-build]
"""

import argparse
import ctypes
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPEC = "examples/accuracy.toml"
BUSY = [sys.executable, "-c", "while True: pass"]


def die_with_parent():
    # PR_SET_PDEATHSIG = 1: SIGKILL this child when the script's thread dies.
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)
    except OSError:
        pass


class BusyProcesses:
    """N busy loops, killed when the `with` block ends however it ends."""

    def __init__(self, n):
        self.n = n
        self.procs = []

    def __enter__(self):
        for _ in range(self.n):
            self.procs.append(subprocess.Popen(BUSY, preexec_fn=die_with_parent))
        time.sleep(0.5)  # let them reach full speed (and the load average follow)
        return self

    def __exit__(self, *exc):
        for p in self.procs:
            p.kill()
        for p in self.procs:
            p.wait()
        self.procs.clear()
        return False


def load():
    return Path("/proc/loadavg").read_text().split()[0]


def journal_steps(journal):
    """Per step after the first: (capture_ms, control_ms)."""
    lines = [json.loads(l) for l in journal.read_text().splitlines() if l.strip()]
    lines = [l for l in lines if l["direction"] != "event"]

    def end(l):
        t = l["time"]
        # 2026-11-27T06:57:38.410121Z -> seconds of the day (runs do not cross midnight here).
        h, m, s = t[11:-1].split(":")
        return int(h) * 3600 + int(m) * 60 + float(s)

    def start(l):
        return end(l) - l["elapsed_us"] / 1e6

    starts = [
        i
        for i, l in enumerate(lines)
        if l["direction"] == "write"
        and l["instrument"] == "awg"
        and l.get("text", "").startswith(":INST:DACM?")
    ]
    # The first state read is part of the upload, before step 1's capture; the others start
    # steps 2..N.
    bounds = starts[1:] + [len(lines)]
    steps = []
    for a, b in zip(bounds, bounds[1:]):
        seg = lines[a:b]
        lab = 0.0
        for i, l in enumerate(seg):
            text = l.get("text", "")
            if l["instrument"] == "scope" and text.startswith(("TRMD SINGLE", "C1:WF?", "C2:WF?")):
                # the request and its reply: from the request's start to the reply's end
                lab += end(seg[i + 1]) - start(l)
                last_transfer = i + 1
        # The step ends with its safe state: the AWG's error read after its outputs go off, and
        # each module's attenuation read back at maximum (the run's own safe state at the end
        # comes later, after waiting for the worker, and is not counted).
        rest = seg[last_transfer + 1 :]
        ends = [next(end(l) for l in rest if l["instrument"] == "awg" and l["direction"] == "read")]
        for module in ("tx", "rx"):
            for i, l in enumerate(rest):
                if l["instrument"] == module and l.get("text", "").startswith("R 03"):
                    ends.append(end(rest[i + 1]))
                    break
        capture = max(ends) - start(seg[0])
        steps.append((capture * 1e3, (capture - lab) * 1e3))
    return steps


def one_run(binary, work, env, label, i):
    out = work / f"{label}-{i}"
    t0 = time.monotonic()
    r = subprocess.run(
        [binary, "campaign", "run", SPEC, "--allow-rf", "--out", str(out)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    wall = time.monotonic() - t0
    if r.returncode != 0:
        sys.exit(f"campaign failed ({label}, run {i}):\n{r.stderr}")
    manifest = tomllib.loads((out / "manifest.toml").read_text())
    timing = manifest["sessions"][-1]["timing"]
    steps = journal_steps(out / "io-journal.jsonl")
    return {
        "wall": wall,
        "wait": timing.get("wait_s", 0.0),
        "capture": statistics.median(s[0] for s in steps),
        "control": statistics.median(s[1] for s in steps),
    }


def series(binary, work, env, label, runs):
    before = load()
    rs = [one_run(binary, work, env, label, i) for i in range(runs)]
    return {
        "label": label,
        "load": f"{before} -> {load()}",
        "wall": statistics.median(r["wall"] for r in rs),
        "walls": [r["wall"] for r in rs],
        "wait": statistics.median(r["wait"] for r in rs),
        "capture": statistics.median(r["capture"] for r in rs),
        "control": statistics.median(r["control"] for r in rs),
    }


def show(s):
    walls = ", ".join(f"{w:.2f}" for w in s["walls"])
    print(
        f"  {s['label']:<24} {s['wall']:7.2f} s  (runs {walls}; load {s['load']})\n"
        f"  {'':<24} per step: capture {s['capture']:6.1f} ms, control exchanges"
        f" {s['control']:5.1f} ms; waited for the worker {s['wait']:.2f} s"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3, help="campaigns per condition (median)")
    ap.add_argument("--busy", type=int, default=2, help="busy processes for the loaded runs")
    ap.add_argument("--bin", default=os.environ.get("RADBENCH_BIN"), help="radbench binary")
    ap.add_argument("--no-build", action="store_true", help="do not run cargo build --release")
    ap.add_argument(
        "--compare-idle",
        action="store_true",
        help="also run quiet with the old idle-class worker (RADBENCH_STEP_WORKER=idle)",
    )
    args = ap.parse_args()

    binary = args.bin or str(ROOT / "target/release/radbench")
    if not args.no_build and not args.bin:
        subprocess.run(
            ["cargo", "build", "--release", "-p", "radbench", "--bin", "radbench"],
            cwd=ROOT,
            check=True,
        )
    env = dict(os.environ)
    env.pop("RADBENCH_STEP_WORKER", None)

    print(
        f"radbench campaign run {SPEC} --allow-rf, built-in mock lab, {os.cpu_count()} cores,"
        f" median of {args.runs}:"
    )
    with tempfile.TemporaryDirectory(prefix="campaign-under-load-") as tmp:
        work = Path(tmp)
        one_run(binary, work, env, "warm-up", 0)  # page cache, first-run costs
        quiet = series(binary, work, env, "quiet", args.runs)
        show(quiet)
        if args.compare_idle:
            idle = series(
                binary, work, dict(env, RADBENCH_STEP_WORKER="idle"), "quiet, idle-class worker", args.runs
            )
            show(idle)
        with BusyProcesses(args.busy):
            loaded = series(binary, work, env, f"{args.busy} busy processes", args.runs)
        show(loaded)
    ratio = loaded["wall"] / quiet["wall"]
    print(f"  loaded / quiet: {ratio:.2f}x (target: at most 3x)")
    return 0 if ratio <= 3.0 else 1


if __name__ == "__main__":
    sys.exit(main())
