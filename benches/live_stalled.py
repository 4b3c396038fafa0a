#!/usr/bin/env python3
"""A campaign with the live view and a stalled browser against the same campaign without one.

Runs `radbench campaign run SPEC --allow-rf --json --live` on the built-in mock lab ROUNDS times
each way, alternating: once with no browser, once with a "browser" that asks for the event stream
as soon as the URL is printed and never reads a byte of it. Prints the median and spread of the
campaign's own duration (the manifest's session timing, `total_s`) and of the command's wall time,
each way.

    python3 benches/live_stalled.py [--radbench target/release/radbench] [--rounds 5] [--steps 30]
"""

import argparse
import json
import os
import re
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
    text = re.sub(r"^step = -0\.03", "step = -0.01", text, count=1, flags=re.M)
    spec = tmp / "live-bench.toml"
    spec.write_text(text)
    return spec


def one(radbench: str, spec: Path, out: Path, stalled: bool):
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [radbench, "campaign", "run", str(spec), "--allow-rf", "--out", str(out), "--json", "--live"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    line = proc.stdout.readline()
    url = json.loads(line)["url"]
    browser = None
    if stalled:
        host, port, token = re.match(r"http://([\d.]+):(\d+)/\?token=(\w+)", url).groups()
        browser = socket.create_connection((host, int(port)))
        browser.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        browser.sendall(f"GET /events?token={token} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
    for _ in proc.stdout:
        pass
    code = proc.wait()
    wall = time.monotonic() - t0
    if browser:
        browser.close()
    assert code == 0, f"radbench exited {code}"
    manifest = tomllib.loads((out / "manifest.toml").read_text())
    return manifest["sessions"][0]["timing"]["total_s"], wall


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--radbench", default=os.environ.get("RADBENCH_BIN", str(REPO / "target/release/radbench")))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=30)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        spec = spec_with_steps(tmp, a.steps)
        runs = {False: [], True: []}
        for r in range(a.rounds):
            for stalled in (False, True):
                runs[stalled].append(one(a.radbench, spec, tmp / f"run-{r}-{stalled}", stalled))
        for stalled, label in ((False, "no browser"), (True, "a stalled browser")):
            camp = [x[0] for x in runs[stalled]]
            wall = [x[1] for x in runs[stalled]]
            print(
                f"{label:18}: campaign {statistics.median(camp):.3f} s "
                f"(min {min(camp):.3f}, max {max(camp):.3f}); command {statistics.median(wall):.3f} s "
                f"(min {min(wall):.3f}, max {max(wall):.3f}); {a.steps} steps, {a.rounds} runs"
            )


if __name__ == "__main__":
    sys.exit(main())
