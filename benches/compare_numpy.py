#!/usr/bin/env python3
"""Times numpy/scipy versions of radbench's five DSP kernels on the same inputs, in the same run,
and prints the speed ratios against the issue's targets.

    python3 benches/compare_numpy.py [--radbench target/release/radbench] [--min-time 0.5]

The script runs `radbench bench --json --write-inputs DIR` (which writes the seeded inputs as .npy),
loads those inputs, times the numpy/scipy steps with the same repeat rule (median of at least
9 runs and 0.5 s), and prints `ratio = numpy median / radbench median`. numpy, scipy and their BLAS are pinned to one
thread, as radbench is. Needs numpy and scipy (e.g. `python3 -m venv /tmp/venv &&
/tmp/venv/bin/pip install numpy scipy`).
"""

import os

# Pin every numerical library to one thread *before* numpy is imported.
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
            "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.fft  # noqa: E402
import scipy.signal  # noqa: E402

# Minimum speed-up of radbench over the numpy/scipy step (issue 2, "Speed").
TARGETS = {
    "decimate_800k": 15.0,
    "decimate_1280k": 15.0,
    "xcorr_160k": 2.5,
    "ofdm_rx_100sym": 2.0,
    "music_m64": 1.5,
}


def time_median(fn, min_runs, min_time):
    fn()  # warm-up (plans, caches)
    times = []
    start = time.perf_counter()
    while len(times) < min_runs or (time.perf_counter() - start < min_time and len(times) < 200):
        t = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t) * 1e3)
    return float(np.median(times)), len(times)


def numpy_kernels(d, meta):
    """numpy/scipy versions of the kernels; each returns its result."""
    factor = meta["decimation_factor"]
    # One full-length FFT per capture (scipy's fastest size), transmit spectrum cached.
    fft_len = scipy.fft.next_fast_len(meta["xcorr_min_single_fft_len"])
    lags = meta["xcorr_lags"]
    tx_spec_conj = np.conj(scipy.fft.fft(d["msk_tx"], fft_len))  # cached, as in radbench
    o = meta["ofdm"]
    n, fft_n, cp, symbols, zp = o["subcarriers"], o["fft_len"], o["cp_len"], o["symbols"], o["zero_pad"]
    bins = (np.arange(n) - n // 2) % fft_n
    tx_symbols = d["ofdm_tx_symbols"].reshape(symbols, n)
    unscale = np.sqrt(n) / fft_n  # undo the generator's unit-power scale
    m_cfg = meta["music"]
    m, p, grid = m_cfg["m"], m_cfg["p"], m_cfg["grid_points"]
    exchange = np.eye(m)[::-1]

    def decimate(x):
        return scipy.signal.resample_poly(x, 1, factor)

    def xcorr():
        spec = scipy.fft.fft(d["msk_rx"], fft_len)
        return scipy.fft.ifft(spec * tx_spec_conj)[:lags] * fft_len

    def ofdm_rx():
        frames = d["ofdm_rx"].reshape(symbols, cp + fft_n)[:, cp:]
        sub = scipy.fft.fft(frames, axis=1)[:, bins] * unscale
        mean = (sub / tx_symbols).mean(axis=0)
        return np.abs(scipy.fft.ifft(mean, n * zp)) * zp  # sum / N, as radbench

    def music():
        x = d["music_column"]
        snaps = np.lib.stride_tricks.sliding_window_view(x, m)  # (N - M + 1, M)
        r = snaps.T @ snaps.conj() / snaps.shape[0]
        r = 0.5 * (r + exchange @ r.conj() @ exchange)
        _, vecs = np.linalg.eigh(r)
        signal = vecs[:, -p:]
        proj = np.abs(scipy.fft.ifft(signal, grid, axis=0) * grid) ** 2
        return 1.0 / np.maximum(m - proj.sum(axis=1), 1e-12 * m)

    return {
        "decimate_800k": lambda: decimate(d["capture_800k"]),
        "decimate_1280k": lambda: decimate(d["capture_1280k"]),
        "xcorr_160k": xcorr,
        "ofdm_rx_100sym": ofdm_rx,
        "music_m64": music,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--radbench", default="target/release/radbench",
                    help="radbench binary (default: target/release/radbench)")
    ap.add_argument("--min-runs", type=int, default=9)
    ap.add_argument("--min-time", type=float, default=0.5)
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="radbench-bench-") as tmp:
        out = subprocess.run(
            [args.radbench, "bench", "--json", "--write-inputs", tmp,
             "--min-runs", str(args.min_runs), "--min-time", str(args.min_time)],
            check=True, capture_output=True, text=True)
        rust = {k["name"]: k for k in json.loads(out.stdout)["kernels"]}
        with open(os.path.join(tmp, "meta.json")) as f:
            meta = json.load(f)
        names = ["capture_800k", "capture_1280k", "msk_tx", "msk_rx", "ofdm_tx_symbols",
                 "ofdm_rx", "music_column"]
        data = {n: np.load(os.path.join(tmp, n + ".npy")) for n in names}

    kernels = numpy_kernels(data, meta)
    try:
        load = os.getloadavg()
    except OSError:
        load = (float("nan"),) * 3
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}")
    print(f"numpy {np.__version__}, scipy {scipy.__version__}, python {platform.python_version()}; "
          "all pinned to one thread")
    print(f"{'kernel':<16} {'radbench ms':>12} {'numpy ms':>10} {'ratio':>7} {'target':>7}  verdict")
    failed = 0
    for name, target in TARGETS.items():
        ms, _ = time_median(kernels[name], args.min_runs, args.min_time)
        ours = rust[name]["median_ms"]
        ratio = ms / ours
        ok = ratio >= target
        failed += not ok
        print(f"{name:<16} {ours:>12.3f} {ms:>10.3f} {ratio:>6.1f}x {target:>6.1f}x  "
              f"{'meets' if ok else 'BELOW target'}")
    print("ratio = numpy/scipy median time / radbench median time (higher is better for radbench)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
