"""radbench's client against instrument servers nobody here wrote: scpipy (a raw-socket SCPI
server) and sinstruments (line servers over TCP and over a pseudo-terminal serial line).

Each server runs from interop/servers/ on 127.0.0.1 with an OS-chosen port (or a fresh pty),
and `radbench idn` / `radbench scpi` run against it as a user would.
"""

import os
import subprocess

import pytest

from conftest import ForeignServer, radbench_binary

#: Every radbench run must end within this many seconds.
RUN_LIMIT_S = 60


def radbench(*args, stdin=None, env=None):
    return subprocess.run(
        [radbench_binary(), *args],
        input=stdin,
        stdin=None if stdin is not None else subprocess.DEVNULL,
        capture_output=True,
        timeout=RUN_LIMIT_S,
        env=env,
    )


@pytest.fixture(scope="module")
def scpipy():
    server = ForeignServer("scpipy_server.py")
    try:
        yield f"TCPIP::127.0.0.1::{server.info['port']}::SOCKET"
    finally:
        server.stop()


@pytest.fixture(scope="module")
def sinstruments():
    server = ForeignServer("sinstruments_server.py")
    try:
        yield {
            "tcp": f"TCPIP::127.0.0.1::{server.info['tcp_port']}::SOCKET",
            "serial": f"ASRL{server.info['serial']}::INSTR",
        }
    finally:
        server.stop()


def test_scpipy_identity(scpipy):
    out = radbench("idn", scpipy, "--timeout", "5")
    assert out.returncode == 0, out.stderr
    text = out.stdout.decode()
    assert "manufacturer: SCPIPY" in text
    assert "model:        INTEROP-METER" in text
    assert "firmware:     1.5.1" in text


def test_scpipy_commands_queries_and_its_error_queue(scpipy):
    out = radbench(
        "scpi", scpipy, "*RST", "MEAS:VOLT?", "SOUR:VOLT 2.5", "MEASure:VOLTage?", "*OPC?",
        "SYST:ERR?", "--check-errors", "--timeout", "5",
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.decode().splitlines() == ["1.25", "2.5", "1", '0,"No error"']


def test_scpipy_refused_query_is_reported_with_the_servers_error(scpipy):
    out = radbench("scpi", scpipy, "NOSUCH:HEADer?", "--timeout", "1")
    assert out.returncode == 3, out.stderr
    err = out.stderr.decode()
    assert "no reply to `NOSUCH:HEADer?`" in err, err
    assert "-110" in err, err
    # The session goes on for the next run: the queue was drained.
    out = radbench("scpi", scpipy, "SYST:ERR?", "--timeout", "5")
    assert out.stdout.decode().strip() == '0,"No error"'


def test_scpipy_short_printable_block_is_saved(scpipy, tmp_path):
    saved = tmp_path / "block.bin"
    out = radbench("scpi", scpipy, "DATA?", "--save-binary", str(saved), "--timeout", "5")
    assert out.returncode == 0, out.stderr
    assert "binary block (definite): 5 bytes" in out.stdout.decode()
    assert saved.read_bytes() == b"hello"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["block.bin"]


def test_scpipy_prompt_fed_from_a_pipe_writes_no_history(scpipy, tmp_path):
    env = dict(os.environ, HOME=str(tmp_path))
    out = radbench("scpi", scpipy, "--timeout", "5", stdin=b"*IDN?\nMEAS:VOLT?\n\\quit\n", env=env)
    assert out.returncode == 0, out.stderr
    assert "SCPIPY,INTEROP-METER" in out.stdout.decode()
    assert not (tmp_path / ".radbench_scpi_history").exists()


@pytest.mark.parametrize("link", ["tcp", "serial"])
def test_sinstruments_identity(sinstruments, link):
    out = radbench("idn", sinstruments[link], "--timeout", "5")
    assert out.returncode == 0, out.stderr
    text = out.stdout.decode()
    assert "manufacturer: SINSTRUMENTS" in text
    assert "model:        LINE-METER" in text


@pytest.mark.parametrize("link", ["tcp", "serial"])
def test_sinstruments_command_then_query(sinstruments, link):
    resource = sinstruments[link]
    assert resource.startswith("ASRL/dev/pts/") or link == "tcp", resource
    out = radbench("scpi", resource, "FREQ 2.5E9", "FREQ?", "*OPC?", "--timeout", "5")
    assert out.returncode == 0, out.stderr
    assert out.stdout.decode().splitlines() == ["2.5E9", "1"]
