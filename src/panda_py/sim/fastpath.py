"""The compiled per-tick path of one simulated robot: its state fill, its command checks,
its commanded joint signal and its joint controller on numba kernels (:mod:`._tick_jit`),
on buffers allocated once.

Used where the kinematics run compiled (numba installed, ``PANDA_PY_NO_JIT`` unset;
``panda_py.kinematics``' choice, so the two never disagree); otherwise, and for the rare
cases the kernels leave out (a NE_T_EE other than the identity, non-finite joints), the
robot runs its NumPy reference, which the kernels equal value for value.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from panda_py import fci, jit, kinematics
from panda_py.fci import MotionGeneratorMode
from panda_py.robots.params import GRAVITY, RobotSpec
from panda_py.sim.command import command_on
from panda_py.sim.physics import DT, FRICTION_SPEED, OMEGA, Physics
from panda_py.sim.safety import CartesianSignal, JointSignal


class FilledState(Protocol):
    """What the compiled path reads and writes of the robot's state assembly
    (:class:`panda_py.sim.state.FilledState`, which holds a :class:`TickKernels`): a
    protocol, so that this module need not import the one that uses it."""

    spec: RobotSpec
    physics: Physics
    mg_mode: MotionGeneratorMode
    joint: JointSignal
    cart: CartesianSignal
    state_buffer: np.ndarray
    state_offsets: dict[str, tuple[int, int]]
    tau_J_d: np.ndarray
    q_hold: np.ndarray
    elbow_c: np.ndarray
    delbow_c: np.ndarray
    ddelbow_c: np.ndarray
    _kin: Any
    _NE_identity: bool
    _filled_mode: MotionGeneratorMode | None
    _T_view: dict[str, np.ndarray]

    def _fill_contacts(self, O_T_EE: np.ndarray) -> None: ...


class TickKernels:
    """The compiled kernels bound to one robot's state buffer and model."""

    def __init__(self, kin: Any, kernels: Any, core: FilledState) -> None:
        self._k = self.kernels = kernels
        self._fk_one = kin.single("fk_one")
        self._chain = core._kin.chain_constants  # the nominal EE's chain, as core._kin.fk uses
        self._fk = np.zeros((2, 4, 4))
        self._off = np.array([core.state_offsets[n][0] for n in kernels.FIELDS], dtype=np.int64)
        ph = core.physics
        links = ph._links_1_6
        if isinstance(links, slice):
            links = np.arange(links.start, links.stop)
        self._links = np.asarray(links, dtype=np.int64)
        self._const = np.array([core.spec.elbow_flip_q, 1.0 / DT, -GRAVITY[2]])
        cart = (MotionGeneratorMode.CARTESIAN_POSITION, MotionGeneratorMode.CARTESIAN_VELOCITY)
        joint = (MotionGeneratorMode.JOINT_POSITION, MotionGeneratorMode.JOINT_VELOCITY)
        self._flags = {
            mg: (kernels.MOVING_CARTESIAN if mg in cart else 0)
            | (kernels.MOVING_JOINT if mg in joint else 0)
            for mg in MotionGeneratorMode
        }
        self._cartesian = frozenset(cart)
        self._tau = np.zeros(7)
        self._warm(ph)

    def _warm(self, ph: Physics) -> None:
        """Compile (or load from the cache) the checks for the views they get in the loop
        (each dialect's command buffer, read-only and possibly unaligned) and the joint
        controller for the arrays it gets, now, not at a motion's first command."""
        k = self._k
        z = np.zeros(7)
        signal = [np.zeros(7) for _ in range(4)]
        seen = set()
        for version in fci.SUPPORTED_VERSIONS:
            d = fci.dialect(version)
            c = command_on(d, bytearray(d.command_size))
            for x in (c.tau_J_d, c.q_c, c.dq_c):
                kind = (x.flags.aligned, x.flags.c_contiguous)
                if kind not in seen:
                    seen.add(kind)
                    k.torque_in_limits(x, z, z, z)
                    k.all_finite(x)
                    k.joint_push(*signal, x, k.PUSH_POSITION, DT)
        k.measured_in_limits(z, z, z, z, z)
        k.all_finite(z)
        k.joint_push(*signal, z, k.PUSH_POSITION, DT)  # (the robot's own IK, generator)
        k.joint_limit_bits(*signal, np.zeros(35), z)
        self.joint_tracking(ph, z, z, z, np.ones(7), np.ones(7))

    def fill_constants(self) -> tuple[np.ndarray, np.ndarray]:
        """The fill kernel's bodies of links 1..6 and its constants."""
        return self._links, self._const

    def fill(self, core: FilledState) -> bool:
        """The per-tick state fields; False (nothing written) where the reference must
        do it: a NE_T_EE other than the identity, joints that are not finite."""
        if not core._NE_identity:
            return False
        ph, fk = core.physics, self._fk
        q = ph._qpos_arm
        if not self._fk_one(q, self._chain, fk[0]):
            return False
        mg = core.mg_mode
        joint = core.joint
        if mg not in self._cartesian and not self._fk_one(joint.q, self._chain, fk[1]):
            return False
        flags = self._flags[mg]
        if core._filled_mode != mg:
            flags |= self._k.MODE_CHANGED
            core._filled_mode = mg
        cart = core.cart
        self._k.fill_state(
            core.state_buffer, self._off, q, ph._qvel_arm, ph.tau_applied, ph._gravcomp_arm,
            ph.dq_before, ph.drive_terms, ph.constraint_arm, core.tau_J_d, joint.q, joint.dq,
            joint.ddq, core.q_hold, cart.T, cart.v, cart.a, core.elbow_c, core.delbow_c,
            core.ddelbow_c, fk, ph._xmat, self._links, self._const, flags,
        )  # fmt: skip
        core._fill_contacts(core._T_view["O_T_EE"])
        return True

    def joint_tracking(
        self,
        ph: Physics,
        q_d: np.ndarray,
        dq_d: np.ndarray,
        ddq_d: np.ndarray,
        K_theta: np.ndarray,
        K_default: np.ndarray,
    ) -> np.ndarray:
        """:meth:`Physics.joint_tracking_torque` at the stiffness scale of ``K_theta``
        against ``K_default``, into a buffer the next call reuses."""
        self._k.joint_tracking(
            ph.mass_matrix(), ph._bias_arm, ph._gravcomp_arm, ph._qpos_arm, ph._qvel_arm, q_d,
            dq_d, ddq_d, K_theta, K_default, ph._coulomb, OMEGA, 1.0 / FRICTION_SPEED,
            self._tau,
        )  # fmt: skip
        return self._tau

    def torque_in_limits(
        self, tau: np.ndarray, tau_J_d: np.ndarray, tau_max: np.ndarray, dtau_step: np.ndarray
    ) -> bool:
        return bool(self._k.torque_in_limits(tau, tau_J_d, tau_max, dtau_step))

    def all_finite(self, x: np.ndarray) -> bool:
        return bool(self._k.all_finite(x))

    def measured_in_limits(
        self, q: np.ndarray, dq: np.ndarray, lo: np.ndarray, hi: np.ndarray, dq_hi: np.ndarray
    ) -> bool:
        return bool(self._k.measured_in_limits(q, dq, lo, hi, dq_hi))


def load(core: FilledState) -> TickKernels | None:
    """The compiled path for ``core``, or None where the kinematics run plain Python."""
    tick = jit.optional("panda_py.sim._tick_jit", requires=kinematics.compiled_kernels)
    if tick is None:
        return None
    return TickKernels(kinematics.compiled_kernels(), tick, core)


__all__ = ["TickKernels", "load"]
