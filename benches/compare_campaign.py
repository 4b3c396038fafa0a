#!/usr/bin/env python3
"""Times the same MSK-LFM campaign steps with `radbench campaign run` and with a Python stack
(pyvisa + pyvisa-py HiSLIP for the AWG, pyvicp for the scope, the Gotmic serial lines through
the pseudo-terminals, numpy/scipy for the processing), against one `mock-lab serve`, in the same
run, and prints per-step wall and host times against the issue's targets (issue 10, "Speed").

    cargo build --release -p radbench --bin radbench -p mock_lab --bin mock-lab
    .venv-interop/bin/python benches/compare_campaign.py [--rounds 3] [--count 12]

The steps are those of examples/accuracy.toml (a pillar at 1.00 m, then steps of 3 cm toward the
radar; `--count` steps), one repetition each. One `mock-lab serve` runs for the whole comparison;
its table is the bench file radbench is given (`--bench`), and the Python client reads the same
resources from it. radbench and the script take turns (`--rounds`), so slow spells of a shared
machine fall on both.

What each side does per step, with its sessions kept open (as in a campaign):
  * radbench: the campaign runner: scene and noise seed on the lab's control channel, the AWG's
    state read back (the waveform is uploaded once per run), Rx then Tx enabled with their
    safety read-backs, AWG outputs on and playing, one marker-triggered acquisition, I and Q
    fetched, the safe state (Tx off, Rx off, AWG off); the processing (decimation
    80 -> 16 GSa/s, correlation range profile, detection, payload) and the step's files (SigMF,
    .trc, profile CSV/NPY/PNG/SVG, result.json, manifest) on its step worker, a thread in the idle
    scheduling class, beside the next steps' captures (at most two steps wait for it).
  * the script: the same scene request; Rx then Tx enabled through the same line protocol
    (CRC-8 framed) with the read-backs RF safety needs (status and faults before, control and
    status after the enable, the attenuation written back and verified); `:OUTP1..3 ON`,
    `:INIT:IMM`, `SYST:ERR?`; `INR?`, `TRMD SINGLE;ARM;WAIT 10;*OPC?`, `INR?`, `C1:WF? ALL`,
    `C2:WF? ALL`; Tx off, Rx off, AWG off (each verified); then numpy/scipy: WAVEDESC parsed,
    words to complex volts, FFT decimation 80 -> 16 GSa/s with the time origin moved to the
    marker edge, circular correlation with the transmitted codes, peaks with parabolic
    interpolation, MSK demodulation of the strongest echo and its bit errors. It writes no files.
    Its waveform (its own MSK-LFM, 10 us, 1 GHz, 128 PRBS bits, 8-bit codes 0.5 dB below full
    scale, marker on the first 64 samples) is uploaded once per round, like radbench's.

Figures:
  * step = the time between consecutive steps' ends, steps 2..N of each round (step 1 also holds
    the connection and the upload): radbench's from its `--json` step events as they arrive,
    the script's from its own clock.
  * instrument time per step = arm + acquisition wait (`TRMD SINGLE;ARM;WAIT 10;*OPC?`, query
    and reply) + the I and Q transfers (`C1:WF? ALL`, `C2:WF? ALL`, query and block): radbench's
    from its I/O journal (`elapsed_us` of those exchanges), the script's from timing the same calls.
  * host = step - instrument time: everything else (serial exchanges, AWG state, processing,
    bookkeeping, the scheduler of a shared machine). The medians pair each interval between two
    results with one capture's instrument time; radbench reports a step's result when its step
    worker is done with it, so that pairing is noisy.
  * whole run = from the first step's result to the last step's, divided by the steps between,
    and its host part = that minus the mean instrument time: nothing left out (for radbench it
    holds the wait for the step worker's last steps). The exit status is 0 only when the medians
    and the whole-run figures all meet the targets.
  * CPU per step = the client's user + system CPU time over its whole run (every thread: for
    radbench also the step worker), divided by the steps: less sensitive than wall times to what
    else runs on a shared machine.

One-shot captures (`--one-shot N`, issue 23): after the campaign rounds, in the same lab, N
turns of one `radbench capture --bench ... --allow-rf --json --trace-io` (a new process each
time, as a user or a shell script runs it) and one step of the Python stack above (its sessions
opened once before the first turn: the script's warm step). From radbench's journal and the
process's own start and end: start -> first instrument byte (the first journal line's start,
less the time just before the process was spawned), connect (the first connect's start to the
last instrument's identification: `*IDN?` of the AWG and the scope, the ID register of Tx and
Rx), after the last exchange (processing and files until the process ended), the whole capture
(spawn to exit). Targets: first byte < 30 ms, connect < 20 ms, the one-shot at least 1.5x
faster than the Python warm step (medians). Each turn also runs the Python stack as a new
process (`--python-one-shot-child`: the interpreter, its imports, the sessions opened, the upload,
one step and its processing, no files), the like-for-like comparison of a one-shot; reported, no
target.

pyserial is not among the interop packages: the pseudo-terminals are opened with os/termios in
raw mode, as pyserial does. Everything stays on 127.0.0.1. This is a benchmark, not a test.
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import re  # noqa: E402
import select  # noqa: E402
import socket  # noqa: E402
import statistics  # noqa: E402
import struct  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import termios  # noqa: E402
import tomllib  # noqa: E402
import time  # noqa: E402
import tty  # noqa: E402
from pathlib import Path  # noqa: E402

from io_journal import connect_span, journal_times  # noqa: E402

import numpy as np  # noqa: E402
import pyvicp  # noqa: E402
import pyvisa  # noqa: E402
import scipy  # noqa: E402
import scipy.fft  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
C0 = 299_792_458.0
FS = 16e9  # waveform rate
PULSE_S = 10e-6
BANDWIDTH = 1e9
N_BITS = 128
MARKER_SAMPLES = 64
BACKOFF_DB = 0.5
MAX_RANGE_M = 10.0
# Issue 10 targets.
STEP_SPEEDUP = 1.5
HOST_RATIO = 3.0


# ---------------------------------------------------------------------------- the lab

class LabResources:
    """The resources of a running lab, read from its bench file (the one-shot Python child)."""

    def __init__(self, bench_file: Path):
        text = bench_file.read_text()
        sections = dict(re.findall(r'\[(\w+)\]\s*\n(?:model = "[^"]*"\s*\n)?\w+ = "([^"]*)"', text))
        self.bench_file = bench_file
        self.awg = sections["awg"]
        self.scope = sections["scope"]
        self.tx = sections["tx"]
        self.rx = sections["rx"]
        self.control = sections["simulation"]


class MockLab:
    """A running `mock-lab serve`: its bench file and resources."""

    def __init__(self, binary: str, workdir: Path):
        self.proc = subprocess.Popen([binary, "serve"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        lines = []
        # mock-lab prints its table at once; a lab that cannot serve exits (end of file).
        for raw in self.proc.stdout:
            line = raw.decode()
            lines.append(line)
            if line.startswith("control = "):
                break
        text = "".join(lines)
        if "[awg]" not in text or "control = " not in text:
            self.stop()
            sys.exit(f"mock-lab printed no bench file: {text}\n{self.proc.stderr.read().decode()}")
        self.bench_file = workdir / "bench.toml"
        self.bench_file.write_text(text[text.index("[awg]"):])
        sections = dict(re.findall(r'\[(\w+)\]\s*\n(?:model = "[^"]*"\s*\n)?\w+ = "([^"]*)"', text))
        self.awg = sections["awg"]
        self.scope = sections["scope"]
        self.tx = sections["tx"]
        self.rx = sections["rx"]
        self.control = sections["simulation"]

    def stop(self):
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)


# ---------------------------------------------------------------------------- radbench

def write_spec(workdir: Path, count: int) -> Path:
    """examples/accuracy.toml with `count` steps."""
    text = (REPO / "examples/accuracy.toml").read_text()
    text, n = re.subn(r"(?m)^count = \d+", f"count = {count}", text)
    assert n == 1, "examples/accuracy.toml has no `count =` line"
    spec = workdir / "accuracy.toml"
    spec.write_text(text)
    return spec


def radbench_round(binary: str, spec: Path, bench: Path, out: Path):
    """One `radbench campaign run --json`: step end times (perf_counter), the journal's
    instrument time per step, the results, the manifest's timing."""
    cmd = [binary, "campaign", "run", str(spec), "--bench", str(bench), "--allow-rf",
           "--out", str(out), "--json"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ends, ranges, done = [], [], None
    for line in proc.stdout:
        now = time.perf_counter()
        event = json.loads(line)
        if event.get("event") == "step":
            ends.append(now)
            ranges.append([t["range_m"] for t in event.get("targets", [])])
        elif event.get("event") == "done":
            done = event
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0 or done is None:
        sys.exit(f"radbench campaign failed ({proc.returncode}): {err}")
    journal = [json.loads(x) for x in (out / "io-journal.jsonl").read_text().splitlines()]
    with open(out / "manifest.toml", "rb") as f:
        sessions = tomllib.load(f)["sessions"]
    timing = sessions[-1]["timing"]
    return {"start": t0, "ends": ends, "instrument_s": journal_instrument_s(journal),
            "serial": journal_serial_per_step(journal), "ranges": ranges, "timing": timing,
            "cpu_s": usage.ru_utime + usage.ru_stime}


def journal_instrument_s(journal):
    """Per step (one per `TRMD SINGLE` arm): arm + acquisition wait and the I/Q transfers."""
    per_step = []
    scope = [r for r in journal if r["instrument"] == "scope"]
    for n, r in enumerate(scope):
        text = r.get("text", "")
        if r["direction"] == "write" and text.startswith("TRMD SINGLE"):
            per_step.append(0.0)
        if not per_step:
            continue
        counted = (text.startswith("TRMD SINGLE") or text.startswith("C1:WF?")
                   or text.startswith("C2:WF?"))
        if r["direction"] == "write" and counted:
            per_step[-1] += r["elapsed_us"] * 1e-6
            # Its reply (the next scope read).
            for nxt in scope[n + 1:]:
                if nxt["direction"] == "read":
                    per_step[-1] += nxt["elapsed_us"] * 1e-6
                    break
    return per_step


def journal_serial_per_step(journal):
    """Serial exchanges (request + reply = one) per step, Tx and Rx, between two arms' ends."""
    counts, current = [], None
    for r in journal:
        if r["instrument"] == "awg" and r.get("text", "").startswith(":INST:DACM?"):
            # The start of a later step (the AWG's state read before reusing the upload).
            if current is not None:
                counts.append(current)
            current = {"tx": 0, "rx": 0}
        if r["instrument"] == "awg" and r.get("text", "").startswith(":TRAC1:DEL:ALL"):
            current = {"tx": 0, "rx": 0}  # step 1: the upload
        if current is not None and r["instrument"] in ("tx", "rx") and r["direction"] == "write":
            current[r["instrument"]] += 1
    if current is not None:
        counts.append(current)
    return counts


# ---------------------------------------------------------------------------- Python stack

def crc8(data: bytes, poly=0x07, init=0x00) -> int:
    crc = init
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


class Gotmic:
    """A Gotmic module on its pseudo-terminal, CRC-8 framed lines (instruments.md section 5)."""
    STATUS, CONTROL, ATT, TEMP, FAULTS = 0x01, 0x02, 0x03, 0x06, 0x07
    ENABLE_MASK, ATT_MAX = 0x000F, 63
    LO_LOCKED, RF_ENABLED, OVER_TEMP, INTERLOCK_OPEN = 1 << 1, 1 << 2, 1 << 3, 1 << 4

    def __init__(self, resource: str, timer):
        path = resource.removeprefix("ASRL").removesuffix("::INSTR")
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        attrs[4] = attrs[5] = termios.B115200
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        termios.tcflush(self.fd, termios.TCIOFLUSH)
        self.buf = b""
        self.timer = timer
        self.exchanges = 0
        self._line("CRC ON")  # OK, or the CRC error of a module already framed
        self.idn = self.query("*IDN?")

    def close(self):
        os.close(self.fd)

    def _line(self, text: str) -> str:
        self.exchanges += 1
        os.write(self.fd, text.encode() + b"\n")
        deadline = time.monotonic() + 2
        while b"\n" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                raise TimeoutError(f"no reply to {text!r}")
            self.buf += os.read(self.fd, 4096)
        line, self.buf = self.buf.split(b"\n", 1)
        return line.decode().strip()

    def query(self, request: str) -> str:
        reply = self._line(f"{request}*{crc8(request.encode()):02X}")
        body, _, crc = reply.rpartition("*")
        if int(crc, 16) != crc8(body.encode()):
            raise RuntimeError(f"bad CRC in {reply!r}")
        if body.startswith("ERR"):
            raise RuntimeError(f"{request!r} refused: {body}")
        return body

    def read(self, reg: int) -> int:
        return int(self.query(f"R {reg:02X}").split()[1], 16)

    def write(self, reg: int, value: int, verify=True):
        self.query(f"W {reg:02X} {value:04X}")
        if verify and self.read(reg) != value:
            raise RuntimeError(f"register {reg:02X} did not take {value:04X}")

    def enable(self, att_code: int):
        status, faults = self.read(self.STATUS), self.read(self.FAULTS)
        att = self.read(self.ATT)
        if faults or status & self.OVER_TEMP or status & self.INTERLOCK_OPEN:
            raise RuntimeError(f"not ready: status {status:04X}, faults {faults:04X}")
        if att != self.ATT_MAX:
            self.write(self.ATT, self.ATT_MAX)
        try:
            self.query(f"W {self.CONTROL:02X} {self.ENABLE_MASK:04X}")
            control, status = self.read(self.CONTROL), self.read(self.STATUS)
            if control != self.ENABLE_MASK or not status & self.RF_ENABLED \
                    or not status & self.LO_LOCKED:
                raise RuntimeError(f"RF not on: control {control:04X}, status {status:04X}")
            self.write(self.ATT, att_code)
        except Exception:
            self.disable()
            raise

    def disable(self):
        self.write(self.CONTROL, 0)
        self.write(self.ATT, self.ATT_MAX)


def msk_lfm(bits: np.ndarray):
    """One MSK-LFM pulse at FS (complex baseband, unit amplitude) carrying `bits`."""
    n = int(round(PULSE_S * FS))
    t = np.arange(n) / FS
    tb = PULSE_S / N_BITS
    a_i = 1.0 - 2.0 * bits[0::2]
    a_q = 1.0 - 2.0 * bits[1::2]
    half = N_BITS // 2
    k_i = np.floor((t + tb) / (2 * tb)).astype(np.int64) % half
    k_q = np.floor(t / (2 * tb)).astype(np.int64) % half
    cos_w = np.cos(np.pi * t / (2 * tb))
    sin_w = np.sin(np.pi * t / (2 * tb))
    m = a_i[k_i] * cos_w - 1j * a_q[k_q] * sin_w
    chirp = np.exp(1j * np.pi * (BANDWIDTH / PULSE_S) * (t - PULSE_S / 2) ** 2)
    return m * chirp, chirp, k_i, k_q, cos_w, sin_w


class PythonStack:
    def __init__(self, lab: MockLab, rm, seed: int):
        self.instrument_s = 0.0
        self.awg = rm.open_resource(lab.awg, open_timeout=10_000)
        self.awg.timeout = 20_000
        self.awg.write_termination = "\n"
        self.awg.read_termination = "\n"
        host, port = re.match(r"VICP::([\d.]+),(\d+)::INSTR", lab.scope).groups()
        self.scope = pyvicp.Client(host, int(port), timeout=20)
        self.scope_ask("CHDR OFF", reply=False)
        self.rx = Gotmic(lab.rx, self)
        self.tx = Gotmic(lab.tx, self)
        host, port = lab.control.split(":")
        self.control = socket.create_connection((host, int(port)), timeout=10)
        self.control_file = self.control.makefile("rwb")
        self.base_scene = self.control_request({"cmd": "get"})["scene"]
        # The waveform, its reference and its receiver tables, built once.
        rng = np.random.default_rng(seed)
        self.bits = rng.integers(0, 2, N_BITS).astype(np.float64)
        pulse, self.chirp, self.k_i, self.k_q, self.cos_w, self.sin_w = msk_lfm(self.bits)
        scale = 127 * 10 ** (-BACKOFF_DB / 20) / max(np.abs(pulse.real).max(),
                                                      np.abs(pulse.imag).max())
        self.i_codes = np.round(pulse.real * scale).astype(np.int8)
        self.q_codes = np.round(pulse.imag * scale).astype(np.int8)
        reference = (self.i_codes + 1j * self.q_codes) / 127.0
        self.ref_conj = np.conj(scipy.fft.fft(reference))
        self.n = len(reference)
        self.lags = int(np.ceil((2 * MAX_RANGE_M / C0 + 20e-9) * FS))
        self.sym_energy_i = np.bincount(self.k_i, self.cos_w ** 2, N_BITS // 2)
        self.sym_energy_q = np.bincount(self.k_q, self.sin_w ** 2, N_BITS // 2)
        self.shift_cache = {}
        self.upload()

    def control_request(self, request):
        self.control_file.write(json.dumps(request).encode() + b"\n")
        self.control_file.flush()
        reply = json.loads(self.control_file.readline())
        if not reply.get("ok"):
            raise RuntimeError(f"control {request}: {reply}")
        return reply

    def scope_ask(self, command: str, reply=True):
        self.scope.send(command.encode() + b"\n")
        return self.scope.receive() if reply else None

    def awg_check(self):
        err = self.awg.query("SYST:ERR?")
        if not err.startswith("0"):
            raise RuntimeError(f"AWG: {err}")

    def upload(self):
        """The AWG's clock, levels, the segment (I + marker, Q); the scope's settings."""
        for cmd in (":ABOR", ":ROSC:SOUR INT", ":INST:DACM DCM", ":INST:MEM:EXT:RDIV DIV4",
                    ":TRAC1:MMOD EXT", ":TRAC2:MMOD EXT", ":FREQ:RAST 64000000000",
                    ":FUNC:MODE ARB", ":INIT:CONT 1", ":INIT:GATE 0", ":VOLT1 0.5",
                    ":VOLT1:OFFS 0", ":VOLT2 0.5", ":VOLT2:OFFS 0", ":VOLT3:AMPL 0.5",
                    ":VOLT3:OFFS 0.25", ":TRAC1:DEL:ALL", f":TRAC1:DEF 1,{self.n}"):
            self.awg.write(cmd)
        self.awg_check()
        ch1 = np.empty(2 * self.n, dtype=np.uint8)
        ch1[0::2] = self.i_codes.view(np.uint8)
        ch1[1::2] = 0
        ch1[1:2 * MARKER_SAMPLES:2] = 1
        for head, data in ((":TRAC1:DATA 1,0,", ch1.tobytes()),
                           (":TRAC2:DATA 1,0,", self.q_codes.tobytes())):
            block = f"#{len(str(len(data)))}{len(data)}".encode()
            self.awg.write_raw(head.encode() + block + data + b"\n")
        if self.awg.query("*OPC?").strip() != "1":
            raise RuntimeError("AWG upload incomplete")
        self.awg.write(":TRAC1:SEL 1")
        self.awg.write(":TRAC2:SEL 1")
        self.awg_check()
        for cmd in ("CFMT DEF9,WORD,BIN", "CORD LO", "WFSU SP,0,NP,0,FP,0,SN,0",
                    "C1:TRA ON", "C1:VDIV 0.05", "C1:OFST 0", "C2:TRA ON", "C2:VDIV 0.05",
                    "C2:OFST 0",
                    "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'",
                    "VBS 'app.Acquisition.Horizontal.SampleRate = 80000000000'",
                    "VBS 'app.Acquisition.Horizontal.HorScale = 0.000001'",
                    "TRSE EDGE,SR,EX,HT,OFF", "EX:TRLV 0.25", "EX:TRSL POS",
                    "TRDL -0.000005"):
            self.scope_ask(cmd, reply=False)
        if int(self.scope_ask("CMR?")) or int(self.scope_ask("EXR?")):
            raise RuntimeError("the scope refused a setting")

    def timed(self, fn, *args):
        t = time.perf_counter()
        out = fn(*args)
        self.instrument_s += time.perf_counter() - t
        return out

    def fetch(self, channel: int):
        self.scope.send(f"C{channel}:WF? ALL\n".encode())
        return self.scope.receive()

    def step(self, range_m: float, seed: int):
        """One step; returns (ranges of the two strongest peaks, bit errors)."""
        scene = dict(self.base_scene)
        amplitude = scene["targets"][0]["amplitude"] if scene.get("targets") else 0.5
        scene["targets"] = [{"range_m": range_m, "amplitude": amplitude, "velocity_mps": 0.0}]
        scene["seed"] = seed
        self.control_request({"cmd": "set", "scene": scene})
        self.control_request({"cmd": "seed", "seed": seed})
        self.instrument_s = 0.0
        try:
            self.rx.enable(0)
            self.tx.enable(0)
            for cmd in (":OUTP1 ON", ":OUTP2 ON", ":OUTP3 ON"):
                self.awg.write(cmd)
            self.awg_check()
            self.awg.write(":INIT:IMM")
            self.awg_check()
            self.scope_ask("INR?")
            self.timed(self.scope_ask, "TRMD SINGLE;ARM;WAIT 10;*OPC?")
            if not int(self.scope_ask("INR?")) & 1:
                raise RuntimeError("no trigger")
            blocks = [self.timed(self.fetch, 1), self.timed(self.fetch, 2)]
        finally:
            self.tx.disable()
            self.rx.disable()
            for cmd in (":OUTP1 OFF", ":OUTP2 OFF", ":OUTP3 OFF", ":OUTP4 OFF", ":ABOR"):
                self.awg.write(cmd)
            self.awg_check()
        return self.process(blocks)

    def process(self, blocks):
        iq, dt, t0 = None, None, None
        for k, block in enumerate(blocks):
            desc = block.index(b"WAVEDESC")
            hdr = block[desc:desc + 346]
            (desc_len,) = struct.unpack_from("<i", hdr, 36)
            (array_len,) = struct.unpack_from("<i", hdr, 60)
            gain, offset = struct.unpack_from("<ff", hdr, 156)
            (dt,) = struct.unpack_from("<f", hdr, 176)
            (t0,) = struct.unpack_from("<d", hdr, 180)
            words = np.frombuffer(block, dtype="<i2", count=array_len // 2,
                                  offset=desc + desc_len)
            volts = gain * words.astype(np.float64) - offset
            if iq is None:
                iq = np.empty(len(volts), dtype=np.complex128)
                iq.real = volts
            else:
                iq.imag = volts
        # Decimation 80 -> 16 GSa/s of the periodic record in the frequency domain, with the
        # time origin moved to the marker edge (the record starts t0 after it).
        spectrum = scipy.fft.fft(iq)
        half = self.n // 2
        kept = np.concatenate([spectrum[:half], spectrum[-half:]])
        key = (len(iq), t0)
        if key not in self.shift_cache:
            f = scipy.fft.fftfreq(self.n, 1 / FS)
            self.shift_cache = {key: np.exp(-2j * np.pi * f * t0) / (len(iq) / self.n)}
        kept *= self.shift_cache[key]
        aligned = scipy.fft.ifft(kept)
        profile = scipy.fft.ifft(kept * self.ref_conj)[: self.lags] / self.n
        mag = np.abs(profile)
        peaks = np.flatnonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:])) + 1
        peaks = peaks[mag[peaks] > 0.1 * mag.max()]
        strongest = peaks[np.argsort(mag[peaks])[::-1][:2]]
        ranges = []
        for p in strongest[::-1]:
            a, b, c = mag[p - 1], mag[p], mag[p + 1]
            frac = 0.5 * (a - c) / (a - 2 * b + c)
            ranges.append((p + frac) / FS * C0 / 2)
        # The payload: the strongest echo, rotated back and derotated, MSK demodulated.
        p = strongest[0]
        rx = np.roll(aligned, -p) * np.exp(-1j * np.angle(profile[p]))
        d = rx * np.conj(self.chirp)
        soft_i = np.bincount(self.k_i, d.real * self.cos_w, N_BITS // 2) / self.sym_energy_i
        soft_q = -np.bincount(self.k_q, d.imag * self.sin_w, N_BITS // 2) / self.sym_energy_q
        bits = np.empty(N_BITS)
        bits[0::2], bits[1::2] = soft_i < 0, soft_q < 0
        return ranges, int(np.sum(bits != self.bits))

    def close(self):
        self.tx.close()
        self.rx.close()
        self.scope.close()
        self.awg.close()
        self.control.close()


def python_round(lab, rm, count, seed):
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    stack = PythonStack(lab, rm, seed)
    ends, instrument, ranges, errors, serial = [], [], [], [], []
    try:
        for k in range(count):
            before = stack.rx.exchanges + stack.tx.exchanges
            r, e = stack.step(1.0 - 0.03 * k, seed + k)
            ends.append(time.perf_counter())
            instrument.append(stack.instrument_s)
            serial.append(stack.rx.exchanges + stack.tx.exchanges - before)
            ranges.append(r)
            errors.append(e)
    finally:
        stack.close()
    return {"start": t0, "ends": ends, "instrument_s": instrument, "ranges": ranges,
            "bit_errors": errors, "serial": serial, "cpu_s": time.process_time() - cpu0}


# ---------------------------------------------------------------------------- one-shot

ONE_SHOT_FIRST_BYTE_S = 0.030
ONE_SHOT_CONNECT_S = 0.020


def radbench_one_shot(binary: str, bench: Path, out: Path):
    """One `radbench capture` process against the lab: its phases from the journal."""
    journal_path = out.with_suffix(".jsonl")
    cmd = [binary, "--trace-io", str(journal_path), "capture", "--bench", str(bench),
           "--allow-rf", "--out", str(out), "--json"]
    spawned = time.time()
    p0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = proc.communicate()
    wall = time.perf_counter() - p0
    ended = spawned + wall
    if proc.returncode != 0:
        sys.exit(f"radbench capture failed ({proc.returncode}): {stderr}")
    journal = [json.loads(x) for x in journal_path.read_text().splitlines()]
    spans = [journal_times(x) for x in journal]
    first = min(s for s, _ in spans)
    last = max(e for _, e in spans)
    c0, c1 = connect_span(journal)
    summary = json.loads(stdout)
    ranges = [t["range_m"] for t in summary.get("targets", [])]
    return {"wall": wall, "first_byte": first - spawned, "connect": c1 - c0,
            "instruments": last - first, "after_last": ended - last, "ranges": ranges}


def python_one_shot(bench: Path):
    """One capture by the Python stack as a new process (this script with
    `--python-one-shot-child`): the interpreter's start, its imports, opening the sessions,
    the upload, one step and its processing; seconds from spawn to exit."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--python-one-shot-child", str(bench)]
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        sys.exit(f"the Python one-shot failed ({proc.returncode}): {proc.stderr}")
    return wall


def python_one_shot_child(bench: Path):
    rm = pyvisa.ResourceManager("@py")
    stack = PythonStack(LabResources(bench), rm, seed=7)
    try:
        ranges, _ = stack.step(1.0, 7)
    finally:
        stack.close()
        rm.close()
    print(json.dumps({"ranges": list(ranges)}))
    return 0


def one_shot_turns(args, lab, rm, work):
    """`--one-shot` turns: radbench capture (new process), the Python warm step, and the Python
    stack as a new process, taking turns against the same lab."""
    stack = PythonStack(lab, rm, seed=7)
    rb, py, py_cold = [], [], []
    try:
        stack.step(1.0, 7)  # the Python stack warm: the first step is not counted
        for n in range(args.one_shot):
            rb.append(radbench_one_shot(args.radbench, lab.bench_file, work / f"one-shot-{n + 1}"))
            t = time.perf_counter()
            stack.step(1.0, 8 + n)
            py.append(time.perf_counter() - t)
            py_cold.append(python_one_shot(lab.bench_file))
    finally:
        stack.close()
    return rb, py, py_cold


def report_one_shot(rb, py, py_cold):
    med = statistics.median
    print()
    print(f"one-shot `radbench capture` (a new process each) against the Python warm step, "
          f"{len(rb)} turns; min / median")
    rows = [("start -> first instrument byte", "first_byte", ONE_SHOT_FIRST_BYTE_S),
            ("connect (4 instruments)", "connect", ONE_SHOT_CONNECT_S),
            ("first byte -> last exchange", "instruments", None),
            ("last exchange -> exit", "after_last", None),
            ("whole capture (spawn -> exit)", "wall", None)]
    met = True
    for name, key, target in rows:
        xs = [r[key] for r in rb]
        verdict = ""
        if target is not None:
            ok = med(xs) < target
            met &= ok
            verdict = f"  target < {1e3 * target:.0f} ms: {'met' if ok else 'MISSED'}"
        print(f"  {name:<32} {ms(min(xs))} / {ms(med(xs))} ms{verdict}")
    speedup = med(py) / med([r["wall"] for r in rb])
    ok = speedup >= STEP_SPEEDUP
    met &= ok
    print(f"  {'Python warm step':<32} {ms(min(py))} / {ms(med(py))} ms")
    print(f"  {'Python step / one-shot':<32} {speedup:7.2f}x (medians)   target >= "
          f"{STEP_SPEEDUP}x: {'met' if ok else 'MISSED'}")
    cold = med(py_cold) / med([r["wall"] for r in rb])
    print(f"  {'Python one-shot (new process)':<32} {ms(min(py_cold))} / {ms(med(py_cold))} ms")
    print(f"  {'Python one-shot / one-shot':<32} {cold:7.2f}x (medians, like for like)")
    print(f"  ranges of the last one-shot (m): {rb[-1]['ranges']}")
    return met


# ---------------------------------------------------------------------------- report

def steady(rounds, key="ends"):
    """Steps 2..N of every round: (step seconds, instrument seconds, host seconds)."""
    steps, inst = [], []
    for r in rounds:
        ends = r["ends"]
        for k in range(1, len(ends)):
            steps.append(ends[k] - ends[k - 1])
            inst.append(r["instrument_s"][k])
    hosts = [s - i for s, i in zip(steps, inst)]
    return steps, inst, hosts


def whole_run(rounds):
    """Per round, from the first step's end to the last step's end divided by the steps between:
    (step seconds, host seconds). Nothing is left out: for radbench the window also holds the
    wait for the step worker's last steps at the end, and a step's end is when its result
    arrives, whichever capture it came with."""
    out = []
    for r in rounds:
        ends, inst = r["ends"], r["instrument_s"]
        n = len(ends) - 1
        span = ends[-1] - ends[0]
        out.append((span / n, (span - sum(inst[1:len(ends)])) / n))
    return out


def ms(x):
    return f"{1e3 * x:7.1f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--radbench", default=str(REPO / "target/release/radbench"))
    ap.add_argument("--mock-lab", default=str(REPO / "target/release/mock-lab"))
    ap.add_argument("--rounds", type=int, default=3, help="radbench/Python turns")
    ap.add_argument("--count", type=int, default=12, help="steps per campaign")
    ap.add_argument("--keep", help="keep radbench's run folders under this folder")
    ap.add_argument("--json", action="store_true", help="also print the raw timings as JSON")
    ap.add_argument("--one-shot", type=int, default=0, metavar="N",
                    help="then N turns of a one-shot `radbench capture`, a Python warm step and "
                         "the Python stack as a new process")
    ap.add_argument("--python-one-shot-child", metavar="BENCH", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.python_one_shot_child:
        return python_one_shot_child(Path(args.python_one_shot_child))
    for binary in (args.radbench, args.mock_lab):
        if not Path(binary).exists():
            sys.exit(f"{binary} not found; run `cargo build --release -p radbench --bin radbench "
                     "-p mock_lab --bin mock-lab`")
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="compare_campaign."))
    work.mkdir(parents=True, exist_ok=True)
    spec = write_spec(work, args.count)
    load_before = os.getloadavg()
    lab = MockLab(args.mock_lab, work)
    rm = pyvisa.ResourceManager("@py")
    rb_rounds, py_rounds = [], []
    one_shot = None
    try:
        for n in range(args.rounds):
            rb_rounds.append(radbench_round(args.radbench, spec, lab.bench_file,
                                            work / f"radbench-{n + 1}"))
            py_rounds.append(python_round(lab, rm, args.count, seed=1 + n))
        if args.one_shot:
            one_shot = one_shot_turns(args, lab, rm, work)
    finally:
        rm.close()
        lab.stop()
    load_after = os.getloadavg()
    if not rb_rounds:
        print(f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
              f"numpy {np.__version__}, pyvisa {pyvisa.__version__}; load average before "
              f"{load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)")
        return 0 if one_shot and report_one_shot(*one_shot) else 1

    rb_step, rb_inst, rb_host = steady(rb_rounds)
    py_step, py_inst, py_host = steady(py_rounds)
    med = statistics.median
    print(f"{args.count} steps x {args.rounds} rounds (examples/accuracy.toml, MSK-LFM 10 us "
          f"1 GHz 128 bits, 1 repetition); medians over steps 2..{args.count} of every round")
    print(f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
          f"numpy {np.__version__}, scipy {scipy.__version__}, pyvisa {pyvisa.__version__}; "
          f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)")
    print()
    print(f"{'ms per step':<28} {'radbench':>8} {'Python':>8} {'ratio':>7}  target     verdict")
    speedup = med(py_step) / med(rb_step)
    host_ratio = med(py_host) / med(rb_host)
    print(f"{'step (wall)':<28} {ms(med(rb_step))} {ms(med(py_step))} {speedup:6.2f}x  "
          f">= {STEP_SPEEDUP}x    {'met' if speedup >= STEP_SPEEDUP else 'MISSED'}")
    print(f"{'  instruments (arm+wait+I/Q)':<28} {ms(med(rb_inst))} {ms(med(py_inst))}")
    print(f"{'  host (step - instruments)':<28} {ms(med(rb_host))} {ms(med(py_host))} "
          f"{host_ratio:6.2f}x  >= {HOST_RATIO}x    "
          f"{'met' if host_ratio >= HOST_RATIO else 'MISSED'}")
    rb_whole, py_whole = whole_run(rb_rounds), whole_run(py_rounds)
    rb_ws, rb_wh = med([w[0] for w in rb_whole]), med([w[1] for w in rb_whole])
    py_ws, py_wh = med([w[0] for w in py_whole]), med([w[1] for w in py_whole])
    print(f"{'step, whole run (mean)':<28} {ms(rb_ws)} {ms(py_ws)} {py_ws / rb_ws:6.2f}x  "
          f">= {STEP_SPEEDUP}x    {'met' if py_ws / rb_ws >= STEP_SPEEDUP else 'MISSED'}")
    print(f"{'  host, whole run (mean)':<28} {ms(rb_wh)} {ms(py_wh)} {py_wh / rb_wh:6.2f}x  "
          f">= {HOST_RATIO}x    {'met' if py_wh / rb_wh >= HOST_RATIO else 'MISSED'}")
    first_rb = med([r["ends"][0] - r["start"] for r in rb_rounds])
    first_py = med([r["ends"][0] - r["start"] for r in py_rounds])
    print(f"{'step 1 (process/connect+upload)':<28} {ms(first_rb)} {ms(first_py)}")
    rb_serial = [s["tx"] + s["rx"] for r in rb_rounds for s in r["serial"][1:]]
    py_serial = [s for r in py_rounds for s in r["serial"][1:]]
    print(f"{'serial exchanges per step':<28} {med(rb_serial):8.0f} {med(py_serial):8.0f}")
    rb_cpu = med([r["cpu_s"] / args.count for r in rb_rounds])
    py_cpu = med([r["cpu_s"] / args.count for r in py_rounds])
    print(f"{'CPU per step (whole run/N)':<28} {ms(rb_cpu)} {ms(py_cpu)} {py_cpu / rb_cpu:6.2f}x"
          "  (user + system, every thread; not the lab's)")
    # The campaign's own work against the work of its captures. A capture (as `radbench capture`
    # does it) is: the bench (connect, place, upload, acquire: bench_s), processing and writing
    # its files; the step worker does the last two beside the next capture. The campaign's own
    # work is what the session did beyond preparing, capturing and waiting for the worker (run
    # folder and manifest at the start, results, report and journal hashes at the end) plus the
    # worker's bookkeeping (hashing every step file, storing the manifest), counted in full even
    # though it runs beside the captures.
    print()
    print("radbench campaign, manifest [sessions.timing] per round: own = (total - prepare - bench "
          "- waiting for the step worker) + bookkeeping; capture = bench + processing + files")
    for n, r in enumerate(rb_rounds):
        t = r["timing"]
        captures = t["bench_s"] + t["processing_s"] + t["files_s"]
        foreground = t["total_s"] - t["prepare_s"] - t["bench_s"] - t["wait_s"]
        own = foreground + t["overhead_s"]
        print(f"  round {n + 1}: total {t['total_s']:.3f} s, prepare {t['prepare_s']:.3f}, capture "
              f"{captures:.3f}, own {own:.3f} ({100 * own / captures:.1f} % of capture; target < 10 %)"
              f": {foreground:.3f} in the session, {t['overhead_s']:.3f} bookkeeping on the step "
              f"worker (processing {t['processing_s']:.3f}, files {t['files_s']:.3f}; waited for "
              f"it {t['wait_s']:.3f})")
    rb_r = rb_rounds[-1]["ranges"]
    py_r = py_rounds[-1]["ranges"]
    print("  last round's ranges (uncalibrated, m), radbench's targets | Python's strongest: "
          + "; ".join(
        f"{'/'.join(f'{x:.4f}' for x in a)} | {b[-1]:.4f}"
        for a, b in zip(rb_r[:3], py_r[:3])) + "; ...")
    print(f"  Python bit errors per step: {[e for r in py_rounds for e in r['bit_errors']]}")
    print(f"  run folders: {work}" if args.keep else "")
    if args.json:
        print(json.dumps({"radbench": {"step_s": rb_step, "instrument_s": rb_inst,
                                       "serial": rb_serial, "timing": [r["timing"] for r in
                                                                        rb_rounds]},
                          "python": {"step_s": py_step, "instrument_s": py_inst,
                                     "serial": py_serial}}, indent=1))
    met = (speedup >= STEP_SPEEDUP and host_ratio >= HOST_RATIO
           and py_ws / rb_ws >= STEP_SPEEDUP and py_wh / rb_wh >= HOST_RATIO)
    if one_shot:
        met &= report_one_shot(*one_shot)
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
