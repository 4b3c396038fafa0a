"""Line instruments built with sinstruments (servers nobody here wrote): one device served over
TCP and over a pseudo-terminal serial line.

Prints one JSON line {"tcp_port": N, "serial": "/dev/pts/M"} once both accept requests, serves
until killed. The TCP port is chosen by the OS.
"""

import json
import sys
import tempfile
from pathlib import Path

import gevent
from sinstruments.simulator import BaseDevice, Server

IDENTITY = b"SINSTRUMENTS,LINE-METER,SN0002,1.5.0"


class LineMeter(BaseDevice):
    """Answers a few SCPI queries, one per line; a command is remembered, unknown ones ignored."""

    def __init__(self, name, **kwargs):
        super().__init__(name, **kwargs)
        self.frequency = b"1.0E+09"

    def handle_message(self, line):
        text = line.strip()
        upper = text.upper()
        if upper == b"*IDN?":
            return IDENTITY + b"\n"
        if upper in (b"FREQ?", b"FREQUENCY?"):
            return self.frequency + b"\n"
        if upper.startswith(b"FREQ "):
            self.frequency = text.split(None, 1)[1]
            return None
        if upper == b"*OPC?":
            return b"1\n"
        return None


def main() -> int:
    # sinstruments links the pty under this path; the test uses the /dev/pts name itself.
    link = Path(tempfile.mkdtemp(prefix="sinstruments-")) / "meter-serial"
    device = {
        "class": "LineMeter",
        "package": "__main__",
        "name": "meter",
        "transports": [
            {"type": "tcp", "url": ["127.0.0.1", 0]},
            {"type": "serial", "url": str(link), "baudrate": 115200},
        ],
    }
    server = Server(devices=[device])
    meter = server.get_device_by_name("meter")
    tcp, serial = meter.transports
    tcp.start()  # binds and accepts now, so the port is known
    tasks = [gevent.spawn(t.serve_forever) for t in meter.transports]
    print(json.dumps({"tcp_port": tcp.server_port, "serial": serial.original_address}), flush=True)
    gevent.joinall(tasks)
    return 0


if __name__ == "__main__":
    sys.exit(main())
