#!/usr/bin/env python3
"""The calibration's phase anchor against the calibration pillar's place in the carrier's cycle
(docs/metrology.md, "The anchor, term by term"): `calibrate response` on a pillar at R0 + k lambda/(2 STEPS),
k = 0..STEPS-1, each anchor's `phase_to_leakage_rad` less the phase the move should give
(-4 pi dR / lambda), relative to the first. A perfect anchor gives 0 everywhere.

    cargo build -p radbench --bin radbench
    python3 benches/anchor_sweep.py leak=0.025 chain=ideal
    python3 benches/anchor_sweep.py leak=0.005 chain=thesis-lab horns=1 iq=1

Keys: leak=AMPLITUDE (pillar 0.5: 0.025 is -26 dB, 0.005 -40 dB), chain=ideal|thesis-lab,
horns=0/1 (clutter 0.02 at 0.02 m), iq=0/1 (Rx DC and I/Q errors), snr=DB, jit=SECONDS, r0=M,
steps, seed, gate=NS (0: the default), jobs. RADBENCH_BIN picks the binary. Deterministic.
"""
import json, math, os, shutil, subprocess, sys, tempfile, tomllib
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.abspath(os.environ.get('RADBENCH_BIN', os.path.join(ROOT, 'target/debug/radbench')))
LAMBDA = 299_792_458.0 / 80e9
cfg = dict(leak=0.025, chain='ideal', horns=0, iq=0, snr=30.0, jit=0.0, r0=1.0, steps=10,
           seed=7, gate=0.0, jobs=2)
for kv in sys.argv[1:]:
    k, v = kv.split('=')
    cfg[k] = v if isinstance(cfg[k], str) else type(cfg[k])(float(v))


def scene(range_m):
    s = f'snr_db = {cfg["snr"]}\ntrigger_jitter_s = {cfg["jit"]!r}\nseed = {cfg["seed"]}\n'
    s += 'clutter = []\n' if not cfg['horns'] else ''
    s += f'\n[[targets]]\nrange_m = {range_m!r}\namplitude = 0.5\n'
    if cfg['horns']:
        s += '\n[[clutter]]\nrange_m = 0.02\namplitude = 0.02\n'
    s += f'\n[leakage]\namplitude = {cfg["leak"]}\ndelay_s = 2e-10\n'
    if cfg['iq']:
        s += '\n[impairments]\ndc_offset_v = [0.002, -0.001]\niq_gain_db = 0.3\niq_phase_deg = 2.0\n'
    return s + f'\n[chain]\npreset = "{cfg["chain"]}"\n'


def anchor(k):
    r = cfg['r0'] + k * LAMBDA / 2 / cfg['steps']
    d = tempfile.mkdtemp(prefix='anchor_sweep_')
    try:
        with open(f'{d}/ref.toml', 'w') as f:
            f.write(scene(r))
        args = [BIN, 'calibrate', 'response', '--reference-range', repr(r), '--scene', 'ref.toml',
                '--allow-rf', '--out', 'response.toml', '--json', '--force']
        if cfg['gate'] > 0:
            args += ['--gate-ns', repr(cfg['gate'])]
        p = subprocess.run(args, cwd=d, capture_output=True, text=True)
        if p.returncode != 0:
            raise RuntimeError(p.stderr)
        with open(f'{d}/response.toml', 'rb') as f:
            h = tomllib.load(f)
        a = h['reference'].get('phase_anchor')
        return r, a, h
    finally:
        shutil.rmtree(d, ignore_errors=True)


with ThreadPoolExecutor(int(cfg['jobs'])) as ex:
    rows = list(ex.map(anchor, range(int(cfg['steps']))))
r0, a0, _ = rows[0]
dev = []
for r, a, h in rows:
    expected = -4 * math.pi * (r - r0) / LAMBDA
    x = a['phase_to_leakage_rad'] - a0['phase_to_leakage_rad'] - expected
    dev.append(math.remainder(x, 2 * math.pi) * 1e3)
print({k: v for k, v in cfg.items() if k != 'jobs'})
print('  anchor less the move, mrad: ' + ' '.join(f'{d:+.2f}' for d in dev))
print(f'  peak-to-peak {max(dev) - min(dev):.2f} mrad; stated phase sd '
      f'{a0["phase_std_rad"] * 1e3:.2f} mrad; leakage at {a0["leakage_range_m"]:.4f} m, '
      f'gate {rows[0][2]["gate_ns"]:.2f} ns')
