"""A raw-socket SCPI instrument built with scpipy (a server nobody here wrote).

Listens on 127.0.0.1, port chosen by the OS, prints one JSON line {"port": N} once it accepts
connections, serves until killed. One error queue for all clients (as on a real instrument),
so the queue survives the reconnection a raw-socket device clear is.
"""

import json
import sys

from scpipy.server import Context, Router, Server

IDENTITY = "SCPIPY,INTEROP-METER,SN0001,1.5.1"

router = Router()


@router.register("*IDN?")
def identity(context: Context) -> str:
    return IDENTITY


@router.register("*RST")
def reset(context: Context):
    context.state["voltage"] = "1.25"


@router.register("MEASure:VOLTage?")
def measure_voltage(context: Context) -> str:
    return context.state.get("voltage", "1.25")


@router.register("SOURce:VOLTage <value>")
def set_voltage(context: Context, value: str):
    context.state["voltage"] = value


@router.register("DATA?")
def data(context: Context) -> str:
    # scpipy answers text only: a short printable definite block.
    return "#15hello"


class AnnouncingServer(Server):
    """Prints the port the OS chose once the listener is up (scpipy 1.5.1 keeps it private)."""

    async def _wait_stop(self):
        port = self._server.sockets[0].getsockname()[1]
        print(json.dumps({"port": port}), flush=True)
        await super()._wait_stop()


def main() -> int:
    server = AnnouncingServer("127.0.0.1", 0, shared_context=True)
    server.include_router(router)
    server.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
