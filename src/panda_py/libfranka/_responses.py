"""The one reader of a hand-type connection's responses (:class:`Responses`), and the
future a command started with ``asynchronous=True`` returns (:class:`CommandFuture`).

The Franka Hand answers a command only when its action ends (a move once the fingers
stopped) and meanwhile answers others (a Stop, which ends the move as aborted). So one
thread reads every TCP response and resolves the future registered under its command id;
callers never read the socket themselves. Any number of threads can thus wait at once,
each wakes as soon as its own answer is in (no polling, no caller starved by another one
holding the socket), a command unanswered within the connection's timeout fails as a
blocking wait used to, and :meth:`Responses.close` resolves whatever is still pending.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import copy
import logging
import select
import socket
import threading
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any

from panda_py.fci import Message
from panda_py.libfranka._network import Network
from panda_py.libfranka.errors import FrankaException, NetworkException

__all__ = ["CommandFuture", "Responses"]

log = logging.getLogger("panda_py.libfranka")


class CommandFuture(concurrent.futures.Future[bool]):
    """A gripper command under way. ``result()`` is what the blocking call returns (True
    on success, False if unsuccessful), or raises what it raises (:class:`CommandException`
    for a failed or aborted command, :class:`NetworkException` for a timeout or a client
    closed first). ``await`` it in a coroutine for the same, without blocking the event
    loop. The command has been sent: ``cancel()`` does nothing (returns False); the
    gripper's ``stop()`` aborts the action. Done-callbacks run in the client's reader
    thread and must not block (a blocking gripper call there raises RuntimeError)."""

    def __init__(self, command: str) -> None:
        super().__init__()
        self.command = command  # "Move", "Grasp", ...

    def __await__(self) -> Generator[Any, None, bool]:
        result: bool = yield from asyncio.wrap_future(self).__await__()
        return result


#: Turns a command's response into the blocking call's return value (or raises).
Finish = Callable[[Message], bool]


@dataclass
class _Pending:
    future: CommandFuture
    finish: Finish
    deadline: float  # time.monotonic() when waiting for the answer gives up


class Responses:
    """Reads ``net``'s TCP responses in a thread of its own and resolves the futures of
    :meth:`submit`. ``label`` names the device in errors ("gripper")."""

    def __init__(self, net: Network, label: str) -> None:
        self._net = net
        self._label = label
        self._fd = net.command_fileno()
        self._lock = threading.Lock()
        self._pending: dict[int, _Pending] = {}
        # set once reading has ended (closed, or the connection failed): what a command
        # submitted from then on fails with
        self._ended: Callable[[str], FrankaException] | None = None
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._thread = threading.Thread(
            target=self._serve, name=f"panda_py {label} responses", daemon=True
        )
        self._thread.start()

    def in_reader(self) -> bool:
        """True in the reader thread (a future's done-callback)."""
        return threading.current_thread() is self._thread

    def submit(self, command_id: int, command: str, finish: Finish,
               send: Callable[[], None]) -> CommandFuture:  # fmt: skip
        """Register a future for ``command_id``, then ``send()`` the command. If the
        connection has ended or the send fails, this raises and nothing stays pending."""
        future = CommandFuture(command)
        future.set_running_or_notify_cancel()  # sent: cancel() can no longer undo it
        with self._lock:
            if self._ended is not None:
                raise self._ended(command)
            # registered before sending, so the answer cannot come first
            self._pending[command_id] = _Pending(
                future, finish, time.monotonic() + self._net.timeout
            )
        try:
            send()
        except BaseException:
            with self._lock:
                self._pending.pop(command_id, None)
            raise
        self._wake()  # the reader's wait now ends at this command's deadline at the latest
        return future

    def close(self) -> None:
        """Stop reading; every pending future fails with a NetworkException saying the
        client was closed before the device answered. Idempotent."""
        label = self._label
        self._end(
            lambda command: NetworkException(
                f"libfranka {label}: {command} command: the client was closed before the "
                f"{label} answered"
            )
        )
        self._wake()
        if not self.in_reader():
            self._thread.join()
        for s in (self._wake_r, self._wake_w):
            s.close()

    # --- the reader thread ------------------------------------------------------------

    def _wake(self) -> None:
        try:
            self._wake_w.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # a wake-up is already queued, or closing

    def _end(self, failure: Callable[[str], FrankaException]) -> None:
        """Mark reading as ended and fail every pending future with ``failure(command)``."""
        with self._lock:
            if self._ended is None:
                self._ended = failure
            failure = self._ended
            pending, self._pending = self._pending, {}
        for p in pending.values():
            p.future.set_exception(failure(p.future.command))

    def _serve(self) -> None:
        wake = self._wake_r.fileno()
        try:
            while True:
                with self._lock:
                    if self._ended is not None:
                        return
                    deadline = min((p.deadline for p in self._pending.values()), default=None)
                timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
                ready, _, _ = select.select([self._fd, wake], [], [], timeout)
                if wake in ready:
                    try:
                        while self._wake_r.recv(4096):
                            pass
                    except (BlockingIOError, InterruptedError):
                        pass
                if self._fd in ready:
                    for msg in self._net.receive_messages():
                        self._resolve(msg)
                self._expire(time.monotonic())
        except FrankaException as exc:  # the connection failed: so does every command
            log.debug("%s responses: %s", self._label, exc)
            failed = exc
            self._end(lambda _command: copy.copy(failed))
        except (OSError, ValueError) as exc:  # the socket was closed under select()
            message = f"libfranka: TCP receive: {exc}"
            self._end(lambda _command: NetworkException(message))
        finally:  # whatever ended the thread, nothing is left waiting for it
            label = self._label
            self._end(
                lambda command: NetworkException(
                    f"libfranka {label}: {command} command: the response reader stopped"
                )
            )

    def _resolve(self, msg: Message) -> None:
        with self._lock:
            p = self._pending.pop(msg.command_id, None)
        if p is None:  # answered after its wait timed out, or never asked: dropped
            log.debug("%s: dropped a response to command id %d", self._label, msg.command_id)
            return
        future, finish = p.future, p.finish
        del p  # finish holds the client: one dropped unclosed is collectable once resolved
        try:
            ok = finish(msg)
        except Exception as exc:  # the blocking call's error, raised where it waits
            del finish
            future.set_exception(exc)
        else:
            del finish
            future.set_result(ok)

    def _expire(self, now: float) -> None:
        with self._lock:
            late = [cid for cid, p in self._pending.items() if p.deadline <= now]
            expired = [self._pending.pop(cid) for cid in late]
        for p in expired:
            p.future.set_exception(NetworkException("libfranka: TCP receive: Timeout"))
