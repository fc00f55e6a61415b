"""Model delivery: the URDF (GetRobotModel) and the native model library
(LoadModelLibrary) are built in a worker thread; the loop answers a request once its
build is done (kError or a refusal, with the reason logged, if it failed) and never
waits for a compiler."""

from __future__ import annotations

import logging
from concurrent.futures import Future
from typing import Any

from panda_py.fci import (
    Command,
    CommandBaseStatus,
    LoadModelLibraryStatus,
)
from panda_py.sim.connections import RobotConnection
from panda_py.sim.parts import ServerState

log = logging.getLogger("panda_py.sim")


class ModelDelivery(ServerState):
    """Builds model files off the loop and answers requests for them."""

    def _build_urdf(self) -> bytes | str:
        """The URDF of GetRobotModel, or why there is none (model thread)."""
        from panda_py.robots.urdf import robot_urdf

        try:
            return robot_urdf(self.spec).encode()
        except Exception as exc:  # reported to the client as a refusal, and logged
            return f"{type(exc).__name__}: {exc}"

    def _build_host_library(self) -> None:
        """Warm the cache with this host's model library (the compiler may take a second
        on first use)."""
        from panda_py.robots.clib import host_platform

        host = host_platform()
        if host is not None:
            self._library((int(host[0]), int(host[1])))

    def _library(self, key: tuple[int, int]) -> Future[bytes | str]:
        future = self._libraries.get(key)
        if future is None:
            future = self._libraries[key] = self._models.submit(self._build_library, *key)
        return future

    def _build_library(self, architecture: int, system: int) -> bytes | str:
        """The library bytes for a client platform, or why there are none (model thread)."""
        from panda_py.robots.clib import ModelLibraryUnavailable, model_library

        try:
            return model_library(self.spec, architecture=architecture, system=system)
        except (ModelLibraryUnavailable, ValueError, OSError) as exc:
            return str(exc)

    def _answer_models(self) -> None:
        """Answer the model requests whose build is done (kError/refused with the reason
        logged if it failed); the others keep waiting, the loop never does."""
        if not self._model_requests:
            return
        waiting = []
        for conn, command, cid, future in self._model_requests:
            if conn.closed or conn is not self.robot_conn:
                continue
            if not future.done():
                waiting.append((conn, command, cid, future))
                continue
            result = future.result()
            if command is Command.GET_ROBOT_MODEL:
                if isinstance(result, str):
                    log.error("no URDF to serve: %s", result)
                    self._reply(conn, command, cid, CommandBaseStatus.COMMAND_NOT_POSSIBLE_REJECTED)
                else:
                    self._reply(conn, command, cid, CommandBaseStatus.SUCCESS, urdf=result)
            elif isinstance(result, str):
                log.error("answering LoadModelLibrary with kError: %s", result)
                self._reply(conn, command, cid, LoadModelLibraryStatus.ERROR)
            else:
                self._reply(conn, command, cid, LoadModelLibraryStatus.SUCCESS, library=result)
        self._model_requests = waiting

    def _cmd_get_robot_model(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._model_requests.append((conn, command, cid, self._urdf))
        self._answer_models()

    def _cmd_load_model_library(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        key = (int(f["architecture"]), int(f["system"]))
        self._model_requests.append((conn, command, cid, self._library(key)))
        self._answer_models()


__all__ = ["ModelDelivery"]
