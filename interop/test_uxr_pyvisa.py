"""pyvisa-py (an independent client) drives mock_lab's Keysight Infiniium UXR emulator over HiSLIP
and VXI-11: identity, the SCPI error queue, a segmented acquisition triggered by the AWG's marker
on the AUX input (the AWG set up over pyvisa too), the Infiniium preamble and a WORD
`:WAVeform:DATA?` block read with pyvisa's own IEEE 488.2 block parser.

Needs: pyvisa, pyvisa-py, pytest, and the mock-lab binary (interop/run.sh builds it).
"""

import json
import os
import select
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

pyvisa = pytest.importorskip("pyvisa")

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def lab():
    binary = os.environ.get("MOCK_LAB_BIN", str(REPO / "target" / "debug" / "mock-lab"))
    if not Path(binary).exists():
        pytest.fail(f"mock-lab binary not found at {binary}; run interop/run.sh")
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen([binary, "serve", "--json", "--scope-model", "keysight-uxr"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 60)
        assert ready, "mock-lab printed no endpoints within 60 s"
        listing = json.loads(proc.stdout.readline())
        yield {(e["instrument"], e["transport"]): e["resource"] for e in listing["endpoints"]}
    finally:
        proc.stdin.close()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
        log.close()


@pytest.fixture(scope="module")
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_inst(rm, resource):
    inst = rm.open_resource(resource)
    inst.timeout = 10_000
    inst.read_termination = "\n"
    inst.write_termination = "\n"
    return inst


def errors(inst):
    codes = []
    while True:
        code = int(inst.query(":SYST:ERR?").split(",")[0])
        if code == 0:
            return codes
        codes.append(code)


def start_awg_marker(rm, lab):
    """The AWG plays a short segment with its marker on channel 3 (I/Q outputs off)."""
    awg = open_inst(rm, lab[("awg", "hislip")])
    for command in [":ABOR", ":INST:DACM DCM", ":INST:MEM:EXT:RDIV DIV4",
                    ":TRAC1:MMOD EXT;:TRAC2:MMOD EXT", ":FREQ:RAST 6.4E10",
                    ":TRAC1:DEL:ALL", ":TRAC1:DEF 1,320"]:
        awg.write(command)
    pairs = []
    for k in range(320):
        pairs += [0, 3 if k < 32 else 0]
    awg.write_binary_values(":TRAC1:DATA 1,0,", pairs, datatype="b")
    awg.write_binary_values(":TRAC2:DATA 1,0,", [0] * 320, datatype="b")
    awg.write(":TRAC1:SEL 1;:TRAC2:SEL 1;:OUTP3 ON;:INIT:IMM")
    assert awg.query("*OPC?") == "1"
    assert errors(awg) == []
    return awg


@pytest.mark.parametrize("transport", ["hislip", "vxi11"])
def test_pyvisa_captures_a_segmented_record_from_the_uxr_emulator(lab, rm, transport):
    awg = start_awg_marker(rm, lab)
    scope = open_inst(rm, lab[("scope", transport)])
    try:
        assert scope.query("*IDN?").startswith("MOCK_LAB,UXR0334A-EMU,")
        for command in [":SYSTem:HEADer OFF", ":WAVeform:FORMat WORD", ":WAVeform:BYTeorder LSBFirst",
                        ":CHANnel1:DISPlay ON", ":CHANnel2:DISPlay ON", ":ACQuire:MODE SEGMented",
                        ":ACQuire:SEGMented:COUNt 4", ":WAVeform:SEGMented:ALL ON",
                        ":ACQuire:SRATe:ANALog 128E9", ":ACQuire:POINts:ANALog 2560",
                        ":TRIGger:EDGE:SOURce AUX", ":TRIGger:LEVel AUX,0.1"]:
            scope.write(command)
        assert errors(scope) == []
        assert scope.query(":ACQuire:SEGMented:COUNt?") == "4"
        scope.write(":SINGle")
        deadline = time.monotonic() + 10
        while scope.query(":ADER?") != "1":
            assert time.monotonic() < deadline, "no acquisition within 10 s"
        scope.write(":WAVeform:SOURce CHANnel1")
        pre = scope.query(":WAVeform:PREamble?").split(",")
        assert pre[0] == "2"  # WORD, in the Infiniium's numbering
        assert int(pre[2]) == 2560
        assert float(pre[4]) == pytest.approx(1 / 128e9)
        words = scope.query_binary_values(":WAVeform:DATA?", datatype="h", is_big_endian=False,
                                          container=list)
        assert len(words) == 4 * 2560
        tags = [float(t) for t in scope.query(":WAVeform:SEGMented:XLISt? TTAG").split(",")]
        assert len(tags) == 4 and tags[0] == 0.0 and tags[1] > 0
        # What the scope refuses, with the SCPI codes a driver must surface.
        scope.write(":CHANnel1:SCALe 7")
        scope.write(":NOT:A:COMMAND")
        assert errors(scope) == [-222, -113]
    finally:
        scope.close()
        awg.write(":OUTP3 OFF;:ABOR")
        awg.close()
