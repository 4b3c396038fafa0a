#!/usr/bin/env python3
"""Phase ranging's errors on the realistic bench, with the scene's terms switched off one at a
time (docs/metrology.md, "Measured"): the bias, the spread within and between calibrations, the
stated uncertainty and the coverage (truth within +-1.96 sd), in phase and envelope mode.

The scene is tests/cli/metrology.rs's: thesis-lab chain, clutter at the horns (0.02 m, 0.02) and
a wall at 12.5 m (0.1), leakage 0.03 at 0.2 ns, 1 kHz of LO phase noise, Rx DC and I/Q errors,
1 ps of trigger jitter, SNR 30 dB; NCAL response calibrations on a pillar at 1.0 m + CAL_OFF
(the wall taken away, as the test does), PER captures each at random positions within +-SPAN/2
of 1.0 m, then `process --ranging envelope` of them.

    cargo build && python3 benches/phase_error_terms.py base
    python3 benches/phase_error_terms.py no-phase-noise pn=0
    python3 benches/phase_error_terms.py cal-quarter pn=0 cal_off=0.000937 ncal=4

Keys: wall=0/1, horns=0/1, pn=HZ (linewidth), leak=AMPLITUDE, iq=0/1 (Rx DC and I/Q errors),
jit=SECONDS, cal_off=M, cal_rand=0/1 (each calibration at a random offset within +-5 mm), ncal,
per, span=M, jobs, env=0/1. RADBENCH_BIN picks the binary (target/debug/radbench by default).
Deterministic (seeded); everything stays in a temporary folder. About 1 s a capture and 6 s a
calibration in the debug build.
"""
import json, math, os, random, shutil, statistics as st, subprocess, sys, tempfile
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.abspath(os.environ.get('RADBENCH_BIN', os.path.join(ROOT, 'target/debug/radbench')))
HALF_LAMBDA = 299_792_458.0 / 80e9 / 2.0
cfg = dict(wall=1, horns=1, pn=1000.0, leak=0.03, iq=1, jit=1e-12, cal_off=0.0, cal_rand=0,
           ncal=8, per=16, span=0.01, jobs=2, env=1)
name = sys.argv[1] if len(sys.argv) > 1 else 'base'
for kv in sys.argv[2:]:
    k, v = kv.split('=')
    cfg[k] = type(cfg[k])(float(v))


def scene(range_m, seed, wall):
    clutter = ([(0.02, 0.02)] if cfg['horns'] else []) + ([(12.5, 0.1)] if wall else [])
    s = f'snr_db = 30.0\ntrigger_jitter_s = {cfg["jit"]!r}\nseed = {seed}\n'
    if not clutter:
        s += 'clutter = []\n'
    s += f'\n[[targets]]\nrange_m = {range_m!r}\namplitude = 0.5\n'
    for r, a in clutter:
        s += f'\n[[clutter]]\nrange_m = {r}\namplitude = {a}\n'
    s += f'\n[leakage]\namplitude = {cfg["leak"]}\ndelay_s = 2e-10\n'
    s += f'\n[impairments]\nphase_noise_linewidth_hz = {cfg["pn"]}\n'
    if cfg['iq']:
        s += 'dc_offset_v = [0.002, -0.001]\niq_gain_db = 0.3\niq_phase_deg = 2.0\n'
    return s + '\n[chain]\npreset = "thesis-lab"\n'


def run(d, args):
    p = subprocess.run([BIN] + args, cwd=d, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f'{args}: {p.stderr}')
    return json.loads(p.stdout)


def nearest(targets, near):
    t = min(targets, key=lambda t: abs(t['range_m'] - near))
    return t['range_m'], t.get('range_std_m', float('nan'))


def one_calibration(job):
    c, cal, positions = job
    d = tempfile.mkdtemp(prefix=f'phase_terms_{name}_')
    try:
        with open(f'{d}/ref.toml', 'w') as f:
            f.write(scene(cal, 40 + c, False))
        run(d, ['calibrate', 'response', '--reference-range', repr(cal), '--scene', 'ref.toml',
                '--allow-rf', '--out', 'response.toml', '--json', '--force'])
        rows = []
        for k, p in enumerate(positions):
            with open(f'{d}/p{k}.toml', 'w') as f:
                f.write(scene(p, 1000 * c + k, cfg['wall']))
            cap = run(d, ['capture', '--allow-rf', '--scene', f'p{k}.toml', '--calibration',
                          'response.toml', '--ranging', 'phase', '--json', '--out', f'p{k}'])
            r, s = nearest(cap['targets'], p)
            fell = 'keeps its envelope range' in json.dumps(cap.get('warnings'))
            rows.append(dict(c=c, p=p, cal=cal, err=r - p, sd=s, fell=fell))
        if cfg['env']:
            out = run(d, ['process', '--ranging', 'envelope', '--json', '--out', 'env']
                      + [f'p{k}' for k in range(len(positions))])
            for row, x in zip(rows, out['processed']):
                r, s = nearest(x['summary']['targets'], row['p'])
                row['eerr'], row['esd'] = r - row['p'], s
        return rows
    finally:
        shutil.rmtree(d, ignore_errors=True)


rng = random.Random(12345)
jobs = []
for c in range(int(cfg['ncal'])):
    cal = 1.0 + cfg['cal_off'] + ((rng.random() - 0.5) * 0.01 if cfg['cal_rand'] else 0.0)
    positions = [1.0 + cfg['span'] * (rng.random() - 0.5) for _ in range(int(cfg['per']))]
    jobs.append((c, cal, positions))
with ThreadPoolExecutor(int(cfg['jobs'])) as ex:
    rows = [r for rs in ex.map(one_calibration, jobs) for r in rs]

ph = [r for r in rows if not r['fell']]
e = [r['err'] * 1e6 for r in ph]
means = {c: st.mean(r['err'] * 1e6 for r in ph if r['c'] == c) for c in {r['c'] for r in ph}}
within = math.sqrt(st.mean((r['err'] * 1e6 - means[r['c']]) ** 2 for r in ph))
z = [abs(r['err'] / r['sd']) for r in rows]
print(name, cfg)
print(f'  phase: bias {st.mean(e):+.2f} um, spread within a calibration {within:.2f} um, between '
      f'calibrations {st.pstdev(list(means.values())):.2f} um, stated '
      f'{math.sqrt(st.mean((r["sd"] * 1e6) ** 2 for r in ph)):.2f} um; truth within 1.96 sd in '
      f'{100 * sum(x <= 1.96 for x in z) / len(z):.1f} % of {len(z)} (worst {max(z):.1f} sd); '
      f'{len(rows) - len(ph)} kept their envelope range')
# The error against the target's carrier phase relative to the calibration's, in tenths of a cycle.
bins = [[] for _ in range(10)]
for r in ph:
    bins[int(((r['p'] - r['cal']) / HALF_LAMBDA) % 1 * 10)].append(r['err'] * 1e6)
print('  by phase against the calibration (tenths of lambda/2), um: '
      + ' '.join(f'{st.mean(b):+.2f}' if b else 'n/a' for b in bins))
if cfg['env']:
    ee = [r['eerr'] * 1e6 for r in rows]
    ez = [abs(r['eerr'] / r['esd']) for r in rows]
    print(f'  envelope: bias {st.mean(ee):+.1f} um, spread {st.pstdev(ee):.1f} um, stated '
          f'{math.sqrt(st.mean((r["esd"] * 1e6) ** 2 for r in rows)):.1f} um; truth within 1.96 '
          f'sd in {100 * sum(x <= 1.96 for x in ez) / len(ez):.1f} %')
