"""The simulated Franka Hand: homing, move, grasp and stop over the MuJoCo fingers.

Each command runs over many ticks and completes with a status (libfranka's gripper
commands block until then). Grasp semantics follow libfranka's ``Gripper::grasp``: close
at ``speed`` until the fingers stall, then hold with ``force``; the grasp succeeds when the
width at rest lies within ``[width - epsilon_inner, width + epsilon_outer]``, so grasping
thin air (fingers close fully) fails.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from panda_py.fci.gripper import GripperStatus
from panda_py.robots.params import FRANKA_HAND
from panda_py.sim.physics import DT, Physics

log = logging.getLogger("panda_py.sim")

# The motor's force acts on the width (the model's finger_width tendon): each finger
# pushes with it, so it is the force an object between the fingers is squeezed with.
_KP = 750.0  # [N/m] width position gain
_KD = 15.0  # [N s/m]
_STALL_SPEED = 0.002  # [m/s] below this the fingers count as stopped
_STALL_TICKS = 60  # [ticks] stopped this long (after moving) ends a grasp
_GOAL_TOLERANCE = 0.001  # [m] a move has arrived within this
_MOVE_TIMEOUT = 1.0  # [s] after its profile ended, a blocked move gives up
_MAX_FORCE = FRANKA_HAND.peak_force  # [N]
# [N/s] how fast a grasp's force builds up once the fingers are blocked (70 N in 35 ms):
# a step of the full force on fingers at rest would throw them into their stop (or the
# object) within a tick, faster than any contact could answer
_FORCE_RATE = 2000.0
_TEMPERATURE = 31  # [deg C] reported hand temperature
# the servo's constants, for the compiled tick (panda_py.sim.compiled): KP, KD, force limit
SERVO_GAINS = (_KP, _KD, _MAX_FORCE)
FORCE_RATE = _FORCE_RATE


@dataclass
class _Action:
    kind: str  # "homing", "move", "grasp"
    command_id: int
    goal: float  # [m] target width of the profile
    speed: float  # [m/s]
    force: float = 0.0  # [N] grasp force
    width: float = 0.0  # [m] grasp: expected object width
    eps_in: float = 0.0
    eps_out: float = 0.0
    start: float = 0.0  # [m] width at start
    t: float = 0.0  # [s] time since start
    stalled: int = 0


class GripperCore:
    """Hand state and the running command; the server calls :meth:`tick` every ms."""

    def __init__(self, physics: Physics) -> None:
        self.physics = physics
        self.max_width = FRANKA_HAND.max_width
        self.action: _Action | None = None
        self.hold_width = physics.gripper_width()
        self.grasp: _Action | None = None  # the grasp being held, for is_grasped
        self.force = 0.0  # [N] motor force this tick (positive opens)
        self.completed: list[tuple[int, GripperStatus]] = []

    @property
    def width(self) -> float:
        """The fingers' opening [m] as the hand measures it: its motor's position, which the
        mechanical stops keep within [0, max_width] (the physics' stops yield by < 0.1 mm
        under the peak force; that does not reach the encoder reading)."""
        return min(max(self.physics.gripper_width(), 0.0), self.max_width)

    @property
    def is_grasped(self) -> bool:
        g = self.grasp
        return g is not None and g.width - g.eps_in <= self.width <= g.width + g.eps_out

    @property
    def temperature(self) -> int:
        return _TEMPERATURE

    # -- commands ------------------------------------------------------------------------

    def _start(self, action: _Action) -> None:
        if self.action is not None:
            self.completed.append((self.action.command_id, GripperStatus.ABORTED))
        action.start = self.width
        self.action = action
        self.grasp = None

    def homing(self, command_id: int) -> None:
        self._start(_Action("homing", command_id, goal=self.max_width, speed=FRANKA_HAND.max_speed))

    def move(self, command_id: int, width: float, speed: float) -> GripperStatus | None:
        if not (math.isfinite(width) and math.isfinite(speed)) or not (
            0.0 <= width <= self.max_width and speed > 0.0
        ):
            log.warning("gripper move rejected: width %r m, speed %r m/s", width, speed)
            return GripperStatus.FAIL
        self._start(
            _Action("move", command_id, goal=width, speed=min(speed, FRANKA_HAND.max_speed))
        )
        return None

    def grasp_object(
        self,
        command_id: int,
        width: float,
        eps_in: float,
        eps_out: float,
        speed: float,
        force: float,
    ) -> GripperStatus | None:
        values = (width, eps_in, eps_out, speed, force)
        if not all(math.isfinite(v) for v in values) or not (
            0.0 <= width <= self.max_width
            and eps_in >= 0.0
            and eps_out >= 0.0
            and speed > 0.0
            and 0.0 <= force <= _MAX_FORCE
        ):
            log.warning("gripper grasp rejected: %r", values)
            return GripperStatus.FAIL
        action = _Action(
            "grasp",
            command_id,
            goal=0.0,
            speed=min(speed, FRANKA_HAND.max_speed),
            force=force,
            width=width,
            eps_in=eps_in,
            eps_out=eps_out,
        )
        self._start(action)
        return None

    def stop(self) -> GripperStatus:
        if self.action is not None:
            self.completed.append((self.action.command_id, GripperStatus.ABORTED))
            self.action = None
        self.grasp = None
        self.hold_width = self.width
        return GripperStatus.SUCCESS

    def client_lost(self) -> None:
        self.action = None
        self.completed.clear()

    # -- the tick ----------------------------------------------------------------------

    def tick(self) -> None:
        """Compute the finger force for this tick and finish actions that are done."""
        w, v = self.width, self.physics.gripper_speed()
        a = self.action
        if a is None:
            if self.grasp is not None:
                # keep squeezing, the force ramping up to the grasp's
                self.force = max(-self.grasp.force, min(0.0, self.force) - _FORCE_RATE * DT)
            else:
                self.force = self._servo(self.hold_width, 0.0, w, v, _MAX_FORCE)
            return
        a.t += DT
        direction = 1.0 if a.goal >= a.start else -1.0
        travel = abs(a.goal - a.start)
        along = min(travel, a.speed * a.t)
        target = a.start + direction * along
        target_v = direction * a.speed if along < travel else 0.0
        limit = a.force if a.kind == "grasp" else _MAX_FORCE
        self.force = self._servo(target, target_v, w, v, limit)
        moving = abs(v) >= _STALL_SPEED
        a.stalled = 0 if moving else a.stalled + 1
        if a.kind == "grasp":
            if a.stalled >= _STALL_TICKS and a.t > 0.05:
                ok = a.width - a.eps_in <= w <= a.width + a.eps_out
                self._finish(GripperStatus.SUCCESS if ok else GripperStatus.UNSUCCESSFUL)
                if ok:
                    self.grasp = a
                else:
                    self.hold_width = w
            return
        if along >= travel and abs(w - a.goal) <= _GOAL_TOLERANCE and not moving:
            if a.kind == "homing":
                self.max_width = FRANKA_HAND.max_width
            self.hold_width = a.goal
            self._finish(GripperStatus.SUCCESS)
        elif along >= travel and a.t > travel / a.speed + _MOVE_TIMEOUT:
            log.info("gripper move blocked at %.4f m (goal %.4f m)", w, a.goal)
            self.hold_width = w
            self._finish(GripperStatus.UNSUCCESSFUL)

    def _finish(self, status: GripperStatus) -> None:
        if self.action is None:
            return
        self.completed.append((self.action.command_id, status))
        self.action = None

    @staticmethod
    def _servo(target: float, target_v: float, w: float, v: float, limit: float) -> float:
        """The motor's force driving the width to ``target`` [m]."""
        f = _KP * (target - w) + _KD * (target_v - v)
        return max(-limit, min(limit, f))
