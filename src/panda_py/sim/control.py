"""The simulator's control RPC: requests of the :class:`~panda_py.sim.Simulator` API
(state, faults, buttons, statistics) served between ticks."""

from __future__ import annotations

import logging
import selectors
import time
from typing import Any

import numpy as np

from panda_py.fci import (
    RobotMode,
)
from panda_py.sim.config import Stats
from panda_py.sim.parts import ServerState
from panda_py.sim.physics import DT

log = logging.getLogger("panda_py.sim")


class ControlRpc(ServerState):
    """Serves the Python API's requests over its pipe."""

    def attach_control(self, conn: Any) -> None:
        """A ``multiprocessing`` connection to serve control requests on between ticks."""
        self._control = conn
        self._sel.register(conn.fileno(), selectors.EVENT_READ, ("control", None))

    def _serve_control(self) -> None:
        conn = self._control
        try:
            request = conn.recv()
        except (EOFError, OSError):
            self._sel.unregister(conn.fileno())
            self._control = None
            self._running = False
            return
        try:
            reply: Any = ("ok", self.control(*request))
        except Exception as exc:  # reported to the caller; the server keeps serving
            reply = ("error", f"{type(exc).__name__}: {exc}")
        try:
            conn.send(reply)
        except (OSError, EOFError):
            self._running = False

    def control(self, op: str, *args: Any) -> Any:
        """Requests of the Python API (between ticks)."""
        core = self.core
        if op == "stop":
            self._running = False
            return None
        if op == "state":
            out: dict[str, Any] = {k: v.copy() for k, v in core.state.items()}
            mg, ctrl, mode = core.state_modes()
            out.update(
                motion_generator_mode=mg, controller_mode=ctrl, robot_mode=mode,
                errors=core.errors.copy(), reflex_reason=core.reflex_reason.copy(),
                time=self.tick_count * DT, cube_position=self._body_position("cube"),
                end_effector=self.physics.end_effector.value,
            )  # fmt: skip
            if self.gripper is not None:
                out.update(gripper_width=self.gripper.width,
                           gripper_is_grasped=self.gripper.is_grasped)  # fmt: skip
            if self.pump is not None:
                held = self.pump.held_body
                out.update(
                    vacuum=self.pump.vacuum, vacuum_sealed=self.pump.sealed,
                    vacuum_held=None if held is None else self.physics.model.body(held).name,
                )  # fmt: skip
            return out
        if op == "inject_reflex":
            core.inject_reflex(list(args[0]))
            return None
        if op == "drop_commands":
            n = int(args[0])
            if n < 0:
                raise ValueError(f"drop_commands: expected n >= 0, got {n}")
            self.drop_commands = n
            return None
        if op == "user_stop":
            core.set_user_stop(bool(args[0]))
            return None
        if op == "guiding":
            core.set_guiding(bool(args[0]))
            return None
        if op == "set_joint_positions":
            if core.robot_mode == RobotMode.MOVE:
                raise ValueError("set_joint_positions: not while a motion runs")
            q = np.asarray(args[0], dtype=float)
            if q.shape != (7,) or not np.all(np.isfinite(q)):
                raise ValueError(f"q: expected 7 finite joint positions, got {q.tolist()}")
            core.reset(q)
            self.desk_ee = 0.0  # the Desk's end-effector configuration applies again
            return None
        if op == "place_cube":
            p = np.asarray(args[0], dtype=float)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"position: expected 3 finite coordinates [m], got {args[0]!r}")
            self.physics.place_body("cube", p)
            return None
        if op == "stats":
            st = self.stats
            wall = time.monotonic() - st.started
            return {
                "ticks": st.ticks, "late_ticks": st.late_ticks, "resyncs": st.resyncs,
                "commands_received": st.commands_received, "commands_lost": st.commands_lost,
                "commands_excused": st.commands_excused,
                "bad_datagrams": st.bad_datagrams, "wall_time": wall,
                "clients_dropped": st.clients_dropped, "worst_late": st.worst_late,
                "cpu_time": time.process_time() - st.cpu_started,
                "sim_time": st.ticks * DT,
            }  # fmt: skip
        if op == "reset_stats":
            self.stats = Stats()
            return None
        raise ValueError(f"unknown control request {op!r}")

    def _body_position(self, name: str) -> list[float] | None:
        import mujoco

        bid = mujoco.mj_name2id(self.physics.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            return None
        return [float(x) for x in self.physics.data.xpos[bid]]


__all__ = ["ControlRpc"]
