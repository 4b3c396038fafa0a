#!/usr/bin/env python3
"""How soon the live page shows a result: headless Chromium on the live view of a campaign.

Runs `radbench campaign run SPEC --allow-rf --live --json` on the built-in mock lab (loopback
only), opens the printed URL in headless Chromium (the interop suite's DevTools driver, every host
name but 127.0.0.1 unresolvable) and, once the campaign is complete, reads the page's latency
record: for each state the page drew, the wall-clock time its oldest result was handed to the live
view (`event_unix_ms`, radbench's clock), when the state was published (`published_unix_ms`) and
when the page's DOM had been updated with it (`Date.now()` right after the re-drawing). Both
clocks are this machine's. Prints the median, 95th percentile and largest delay over the states
that carried a new step (the table grew) and over all, for ROUNDS campaigns.

    .venv-interop/bin/python benches/live_latency.py [--radbench target/debug/radbench]
        [--rounds 3] [--steps 30]

SPEC is examples/accuracy.toml with --steps steps of 5 mm.
"""

import argparse
import json
import os
import re
import select
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "interop"))

from test_report_browser import Browser  # noqa: E402

LIMIT_S = 300


def spec_with_steps(tmp: Path, steps: int) -> Path:
    text = (REPO / "examples" / "accuracy.toml").read_text()
    text = re.sub(r"^count = \d+", f"count = {steps}", text, count=1, flags=re.M)
    text = re.sub(r"^step = -0\.03", "step = -0.005", text, count=1, flags=re.M)
    spec = tmp / "live-latency.toml"
    spec.write_text(text)
    return spec


def read_line(proc, deadline) -> str:
    line = b""
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        assert left > 0, "radbench printed no live event in time"
        ready, _, _ = select.select([proc.stdout], [], [], left)
        if ready:
            c = os.read(proc.stdout.fileno(), 1)
            assert c, "radbench closed its stdout"
            line += c
    return line.decode()


def one(radbench: str, spec: Path, tmp: Path, k: int):
    out = tmp / f"run-{k}"
    proc = subprocess.Popen(
        [radbench, "campaign", "run", str(spec), "--allow-rf", "--out", str(out), "--json", "--live"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    browser = Browser(tmp / f"profile-{k}", resolver_rules="MAP * ~NOTFOUND, EXCLUDE 127.0.0.1")
    browser.deadline = time.monotonic() + LIMIT_S
    try:
        url = json.loads(read_line(proc, time.monotonic() + LIMIT_S))["url"]
        browser.open(url)
        while browser.evaluate("document.getElementById('status').textContent") != "complete":
            assert time.monotonic() < browser.deadline, "the campaign did not complete in time"
            time.sleep(0.2)
        record = browser.evaluate("window.radbenchLatency")
        _, err = proc.communicate(timeout=LIMIT_S)
        assert proc.returncode == 0, err.decode()
    finally:
        browser.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    return record


def describe(name, values):
    values = sorted(values)
    if not values:
        return f"{name}: none"
    p95 = values[min(len(values) - 1, int(round(0.95 * (len(values) - 1))))]
    return (
        f"{name}: median {statistics.median(values):.1f} ms, 95th percentile {p95:.1f} ms, "
        f"largest {values[-1]:.1f} ms ({len(values)} states)"
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--radbench", default=os.environ.get("RADBENCH_BIN", str(REPO / "target/debug/radbench")))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=30)
    a = ap.parse_args()
    steps, every = [], []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        spec = spec_with_steps(tmp, a.steps)
        for k in range(a.rounds):
            record = one(a.radbench, spec, tmp, k)
            last_rows = None
            for r in record:
                delay = r["dom_ms"] - r["event_ms"]
                every.append(delay)
                if last_rows is not None and r["rows"] > last_rows:
                    steps.append(delay)
                last_rows = r["rows"]
    print(f"{a.rounds} campaigns of {a.steps} steps, load average {os.getloadavg()[0]:.1f}")
    print(describe("result handed over -> DOM updated, states with a new step", steps))
    print(describe("result handed over -> DOM updated, every state", every))


if __name__ == "__main__":
    main()
