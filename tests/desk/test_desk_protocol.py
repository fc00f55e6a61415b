"""The simulated Desk's connection bounds (``sim.desk.protocol``) where asyncio's TLS
transport has let go of its connection: uvicorn closed it twice, which leaves the
transport without its TLS protocol (``get_protocol()``, ``get_extra_info()`` and
``abort()`` reach nothing) while the TLS goodbye goes on. The check then raised
AttributeError in its timer (seen in a CI run's log), stopped checking, and the connection
was held until asyncio's 30 s shutdown timeout."""

from __future__ import annotations

import asyncio
import socket
from typing import Any

import pytest

from panda_py.sim.desk.protocol import desk_protocol

pytestmark = pytest.mark.timeout(30)
HEADER_TIMEOUT = 0.05  # [s]


class _ClosedTwice(asyncio.Transport):
    """A TLS transport as uvicorn's second close() leaves it: closing, its protocol gone."""

    def __init__(self, sock: socket.socket) -> None:
        super().__init__()
        self._info: dict[str, Any] | None = {"socket": sock, "peername": ("127.0.0.1", 1),
                                             "sockname": ("127.0.0.1", 2)}  # fmt: skip
        self._closing = False

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        if self._info is None:
            raise AttributeError("'NoneType' object has no attribute '_get_extra_info'")
        return self._info.get(name, default)

    def get_protocol(self) -> Any:
        raise AttributeError("'NoneType' object has no attribute '_app_protocol'")

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        self._closing = True
        self._info = None  # (the second close: asyncio drops its TLS protocol)

    def abort(self) -> None:
        self._closing = True  # reaches nothing

    def write(self, data: Any) -> None:
        pass

    def pause_reading(self) -> None:
        pass

    def resume_reading(self) -> None:
        pass


def test_a_goodbye_unanswered_on_a_transport_closed_twice_is_still_cut_short() -> None:
    from uvicorn.config import Config
    from uvicorn.server import ServerState

    ours, peer = socket.socketpair()
    peer.settimeout(5.0)
    errors: list[dict[str, Any]] = []

    async def main() -> None:
        loop = asyncio.get_running_loop()
        loop.set_exception_handler(lambda _loop, context: errors.append(context))
        config = Config(app=lambda *a: None, limit_concurrency=64)
        config.load()
        proto = desk_protocol(HEADER_TIMEOUT)(config, ServerState(), {}, _loop=loop)
        transport = _ClosedTwice(ours)
        proto.connection_made(transport)
        transport.close()  # the goodbye begins; the transport lets go of its connection
        await asyncio.sleep(4 * HEADER_TIMEOUT)

    asyncio.run(main())
    assert not errors, errors
    assert peer.recv(1) == b""  # the Desk shut the connection down: the peer reads its end
    ours.close()
    peer.close()
