#!/usr/bin/env python3
"""A campaign with the live view and a stalled browser against the same campaign without one.

Runs `radbench campaign run SPEC --allow-rf --json` on the built-in mock lab ROUNDS times each
way, in turn: without `--live`; with `--live` and no browser; with `--live` and a "browser" that
asks for the event stream as soon as the URL is printed (its receive buffer 4 KiB) and never reads
a byte of it. SPEC is examples/accuracy.toml with --steps steps of 5 mm (120 by default: its frames, about 20 kB
each, then overflow the kernel's socket buffers, so the stalled browser really holds its frames up). Prints the median and spread of the
campaign's own duration (the manifest's session timing, `total_s`) and of the command's wall time,
each way, and of its CPU time (user + system, getrusage of the child), which the machine's load
moves less than the durations.

    python3 benches/live_stalled.py [--radbench target/release/radbench] [--rounds 4] [--steps 120]
"""

import argparse
import json
import os
import re
import resource
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def spec_with_steps(tmp: Path, steps: int) -> Path:
    text = (REPO / "examples" / "accuracy.toml").read_text()
    text = re.sub(r"^count = \d+", f"count = {steps}", text, count=1, flags=re.M)
    text = re.sub(r"^step = -0\.03", "step = -0.005", text, count=1, flags=re.M)
    spec = tmp / "live-bench.toml"
    spec.write_text(text)
    return spec


def one(radbench: str, spec: Path, out: Path, mode: str):
    """mode: "off" (no --live), "live" (no browser), "stalled"."""
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    live = ["--live"] if mode != "off" else []
    proc = subprocess.Popen(
        [radbench, "campaign", "run", str(spec), "--allow-rf", "--out", str(out), "--json", *live],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    browser = None
    if mode != "off":
        url = json.loads(proc.stdout.readline())["url"]
    if mode == "stalled":
        host, port, token = re.match(r"http://([\d.]+):(\d+)/\?token=(\w+)", url).groups()
        browser = socket.socket()
        browser.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        browser.connect((host, int(port)))
        browser.sendall(f"GET /events?token={token} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
    _, err = proc.communicate()
    code = proc.returncode
    wall = time.monotonic() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    if browser:
        browser.close()
    assert code == 0, f"radbench exited {code}"
    manifest = tomllib.loads((out / "manifest.toml").read_text())
    # radbench prints the live view's counters on stderr when it closes.
    m = re.search(r"live view closed: (\d+) frames published, (\d+) skipped", err.decode())
    frames, skipped = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
    return manifest["sessions"][0]["timing"]["total_s"], wall, frames, skipped, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--radbench", default=os.environ.get("RADBENCH_BIN", str(REPO / "target/release/radbench")))
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--steps", type=int, default=120)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        spec = spec_with_steps(tmp, a.steps)
        modes = (("off", "without --live"), ("live", "--live, no browser"), ("stalled", "--live, stalled browser"))
        runs = {m: [] for m, _ in modes}
        for r in range(a.rounds):
            for m, _ in modes:
                runs[m].append(one(a.radbench, spec, tmp / f"run-{r}-{m}", m))
        for m, label in modes:
            camp = [x[0] for x in runs[m]]
            wall = [x[1] for x in runs[m]]
            cpu = [x[4] for x in runs[m]]
            frames = statistics.median(x[2] for x in runs[m])
            skipped = statistics.median(x[3] for x in runs[m])
            print(
                f"{label:24}: campaign {statistics.median(camp):.3f} s "
                f"(min {min(camp):.3f}, max {max(camp):.3f}); command {statistics.median(wall):.3f} s "
                f"(min {min(wall):.3f}, max {max(wall):.3f}); CPU {statistics.median(cpu):.3f} s "
                f"(min {min(cpu):.3f}, max {max(cpu):.3f}); {a.steps} steps, {a.rounds} runs"
                + (f"; frames published {frames:.0f}, not sent to a browser {skipped:.0f}" if m != "off" else "")
            )


if __name__ == "__main__":
    sys.exit(main())
