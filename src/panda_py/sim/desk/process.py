"""The simulated Desk's own process, and its handle in the process that starts it.

The Desk (uvicorn, TLS, the page) runs in a process of its own, beside the simulator's
1 kHz loop, so that no web request ever holds the loop's GIL. The two share only the
:class:`~panda_py.sim.desk.link.DeskLink` block.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import socket
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from panda_py.sim.children import start_child, stop_child
from panda_py.sim.desk.link import DeskLink
from panda_py.sim.desk.protocol import desk_protocol

log = logging.getLogger("panda_py.sim.desk")

DEFAULT_USER = "franka"
"""The simulated Desk's documented default user name (``panda-sim --desk-user``)."""
DEFAULT_PASSWORD = "franka123"
"""The simulated Desk's documented default password (``panda-sim --desk-password``)."""
DESK_NICE = 5  # the Desk yields the CPU to the simulator's loop
STOP_GRACE = 1  # [s] a stopping Desk waits this long for open connections (whole seconds)


class DeskStartError(RuntimeError):
    """The simulated Desk could not start (e.g. its port is taken or not permitted)."""


@dataclass
class DeskConfig:
    """How to run a simulated robot's Desk. ``locked``: start as a robot after power-up
    (brakes closed, FCI inactive) instead of ready (unlocked, FCI active)."""

    port: int = 443
    user: str = DEFAULT_USER
    password: str = DEFAULT_PASSWORD
    locked: bool = False
    token_force_timeout: float = 10.0  # [s] to press the Pilot after a forced take
    cert_dir: str | None = None  # default: ~/.cache/panda_py/desk
    page: bool = True
    header_timeout: float = 10.0  # [s] a request head slower than this (to twice it): aborted
    self_test_duration: float = 1.0  # [s] the simulated safety self-test takes this long

    def __post_init__(self) -> None:
        if not 0 <= self.port < 65536:
            raise ValueError(f"desk port: expected 0..65535, got {self.port}")
        if not self.user or not self.password:
            raise ValueError("desk user and password: expected non-empty strings")
        if not self.header_timeout > 0:
            raise ValueError(f"header_timeout: expected > 0 s, got {self.header_timeout}")
        if not self.token_force_timeout > 0:
            raise ValueError(f"token_force_timeout: expected > 0 s, got {self.token_force_timeout}")
        if not 0 < self.self_test_duration <= 600:
            raise ValueError(
                f"self_test_duration: expected 0 < s <= 600, got {self.self_test_duration}"
            )


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    return sock


def desk_main(
    host: str,
    robot: str,
    config: DeskConfig,
    array: Any,
    conn: Any,
    log_level: str,
    end_effector: str = "hand",
) -> None:
    """Entry point of the Desk process: serve until told to stop (or the parent goes)."""
    logging.basicConfig(level=log_level, format="panda-sim desk %(levelname)s: %(message)s")
    try:
        os.nice(DESK_NICE)
    except OSError:
        pass
    import uvicorn

    from panda_py.robots.end_effectors import get_end_effector
    from panda_py.sim.desk.app import DeskApp
    from panda_py.sim.desk.cert import default_cert_dir, ensure_certificate, fingerprint
    from panda_py.sim.desk.duties import initial_end_effector
    from panda_py.sim.desk.state import DeskState

    state = DeskState(
        robot, {config.user: config.password}, DeskLink(array),
        token_force_timeout=config.token_force_timeout,
        self_test_duration=config.self_test_duration,
        end_effector=initial_end_effector(get_end_effector(end_effector)),
    )  # fmt: skip
    try:
        cert_dir = Path(config.cert_dir) if config.cert_dir else default_cert_dir()
        cert = ensure_certificate(cert_dir)
        sock = _bind(host, config.port)
    except Exception as exc:  # reported to the parent as the start failure
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    server = uvicorn.Server(
        uvicorn.Config(
            DeskApp(state, page=config.page),
            ssl_certfile=str(cert),  # the key follows the certificate in this file
            log_level="warning",
            access_log=False,
            lifespan="off",
            http=desk_protocol(config.header_timeout),
            ws="websockets-sansio",
            ws_max_size=64 * 1024,
            timeout_keep_alive=5,
            # a client that holds a connection (one it never closes, or a TLS close it never
            # answers) must not keep a stopping Desk alive: stop waited 10 s, then left it
            timeout_graceful_shutdown=STOP_GRACE,
            limit_concurrency=64,
        )
    )

    def control(loop: asyncio.AbstractEventLoop) -> None:
        """Requests of the parent (the Simulator), run on the event loop."""
        while True:
            try:
                op, *args = conn.recv()
            except (EOFError, OSError):
                server.should_exit = True
                return
            if op == "stop":
                server.should_exit = True
                return

            async def run(op: str = op, args: list[Any] = args) -> Any:
                return _control(state, op, *args)

            try:
                reply: Any = ("ok", asyncio.run_coroutine_threadsafe(run(), loop).result(10))
            except Exception as exc:  # reported to the caller; the Desk keeps serving
                reply = ("error", f"{type(exc).__name__}: {exc}")
            try:
                conn.send(reply)
            except (OSError, EOFError):
                server.should_exit = True
                return

    async def serve() -> None:
        threading.Thread(target=control, args=(asyncio.get_running_loop(),), daemon=True).start()
        conn.send(("ready", {"port": sock.getsockname()[1], "fingerprint": fingerprint(cert)}))
        await server.serve(sockets=[sock])

    asyncio.run(serve())


def _control(state: Any, op: str, *args: Any) -> Any:
    if op == "press":
        state.press(str(args[0]))
        return None
    if op == "inject_safety_error":
        state.inject_safety_error(str(args[0]), confirmable=bool(args[1]))
        return None
    if op == "status":
        return state.legacy_status()
    if op == "power_cycle":  # as after power-up (tests): locked, nobody in control
        state.reboot()
        state.recovery = None
        state.powered_off = False
        return None
    if op == "make_self_test_due":
        state.make_self_test_due(float(args[0]))
        return None
    if op == "set":  # the test switches DeskState names
        name, value = str(args[0]), bool(args[1])
        if name not in ("fail_next_self_test", "brakes_jammed", "fci_installed"):
            raise ValueError(f"unknown Desk switch {name!r}")
        setattr(state, name, value)
        return None
    if op == "end_effector":
        return state.end_effector_legacy()
    raise ValueError(f"unknown Desk request {op!r}")


class DeskProcess:
    """Handle on a running simulated Desk (started by :class:`~panda_py.sim.Simulator`
    or ``panda-sim``)."""

    def __init__(
        self,
        host: str,
        robot: str,
        config: DeskConfig,
        link: DeskLink,
        log_level: str = "WARNING",
        *,
        end_effector: str = "hand",
    ) -> None:
        self.host, self.robot, self.config, self.link = host, robot, config, link
        self.log_level = log_level
        self.end_effector_kind = end_effector
        self.port = config.port
        self.fingerprint = ""
        self._process: Any = None
        self._conn: Any = None
        self._lock = threading.Lock()

    @property
    def url(self) -> str:
        """The Desk's address, ``https://host`` with the port unless it is 443."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"https://{host}" + ("" if self.port == 443 else f":{self.port}")

    @property
    def hostname(self) -> str:
        """What a Desk client is given: the host, with the port unless it is 443."""
        return self.url.removeprefix("https://")

    def start(self, timeout: float = 30.0) -> DeskProcess:
        """Start the Desk's process and return this handle once it serves (its port and
        certificate fingerprint known); raises :class:`DeskStartError` if it does not within
        ``timeout`` [s]."""
        ctx = multiprocessing.get_context("spawn")
        parent, child = ctx.Pipe()
        proc = ctx.Process(
            target=desk_main,
            args=(
                self.host,
                self.robot,
                self.config,
                self.link.array,
                child,
                self.log_level,
                self.end_effector_kind,
            ),
            daemon=True,
            name="panda-sim-desk",
        )
        start_child(proc)
        child.close()
        if not parent.poll(timeout):
            proc.kill()
            raise DeskStartError(f"the simulated Desk did not start within {timeout} s")
        try:
            kind, detail = parent.recv()
        except EOFError as exc:
            proc.join(1)
            raise DeskStartError(f"the Desk process died on start (exit {proc.exitcode})") from exc
        if kind != "ready":
            proc.join(1)
            raise DeskStartError(
                f"the simulated Desk could not serve on {self.host}:{self.config.port}: {detail}"
            )
        self.port, self.fingerprint = detail["port"], detail["fingerprint"]
        self._process, self._conn = proc, parent
        return self

    def request(self, op: str, *args: Any) -> Any:
        """Run ``op`` (a name of the Desk process's control operations, with ``args``) in the
        Desk process and return its result; ``ValueError`` for an operation it refuses."""
        with self._lock:
            if self._conn is None:
                raise DeskStartError("the simulated Desk is not running")
            try:
                self._conn.send((op, *args))
                kind, value = self._conn.recv()
            except (OSError, EOFError) as exc:
                raise DeskStartError("the Desk process is gone") from exc
        if kind == "error":
            raise ValueError(value)
        return value

    def press_pilot_button(self, button: str = "circle") -> None:
        """Press and release a Pilot button: ``circle``, ``cross``, ``check``, ``left``,
        ``right``, ``down``, ``up``, or the FR3's ``top``."""
        self.request("press", button)

    def inject_safety_error(self, kind: str = "SafetyError", *, confirmable: bool = True) -> None:
        """A recoverable safety error: brakes close, FCI off, until confirmed
        (``confirmable=False``: its cause persists; confirming it is refused)."""
        self.request("inject_safety_error", kind, confirmable)

    def make_self_test_due(self, due_in: float = 0.0) -> None:
        """The safety self-test (an FR3's) falls due in ``due_in`` [s] (0: now, as if
        24 h had passed since the last one; 86400: as just after one)."""
        if not 0 <= due_in <= 86400:
            raise ValueError(f"due_in: expected 0 to 86400 s, got {due_in!r}")
        self.request("make_self_test_due", float(due_in))

    def fail_next_self_test(self, fail: bool = True) -> None:
        """The next safety self-test does not pass (the robot still demands it)."""
        self.request("set", "fail_next_self_test", fail)

    def jam_brakes(self, jammed: bool = True) -> None:
        """The brakes do not open, though the Desk answers the unlock (a fault)."""
        self.request("set", "brakes_jammed", jammed)

    def install_fci(self, installed: bool = True) -> None:
        """Whether the FCI feature is installed (without it, activating the FCI is refused)."""
        self.request("set", "fci_installed", installed)

    def end_effector(self) -> dict[str, Any]:
        """The stored end-effector configuration (the legacy document)."""
        return dict(self.request("end_effector"))

    def status(self) -> dict[str, Any]:
        """What the Desk shows: ``/admin/api/system-status`` plus the arm's pose."""
        return dict(self.request("status"))

    def power_cycle(self) -> None:
        """Brakes closed, FCI off, no control token, no sessions, no safety error (as after
        power-up; a shut-down robot is on again)."""
        self.request("power_cycle")

    def stop(self) -> None:
        """Stop the Desk's process (asked, then SIGTERM after 5 s); nothing happens if it is not
        running."""
        proc, conn = self._process, self._conn
        if proc is None:
            return
        self._process = self._conn = None
        stop_child(proc, conn, kill=False)


__all__ = ["DEFAULT_PASSWORD", "DEFAULT_USER", "DeskConfig", "DeskProcess", "DeskStartError"]
