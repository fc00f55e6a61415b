"""The user's side of the control process: start it, talk to it, notice when it dies.

The control process starts warm (:mod:`panda_py.warmstart`): forked from a server that
has imported the loop's modules and loaded its compiled kernels (:mod:`panda_py.rt.warm`),
never importing the user's script. It gets its end of a Unix socket pair and the
shared-memory file as inherited descriptors and nothing else. A reader thread in this
process takes its messages: replies go to the caller waiting for them, events (errors of
the loop, log lines) to the error queue and the logger. Only this process's threads take
this process's locks.

No orphans: the control process exits when its channel closes (this process died) or it
is re-parented (its parent, the warm server, ends with this process);
:meth:`ControlProcess.close` (also at interpreter exit, before ``multiprocessing`` ends
its children) asks it to finish, then terminates it, then kills it.
"""

from __future__ import annotations

import atexit
import collections
import concurrent.futures
import itertools
import logging
import multiprocessing.util  # noqa: F401  (its exit handler registered first: ours runs first)
import os
import signal
import socket
import threading
import time
import weakref
from typing import Any

from panda_py import warmstart
from panda_py.libfranka.errors import FrankaException
from panda_py.rt import requests as rq
from panda_py.rt.channel import Channel, ChannelClosed
from panda_py.rt.shm import HEADER, SharedBlock

__all__ = ["ControlProcess", "ControlProcessError", "Pending"]

CLOSE_TIMEOUT = 5.0  # [s] for the control process to finish a motion and exit
READY_TIMEOUT = 300.0  # [s] after connecting: first-run JIT compilation can take this long


class ControlProcessError(FrankaException):
    """The control process is gone (it crashed or was killed); ``exitcode`` as
    ``multiprocessing`` reports it (negative: the signal that ended it)."""

    def __init__(self, message: str, *, exitcode: int | None = None) -> None:
        super().__init__(message)
        self.exitcode = exitcode


class Pending(concurrent.futures.Future[Any]):
    """The reply to a request on its way: a ``concurrent.futures.Future`` the reader
    thread completes (the value, or the exception the control process raised), with the
    request's id (``rid``)."""

    def __init__(self, rid: int) -> None:
        super().__init__()
        self.rid = rid


_LIVE: weakref.WeakSet[ControlProcess] = weakref.WeakSet()


@atexit.register
def _close_all() -> None:
    for proc in list(_LIVE):
        proc.close()


class ControlProcess:
    """One control process, connected to the robot at ``hostname``."""

    def __init__(
        self,
        hostname: str,
        realtime_config: int,
        *,
        timeout: float,
        logger: logging.Logger,
        cpus: tuple[int, ...] | None = None,
    ) -> None:
        self.logger = logger
        self.block, shm_fd = SharedBlock.create()
        mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        self.chan = Channel(mine)
        # (it imports from where this process does: multiprocessing hands it sys.path; a
        # controller class is sent by reference to its module)
        self.proc = warmstart.context().Process(
            target=warmstart.run_with_environ,
            args=(dict(os.environ), "panda_py.rt.child:main",
                  warmstart.InheritedFd(theirs.fileno()), warmstart.InheritedFd(shm_fd)),
            name="panda_py-control",
            daemon=True,
        )  # fmt: skip
        try:
            warmstart.start(self.proc)
        finally:
            theirs.close()
            os.close(shm_fd)
        self._ids = itertools.count(1)
        self._waiters: dict[int, Pending] = {}
        self._send_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self.errors: collections.deque[BaseException] = collections.deque()
        self.events_seen = 0  # events the reader has taken (the loop counts those it sent)
        self.dead = False
        self.closed = False
        self._reader = threading.Thread(target=self._read, name="panda_py-rt-reader", daemon=True)
        self._reader.start()
        _LIVE.add(self)
        try:
            info = self.call(
                rq.Connect(hostname, int(realtime_config), float(timeout), cpus),
                timeout=timeout + READY_TIMEOUT,
            )
            self.info: rq.Connected = info
        except BaseException:
            self.close()
            raise

    # --- messages ------------------------------------------------------------------------

    def _read(self) -> None:
        try:
            while True:
                msg, fds = self.chan.recv()
                for fd in fds:
                    os.close(fd)
                if isinstance(msg, rq.Reply):
                    waiter = self._waiters.pop(msg.rid, None)
                    if waiter is not None and not waiter.done():
                        if msg.ok:
                            waiter.set_result(msg.value)
                        else:
                            waiter.set_exception(msg.value)
                elif isinstance(msg, (rq.LoopError, rq.LogLine)):
                    self._event(msg)
                    self.events_seen += 1
        except (ChannelClosed, OSError, EOFError):
            pass
        finally:
            self.dead = True
            for waiter in list(self._waiters.values()):
                if not waiter.done():
                    waiter.set_exception(
                        ControlProcessError("the control process is gone before it answered")
                    )
            self._waiters.clear()

    def _event(self, event: rq.LoopError | rq.LogLine) -> None:
        if isinstance(event, rq.LoopError):
            self.errors.append(event.error)
            self.logger.error("Control loop interrupted: %s", event.error)
        else:
            self.logger.log(event.level, event.message)

    def gone(self) -> ControlProcessError:
        """The error that says this process is gone (with how it ended)."""
        self.proc.join(1.0)
        code = self.proc.exitcode
        how = (
            f"killed by signal {signal.Signals(-code).name}"
            if code is not None and code < 0
            else f"exit code {code}"
        )
        return ControlProcessError(
            f"the control process (pid {self.proc.pid}) is gone ({how}); create a new "
            "Panda to reconnect",
            exitcode=code,
        )

    def submit(self, request: rq.Request, *, fds: tuple[int, ...] = ()) -> Pending:
        """Send a request; its reply arrives in the returned :class:`Pending`."""
        if self.closed:
            raise ControlProcessError("this Panda is closed")
        if self.dead:
            raise self.gone()
        rid = next(self._ids)
        waiter = Pending(rid)
        self._waiters[rid] = waiter
        try:
            with self._send_lock:
                self.chan.send(rq.Call(rid, request), fds)
                # counted after the send: the loop that sees the count finds the message
                self.block.header[HEADER.REQUESTS] += 1
        except (ChannelClosed, OSError):
            self._waiters.pop(rid, None)
            raise self.gone() from None
        if self.dead and not waiter.done():  # the reader ended before it could answer
            self._waiters.pop(rid, None)
            raise self.gone()
        return waiter

    def call(self, request: rq.Request, *, fds: tuple[int, ...] = (),
             timeout: float | None = None) -> Any:  # fmt: skip
        """Send a request and wait for its reply; raises what the control process raised."""
        waiter = self.submit(request, fds=fds)
        return self.wait(waiter, request, timeout)

    def wait(self, waiter: Pending, request: rq.Request, timeout: float | None = None) -> Any:
        """The reply in ``waiter`` (``request`` names it in a timeout's message)."""
        try:
            return waiter.result(timeout)
        except concurrent.futures.TimeoutError:
            self._waiters.pop(waiter.rid, None)
            raise ControlProcessError(
                f"the control process did not answer {request.kind.value!r} in time"
            ) from None
        except ControlProcessError:
            if self.dead:
                raise self.gone() from None
            raise

    def check(self) -> None:
        """Raise the oldest pending error of the loop, or that the process is gone."""
        if self.block.header[HEADER.EVENTS] > self.events_seen and not self.dead:
            # an event is on its way through the channel: let the reader take it
            deadline = time.monotonic() + 1.0
            while (
                self.block.header[HEADER.EVENTS] > self.events_seen
                and not self.dead
                and time.monotonic() < deadline
            ):
                time.sleep(1e-4)
        if self.errors:
            raise self.errors.popleft()
        if self.dead and not self.closed:
            raise self.gone()

    # --- shutdown ------------------------------------------------------------------------

    def close(self) -> None:
        """Finish any motion, let the process exit; terminate or kill it if it does not."""
        if self.closed:
            return
        if not self.dead:
            try:
                self.call(rq.Close(), timeout=CLOSE_TIMEOUT)
            except Exception:
                pass
        self.closed = True
        proc = self.proc
        proc.join(CLOSE_TIMEOUT)
        if proc.exitcode is None:
            proc.terminate()
            proc.join(1.0)
            if proc.exitcode is None:
                proc.kill()
                proc.join()
        self.chan.close()
        _LIVE.discard(self)
