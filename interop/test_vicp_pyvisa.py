"""pyvisa + pyvisa-py's VICP resource (through pyvicp) against mock-lab.

pyvisa-py only reaches VICP on the standard port 1861 (it ignores a port in the resource
string), so this starts a second mock-lab with `--vicp-port 1861` and skips when that port is
already taken on this machine.
"""

import socket

import pytest
import pyvisa

from conftest import MockLab

VICP_PORT = 1861


def port_is_free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@pytest.fixture(scope="module")
def vicp_resource():
    if not port_is_free(VICP_PORT):
        pytest.skip(f"port {VICP_PORT} is in use on this machine; pyvisa's VICP needs exactly it")
    lab = MockLab("--vicp-port", str(VICP_PORT))
    try:
        assert lab.endpoints["vicp"]["resource"] == "VICP::127.0.0.1::INSTR"
        yield lab.endpoints["vicp"]["resource"]
    finally:
        lab.stop()


def test_pyvisa_vicp_identity_clear_and_status(vicp_resource):
    rm = pyvisa.ResourceManager("@py")
    try:
        inst = rm.open_resource(vicp_resource, open_timeout=10_000)
        inst.timeout = 10_000
        inst.read_termination = "\n"
        assert inst.query("*IDN?").strip() == "MOCK_LAB,LOOPBACK,0,0.1"
        inst.write("BOGUS")
        assert inst.query("*OPC?").strip() == "1"
        # pyvisa-py's VICP session has no read_stb (VI_ERROR_NSUP_OPER); pyvicp's serial poll
        # is checked in test_servers.py. Here the status byte comes from *STB?.
        assert int(inst.query("*STB?")) & 0x04 == 0x04
        inst.write("SLOW? 60000")
        inst.clear()
        assert inst.query("SYST:ERR?").strip() == '-113,"Undefined header"'
        inst.close()
    finally:
        rm.close()
