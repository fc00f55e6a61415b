"""The simulated Cobot Pump: vacuum, drop-off and stop over the MuJoCo suction cup.

The pump works as a Schmalz electric vacuum generator in control mode: it evacuates the
cup until the vacuum reaches the setpoint H1, and the vacuum only builds while the cup's
lip is sealed on a surface (flat against a face, its rim on that face). ``Vacuum``
succeeds once the vacuum lies in the control range (H1 less its hysteresis h1) within
its timeout, else it is unsuccessful and the pump keeps sucking (panda-py's example
stops it in a ``finally``). Above the part-present threshold H2 the part on the cup is
held: a MuJoCo weld between the pump and the part, activated at the pose it has then.
A weld, not an adhesion force, because it holds the part at the cup whatever the arm
does (an adhesion force's grip depends on contact friction, which MuJoCo keeps soft, so
the part would creep during the paper's moves) and costs one constraint. ``DropOff``
switches the pump off and blows the vacuum off: below H2 - h2 the weld lets go and the
part is detached. ``Stop`` aborts what runs and switches the pump off; a sealed cup then
loses its vacuum slowly, through leaks.

The thresholds' proportions follow the ECBPi's default parameters as we know them
(H1 750, h1 150, H2 550, h2 10 mbar), scaled to the requested setpoint; the time
constants are our choices (a cup and hose of a few cm^3 on a pump of some l/min):
neither is published by Franka in a form we could cite.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from panda_py.fci.vacuum import VACUUM_SETPOINT_UNIT, VacuumProfile, VacuumStatus
from panda_py.robots.end_effectors import COBOT_PUMP
from panda_py.sim.physics import DT, Physics

log = logging.getLogger("panda_py.sim")

_MAX_VACUUM = COBOT_PUMP.max_vacuum  # [mbar]
_CONTROL_HYSTERESIS = 0.2  # h1 / H1
_PART_PRESENT = 0.73  # H2 / H1
_PART_HYSTERESIS = 0.013  # h2 / H1
_TAU_EVACUATE = 0.05  # [s] a sealed cup's vacuum approaches the pump's maximum
_TAU_OPEN = 0.005  # [s] an open cup's vacuum vanishes
_TAU_BLOW_OFF = 0.01  # [s] drop-off's blow-off pulse
_TAU_LEAK = 2.0  # [s] a sealed cup with the pump off
_RELEASED = 1.0  # [mbar] below this a drop-off is done
# A seal needs the cup flat on the surface (contact normal within this of the cup's
# axis) and its rim on the face, the lip flexing by up to _LIP_FLEX past the edge.
_SEAL_ANGLE = math.radians(15.0)
_LIP_FLEX = 0.002  # [m]
_FULL_POWER = 100  # [%] actual_power while evacuating


@dataclass
class _Action:
    kind: str  # "vacuum" or "drop_off"
    command_id: int
    timeout: float  # [s]
    t: float = 0.0  # [s] since the command started


class VacuumCore:
    """Pump state and the running command; the server calls :meth:`tick` every ms."""

    def __init__(self, physics: Physics) -> None:
        self.physics = physics
        m = physics.model
        self._cup = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "cup_geom")
        self._pump = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cobot_pump")
        self._tcp = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "tcp")
        if min(self._cup, self._pump, self._tcp) < 0:
            raise ValueError("the Cobot Pump's model needs cup_geom, cobot_pump and tcp")
        # the welds the pump may hold parts with: body -> equality id
        self._welds = {
            int(m.eq_obj2id[i]): i
            for i in range(m.neq)
            if (m.equality(i).name or "").startswith("hold_") and m.eq_obj1id[i] == self._pump
        }
        self._robot_geom = physics._robot_geom
        self._cos_seal = math.cos(_SEAL_ANGLE)
        self.vacuum = 0.0  # [mbar] below ambient
        self.setpoint = 0.0  # [mbar] H1 of the last Vacuum command
        self.pump_on = False
        self.blowing = False
        self.action: _Action | None = None
        self.held: int | None = None  # the active weld
        self.part_present = False
        self.part_detached = False
        self.sealed = False
        self.completed: list[tuple[int, VacuumStatus]] = []

    # -- what the state reports -----------------------------------------------------------

    @property
    def in_control_range(self) -> bool:
        return self.pump_on and self.vacuum >= self.setpoint * (1.0 - _CONTROL_HYSTERESIS)

    @property
    def actual_power(self) -> int:
        """[%]: full while evacuating, nothing once the setpoint holds."""
        return _FULL_POWER if self.pump_on and self.vacuum < self.setpoint else 0

    @property
    def held_body(self) -> int | None:
        """The MuJoCo body the cup holds, if any."""
        if self.held is None:
            return None
        return int(self.physics.model.eq_obj2id[self.held])

    # -- commands ------------------------------------------------------------------------

    def _start(self, action: _Action) -> None:
        if self.action is not None:
            self.completed.append((self.action.command_id, VacuumStatus.ABORTED))
        self.action = action

    def vacuum_on(
        self, command_id: int, setpoint: int, timeout_ms: int, profile: int
    ) -> VacuumStatus | None:
        """Start sucking to ``setpoint`` [10 mbar]; None: the answer comes when done."""
        if setpoint <= 0 or timeout_ms < 0 or profile not in tuple(VacuumProfile):
            log.warning(
                "vacuum rejected: setpoint %r, timeout %r ms, profile %r",
                setpoint, timeout_ms, profile,
            )  # fmt: skip
            return VacuumStatus.FAIL
        # Profiles P0..P3 are the pump's stored production setups; every one is the
        # default setup here. A setpoint beyond the pump's reach is its maximum.
        self.setpoint = min(setpoint * VACUUM_SETPOINT_UNIT, _MAX_VACUUM)
        self.pump_on, self.blowing, self.part_detached = True, False, False
        self._start(_Action("vacuum", command_id, timeout_ms / 1000.0))
        return None

    def drop_off(self, command_id: int, timeout_ms: int) -> VacuumStatus | None:
        if timeout_ms < 0:
            log.warning("drop-off rejected: timeout %r ms", timeout_ms)
            return VacuumStatus.FAIL
        self.pump_on, self.blowing = False, True
        self._start(_Action("drop_off", command_id, timeout_ms / 1000.0))
        return None

    def stop(self) -> VacuumStatus:
        if self.action is not None:
            self.completed.append((self.action.command_id, VacuumStatus.ABORTED))
            self.action = None
        self.pump_on = self.blowing = False
        return VacuumStatus.SUCCESS

    def client_lost(self) -> None:
        self.action = None
        self.completed.clear()

    # -- the tick --------------------------------------------------------------------------

    def tick(self) -> None:
        """Advance the vacuum one tick, hold or release the part, finish commands."""
        part = self._seal()
        self.sealed = self.held is not None or part is not None
        v = self.vacuum
        if self.blowing:
            v -= v * DT / _TAU_BLOW_OFF
        elif not self.sealed:
            v -= v * DT / _TAU_OPEN
        elif self.pump_on:
            if v < self.setpoint:  # control mode: evacuate up to H1, then hold it
                v = min(self.setpoint, v + (_MAX_VACUUM - v) * DT / _TAU_EVACUATE)
        else:
            v -= v * DT / _TAU_LEAK
        self.vacuum = v
        h1 = self.setpoint
        if self.part_present and v < h1 * (_PART_PRESENT - _PART_HYSTERESIS):
            self.part_present = False
        elif not self.part_present and h1 > 0.0 and v >= h1 * _PART_PRESENT and self.sealed:
            self.part_present = True
        if self.part_present and self.held is None and part is not None and part >= 0:
            self._hold(part)
        elif not self.part_present and self.held is not None:
            self._release()
        self._finish_action()

    def _finish_action(self) -> None:
        a = self.action
        if a is None:
            return
        a.t += DT
        status: VacuumStatus | None = None
        if a.kind == "vacuum" and self.in_control_range:
            status = VacuumStatus.SUCCESS
        elif a.kind == "drop_off" and self.vacuum < _RELEASED and self.held is None:
            self.blowing = False
            status = VacuumStatus.SUCCESS
        elif a.t >= a.timeout:
            log.info("vacuum %s unsuccessful at %.0f mbar", a.kind, self.vacuum)
            status = VacuumStatus.UNSUCCESSFUL
        if status is not None:
            self.completed.append((a.command_id, status))
            self.action = None

    # -- the cup ---------------------------------------------------------------------------

    def _seal(self) -> int | None:
        """The body the cup is sealed on (-1 for one it cannot hold, e.g. the table's),
        or None if the cup is open."""
        m, d = self.physics.model, self.physics.data
        if d.ncon == 0:
            return None
        touching = np.flatnonzero((d.contact.geom == self._cup).any(axis=1))
        if touching.size == 0:  # most ticks: look no further
            return None
        axis = d.xmat[self._pump].reshape(3, 3)[:, 2]
        for i in touching.tolist():
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            other = g2 if g1 == self._cup else g1
            if self._robot_geom[other]:
                continue
            if abs(float(np.dot(c.frame[:3], axis))) < self._cos_seal:
                continue
            if not self._rim_on_face(other, axis):
                continue
            body = int(m.geom_bodyid[other])
            return body if body in self._welds else -1
        return None

    def _rim_on_face(self, geom: int, axis: np.ndarray) -> bool:
        """Whether the cup's rim lies on the face of a box it touches (other shapes: the
        contact's alignment decides alone)."""
        m, d = self.physics.model, self.physics.data
        if m.geom_type[geom] != mujoco.mjtGeom.mjGEOM_BOX:
            return True
        R = d.geom_xmat[geom].reshape(3, 3)
        local = R.T @ (d.site_xpos[self._tcp] - d.geom_xpos[geom])
        k = int(np.argmax(np.abs(R.T @ axis)))  # the face's normal axis
        half = m.geom_size[geom]
        reach = self.physics.model.geom_size[self._cup][0] - _LIP_FLEX
        return all(abs(local[j]) <= half[j] - reach for j in range(3) if j != k)

    def _hold(self, body: int) -> None:
        """Weld ``body`` to the pump where it is now."""
        m, d = self.physics.model, self.physics.data
        eq = self._welds[body]
        Rp = d.xmat[self._pump].reshape(3, 3)
        Rb = d.xmat[body].reshape(3, 3)
        m.eq_data[eq][3:6] = Rp.T @ (d.xpos[body] - d.xpos[self._pump])  # body in pump frame
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (Rp.T @ Rb).ravel())
        m.eq_data[eq][6:10] = quat
        d.eq_active[eq] = 1
        self.held = eq
        log.info("cobot pump holds %s at %.0f mbar", m.body(body).name, self.vacuum)

    def _release(self) -> None:
        if self.held is None:
            return
        self.physics.data.eq_active[self.held] = 0
        self.held = None
        self.part_detached = True
        log.info("cobot pump released its part")
