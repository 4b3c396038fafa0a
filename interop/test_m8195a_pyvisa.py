"""pyvisa-py (an independent client) drives mock_lab's M8195A emulator over raw socket, HiSLIP and
VXI-11: identity, the driver's DCM / DIV4 setup, int8 block downloads with interleaved marker bytes,
read-back, and SCPI error codes from :SYST:ERR?.

Needs: pyvisa, pyvisa-py, pytest, and cargo on PATH (the serving example is built on the fly).
"""

import json
import os
import pathlib
import select
import subprocess

import pytest

pyvisa = pytest.importorskip("pyvisa")

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def resources():
    cargo = os.environ.get("CARGO", "cargo")
    subprocess.run([cargo, "build", "-q", "-p", "mock_lab", "--example", "serve_m8195a"],
                   cwd=ROOT, check=True, timeout=900)
    binary = ROOT / "target" / "debug" / "examples" / "serve_m8195a"
    proc = subprocess.Popen([str(binary)], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 60)
        assert ready, "serve_m8195a did not print its endpoints within 60 s"
        yield json.loads(proc.stdout.readline())
    finally:
        proc.stdin.close()
        proc.wait(timeout=30)


@pytest.fixture(scope="module")
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_awg(rm, resource):
    inst = rm.open_resource(resource)
    inst.timeout = 10_000
    inst.read_termination = "\n"
    inst.write_termination = "\n"
    return inst


def drain_errors(inst):
    codes = []
    while True:
        reply = inst.query(":SYST:ERR?")
        code = int(reply.split(",")[0])
        if code == 0:
            assert reply == '0,"No error"'
            return codes
        codes.append(code)


@pytest.mark.parametrize("transport", ["raw", "hislip", "vxi11"])
def test_pyvisa_drives_the_m8195a_emulator(resources, rm, transport):
    inst = open_awg(rm, resources[transport])
    try:
        assert inst.query("*IDN?").startswith("MOCK_LAB,M8195A-EMU,")
        inst.write("*RST")
        assert inst.query("*OPC?") == "1"
        for command in [":ABOR", ":INST:DACM DCM", ":INST:MEM:EXT:RDIV DIV4",
                        ":TRAC1:MMOD EXT;:TRAC2:MMOD EXT", ":FREQ:RAST 6.4E10",
                        ":TRAC1:DEL:ALL", ":TRAC1:DEF 1,320"]:
            inst.write(command)
        n = 320
        i = [(k * 7) % 256 - 128 for k in range(n)]
        q = [(k * 5) % 256 - 128 for k in range(n)]
        pairs = []
        for k in range(n):
            pairs += [i[k], 3 if k < 32 else 0]
        inst.write_binary_values(":TRAC1:DATA 1,0,", pairs, datatype="b")
        inst.write_binary_values(":TRAC2:DATA 1,0,", q, datatype="b")
        assert inst.query("*OPC?") == "1"
        assert drain_errors(inst) == []
        assert inst.query(":TRAC1:CAT?") == "1,320"
        assert inst.query(":TRAC1:DATA? 1,0,2") == f"{i[0]},3,{i[1]},3"
        assert inst.query(":TRAC2:DATA? 1,318,2") == f"{q[318]},{q[319]}"
        assert float(inst.query(":FREQ:RAST?")) == 64e9
        inst.write(":TRAC1:SEL 1;:TRAC2:SEL 1;:OUTP1 ON;:OUTP3 ON;:INIT:IMM")
        assert drain_errors(inst) == []
        # What the real instrument refuses, with the SCPI codes a driver must surface.
        inst.write(":FREQ:RAST 16E9")
        inst.write(":TRAC1:DEF 2,1000")
        inst.write(":NOT:A:COMMAND")
        assert drain_errors(inst) == [-222, -221, -113]
        inst.write(":ABOR")
    finally:
        inst.close()
