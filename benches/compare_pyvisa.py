#!/usr/bin/env python3
"""Moves a 64 MiB block over loopback through each transport with radbench's client and with
pyvisa-py, against the same running mock-lab server, in the same run, and prints MB/s side by
side against the issue's targets (issue 3, "Speed").

    cargo build --release -p radbench --bin radbench -p mock_lab --bin mock-lab
    .venv-interop/bin/python benches/compare_pyvisa.py [--runs 7] [--rounds 2]

One `mock-lab serve` is started for the whole run (its loopback instrument stores a block with
`DATA <block>` and returns it with `DATA?`). For each transport (SOCKET, VXI-11 INSTR, HiSLIP,
VICP) and each round, radbench (`radbench bench io --json`) and pyvisa-py take turns; each does
one untimed warm-up, `--runs` timed uploads (`DATA #8<bytes>` then `*OPC?`, so the instrument holds
every byte) and `--runs` timed downloads (`DATA?`). Both clients move the same bytes (SplitMix64,
seed 1; the SHA-256 of radbench's payload must match the one computed here), and every download
is checked against the payload after its timer stops. The figure is the median over all runs
of all rounds, in decimal MB/s (1e6 bytes per second). Alternating the clients in rounds
spreads slow spells of a shared machine over both.

pyvisa-py's VICP resource only reaches port 1861 (it ignores a port in the resource string), so
mock-lab's loopback VICP endpoint is put there; VICP is skipped when 1861 is taken.

Needs pyvisa, pyvisa-py, pyvicp and numpy (interop/requirements.txt; interop/run.sh makes
.venv-interop with them). Everything stays on 127.0.0.1. This is a benchmark, not a test.
"""

import argparse
import hashlib
import json
import os
import platform
import select
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyvisa

REPO = Path(__file__).resolve().parent.parent
VICP_PORT = 1861
TRANSPORTS = ["raw", "vxi11", "hislip", "vicp"]
LABELS = {"raw": "SOCKET", "vxi11": "VXI-11", "hislip": "HiSLIP", "vicp": "VICP"}
# Issue 3 targets: absolute MB/s floor, and the factor over pyvisa-py.
FLOOR_MB_S = {"raw": 1000.0, "vxi11": 500.0, "hislip": 1000.0, "vicp": 1000.0}
MIN_RATIO = 3.0
TIMEOUT_MS = 120_000


def splitmix64_bytes(n: int, seed: int) -> bytes:
    """radbench's bench payload: SplitMix64 words, little-endian (as `radbench bench io`)."""
    words = (n + 7) // 8
    golden = np.uint64(0x9E3779B97F4A7C15)
    state = np.uint64(seed) + golden * np.arange(1, words + 1, dtype=np.uint64)
    z = state
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return z.astype("<u8").tobytes()[:n]


def port_is_free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


class MockLab:
    """A running `mock-lab serve --json`; `endpoints` maps transport -> loopback resource."""

    def __init__(self, binary: str, vicp_port: int, cpus=None):
        self.proc = subprocess.Popen(
            [binary, "serve", "--json", "--loopback-vicp-port", str(vicp_port)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            preexec_fn=(lambda: os.sched_setaffinity(0, cpus)) if cpus else None)
        ready, _, _ = select.select([self.proc.stdout], [], [], 60)
        line = self.proc.stdout.readline() if ready else b""
        if not line:
            self.stop()
            sys.exit(f"mock-lab printed no endpoints: {self.proc.stderr.read().decode(errors='replace')}")
        listing = json.loads(line)
        self.endpoints = {e["transport"]: e["resource"] for e in listing["endpoints"]
                          if e["instrument"] == "loopback"}

    def stop(self):
        # End of stdin asks mock-lab to stop.
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)


def radbench_round(binary: str, resource: str, size: int, runs: int, payload_sha: str):
    """`radbench bench io --json` on one resource: {direction: [seconds per run]}."""
    out = subprocess.run([binary, "bench", "io", "--json", "--size", str(size), "--runs", str(runs),
                          "--seed", "1", resource], check=True, capture_output=True, text=True)
    doc = json.loads(out.stdout)
    if doc["payload_sha256"] != payload_sha:
        sys.exit(f"radbench's payload differs from this script's (SHA-256 {doc['payload_sha256']})")
    return {r["direction"]: r["seconds"] for r in doc["results"]}


class PyvisaClient:
    """pyvisa-py with its best settings for big blocks (chosen on this machine, see docs/speed.md):

    * uploads: `write_raw` of the whole program message built once before timing (`DATA `,
      the `#8` header, the payload, LF). `write_binary_values(..., datatype='B')` would do the
      same with three extra 64 MB concatenations per call; prebuilding spares pyvisa-py those.
    * downloads on END-delimited transports (VXI-11, HiSLIP, VICP): termination character
      off (otherwise every LF byte inside the block ends a read) and `query_binary_values(
      "DATA?", datatype='B', container=np.ndarray, chunk_size=...)`: numpy's frombuffer is a
      zero-copy view, where `container=bytes` would go through a 64-million-element tuple.
    * downloads on SOCKET: a raw socket has no END, and pyvisa-py's socket read waits for the
      whole timeout when the termination character is off, so the block header is read with
      `read_bytes` and the known remainder with one `read_bytes(n + 1, chunk_size=...)`.
    * `chunk_size` (`--chunk-size`): the largest pyvisa read request; 4 MiB was the fastest of
      4, 16 and 64 MiB here (HiSLIP and VICP reads ~1.15 GB/s against ~0.9 and ~0.4).
    """

    def __init__(self, rm, transport: str, resource: str, chunk_size: int):
        self.transport = transport
        self.chunk_size = chunk_size
        self.inst = rm.open_resource(resource, open_timeout=10_000)
        self.inst.timeout = TIMEOUT_MS
        self.inst.write_termination = "\n"
        self.inst.chunk_size = chunk_size

    def close(self):
        self.inst.close()

    def opc(self):
        self.inst.read_termination = "\n"
        reply = self.inst.query("*OPC?").strip()
        if reply != "1":
            raise RuntimeError(f"*OPC? answered {reply!r}")

    def upload(self, message: bytes):
        self.inst.write_raw(message)
        self.opc()

    def download(self):
        self.inst.read_termination = None
        if self.transport == "raw":
            self.inst.write("DATA?")
            head = self.inst.read_bytes(2)
            digits = int(head[1:2])
            length = int(self.inst.read_bytes(digits))
            return memoryview(self.inst.read_bytes(length + 1, chunk_size=self.chunk_size))[:length]
        return self.inst.query_binary_values("DATA?", datatype="B", container=np.ndarray,
                                             chunk_size=self.chunk_size)


def pyvisa_round(rm, transport, resource, payload, runs, chunk_size):
    header = f"#{len(str(len(payload)))}{len(payload)}".encode()
    message = b"DATA " + header + payload + b"\n"
    want = hashlib.sha256(payload).digest()
    client = PyvisaClient(rm, transport, resource, chunk_size)
    try:
        client.upload(message)
        if hashlib.sha256(client.download()).digest() != want:
            raise RuntimeError(f"pyvisa-py {transport}: warm-up download differs from the payload")
        writes, reads = [], []
        for _ in range(runs):
            t = time.perf_counter()
            client.upload(message)
            writes.append(time.perf_counter() - t)
        for _ in range(runs):
            t = time.perf_counter()
            data = client.download()
            reads.append(time.perf_counter() - t)
            # Also proves the last upload arrived whole.
            if len(data) != len(payload) or hashlib.sha256(data).digest() != want:
                raise RuntimeError(f"pyvisa-py {transport}: download differs from the payload")
            del data
    finally:
        client.close()
    return {"read": reads, "write": writes}


def mb_s(size: int, seconds: list) -> float:
    return size / statistics.median(seconds) / 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--radbench", default=str(REPO / "target/release/radbench"))
    ap.add_argument("--mock-lab", default=str(REPO / "target/release/mock-lab"))
    ap.add_argument("--size", type=int, default=64 << 20, help="block size in bytes")
    ap.add_argument("--runs", type=int, default=7, help="timed runs per client, direction, round")
    ap.add_argument("--rounds", type=int, default=2, help="radbench/pyvisa-py turns per transport")
    ap.add_argument("--chunk-size", type=int, default=4 << 20, help="pyvisa-py chunk_size")
    ap.add_argument("--transports", default=",".join(TRANSPORTS),
                    help="comma-separated subset of " + ",".join(TRANSPORTS))
    ap.add_argument("--json", action="store_true", help="also print the raw timings as JSON")
    ap.add_argument("--pin", action="store_true",
                    help="run mock-lab on the first allowed CPU and both clients (this script, "
                         "so pyvisa-py, and radbench) on the others, the same for both clients")
    args = ap.parse_args()
    for binary in (args.radbench, args.mock_lab):
        if not Path(binary).exists():
            sys.exit(f"{binary} not found; run `cargo build --release -p radbench --bin radbench "
                     "-p mock_lab --bin mock-lab`")

    payload = splitmix64_bytes(args.size, 1)
    payload_sha = hashlib.sha256(payload).hexdigest()
    transports = [t for t in args.transports.split(",") if t]
    vicp_ok = port_is_free(VICP_PORT)
    if "vicp" in transports and not vicp_ok:
        print(f"note: port {VICP_PORT} is taken; pyvisa-py's VICP needs exactly it, VICP skipped")
        transports.remove("vicp")

    server_cpus = None
    if args.pin:
        allowed = sorted(os.sched_getaffinity(0))
        if len(allowed) < 2:
            sys.exit("--pin needs at least two CPUs")
        server_cpus = {allowed[0]}
        # radbench is started from here and inherits this affinity.
        os.sched_setaffinity(0, set(allowed[1:]))

    load_before = os.getloadavg()
    lab = MockLab(args.mock_lab, VICP_PORT if vicp_ok else 0, server_cpus)
    rm = pyvisa.ResourceManager("@py")
    timings = {t: {"radbench": {"read": [], "write": []}, "pyvisa": {"read": [], "write": []}}
               for t in transports}
    try:
        for transport in transports:
            resource = lab.endpoints[transport]
            for _ in range(args.rounds):
                rb = radbench_round(args.radbench, resource, args.size, args.runs, payload_sha)
                py = pyvisa_round(rm, transport, resource, payload, args.runs, args.chunk_size)
                for d in ("read", "write"):
                    timings[transport]["radbench"][d] += rb[d]
                    timings[transport]["pyvisa"][d] += py[d]
    finally:
        rm.close()
        lab.stop()
    load_after = os.getloadavg()

    print(f"{args.size} bytes per transfer; median of {args.runs} x {args.rounds} timed runs per "
          f"client and direction; MB/s = 1e6 bytes/s; payload SHA-256 {payload_sha[:16]}...")
    print(f"{platform.machine()}, {os.cpu_count()} CPUs, pyvisa {pyvisa.__version__}; load "
          f"average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)"
          + (f"; mock-lab pinned to CPU {min(server_cpus)}, clients to the others"
             if server_cpus else ""))
    print()
    print(f"{'transport':<9} {'direction':<9} {'radbench':>9} {'pyvisa-py':>9} {'ratio':>6}  "
          f"{'target':<21} verdict")
    all_met = True
    for transport in transports:
        for direction in ("read", "write"):
            rb = mb_s(args.size, timings[transport]["radbench"][direction])
            py = mb_s(args.size, timings[transport]["pyvisa"][direction])
            ratio = rb / py
            floor = FLOOR_MB_S[transport]
            met = rb >= floor and ratio >= MIN_RATIO
            all_met &= met
            target = f">= {floor:.0f} MB/s, >= {MIN_RATIO:.0f}x"
            print(f"{LABELS[transport]:<9} {direction:<9} {rb:>9.0f} {py:>9.0f} {ratio:>5.1f}x  "
                  f"{target:<21} {'met' if met else 'MISSED'}")
    print("\nread = instrument to client (DATA?), write = client to instrument (DATA #8..., *OPC?)")
    if args.json:
        print(json.dumps({"bytes": args.size, "load_before": load_before, "load_after": load_after,
                          "seconds": timings}, indent=1))
    return 0 if all_met else 1


if __name__ == "__main__":
    sys.exit(main())
