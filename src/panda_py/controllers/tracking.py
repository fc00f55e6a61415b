"""How a moving reference becomes joint torques: joint impedance or Cartesian impedance
around the reference, plus the inertial and friction feed-forward of its motion, so that
the arm follows the reference instead of lagging behind it.

Shared by the laws that track a reference in the control process: the planned moves
(:mod:`panda_py.controllers.moves`) and the streamed targets
(:mod:`panda_py.controllers.streaming`). Both include the Coriolis torques (compiled with
the model terms in one call where numba is installed: :mod:`._fused`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import laws
from panda_py.controllers.law import StateView
from panda_py.controllers.model import FRICTION_SPEED, ControlModel

__all__ = ["PoseImpedance", "joint_impedance_torque"]

FloatArray = NDArray[np.float64]


# [1/s] the friction feed-forward follows the reference's joint velocity plus the one that
# closes the tracking error at this rate: a millimetre behind, the drives' dry friction
# would otherwise hold the arm against the impedance's few newtons (a lag the reference's
# end leaves to the settle phase, which costs a Cartesian move a few hundred ms)
FRICTION_ERROR_RATE = 10.0
# ticks between updates of the arm's mass matrix and the damping from it (they change
# slowly with the configuration: updated every 20 ms, the arm tracks as well as with both
# every tick; the mass matrix took a quarter of a streamed target's tick on the loop's
# cold caches, 5-6 us of about 40)
DAMPING_TICKS = 20
# the smallest eigenvalue kept of the end effector's inverse inertia J M^-1 J^T [1/kg along
# a translation, 1/(kg m^2) about a rotation]: near a singularity the inertia along the
# lost direction grows without bound
MIN_INVERSE_INERTIA = 1e-2

# PoseImpedance's arrays in its one buffer: name -> (offset, size). The scalars: dt, k_n,
# the damping ratio, FRICTION_SPEED, FRICTION_ERROR_RATE, MIN_INVERSE_INERTIA, 1 to update
# the mass matrix and the damping this tick (else 0), 1 if J_prev holds the previous
# tick's Jacobian (else 0). M: the links' mass matrix as last updated. viscous: the drives'
# viscous friction fed forward along the reference (zeros: none). The compiled tracking
# (_fused) reads it at these offsets (its cache key covers this file).
LAW_LAYOUT = {"scalars": (0, 8), "K": (8, 36), "D": (44, 36), "q_n": (80, 7), "err": (87, 6),
              "J_pinv": (93, 42), "J": (135, 42), "J_prev": (177, 42), "M": (219, 49),
              "viscous": (268, 7)}  # fmt: skip
LAW_SIZE = 275
_K, _QN, _J = LAW_LAYOUT["K"][0], LAW_LAYOUT["q_n"][0], LAW_LAYOUT["J"][0]


def joint_impedance_torque(
    K: FloatArray, D: FloatArray, q_d: FloatArray, dq_d: FloatArray, ddq_d: FloatArray,
    state: StateView, model: ControlModel, friction_speed: float = FRICTION_SPEED,
    error_rate: float = FRICTION_ERROR_RATE,
) -> FloatArray:  # fmt: skip
    """``K (q_d - q) + D (dq_d - dq) + M ddq_d + friction(dq_d + error_rate (q_d - q)) +
    C(q, dq) dq`` [Nm]: joint impedance (stiffness ``K`` [Nm/rad], damping ``D`` [Nm
    s/rad]) around the reference ``q_d``, ``dq_d`` with the inertial (links and rotors)
    feed-forward of its motion, the dry friction cancelled along it and the way back to it
    (in full above ``friction_speed`` [rad/s]: ``coulomb tanh(v / friction_speed)``), and
    the Coriolis torques (compiled in one call with the model terms where numba is
    installed: ``_fused.joint_tracking_step``)."""
    fused = laws.fused()
    if fused is not None and type(model) is ControlModel:
        tau = np.empty(7)
        fused.joint_tracking_step(state.q, state.dq, *model.kernel_arrays(state)[1],
                                  model.armature, model.coulomb, K, D, q_d, dq_d, ddq_d,
                                  friction_speed, error_rate, tau)  # fmt: skip
        return tau
    e = q_d - state.q
    tau = K * e + D * (dq_d - state.dq)
    tau += model.driven_mass_of(state) @ ddq_d
    tau += model.friction_for((dq_d + error_rate * e) * (FRICTION_SPEED / friction_speed))
    return tau + model.coriolis_of(state)


def mass_damping(K: FloatArray, zeta: float, M: FloatArray, J: FloatArray) -> FloatArray:
    """The Cartesian damping (6, 6) that gives the stiffness ``K`` the damping ratio
    ``zeta`` on the end effector's inertia ``Lambda = (J M^-1 J^T)^-1`` (``M`` the driven
    mass matrix): ``D = 2 zeta S (S^-1 K S^-1)^(1/2) S``, ``S = Lambda^(1/2)``; for one
    axis ``2 zeta sqrt(K Lambda)`` (the reference of ``_kernels.mass_damping``)."""
    A = J @ np.linalg.solve(M, J.T)
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    r = np.sqrt(np.maximum(w, MIN_INVERSE_INERTIA))
    S, S_inv = (V / r) @ V.T, (V * r) @ V.T
    Kt = S_inv @ K @ S_inv
    u, U = np.linalg.eigh(0.5 * (Kt + Kt.T))
    out = S @ ((U * np.sqrt(np.maximum(u, 0.0))) @ U.T) @ S
    return zeta * (out + out.T)


class PoseImpedance:
    """Cartesian impedance around a moving pose reference, with a joint impedance toward
    ``q_nullspace`` in the task's nullspace and the inertial feed-forward of the reference's
    acceleration: ``tau = J^T (-K e - D (J dq - v_d)) + M J^+ (a_d - dJ dq)
    + N (k_n (q_n - q) - 2 sqrt(k_n) dq)`` plus the drives' dry friction along
    ``J^+ (v_d - FRICTION_ERROR_RATE e)`` and, with ``viscous_feedforward``, their viscous
    friction along the reference's joint velocities, ``b J^+ v_d`` (``ControlModel.viscous``:
    0.21 Nm s/rad a joint, which a Cartesian move's 30-40 Nm/rad of wrist stiffness
    otherwise pays for with mrad of lag at the end of its trajectory).

    The damping gives the stiffness the damping ratio ``damping_ratio`` on the arm's own
    end-effector inertia (:func:`mass_damping`, updated every DAMPING_TICKS): panda-py's
    ``2 damping_ratio sqrt(K)`` assumes a unit mass, which left the translation
    under-damped (the arm's 3-5 kg: ratio ~0.5, it overshot) and the rotation overdamped
    (the wrist's ~0.03 kg m^2: ratio ~6, it crept to its orientation for half a second).
    The feed-forward's inertia (links and rotors) is the one of that update too (the
    links' part kept as :attr:`M`): a load picked up counts within DAMPING_TICKS.

    After :meth:`torque`, ``err`` (6,) is the pose error [m, rad], ``J_prev`` the
    Jacobian of that tick (its rate is taken from the change of the Jacobian) and
    ``J_pinv`` its damped pseudo-inverse."""

    def __init__(self, impedance: FloatArray, damping_ratio: float, q_nullspace: FloatArray,
                 nullspace_stiffness: float,
                 viscous_feedforward: bool = False) -> None:  # fmt: skip
        # its arrays live in one buffer, which the compiled tracking takes whole (one
        # argument of its call where there were eight: each costs the call ~0.2 us on the
        # loop's cold caches), laid out as LAW_LAYOUT; the views other than the Jacobian's
        # are made on first use (a hand-over builds this law on cold caches, where each
        # NumPy call costs tens of microseconds)
        self.zeta = float(damping_ratio)
        self.kn = float(nullspace_stiffness)
        self.viscous_feedforward = viscous_feedforward  # (set into the buffer on the 1st tick)
        buf = self.buffer = np.zeros(LAW_SIZE)
        buf[:8] = (0.0, self.kn, self.zeta, FRICTION_SPEED, FRICTION_ERROR_RATE,
                   MIN_INVERSE_INERTIA, 0.0, 0.0)  # fmt: skip
        buf[_K : _K + 36] = np.asarray(impedance, dtype=np.float64).reshape(36)
        buf[_QN : _QN + 7] = q_nullspace
        self._scalars = buf[:8]
        self.J_prev: FloatArray | None = None
        self._damping_due = 0  # ticks until the damping is updated
        # the compiled step's Jacobian, as J_prev shows it after a tick (the kernel copies
        # it to the buffer's J_prev before it computes this tick's)
        self._J0 = buf[_J : _J + 42].reshape(6, 7)

    def _view(self, name: str) -> FloatArray:
        a, size = LAW_LAYOUT[name]
        return self.buffer[a : a + size]

    @functools.cached_property
    def K(self) -> FloatArray:
        """The stiffness (6, 6) [N/m, Nm/rad] (in the buffer)."""
        return self._view("K").reshape(6, 6)

    @functools.cached_property
    def D(self) -> FloatArray:
        """The damping (6, 6) [N s/m, Nm s/rad] (in the buffer): every path of torque() sets
        it on its first call (from the arm's inertia, _damping_due 0) before it reads it."""
        return self._view("D").reshape(6, 6)

    @functools.cached_property
    def M(self) -> FloatArray:
        """The links' mass matrix (7, 7) [kg m^2] as last updated with the damping (in the
        buffer; the rotors' inertia is added where it is used)."""
        return self._view("M").reshape(7, 7)

    @functools.cached_property
    def qn(self) -> FloatArray:
        """The nullspace's configuration (7,) [rad] (in the buffer)."""
        return self._view("q_n")

    @functools.cached_property
    def viscous(self) -> FloatArray:
        """The drives' viscous friction fed forward (7,) [Nm s/rad] (in the buffer; zeros
        without ``viscous_feedforward``)."""
        return self._view("viscous")

    @functools.cached_property
    def err(self) -> FloatArray:
        """The pose error (6,) [m, rad] of the last tick (in the buffer)."""
        return self._view("err")

    @functools.cached_property
    def J_pinv(self) -> FloatArray:
        """The damped pseudo-inverse (7, 6) of the last tick's Jacobian (in the buffer)."""
        return self._view("J_pinv").reshape(7, 6)

    @property
    def damping_due(self) -> int:
        """Ticks until the damping is updated (negative: at the next)."""
        return self._damping_due

    def compiled_ran(self, damping_due: int) -> None:
        """A compiled loop ran ticks of this law on its buffer (setting its scalars as
        :meth:`compiled_inputs` does): ``damping_due`` ticks until the next update; the
        buffer holds the last tick's Jacobian."""
        self._damping_due = damping_due
        self.J_prev = self._J0

    def compiled_inputs(self, dt: float) -> FloatArray:
        """The buffer the compiled tracking takes (:data:`LAW_LAYOUT`), its scalars set for
        a tick ``dt`` [s] after the previous one; afterwards ``J_prev`` is that tick's
        Jacobian (in the buffer)."""
        self._damping_due -= 1
        s = self._scalars
        s[0] = dt
        s[7] = 0.0 if self.J_prev is None else 1.0
        if self._damping_due < 0:
            s[6] = 1.0
            self._damping_due = DAMPING_TICKS - 1
        else:
            s[6] = 0.0
        self.J_prev = self._J0
        return self.buffer

    def torque(self, state: StateView, model: ControlModel, dt: float, p_d: FloatArray,
               quat_d: FloatArray, v_d: FloatArray, a_d: FloatArray) -> FloatArray:  # fmt: skip
        """The torques [Nm] (with the Coriolis torques) toward the reference position
        ``p_d`` [m], orientation ``quat_d`` (x, y, z, w), twist ``v_d`` [m/s, rad/s] and its
        rate ``a_d`` [m/s^2, rad/s^2], ``dt`` [s] after the previous call."""
        if self.J_prev is None and self.viscous_feedforward:  # the first tick: the drives'
            viscous = getattr(model, "viscous", None)
            if viscous is not None:
                self.viscous[:] = viscous
        fused = laws.fused()
        if fused is not None and type(model) is ControlModel:  # all of it in one call
            chain, arm = model.kernel_arrays(state)
            buf = self.compiled_inputs(dt)
            tau = np.empty(7)
            fused.pose_tracking_step(state.O_T_EE, state.q, state.dq, chain, *arm,
                                     model.armature, model.coulomb, p_d, quat_d, v_d, a_d, buf,
                                     tau)  # fmt: skip
            return tau
        self._damping_due -= 1
        q, dq = state.q, state.dq
        J = model.ee_jacobian(state)
        kn = self.kn
        kernels = laws.compiled()
        M = self.M
        if kernels is not None:  # the same terms, compiled in one call
            if self._damping_due < 0:
                M[:] = model.mass_of(state)
                kernels.mass_damping(self.K, self.zeta, M, model.armature, J,
                                     MIN_INVERSE_INERTIA, self.D)  # fmt: skip
                self._damping_due = DAMPING_TICKS - 1
            tau = np.empty(7)
            kernels.pose_tracking_torque(
                state.O_T_EE, J, J if self.J_prev is None else self.J_prev, q, dq, dt, p_d,
                quat_d, v_d, a_d, self.K, self.D, self.qn, kn, M, model.armature, model.coulomb,
                self.viscous, FRICTION_SPEED, FRICTION_ERROR_RATE, tau, self.err, self.J_pinv,
            )  # fmt: skip
        else:
            if self._damping_due < 0:
                M[:] = model.mass_of(state)
                self.D[:] = mass_damping(self.K, self.zeta, M + np.diag(model.armature), J)
                self._damping_due = DAMPING_TICKS - 1
            err = self.err
            err[:] = laws.cartesian_error(state.O_T_EE, p_d, quat_d)
            tau = J.T @ (-(self.K @ err) - self.D @ (J @ dq - v_d))
            tau += laws.nullspace_projector(J) @ (kn * (self.qn - q) - 2.0 * math.sqrt(kn) * dq)
            J_pinv = self.J_pinv
            J_pinv[:] = laws.damped_pinv(J)
            a = a_d
            if self.J_prev is not None and dt > 0.0:
                a = a - ((J - self.J_prev) @ dq) / dt
            ddq = J_pinv @ a
            tau += M @ ddq + model.armature * ddq
            tau += model.friction_for(J_pinv @ (v_d - FRICTION_ERROR_RATE * err))
            tau += self.viscous * (J_pinv @ v_d)
        self.J_prev = J
        return tau + model.coriolis_of(state)
