#!/usr/bin/env python3
"""A corrected capture's processing, this radbench against an older one (issue 38: at most 1.2x
what it cost before that issue's work, the binary of 1f32a8c's parent).

Each binary calibrates on the same reference scene (a pillar at 1.0 m, `thesis-lab` chain, SNR
25 dB) and processes the same capture (a pillar at 2.3 m, taken by the older binary, whose files
both read) with `--correction none` and with `--correction rx` and its own calibration: one fresh
process per run, the binaries and modes taking turns so that a load that comes and goes hits
both. Prints best and median wall time and CPU time (user + system, children) per binary, mode
and waveform, the ratios, and the load average.

    python3 benches/correction_against_before.py --before OLD_BIN [--after target/release/radbench] [--runs 15]

Everything stays in a temporary folder.
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

SCENE = """snr_db = 25.0
seed = {seed}
[[targets]]
range_m = {range_m}
amplitude = 0.5
[chain]
preset = "thesis-lab"
"""


def run(args, cwd):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(args, cwd=cwd, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({done.returncode}): {done.stderr.decode()[-400:]}")
    return wall, cpu


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", required=True, help="the older radbench binary")
    p.add_argument("--after", default="target/release/radbench", help="this radbench binary")
    p.add_argument("--runs", type=int, default=15)
    a = p.parse_args()
    bins = {"before": os.path.realpath(a.before), "after": os.path.realpath(a.after)}
    with tempfile.TemporaryDirectory() as work:
        for name, (range_m, seed) in {"reference": (1.0, 7), "pillar": (2.3, 11)}.items():
            with open(os.path.join(work, f"{name}.toml"), "w") as f:
                f.write(SCENE.format(range_m=range_m, seed=seed))
        waveforms = ["msk-lfm", "ofdm"]
        for w in waveforms:
            for b, path in bins.items():
                run([path, "calibrate", "response", "--reference-range", "1.0", "--scene",
                     "reference.toml", "--allow-rf", "--waveform", w, "--out",
                     f"cal-{b}-{w}.toml"], work)
            run([bins["before"], "capture", "--allow-rf", "--scene", "pillar.toml",
                 "--waveform", w, "--correction", "none", "--out", f"cap-{w}"], work)
        load = open("/proc/loadavg").read().split()[0]
        times = {}
        for w in waveforms:
            for _ in range(a.runs):
                for b, path in bins.items():
                    for mode in ["none", "rx"]:
                        subprocess.run(["rm", "-rf", os.path.join(work, "out")])
                        extra = ["--calibration", f"cal-{b}-{w}.toml"] if mode == "rx" else []
                        t = run([path, "process", f"cap-{w}", "--correction", mode, *extra,
                                 "--out", "out"], work)
                        times.setdefault((w, b, mode), []).append(t)
        print(f"radbench process, {a.runs} runs each, load average {load} -> "
              f"{open('/proc/loadavg').read().split()[0]} ({os.cpu_count()} cores)")
        for w in waveforms:
            best = {}
            for b in bins:
                for mode in ["none", "rx"]:
                    walls = sorted(t[0] for t in times[(w, b, mode)])
                    cpus = sorted(t[1] for t in times[(w, b, mode)])
                    best[(b, mode)] = (walls[0], statistics.median(walls), statistics.median(cpus))
                    print(f"  {w:8} {b:6} {mode:4}: wall best {walls[0] * 1e3:4.0f} ms, median "
                          f"{statistics.median(walls) * 1e3:4.0f} ms; CPU median "
                          f"{statistics.median(cpus) * 1e3:4.0f} ms")
            ratio = [best[("after", "rx")][i] / best[("before", "rx")][i] for i in range(3)]
            print(f"  {w:8} rx after / before: wall best {ratio[0]:.2f}x, wall median "
                  f"{ratio[1]:.2f}x, CPU median {ratio[2]:.2f}x")


if __name__ == "__main__":
    main()
