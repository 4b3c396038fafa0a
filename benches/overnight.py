#!/usr/bin/env python3
"""A night on a glitching bench (issue 40): a campaign of N steps (default 5000) on `radbench
mock-lab serve`, with a transient fault injected over the lab's control channel about every 100
steps (a dropped AWG or scope connection, the Tx power-cycled, the marker cable out for longer
than the acquisition's wait), and radbench's memory (VmRSS), open file descriptors and threads
sampled every second. It prints the samples' first and last tenths (flat: no leak over the
night), the steps' own first and last tenths (the time between two steps' starts, and the step
worker's bookkeeping: hashing the files and storing the manifest, from radbench's debug log),
the manifest's size at the end, the faults injected and the retries the manifest recorded, and,
with --compare, whether results.json equals an undisturbed run's on a fresh lab.

It is a benchmark, not a test: minutes per run (about 50 ms a step on a quiet PC).

    python3 benches/overnight.py [--steps 5000] [--every 100] [--compare] [--bin PATH] [--no-build]

Only loopback is used: the lab listens on 127.0.0.1, and the faults are JSON lines on its control
channel: {"cmd":"fault","drop":"awg"}, {"cmd":"fault","drop":"scope"},
{"cmd":"fault","power_cycle":"tx","for_s":0.5}, {"cmd":"fault","marker_cable":false} (plugged
back 1.5 s later; the spec waits 1 s for a marker edge).
"""

import argparse
import json
import os
import random
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

FAULTS = [
    ({"cmd": "fault", "drop": "awg"}, None),
    ({"cmd": "fault", "drop": "scope"}, None),
    ({"cmd": "fault", "power_cycle": "tx", "for_s": 0.5}, None),
    ({"cmd": "fault", "marker_cable": False}, ({"cmd": "fault", "marker_cable": True}, 1.5)),
]


def control(address, request):
    host, port = address.rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall((json.dumps(request) + "\n").encode())
        reply = s.makefile().readline()
    answer = json.loads(reply)
    if not answer.get("ok"):
        raise RuntimeError(f"the lab refused {request}: {answer}")
    return answer


def start_lab(binary):
    lab = subprocess.Popen(
        [binary, "mock-lab", "serve", "--json"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        text=True,
    )
    described = json.loads(lab.stdout.readline())
    return lab, described


def bench_file(described, path):
    def resource(instrument, transport):
        for e in described["endpoints"]:
            if e["instrument"] == instrument and e["transport"] == transport and e.get("active", True):
                return e["resource"]
        raise SystemExit(f"the lab serves no {instrument} over {transport}")

    path.write_text(
        f'[awg]\nmodel = "keysight-m8195a"\nresource = "{resource("awg", "hislip")}"\n'
        f'[scope]\nmodel = "lecroy-labmaster10zi-a"\nresource = "{resource("scope", "vicp")}"\n'
        f'[tx]\nmodel = "gotmic-eband-tx"\nresource = "{resource("tx", "serial")}"\n'
        f'[rx]\nmodel = "gotmic-eband-rx"\nresource = "{resource("rx", "serial")}"\n'
        f'[simulation]\ncontrol = "{described["control"]}"\n'
    )


def spec_file(path, steps, bench):
    path.write_text(
        'name = "overnight"\nwait_s = 1.0\n'
        f'[bench]\nfile = "{bench}"\n'
        '[waveform]\nkind = "msk-lfm"\n'
        '[sweep]\nparameter = "position"\n'
        f"start = 1.0\nstep = {-0.5 / steps}\ncount = {steps}\n"
        "[run]\nretries = 2\nretry_backoff_s = 0.5\n"
        # A night's disk (docs/campaign.md, "Disk budget"): the SigMF recording stays, the
        # scope's own .trc copy and the bitmaps go (about 3.5 MB a step instead of 7).
        "[output]\nkeep_trc = false\nkeep_bitmaps = false\n"
    )


class Sampler(threading.Thread):
    """VmRSS (kB), open descriptors and threads of `pid`, and the load average, every second."""

    def __init__(self, pid):
        super().__init__(daemon=True)
        self.pid = pid
        self.samples = []
        self.stop = threading.Event()

    def run(self):
        while not self.stop.wait(1.0):
            try:
                status = Path(f"/proc/{self.pid}/status").read_text()
                fds = len(os.listdir(f"/proc/{self.pid}/fd"))
            except OSError:
                return
            fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
            rss = int(fields["VmRSS"].split()[0])
            threads = int(fields["Threads"])
            # The machine's load (1-minute average): the steps' times depend on it.
            load = float(Path("/proc/loadavg").read_text().split()[0])
            self.samples.append((time.monotonic(), rss, fds, threads, load))


# The runner's debug line per step (src/campaign/runner.rs, `settle_oldest`).
STEP_LOG = re.compile(r"step processed and written.*?step=(\d+).*?bookkeeping_s=([0-9.e-]+).*?waited_s=([0-9.e-]+)")


def run_campaign(binary, spec, out, every, inject, control_address, seed):
    cmd = [binary, "campaign", "run", str(spec), "--allow-rf", "--json", "--out", str(out)]
    # Warnings as without it, and the runner's line per step (the worker's bookkeeping time).
    env = dict(os.environ, RADBENCH_LOG="warn,radbench::campaign::runner=debug", NO_COLOR="1")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    sampler = Sampler(proc.pid)
    sampler.start()
    rng = random.Random(seed)
    injected = []
    timers = []
    notes = []
    err_reader = threading.Thread(target=lambda: notes.extend(proc.stderr), daemon=True)
    err_reader.start()
    next_at = every
    starts = {}
    for line in proc.stdout:
        event = json.loads(line)
        if event.get("event") != "start":
            continue
        index = event["index"]
        # The first start of each step (a retried step starts once).
        starts.setdefault(index, time.monotonic())
        if not inject:
            continue
        if index >= next_at:
            next_at = index + rng.randint(every // 2, every + every // 2)
            request, undo = FAULTS[len(injected) % len(FAULTS)]
            # Mid-step: the step's capture has just begun.
            time.sleep(0.005)
            control(control_address, request)
            injected.append((index, request))
            if undo:
                t = threading.Timer(undo[1], control, (control_address, undo[0]))
                t.start()
                timers.append(t)
    code = proc.wait()
    sampler.stop.set()
    sampler.join()
    err_reader.join(timeout=5)
    for t in timers:
        t.join()
    order = sorted(starts)
    step_s = [starts[b] - starts[a] for a, b in zip(order, order[1:]) if b == a + 1]
    bookkeeping = []
    kept_notes = []
    for note in notes:
        m = STEP_LOG.search(note)
        if m:
            bookkeeping.append((int(m[1]), float(m[2]), float(m[3])))
        else:
            kept_notes.append(note)
    bookkeeping.sort()
    return code, sampler.samples, injected, kept_notes, step_s, bookkeeping


def first_last(values):
    """Medians of the first and the last tenth of `values`."""
    n = max(1, len(values) // 10)
    return statistics.median(values[:n]), statistics.median(values[-n:])


def tenths(samples):
    return [
        (name, *first_last([r[k] for r in samples]))
        for name, k in (("VmRSS kB", 1), ("fds", 2), ("threads", 3), ("load avg", 4))
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--every", type=int, default=100, help="a fault about every N steps")
    ap.add_argument("--compare", action="store_true", help="also run undisturbed and compare results.json")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bin", default=os.environ.get("RADBENCH_BIN"), help="radbench binary")
    ap.add_argument("--no-build", action="store_true", help="do not run cargo build --release")
    ap.add_argument("--save", type=Path, help="write each run's samples and per-step times there (CSV)")
    args = ap.parse_args()
    binary = args.bin or str(ROOT / "target/release/radbench")
    if not args.no_build and not args.bin:
        subprocess.run(["cargo", "build", "--release", "-p", "radbench", "--bin", "radbench"], cwd=ROOT, check=True)

    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for label, inject in (("faults", True), ("undisturbed", False)):
            if label == "undisturbed" and not args.compare:
                break
            lab, described = start_lab(binary)
            try:
                bench = tmp / f"bench-{label}.toml"
                spec = tmp / f"spec-{label}.toml"
                bench_file(described, bench)
                spec_file(spec, args.steps, bench)
                out = tmp / f"run-{label}"
                t0 = time.monotonic()
                code, samples, injected, notes, step_s, bookkeeping = run_campaign(
                    binary, spec, out, args.every, inject, described["control"], args.seed
                )
                wall = time.monotonic() - t0
            finally:
                lab.terminate()
                lab.wait(timeout=30)
            manifest = tomllib.loads((out / "manifest.toml").read_text())
            retries = manifest.get("retries", [])
            print(f"{label}: exit {code}, {manifest['status']}, {args.steps} steps in {wall:.0f} s "
                  f"({1000 * wall / args.steps:.1f} ms a step)")
            if inject:
                print(f"  faults injected: {len(injected)}; retries recorded: {len(retries)}; "
                      f"steps retried: {len({r['step'] for r in retries})}")
                spent = [r for r in retries if r["attempt"] > 2]
                if spent:
                    print(f"  WARNING: {len(spent)} retries beyond the second")
            for name, first, last in tenths(samples):
                print(f"  {name:9}: first tenth {first:10.1f}, last tenth {last:10.1f}")
            if step_s:
                first, last = first_last(step_s)
                print(f"  step (start to next start), median: first tenth {1000 * first:.1f} ms, "
                      f"last tenth {1000 * last:.1f} ms")
            if bookkeeping:
                first, last = first_last([b for _, b, _ in bookkeeping])
                print(f"  worker's bookkeeping a step (hashing, manifest), median: first tenth "
                      f"{1000 * first:.1f} ms, last tenth {1000 * last:.1f} ms")
                first, last = first_last([w for _, _, w in bookkeeping])
                print(f"  capture path waiting for the worker a step, median: first tenth "
                      f"{1000 * first:.1f} ms, last tenth {1000 * last:.1f} ms")
            print(f"  manifest.toml at the end: {(out / 'manifest.toml').stat().st_size / 1e6:.1f} MB")
            if args.save:
                args.save.mkdir(parents=True, exist_ok=True)
                with open(args.save / f"{label}-samples.csv", "w") as f:
                    f.write("t_s,vmrss_kb,fds,threads,loadavg\n")
                    t0s = samples[0][0] if samples else 0
                    f.writelines(f"{t - t0s:.2f},{r},{d},{n},{a}\n" for t, r, d, n, a in samples)
                with open(args.save / f"{label}-steps.csv", "w") as f:
                    f.write("step,bookkeeping_s,waited_s\n")
                    f.writelines(f"{k},{b:.6f},{w:.6f}\n" for k, b, w in bookkeeping)
                with open(args.save / f"{label}-intervals.csv", "w") as f:
                    f.write("k,start_to_next_start_s\n")
                    f.writelines(f"{k},{v:.6f}\n" for k, v in enumerate(step_s, 1))
            if code != 0:
                print("".join(notes[-20:]), file=sys.stderr)
            results[label] = json.loads((out / "results.json").read_text())
            if args.save:
                shutil.copy(out / "results.json", args.save / f"{label}-results.json")
                if inject:
                    (args.save / "faults.json").write_text(json.dumps(
                        {"injected": injected, "retries": retries}, indent=1))
            # 5000 steps are ~17 GB: only results.json is compared, so the run goes before the next.
            shutil.rmtree(out)
    if args.compare:
        same = results["faults"] == results["undisturbed"]
        print(f"results.json equal to the undisturbed run's: {same}")
        if not same:
            a, b = results["faults"]["steps"], results["undisturbed"]["steps"]
            if len(a) != len(b):
                print(f"  {len(a)} steps against {len(b)}")
            differ = [x["index"] for x, y in zip(a, b) if x != y]
            print(f"  steps that differ ({len(differ)}): {differ[:40]}")
            for x, y in zip(a, b):
                if x != y:
                    keys = sorted(k for k in set(x) | set(y) if x.get(k) != y.get(k))
                    print(f"  first: step {x['index']}, keys {keys}")
                    break
        return 0 if same else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
