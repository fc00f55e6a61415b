"""Sockets of one FCI connection: a TCP command channel and a UDP state/command channel.

Every socket call has a timeout, and every low-level failure (``OSError``,
``socket.timeout``, a malformed message) is translated to this package's exceptions in one
function, :func:`translate`. The UDP socket is bound to ``0.0.0.0:0`` and commands go back
to the source address of the states, as libfranka does. Datagrams from any other address
than the robot's (the TCP peer's) are dropped, so a stray or spoofed datagram can neither
be taken for a state nor redirect the commands; every wait ends at a deadline.
"""

from __future__ import annotations

import select
import socket
import struct
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from panda_py.checks import timeout as _timeout
from panda_py.fci import MESSAGE_ID, PERIOD, Message, MessageReader, ProtocolError
from panda_py.libfranka.errors import FrankaException, NetworkException, ProtocolException

__all__ = ["CONNECT_TIMEOUT", "TCP_TIMEOUT", "UDP_TIMEOUT", "Network", "translate"]

CONNECT_TIMEOUT = 5.0  # [s] TCP connect
TCP_TIMEOUT = 10.0  # [s] default wait for a TCP response
UDP_TIMEOUT = 1.0  # [s] wait for a UDP datagram (libfranka: 1 s)
# Hybrid wait for the next 1 kHz state: sleep until SPIN_LEAD before it is due, then poll
# without sleeping for at most SPIN_BUDGET, then sleep again. A thread woken from sleep
# runs its first microseconds on cold caches (several times slower on a VM), so catching
# the datagram while spinning cuts the per-tick latency; the budget bounds the CPU burnt.
# When a state is due is tracked as a phase: the robot sends on absolute deadlines and
# delays only ever add, so an early state sets the phase at once, while one that is late
# but still inside the spin moves it by PHASE_SLEW only (else one late state would end
# the wait for the next, which comes on time, too late: woken on cold caches, or in the
# middle of the loop's cache warm-up); a state later than the spin covers resets it.
STATE_PERIOD = PERIOD  # [s]
SPIN_LEAD = 150e-6  # [s]
SPIN_BUDGET = 300e-6  # [s]
PHASE_SLEW = 10e-6  # [s] per state
_clock = time.perf_counter
_UDP_BUFFER = 4096  # [bytes] larger than any state datagram
_INT_BUFFER = bytes(4)  # FIONREAD's answer: a C int
_NONE_QUEUED = bytes(4)
_MESSAGE_ID = MESSAGE_ID

if sys.platform != "win32":
    import fcntl
    import termios

    _FIONREAD: int | None = termios.FIONREAD
else:  # no ioctl: a non-blocking receive that fails tells instead
    fcntl = None
    _FIONREAD = None


def translate(exc: BaseException, what: str) -> FrankaException:
    """The one place where socket and decoding errors become this package's exceptions."""
    if isinstance(exc, FrankaException):
        return exc
    if isinstance(exc, (ProtocolError, struct.error)):
        return ProtocolException(f"libfranka: {what}: {exc}")
    if isinstance(exc, (TimeoutError, socket.timeout)):
        return NetworkException(f"libfranka: {what}: Timeout")
    if isinstance(exc, ConnectionRefusedError):
        return NetworkException(
            f"libfranka: {what}: Connection refused. Is FCI enabled and the address right?"
        )
    if isinstance(exc, OSError):
        return NetworkException(f"libfranka: {what}: {exc.strerror or exc}")
    return FrankaException(f"libfranka: {what}: {exc}")


class Network:
    """TCP + UDP sockets to ``host:port``; ``reader`` cuts the TCP stream into messages."""

    def __init__(
        self, host: str, port: int, reader: MessageReader, *, udp_size: int, timeout: float
    ) -> None:
        if not isinstance(host, str) or not host:
            raise ValueError(f"hostname: expected a host name or IP address, got {host!r}")
        self.host = host
        self.timeout = _timeout("timeout", timeout)
        self._reader = reader
        self._udp_size = udp_size  # datagrams shorter than this are a protocol error
        self._responses: dict[int, deque[Message]] = {}
        self._tcp_lock = threading.Lock()
        # a wait_response reads the socket (without the lock while it waits); the others
        # wait on _arrived, notified when it queued responses or stopped reading
        self._arrived = threading.Condition(self._tcp_lock)
        self._reading = False
        self._udp_peer: tuple[str, int] | None = None
        # the UDP socket is connected to the robot's address once its first state came;
        # _checked: every datagram queued before the connect was read (with its sender)
        self._checked = False
        self._next_due = 0.0  # perf_counter when the next state is expected
        self.broken = False  # the robot closed the TCP connection (or it failed)
        self.spin = True  # hybrid sleep/spin wait for states (False: sleep only)
        #: Called when a hybrid wait has slept and starts polling for a state that is due
        #: shortly (a control loop warms its caches there, see :mod:`._warm`).
        self.before_spin: Callable[[], None] | None = None
        self._tcp: socket.socket | None = None
        self._udp: socket.socket | None = None
        self._robot_ip = ""  # states are accepted from this address only
        self.foreign_datagrams = 0  # dropped: not from the robot (read before the connect)
        # states received and passed over for a newer one queued behind them (the caller
        # was late): Robot.skipped_states
        self.skipped_states = 0
        try:
            self._tcp = socket.create_connection((host, port), timeout=CONNECT_TIMEOUT)
            self._tcp.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._tcp.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
            self._tcp.settimeout(self.timeout)
            self._robot_ip = self._tcp.getpeername()[0]
            self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._udp.bind(("0.0.0.0", 0))
            # Non-blocking: a socket with a Python timeout waits for readability even when
            # asked not to (MSG_DONTWAIT), so draining would block; waits use select().
            self._udp.setblocking(False)
        except OSError as exc:
            self.close()
            raise translate(exc, f"Connection to {host}:{port}") from exc
        except BaseException:
            self.close()  # no socket is left open on any error path
            raise

    @property
    def udp_port(self) -> int:
        """The local UDP port the robot sends states to."""
        assert self._udp is not None
        return int(self._udp.getsockname()[1])

    def state_fileno(self) -> int:
        """The UDP socket's descriptor (readable when a state datagram is waiting)."""
        if self._udp is None:
            raise NetworkException("libfranka: the connection is closed")
        return self._udp.fileno()

    def close(self) -> None:
        for s in (self._tcp, self._udp):
            if s is not None:
                try:
                    s.close()
                except OSError:
                    pass
        self._tcp = self._udp = None

    @property
    def closed(self) -> bool:
        return self._tcp is None

    # --- TCP --------------------------------------------------------------------------

    def _sock(self) -> socket.socket:
        if self._tcp is None:
            raise NetworkException("libfranka: connection is closed")
        return self._tcp

    def send(self, data: bytes) -> None:
        """Send one complete TCP message."""
        try:
            self._sock().sendall(data)
        except OSError as exc:
            raise translate(exc, "TCP send") from exc

    def _pump(self, timeout: float) -> None:
        """Read what the TCP socket has (waiting up to ``timeout`` [s]) into the response
        queues. Caller holds ``_tcp_lock``."""
        sock = self._sock()
        try:
            ready, _, _ = select.select([sock], [], [], max(0.0, timeout))
            if not ready:
                return
            data = sock.recv(65536)
            if not data:
                self.broken = True
                raise NetworkException("libfranka: server closed connection")
            for msg in self._reader.feed(data):
                self._responses.setdefault(msg.command_id, deque()).append(msg)
        except (OSError, ProtocolError, ValueError) as exc:
            raise translate(exc, "TCP receive") from exc

    def command_fileno(self) -> int:
        """The TCP socket's descriptor (readable when a response, or the end, is waiting)."""
        return self._sock().fileno()

    def receive_messages(self) -> list[Message]:
        """Read once from the TCP socket, which select() found readable, and return the
        complete messages it held (none if a message is still incomplete). For a
        connection whose responses one thread reads and hands out (the hand clients', see
        :mod:`._responses`) instead of :meth:`wait_response`."""
        sock = self._sock()
        try:
            data = sock.recv(65536)
            if not data:
                self.broken = True
                raise NetworkException("libfranka: server closed connection")
            return self._reader.feed(data)
        except (BlockingIOError, InterruptedError):
            return []
        except (OSError, ProtocolError, ValueError) as exc:
            raise translate(exc, "TCP receive") from exc

    def _take(self, command_id: int) -> Message | None:
        """The next queued response to ``command_id``, if any. Caller holds ``_tcp_lock``."""
        queue = self._responses.get(command_id)
        if not queue:
            return None
        msg = queue.popleft()
        if not queue:
            del self._responses[command_id]
        return msg

    def poll_response(self, command_id: int) -> Message | None:
        """The next queued response to ``command_id``, reading the socket without waiting
        (unless a :meth:`wait_response` is reading it: that one queues what comes)."""
        with self._tcp_lock:
            msg = self._take(command_id)
            if msg is None and not self._reading:
                self._pump(0.0)
                msg = self._take(command_id)
        return msg

    def wait_response(self, command_id: int, timeout: float | None = None) -> Message:
        """Block (at most ``timeout`` [s], default the connection's) for a response.

        Several threads may wait at once: one of them reads the socket, without holding
        the lock while it waits, and wakes the others whenever it queued responses; when
        it has its own, another waiter takes over the reading."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        with self._arrived:
            while True:
                msg = self._take(command_id)
                if msg is not None:
                    return msg
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    raise NetworkException("libfranka: TCP receive: Timeout")
                if self._reading:  # another waiter reads: it wakes us when it queued some
                    self._arrived.wait(remaining)
                    continue
                self._reading = True
                try:
                    sock = self._sock()
                    self._arrived.release()
                    try:
                        ready, _, _ = select.select([sock], [], [], remaining)
                    except (OSError, ValueError) as exc:
                        raise translate(exc, "TCP receive") from exc
                    finally:
                        self._arrived.acquire()
                    if ready:
                        self._pump(0.0)
                finally:
                    self._reading = False
                    self._arrived.notify_all()

    def check_closed(self) -> None:
        """Raise NetworkException if the robot closed the TCP connection (a select and, if
        readable, one peek; pending responses stay queued in the socket)."""
        sock = self._sock()
        try:
            ready, _, _ = select.select([sock], [], [], 0.0)
            if ready and sock.recv(1, socket.MSG_PEEK) == b"":
                self.broken = True
                raise NetworkException("libfranka: server closed connection")
        except (BlockingIOError, InterruptedError):
            return
        except (OSError, ValueError) as exc:
            self.broken = True
            raise translate(exc, "TCP receive") from exc

    # --- UDP --------------------------------------------------------------------------

    def _recv_udp(self, block: bool, deadline: float | None = None) -> bytes | None:
        """The next datagram from the robot: None if none is queued (``block=False``);
        else waits until ``deadline`` (``_clock()``; default one UDP timeout from now)."""
        udp = self._udp
        if udp is None:
            raise NetworkException("libfranka: connection is closed")
        if block and deadline is None:
            deadline = _clock() + UDP_TIMEOUT
        spin = block and self.spin
        while True:
            try:
                if block:
                    if spin:
                        spin = False  # once per call: foreign datagrams must not re-arm it
                        data = self._spin_wait(udp)
                        if data is not None:
                            return data
                    remaining = deadline - _clock()  # type: ignore[operator]
                    if remaining <= 0.0:
                        raise NetworkException("libfranka: UDP receive: Timeout")
                    ready, _, _ = select.select([udp], [], [], remaining)
                    if not ready:
                        raise NetworkException("libfranka: UDP receive: Timeout")
                accepted = self._receive(udp)
            except (BlockingIOError, InterruptedError):
                if not block:
                    return None  # nothing (left) to read
                continue  # readable, then gone: wait again
            except (OSError, ValueError) as exc:
                raise translate(exc, "UDP receive") from exc
            if accepted is not None:
                return accepted

    def _receive(self, udp: socket.socket) -> bytes | None:
        """The next datagram on ``udp``: the robot's, or None for one that is not (counted);
        BlockingIOError if none is queued. The first state connects the socket to where it
        came from: the kernel then drops every other sender's datagrams, and the receive
        and the send no longer format and parse an address each tick (``recvfrom``'s
        address, printed by sprintf, was ~3 % of the control process's CPU). What was
        queued before the connect is still read with its sender, until the queue was once
        empty."""
        if self._checked:
            return self._accept(udp.recv(_UDP_BUFFER))
        data, addr = udp.recvfrom(_UDP_BUFFER)
        if self._foreign(addr):
            return None
        if self._udp_peer is None:
            udp.connect(addr)
            self._udp_peer = addr
        if not self._queued(udp):
            self._checked = True
        return self._accept(data)

    def _foreign(self, addr: tuple[str, int]) -> bool:
        """True (and counted) for a datagram not from the robot: the robot's IP always, and
        once a state came, the same source port."""
        peer = self._udp_peer
        if addr[0] == self._robot_ip if peer is None else addr == peer:
            return False
        self.foreign_datagrams += 1
        return True

    def _accept(self, data: bytes) -> bytes:
        """A datagram from the robot: checked for its size; the state's phase from when
        it came."""
        if len(data) < self._udp_size:
            raise ProtocolException("libfranka: incorrect object size")
        now = _clock()
        due = self._next_due
        if due < now <= due + (SPIN_BUDGET - SPIN_LEAD):  # late, within the spin
            self._next_due = due + STATE_PERIOD + PHASE_SLEW
        else:  # early (or no phase yet, or far off): this arrival sets it
            self._next_due = now + STATE_PERIOD
        return data

    def _spin_wait(self, udp: socket.socket) -> bytes | None:
        """Sleep until shortly before the next state is due, then poll for it."""
        due = self._next_due - SPIN_LEAD
        now = _clock()
        if due > now:
            ready, _, _ = select.select([udp], [], [], due - now)
            if ready:
                try:
                    return self._receive(udp)
                except (BlockingIOError, InterruptedError):
                    return None
            hook = self.before_spin
            if hook is not None:
                hook()
        end = _clock() + SPIN_BUDGET
        receive = self._receive
        while True:
            try:
                got = receive(udp)
            except (BlockingIOError, InterruptedError):
                if _clock() > end:
                    return None
                continue
            if got is not None:
                return got

    def pending(self) -> bool:
        """True if a datagram waits on the UDP socket (a poll, no wait)."""
        udp = self._udp
        return udp is not None and bool(select.select([udp], [], [], 0.0)[0])

    def _queued(self, udp: socket.socket) -> bool:
        """True if a datagram may wait on ``udp``: one ioctl (FIONREAD), cheaper than a
        receive that fails with an exception when nothing is queued, as is usual before
        each tick's state. Always True where there is no ioctl."""
        if _FIONREAD is None:
            return True
        try:
            return fcntl.ioctl(udp.fileno(), _FIONREAD, _INT_BUFFER) != _NONE_QUEUED
        except OSError:
            return True  # let the receive report what is wrong

    def receive_newest(self, last_id: int) -> bytes:
        """The newest robot state on the UDP socket whose ``message_id`` (u64 at offset 0)
        is above ``last_id``; waits for one if there is none (libfranka's
        ``receiveRobotState``), at most one UDP timeout in all: states that keep coming
        but are all older (after a bogus id) end in the same timeout as silence."""
        udp = self._udp
        if udp is None:
            raise NetworkException("libfranka: connection is closed")
        best: bytes | None = None
        best_id = last_id
        unpack = _MESSAGE_ID.unpack_from
        deadline = 0.0
        while True:
            # take every state already queued, keep the newest: a receive first (in a
            # loop the state is there: two system calls a tick, not three), then one
            # more for each the ioctl says is queued
            data = self._recv_udp(block=False)
            while data is not None:
                mid = unpack(data)[0]
                if mid > best_id:
                    if best is not None:
                        self.skipped_states += 1
                    best, best_id = data, mid
                data = self._recv_udp(block=False) if self._queued(udp) else None
            if best is not None:
                return best
            if not deadline:  # none queued: a robot that closed the connection sends none
                self.check_closed()
                deadline = _clock() + UDP_TIMEOUT
            data = self._recv_udp(block=True, deadline=deadline)
            if data is not None and unpack(data)[0] > best_id:
                best, best_id = data, unpack(data)[0]

    def discard_queued(self) -> None:
        """Drop every datagram already queued on the UDP socket (libfranka's ``readOnce``
        does this first, so what follows was sent after everything the caller did)."""
        udp = self._udp
        if udp is None:
            raise NetworkException("libfranka: connection is closed")
        try:
            while True:
                if self._checked:
                    udp.recv(_UDP_BUFFER)
                else:
                    self._foreign(udp.recvfrom(_UDP_BUFFER)[1])  # counted if it was
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            raise translate(exc, "UDP receive") from exc

    def receive_fresh(self) -> bytes:
        """The next datagram sent after this call: queued ones are discarded first, then
        this waits (up to the UDP timeout) for a new one (libfranka's gripper ``readOnce``)."""
        self.discard_queued()
        data = None
        while data is None:
            data = self._recv_udp(block=True)
        return data

    def send_udp(self, data: Any) -> None:
        """Send a datagram to where the states come from (the socket is connected there)."""
        udp = self._udp
        if udp is None or self._udp_peer is None:
            raise NetworkException("libfranka: UDP send: no robot state received yet")
        try:
            udp.send(data)
        except OSError as exc:
            raise translate(exc, "UDP send") from exc
