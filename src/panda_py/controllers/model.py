"""The model controllers get in the control process: libfranka's :class:`Model` plus fast
per-state helpers on the compiled kinematics and the recursive dynamics.

``ee_jacobian(state)``, ``coriolis_of(state)`` and ``gravity_of(state)`` take the
end effector and the load from the state (as libfranka's ``Model`` does with a
``RobotState``) and remember the last answer, so several terms of one tick pay once.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import dynamics, kinematics
from panda_py.controllers.state import StateView
from panda_py.libfranka.model import Model
from panda_py.libfranka.state import RobotState, combine_load
from panda_py.libfranka.types import Frame

__all__ = ["ControlModel"]

FloatArray = NDArray[np.float64]

# A planned joint speed this fast gets most (76 %) of the drives' dry friction compensated
# [rad/s] (tanh: smooth through zero, so a joint at rest is never pushed).
FRICTION_SPEED = 0.01
# the state fields that make the load the dynamics see (the end effector and the payload)
LOAD_FIELDS = ("m_ee", "I_ee", "F_x_Cee", "m_load", "I_load", "F_x_Cload")


class ControlModel(Model):
    """:class:`~panda_py.libfranka.Model` with cached per-state helpers for control laws."""

    def __init__(self, robot: Any = "fer") -> None:
        super().__init__(robot)
        self._kin_key: bytes | None = None
        self._kin: Any = None
        self._jac: tuple[Any, FloatArray] | None = None
        self._cor: tuple[Any, FloatArray] | None = None
        self._grav: tuple[Any, FloatArray] | None = None
        self._mass: tuple[Any, FloatArray] | None = None
        self._driven: tuple[Any, FloatArray] | None = None
        self._arm_key: bytes | None = None
        self._arm_state: Any = None
        self._arm_cached: dynamics.LoadedArm | None = None
        self._armature = np.array(self.spec.drives.armature)
        self._rotors = np.diag(self._armature)
        self._coulomb = np.array(self.spec.drives.coulomb)
        self._viscous = np.array(self.spec.drives.viscous)
        # compile (or load) the model's kernels now, not in the loop's first tick
        dynamics.LoadedArm(self.spec).coriolis(np.zeros(7), np.zeros(7))

    def _kinematics(self, F_T_EE: FloatArray) -> Any:
        key = F_T_EE.tobytes()
        if key != self._kin_key:
            self._kin = kinematics.get_kinematics(self.spec, F_T_EE.reshape(4, 4, order="F"))
            self._kin_key = key
        return self._kin

    def ee_jacobian(self, state: StateView) -> FloatArray:
        """Zero Jacobian (6, 7) of the end effector (the state's ``F_T_EE``)."""
        cached = self._jac
        if cached is not None and cached[0] is state:
            return cached[1]
        J = self._kinematics(state.F_T_EE).zero_jacobian(state.q)
        self._jac = (state, J)
        return J

    def kernel_arrays(self, state: StateView) -> tuple[FloatArray, tuple[FloatArray, ...]]:
        """What a law compiled with its model terms takes (``_fused``): the packed chain to
        the state's end effector (``F_T_EE``) and the arm's parameters with the state's
        total load (``LoadedArm.arrays``), each prepared once per end effector and load."""
        return self._kinematics(state.F_T_EE).chain_constants, self._arm(state).arrays

    def kernel_chain(self, state: StateView) -> FloatArray:
        """The packed chain to the state's end effector alone (:meth:`kernel_arrays`' first
        part), for a compiled law that needs no dynamics."""
        return self._kinematics(state.F_T_EE).chain_constants

    def _arm(self, state: StateView) -> dynamics.LoadedArm:
        """The arm with the state's total load, prepared once per load: keyed on the raw
        end-effector and payload fields, combined (``combine_load``) only when they
        change."""
        if state is self._arm_state:  # Coriolis, gravity and the mass matrix of one tick
            return self._arm_cached  # type: ignore[return-value]
        key = state.raw_fields(LOAD_FIELDS)
        if key != self._arm_key:
            m, c, inertia = combine_load(state.m_ee, state.F_x_Cee, state.I_ee, state.m_load,
                                         state.F_x_Cload, state.I_load)  # fmt: skip
            self._arm_cached = dynamics.LoadedArm(self.spec, m_load=m, F_x_Cload=c, I_load=inertia)
            self._arm_key = key
        assert self._arm_cached is not None
        self._arm_state = state
        return self._arm_cached

    def coriolis_of(self, state: StateView) -> FloatArray:
        """Coriolis and centrifugal torques (7,) [Nm] with the state's total load."""
        cached = self._cor
        if cached is not None and cached[0] is state:
            return cached[1]
        tau = self._arm(state).coriolis(state.q, state.dq)
        self._cor = (state, tau)
        return tau

    def mass_of(self, state: StateView) -> FloatArray:
        """Joint-space mass matrix (7, 7) [kg m^2] with the state's total load."""
        cached = self._mass
        if cached is not None and cached[0] is state:
            return cached[1]
        M = self._arm(state).mass_matrix(state.q)
        self._mass = (state, M)
        return M

    def driven_mass_of(self, state: StateView) -> FloatArray:
        """The inertia the joint torques accelerate (7, 7) [kg m^2]: the links'
        (:meth:`mass_of`, libfranka's model) plus the drives' reflected rotor inertia
        (``robots.params.JointDrives``), which libfranka's model leaves out; a move's
        inertial feed-forward needs both.

        Computed once per state (a mass matrix costs about 1.5 us compiled: as little as
        a check whether an older one could be reused); read-only."""
        cached = self._driven
        if cached is not None and cached[0] is state:
            return cached[1]
        M = self._arm(state).mass_matrix(state.q)
        M += self._rotors
        M.flags.writeable = False
        self._driven = (state, M)
        return M

    @property
    def armature(self) -> FloatArray:
        """The drives' reflected rotor inertia (7,) [kg m^2], the diagonal
        :meth:`driven_mass_of` adds to the links' mass matrix."""
        return self._armature

    @property
    def viscous(self) -> FloatArray:
        """The drives' viscous friction (7,) [Nm s/rad] (``JointDrives.viscous``)."""
        return self._viscous

    @property
    def coulomb(self) -> FloatArray:
        """The drives' dry friction the moves compensate (7,) [Nm] (``friction_for``)."""
        return self._coulomb

    def friction_for(self, dq_planned: FloatArray) -> FloatArray:
        """The torque [Nm] that cancels the drives' dry friction (``JointDrives.coulomb``,
        what is left of it under torque commands on a robot) for joints moving at the
        planned ``dq_planned`` [rad/s]: a feed-forward along the plan, so an arm at rest
        (or stopping) is never pushed by it."""
        return self._coulomb * np.tanh(dq_planned * (1.0 / FRICTION_SPEED))

    def gravity_of(self, state: StateView) -> FloatArray:
        """Gravity torques (7,) [Nm] with the state's total load."""
        cached = self._grav
        if cached is not None and cached[0] is state:
            return cached[1]
        tau = self._arm(state).gravity(state.q)
        self._grav = (state, tau)
        return tau

    # --- libfranka's Model API for a RobotState, on the fast paths ----------------------

    def zero_jacobian(self, frame: Any, q: Any, F_T_EE: Any = None, EE_T_K: Any = None) -> Any:
        """As :meth:`Model.zero_jacobian`; for the end effector of a ``RobotState`` the
        compiled kinematics answer (42,) column-major, as libfranka."""
        if _is_state(q) and F_T_EE is None and EE_T_K is None and _is_ee(frame):
            return self.ee_jacobian(q).reshape(42, order="F")
        return super().zero_jacobian(frame, q, F_T_EE, EE_T_K)

    def coriolis(self, q: Any, dq: Any = None, I_total: Any = None, m_total: Any = None,
                 F_x_Ctotal: Any = None) -> Any:  # fmt: skip
        if _is_state(q) and dq is None and I_total is None:
            return self.coriolis_of(q).copy()
        return super().coriolis(q, dq, I_total, m_total, F_x_Ctotal)

    def gravity(self, q: Any, m_total: Any = None, F_x_Ctotal: Any = None,
                gravity_earth: Any = None) -> Any:  # fmt: skip
        if _is_state(q) and m_total is None and F_x_Ctotal is None and gravity_earth is None:
            return self.gravity_of(q).copy()
        if gravity_earth is None:
            return super().gravity(q, m_total, F_x_Ctotal)
        return super().gravity(q, m_total, F_x_Ctotal, gravity_earth)

    def mass(self, q: Any, I_total: Any = None, m_total: Any = None,
             F_x_Ctotal: Any = None) -> Any:  # fmt: skip
        if _is_state(q) and I_total is None:
            return self.mass_of(q).reshape(49, order="F")
        return super().mass(q, I_total, m_total, F_x_Ctotal)


def _is_state(value: Any) -> bool:
    return type(value) is RobotState


def _is_ee(frame: Any) -> bool:
    try:
        return Frame(frame) == Frame.kEndEffector
    except ValueError:
        return False
