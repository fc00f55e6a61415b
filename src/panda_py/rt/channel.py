"""The request channel between the user's process and the control process: a Unix
stream socket carrying length-prefixed pickles, optionally with file descriptors.

Used only for what is not per-tick (start a controller, a move, setters, logging files,
replies and asynchronous events); the per-tick data goes through shared memory.

A message whose arrays are large (a sampled trajectory of a long move) does not travel
through the socket: its pickle (protocol 5) leaves the arrays' bytes out of band, they are
written to an anonymous memory file (``memfd``) sent along as a descriptor, and the
receiver maps it and unpickles the arrays onto the mapping, without copying. The socket
then only ever carries small messages, so a send never waits for the reader: the control
loop reads a request when it is whole (all its bytes buffered, :meth:`Channel.whole`, or
counted by its sender, see ``ControlProcess.submit``), and a sender blocked on a full
socket buffer would wait for a loop that waits for it.
"""

from __future__ import annotations

import mmap
import os
import pickle
import select
import socket
import struct
import tempfile
from typing import Any

__all__ = ["Channel", "ChannelClosed"]

_LEN = struct.Struct("<I")
_MAX_MESSAGE = 256 * 1024 * 1024  # [bytes] a sampled trajectory of a few minutes fits
# A message whose arrays hold more than this goes out of band, through a memfd [bytes]
# (far below the socket's buffer, about 200 KiB: a send of the rest never blocks).
OUT_OF_BAND = 32 * 1024
_OOB_FLAG = 1 << 31  # in the length word: the last descriptor holds the arrays' bytes
_COUNT = struct.Struct("<I")
_SIZE = struct.Struct("<Q")
_INT = struct.Struct("i")  # FIONREAD's answer: the bytes buffered
_INT_ZERO = _INT.pack(0)
try:
    import fcntl
    import termios

    _FIONREAD: int | None = termios.FIONREAD
except ImportError:  # (no fcntl, termios: Windows)
    _FIONREAD = None


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
        # in band first: most messages are small, and one pickle is what they cost
        payload = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
        memfd = -1
        if len(payload) >= OUT_OF_BAND:  # large: its arrays, if they are, out of band
            buffers: list[pickle.PickleBuffer] = []
            oob = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
            views = [b.raw() for b in buffers]
            if sum(v.nbytes for v in views) >= OUT_OF_BAND:
                memfd = _write_memfd(views)
                table = _COUNT.pack(len(views)) + b"".join(_SIZE.pack(v.nbytes) for v in views)
                payload = table + oob
                fds = (*fds, memfd)
        if len(payload) >= _OOB_FLAG:
            raise ValueError(f"control channel: message of {len(payload)} bytes is too large")
        data = _LEN.pack(len(payload) | (_OOB_FLAG if memfd >= 0 else 0)) + payload
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
        finally:
            if memfd >= 0:
                os.close(memfd)  # the receiver has its own descriptor of it now

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
        oob = bool(n & _OOB_FLAG)
        n &= ~_OOB_FLAG
        if n > _MAX_MESSAGE:
            raise ChannelClosed(f"control channel: message of {n} bytes is too large")
        payload = self._recv_exact(n)
        if not oob:
            return pickle.loads(payload), list(fds)
        if not fds:
            raise ChannelClosed("control channel: an out-of-band message came without its data")
        memfd = fds.pop()
        try:
            return _loads_mapped(payload, memfd), list(fds)
        finally:
            os.close(memfd)

    def whole(self) -> bool:
        """True if a whole message is buffered, so that :meth:`recv` takes it without
        waiting; never waits, and reads nothing. False where the buffered bytes cannot
        be counted (no ``FIONREAD``)."""
        if _FIONREAD is None:
            return False
        try:
            buffered = _INT.unpack(fcntl.ioctl(self.sock, _FIONREAD, _INT_ZERO))[0]
            if buffered < 4:
                return False
            head = self.sock.recv(4, socket.MSG_PEEK | socket.MSG_DONTWAIT)
        except OSError:  # (BlockingIOError among them)
            return False
        if len(head) < 4:
            return False
        return bool(buffered >= 4 + (_LEN.unpack(head)[0] & ~_OOB_FLAG))

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


def _write_memfd(views: list[memoryview]) -> int:
    """A new anonymous memory file holding ``views`` one after another (its descriptor);
    where the system has no ``memfd_create`` (macOS), an unlinked temporary file."""
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create("panda-py-message", os.MFD_CLOEXEC)
    else:
        with tempfile.TemporaryFile() as f:  # unlinked at once; our descriptor keeps it
            fd = os.dup(f.fileno())
    try:
        for data in views:  # (raw(): flat byte views)
            while data:
                written = os.write(fd, data)
                data = data[written:]
    except BaseException:
        os.close(fd)
        raise
    return fd


def _loads_mapped(payload: bytes, memfd: int) -> Any:
    """Unpickle a message whose arrays' bytes are in ``memfd``: they become arrays on a
    private (copy-on-write) mapping of it, so nothing is copied and the arrays may be
    written to."""
    (count,) = _COUNT.unpack_from(payload)
    sizes = [_SIZE.unpack_from(payload, 4 + 8 * i)[0] for i in range(count)]
    body = memoryview(payload)[4 + 8 * count :]
    total = sum(sizes)
    if total == 0 or total != os.fstat(memfd).st_size:
        raise ChannelClosed(
            f"control channel: out-of-band data of {os.fstat(memfd).st_size} bytes, "
            f"expected {total}"
        )
    whole = memoryview(mmap.mmap(memfd, total, access=mmap.ACCESS_COPY))
    buffers, offset = [], 0
    for size in sizes:
        buffers.append(whole[offset : offset + size])
        offset += size
    return pickle.loads(body, buffers=buffers)
