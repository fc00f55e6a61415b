"""The request channel between the user's process and the control process: a Unix
stream socket carrying length-prefixed pickles, optionally with file descriptors.

Used only for what is not per-tick (start a controller, a move, setters, logging files,
replies and asynchronous events); the per-tick data goes through shared memory.
"""

from __future__ import annotations

import pickle
import select
import socket
import struct
from typing import Any

__all__ = ["Channel", "ChannelClosed"]

_LEN = struct.Struct("<I")
_MAX_MESSAGE = 256 * 1024 * 1024  # [bytes] a sampled trajectory of a few minutes fits


class ChannelClosed(EOFError):
    """The other process closed its end (it exited or died)."""


class Channel:
    """One end of the socket pair."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.sock.setblocking(True)

    @classmethod
    def from_fd(cls, fd: int) -> Channel:
        return cls(socket.socket(fileno=fd))

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass

    def send(self, obj: Any, fds: tuple[int, ...] = ()) -> None:
        payload = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
        data = _LEN.pack(len(payload)) + payload
        try:
            if fds:
                sent = socket.send_fds(self.sock, [data[:4]], list(fds))
                if sent != 4:
                    raise ChannelClosed("short write on the control channel")
                self.sock.sendall(data[4:])
            else:
                self.sock.sendall(data)
        except (BrokenPipeError, ConnectionResetError) as exc:
            raise ChannelClosed("the other process closed the control channel") from exc

    def _recv_exact(self, n: int) -> bytes:
        chunks = []
        while n:
            chunk = self.sock.recv(min(n, 1 << 20))
            if not chunk:
                raise ChannelClosed("the other process closed the control channel")
            chunks.append(chunk)
            n -= len(chunk)
        return b"".join(chunks)

    def recv(self) -> tuple[Any, list[int]]:
        """The next message and the descriptors that came with it (blocks)."""
        try:
            head, fds, _flags, _addr = socket.recv_fds(self.sock, 4, 8)
        except (ConnectionResetError, OSError) as exc:
            raise ChannelClosed(f"control channel: {exc}") from exc
        if not head:
            raise ChannelClosed("the other process closed the control channel")
        if len(head) < 4:
            head += self._recv_exact(4 - len(head))
        (n,) = _LEN.unpack(head)
        if n > _MAX_MESSAGE:
            raise ChannelClosed(f"control channel: message of {n} bytes is too large")
        return pickle.loads(self._recv_exact(n)), list(fds)

    def poll(self, timeout: float = 0.0) -> bool:
        """True if a message (or the close) is waiting."""
        return bool(select.select([self.sock], [], [], timeout)[0])

    def peer_closed(self) -> bool:
        """True if the other end closed the channel (and nothing is left to read); never
        waits, and reads nothing."""
        try:
            return self.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except (BlockingIOError, InterruptedError):
            return False
        except OSError:
            return True
