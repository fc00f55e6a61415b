"""panda-py's controller library: the same constructors, ``set_control`` signatures,
setters and defaults (panda-python 1.1.1), each law written once and run at 1 kHz in the
control process. Targets and gains pass panda-py's first-order input filter
(``filter_coeff``); the loop adds the joint walls, the torque-rate saturation and the
torque limits after ``step``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from panda_py import checks
from panda_py.checks import QUATERNION_NORM_TOL
from panda_py.controllers import laws
from panda_py.controllers._base import FloatArray, TorqueController
from panda_py.controllers.law import CompiledTicks, StateView, readonly
from panda_py.controllers.model import LOAD_FIELDS, ControlModel
from panda_py.libfranka.errors import ControlException
from panda_py.robots.params import START_POSE

# the squared norm's bound on set_control's fast path (|o|^2 - 1 = 2 (|o| - 1) to first order)
_NORM2_TOL = 2.0 * QUATERNION_NORM_TOL

__all__ = [
    "AppliedForce",
    "AppliedTorque",
    "CartesianImpedance",
    "Force",
    "IntegratedVelocity",
    "JointPosition",
]

# panda-python 1.1.1's defaults
JOINT_STIFFNESS = (600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0)  # [Nm/rad]
JOINT_DAMPING = (50.0, 50.0, 50.0, 20.0, 20.0, 20.0, 10.0)  # [Nm s/rad]
CARTESIAN_IMPEDANCE = np.diag([600.0, 600.0, 600.0, 30.0, 30.0, 30.0])  # [N/m], [Nm/rad]
FORCE_DAMPING = (1.0, 1.0, 1.0, 1.0, 0.33, 0.33, 0.17)  # [Nm s/rad]
ZERO7 = (0.0,) * 7
_ZERO7_LIST = list(ZERO7)
_START_LIST = list(START_POSE)
_fast = checks.fast_floats
_F64 = np.dtype(np.float64)
# CartesianImpedance's filtered inputs in one buffer, as its fused step
# (_fused.cartesian_impedance_step) takes them: K (6x6), Kd (6x6), p (3), quat (4),
# q_n (7), k_n; and the inputs whose offsets it takes, in this order
_FILTERED_SIZE = 87
_FUSED_SIGNALS = ("position", "orientation", "q_nullspace", "impedance", "filter_coeff",
                  "nullspace_stiffness")  # fmt: skip
# the inputs whose offsets AppliedForce's and Force's fused steps take, in this order
# (_fused.applied_force_step, _fused.force_step; Force's k_i follows its k_p), and the size
# of Force's buffer (its filtered inputs, where it started, its integral: _fused's _FORCE_*)
_APPLIED_SIGNALS = ("force", "damping", "filter_coeff")
_FORCE_SIGNALS = ("force", "k_p", "damping", "threshold", "filter_coeff")
_FORCE_SIZE = 30


# a compiled law's inputs that nothing guards (CompiledTicks of a law that computes nothing
# from its inputs in Python)
_NO_GUARD = np.zeros((0, 2), dtype=np.int64)
_NO_KEY = np.zeros(0)


def _sqrtm_psd(K: FloatArray) -> FloatArray:
    """Square root of a symmetric PSD matrix (the element-wise root for diagonal ones)."""
    if np.count_nonzero(K - np.diag(np.diagonal(K))) == 0:
        return np.diag(np.sqrt(np.maximum(np.diagonal(K), 0.0)))
    w, v = np.linalg.eigh(K)
    return (v * np.sqrt(np.maximum(w, 0.0))) @ v.T


class JointPosition(TorqueController):
    """Joint impedance around a desired joint position and velocity:
    ``tau = K (q_d - q) + D (dq_d - dq)``; ``q_d`` starts at the current position."""

    signals: ClassVar[dict[str, int]] = {
        "position": 7,
        "velocity": 7,
        "stiffness": 7,
        "damping": 7,
        "filter_coeff": 1,
    }

    def __init__(
        self,
        stiffness: Any = JOINT_STIFFNESS,
        damping: Any = JOINT_DAMPING,
        filter_coeff: float = 1.0,
    ) -> None:
        super().__init__()
        self._values[:] = 0.0
        self._write(
            stiffness=checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]"),
            damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"),
            filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)],
        )
        self._bind_views()

    def _bind_views(self) -> None:
        v = self._values
        self._q_t, self._dq_t, self._K_t, self._D_t = v[0:7], v[7:14], v[14:21], v[21:28]

    def set_control(self, position: Any, velocity: Any = ZERO7) -> None:
        """Desired joint position [rad] and velocity [rad/s]."""
        q = _fast("position", position, 7, "[rad]")
        dq = _ZERO7_LIST if velocity is ZERO7 else _fast("velocity", velocity, 7, "[rad/s]")
        self._send(0, q + dq)

    def set_stiffness(self, stiffness: Any) -> None:
        """Joint stiffness ``K`` (7,) [Nm/rad], each >= 0."""
        self._write(stiffness=checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]"))

    def set_damping(self, damping: Any) -> None:
        """Joint damping ``D`` (7,) [Nm s/rad], each >= 0."""
        self._write(damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"))

    def set_filter(self, filter_coeff: float) -> None:
        """The low-pass coefficient in (0, 1] by which the target, stiffness and damping move
        toward new values each tick (1: at once)."""
        self._write(filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)])

    def start(self, state: StateView, model: ControlModel) -> None:
        q = state.q
        self.initial_signals(position=q, velocity=np.zeros(7))
        self._q_d, self._dq_d = q.copy(), np.zeros(7)
        self._K, self._D = self._K_t.copy(), self._D_t.copy()

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_laws.joint_position_ticks``."""
        L = self._sig_layout
        at = np.array([L[n][0] for n in ("position", "velocity", "stiffness", "damping",
                                         "filter_coeff")])  # fmt: skip
        arrays = (self._values, _NO_GUARD, _NO_KEY, at, self._q_d, self._dq_d, self._K, self._D)
        return CompiledTicks("joint_position_ticks", arrays, (), np.array([self.t, self.dt]))

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        a = self._scalar("filter_coeff")
        laws.ema(self._q_d, self._q_t, a)
        laws.ema(self._dq_d, self._dq_t, a)
        laws.ema(self._K, self._K_t, a)
        laws.ema(self._D, self._D_t, a)
        return self._K * (self._q_d - state.q) + self._D * (self._dq_d - state.dq)


class IntegratedVelocity(TorqueController):
    """Joint impedance around a position integrated from the desired joint velocity
    (``q_d += dt dq_d``, kept within the joint limits): ``tau = K (q_d - q) - D dq``."""

    signals: ClassVar[dict[str, int]] = {"velocity": 7, "stiffness": 7, "damping": 7}
    outputs: ClassVar[dict[str, int]] = {"q_d": 7}

    def __init__(self, stiffness: Any = JOINT_STIFFNESS, damping: Any = JOINT_DAMPING) -> None:
        super().__init__()
        self._write(
            stiffness=checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]"),
            damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"),
        )
        self._bind_views()

    def _bind_views(self) -> None:
        v = self._values
        self._dq_t, self._K, self._D = v[0:7], v[7:14], v[14:21]

    def set_control(self, velocity: Any) -> None:
        """Desired joint velocity [rad/s]."""
        self._send(0, _fast("velocity", velocity, 7, "[rad/s]"))

    def set_stiffness(self, stiffness: Any) -> None:
        """Joint stiffness ``K`` (7,) [Nm/rad], each >= 0."""
        self._write(stiffness=checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]"))

    def set_damping(self, damping: Any) -> None:
        """Joint damping ``D`` (7,) [Nm s/rad], each >= 0."""
        self._write(damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"))

    def get_qd(self) -> FloatArray:
        """The integrated desired joint position [rad]."""
        return self.get_output("q_d")

    def start(self, state: StateView, model: ControlModel) -> None:
        self.initial_signals(velocity=np.zeros(7))
        self._q_d = state.q.copy()
        self._lower = np.array(model.spec.joints.q_min) if hasattr(model, "spec") else None
        self._upper = np.array(model.spec.joints.q_max) if hasattr(model, "spec") else None
        self.set_output("q_d", self._q_d)

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_laws.integrated_velocity_ticks``."""
        if self._lower is None:
            return None
        L = self._sig_layout
        at = np.array([L["velocity"][0], L["stiffness"][0], L["damping"][0],
                       self._out_layout["q_d"][0]])  # fmt: skip
        arrays = (self._values, _NO_GUARD, _NO_KEY, at, self._q_d, self._lower, self._upper)
        return CompiledTicks("integrated_velocity_ticks", arrays, (),
                             np.array([self.t, self.dt]))  # fmt: skip

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        self._q_d += self.dt * self._dq_t
        if self._lower is not None:
            np.clip(self._q_d, self._lower, self._upper, out=self._q_d)
        self.set_output("q_d", self._q_d)
        return self._K * (self._q_d - state.q) - self._D * state.dq


class _Applied(TorqueController):
    """What AppliedTorque and AppliedForce share: one filtered input (its name and size
    are the first signal) plus filtered joint damping: ``tau = map(input) - D dq``."""

    _input: ClassVar[tuple[str, int, str]]  # name, size, unit of the applied input

    def __init__(self, damping: Any = ZERO7, filter_coeff: float = 1.0) -> None:
        super().__init__()
        self._write(
            damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"),
            filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)],
        )
        self._bind_views()

    def _bind_views(self) -> None:
        n = self._input[1]
        v = self._values
        self._in_t, self._D_t = v[0:n], v[n : n + 7]

    def _set_input(self, value: Any) -> None:
        name, n, unit = self._input
        self._send(0, _fast(name, value, n, unit))

    def set_damping(self, damping: Any) -> None:
        """Joint damping ``D`` (7,) [Nm s/rad], each >= 0."""
        self._write(damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"))

    def set_filter(self, filter_coeff: float) -> None:
        """The low-pass coefficient in (0, 1] by which the input and the damping move toward new
        values each tick (1: at once)."""
        self._write(filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)])

    def start(self, state: StateView, model: ControlModel) -> None:
        name, n, _ = self._input
        self.initial_signals(**{name: np.zeros(n)})
        self._in, self._D = np.zeros(n), self._D_t.copy()

    def _filtered(self) -> FloatArray:
        a = self._scalar("filter_coeff")
        laws.ema(self._in, self._in_t, a)
        laws.ema(self._D, self._D_t, a)
        return self._in


class AppliedTorque(_Applied):
    """Applies the given joint torques plus joint damping: ``tau = tau_d - D dq``."""

    signals: ClassVar[dict[str, int]] = {"torque": 7, "damping": 7, "filter_coeff": 1}
    _input = ("torque", 7, "[Nm]")

    def set_control(self, torque: Any) -> None:
        """Joint torques to apply [Nm] (on top of the robot's gravity compensation)."""
        self._set_input(torque)

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_laws.applied_torque_ticks``."""
        L = self._sig_layout
        at = np.array([L["torque"][0], L["damping"][0], L["filter_coeff"][0]])
        arrays = (self._values, _NO_GUARD, _NO_KEY, at, self._in, self._D)
        return CompiledTicks("applied_torque_ticks", arrays, (), np.array([self.t, self.dt]))

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        return self._filtered() - self._D * state.dq


class AppliedForce(_Applied):
    """Applies a wrench at the end effector (base frame) plus joint damping:
    ``tau = J^T f - D dq``."""

    signals: ClassVar[dict[str, int]] = {"force": 6, "damping": 7, "filter_coeff": 1}
    _input = ("force", 6, "[N, Nm]")

    def set_control(self, force: Any) -> None:
        """Wrench at the end effector in the base frame [N, Nm]."""
        self._set_input(force)

    def start(self, state: StateView, model: ControlModel) -> None:
        super().start(state, model)
        layout = self._sig_layout
        self._at = np.array([layout[name][0] for name in _APPLIED_SIGNALS], dtype=np.int64)
        self._J = np.empty((1, 6, 7))

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_wrench.applied_force_ticks``: the fused step on its own
        buffers (the Jacobian's chain made for the state's end effector)."""
        if laws.fused() is None or type(model) is not ControlModel:
            return None
        arrays = (self._values, _NO_GUARD, _NO_KEY, readonly(self._values), readonly(self._at),
                  self._in, self._D, model.kernel_chain(state), self._J)  # fmt: skip
        return CompiledTicks("applied_force_ticks", arrays, ("F_T_EE",),
                             np.array([self.t, self.dt]))  # fmt: skip

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        fused = laws.fused()
        if fused is not None and type(model) is ControlModel:  # all of it in one call
            tau = np.empty(7)
            fused.applied_force_step(self._values, self._at, self._in, self._D, state.q,
                                     state.dq, model.kernel_chain(state), self._J,
                                     tau)  # fmt: skip
            return tau
        return model.ee_jacobian(state).T @ self._filtered() - self._D * state.dq


class Force(TorqueController):
    """Force control at the end effector: feed-forward plus PI on the joint torques of the
    desired force (base frame, [N]) against the measured external torques. Aborts when
    the end effector moves more than ``threshold`` [m] from where it started."""

    signals: ClassVar[dict[str, int]] = {
        "force": 3,
        "k_p": 1,
        "k_i": 1,
        "damping": 7,
        "threshold": 1,
        "filter_coeff": 1,
    }

    def __init__(
        self,
        k_p: float = 1.0,
        k_i: float = 2.0,
        damping: Any = FORCE_DAMPING,
        threshold: float = 0.01,
        filter_coeff: float = 0.001,
    ) -> None:
        super().__init__()
        self._write(
            k_p=[checks.nonnegative_scalar("k_p", k_p)],
            k_i=[checks.nonnegative_scalar("k_i", k_i)],
            damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"),
            threshold=[checks.nonnegative_scalar("threshold", threshold, "[m]")],
            filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)],
        )
        self._bind_views()

    def _bind_views(self) -> None:
        v = self._values
        self._f_t, self._gains_t, self._D_t = v[0:3], v[3:5], v[5:12]

    @property
    def name(self) -> str:
        return "Force Controller"

    def set_control(self, force: Any) -> None:
        """Desired force at the end effector in the base frame [N]."""
        self._send(0, _fast("force", force, 3, "[N]"))

    def set_proportional_gain(self, k_p: float) -> None:
        """The proportional gain ``k_p`` [-] on the joint torque error, >= 0."""
        self._write(k_p=[checks.nonnegative_scalar("k_p", k_p)])

    def set_integral_gain(self, k_i: float) -> None:
        """The integral gain ``k_i`` [1/s] on the joint torque error, >= 0."""
        self._write(k_i=[checks.nonnegative_scalar("k_i", k_i)])

    def set_threshold(self, threshold: float) -> None:
        """How far [m] the end effector may move from where the controller started before it
        aborts, >= 0."""
        self._write(threshold=[checks.nonnegative_scalar("threshold", threshold, "[m]")])

    def set_damping(self, damping: Any) -> None:
        """Joint damping ``D`` (7,) [Nm s/rad], each >= 0."""
        self._write(damping=checks.nonnegative("damping", damping, 7, "[Nm s/rad]"))

    def set_filter(self, filter_coeff: float) -> None:
        """The low-pass coefficient in (0, 1] by which the force, gains, damping and threshold
        move toward new values each tick (1: at once)."""
        self._write(filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)])

    def start(self, state: StateView, model: ControlModel) -> None:
        self.initial_signals(force=np.zeros(3))
        # the filtered inputs, where it started and its integral in one buffer (views by
        # name), as its fused step takes them
        law = self._law = np.zeros(_FORCE_SIZE)
        self._f, self._gains, self._D, self._threshold = law[0:3], law[3:5], law[5:12], law[12:13]
        self._p0, self._tau_ext0, self._integral = law[13:16], law[16:23], law[23:30]
        self._gains[:] = self._gains_t
        self._D[:] = self._D_t
        self._threshold[0] = self._scalar("threshold")
        self._p0[:] = state.O_T_EE[12:15]
        self._tau_ext0[:] = state.tau_J - model.gravity_of(state)  # bias of the torque sensors
        layout = self._sig_layout
        self._at = np.array([layout[name][0] for name in _FORCE_SIGNALS], dtype=np.int64)
        self._J = np.empty((1, 6, 7))
        self._tau_J = np.zeros(7)  # (the compiled ticks decode the measured torques into it)

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_wrench.force_ticks``: the fused step on its own buffers;
        the tick whose state passes the threshold is Python's (its step raises)."""
        if laws.fused() is None or type(model) is not ControlModel:
            return None
        chain, arm = model.kernel_arrays(state)
        arrays = (
            self._values, _NO_GUARD, _NO_KEY, readonly(self._values), readonly(self._at),
            self._law, self._tau_J, readonly(self._tau_J), chain, *arm, self._J,
        )  # fmt: skip
        return CompiledTicks("force_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def _exceeded(self, moved: float) -> ControlException:
        return ControlException(
            f"{self.name}: distance threshold exceeded ({moved:.4f} m > "
            f"{float(self._threshold[0]):.4f} m)"
        )

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        fused = laws.fused()
        if fused is not None and type(model) is ControlModel:  # all of it in one call
            chain, arm = model.kernel_arrays(state)
            tau = np.empty(7)
            moved = fused.force_step(self._values, self._at, self._law, self.t, self.dt,
                                     state.O_T_EE, state.q, state.dq, state.tau_J, chain, *arm,
                                     self._J, tau)  # fmt: skip
            if moved >= 0.0:
                raise self._exceeded(moved)
            return tau
        a = self._scalar("filter_coeff")
        laws.ema(self._f, self._f_t, a)
        laws.ema(self._gains, self._gains_t, a)
        laws.ema(self._D, self._D_t, a)
        self._threshold += a * (self._scalar("threshold") - self._threshold)
        moved = float(np.linalg.norm(state.O_T_EE[12:15] - self._p0))
        if self.t > 0.0 and moved > self._threshold[0]:
            raise self._exceeded(moved)
        J = model.ee_jacobian(state)
        tau_ext = state.tau_J - model.gravity_of(state) - self._tau_ext0
        tau_d = J[:3].T @ self._f
        self._integral += self.dt * (tau_d - tau_ext)
        k_p, k_i = self._gains
        return tau_d + k_p * (tau_d - tau_ext) + k_i * self._integral - self._D * state.dq


class CartesianImpedance(TorqueController):
    """Cartesian impedance around a desired end-effector pose (base frame), with a joint
    impedance toward ``q_nullspace`` in the nullspace of the task:
    ``tau = J^T (-K e - D J dq) + N (k_n (q_n - q) - 2 sqrt(k_n) dq) + coriolis``,
    ``D = 2 damping_ratio sqrt(K)``."""

    _Kd_key: tuple[FloatArray, float] | None = None

    signals: ClassVar[dict[str, int]] = {
        "position": 3,
        "orientation": 4,
        "q_nullspace": 7,
        "impedance": 36,
        "damping_ratio": 1,
        "nullspace_stiffness": 1,
        "filter_coeff": 1,
    }

    def __init__(
        self,
        impedance: Any = CARTESIAN_IMPEDANCE,
        damping_ratio: float = 1.0,
        nullspace_stiffness: float = 0.5,
        filter_coeff: float = 1.0,
    ) -> None:
        super().__init__()
        self._write(
            orientation=[0.0, 0.0, 0.0, 1.0],  # x, y, z, w
            impedance=checks.matrix6("impedance", impedance, "[N/m, Nm/rad]"),
            damping_ratio=[checks.nonnegative_scalar("damping_ratio", damping_ratio)],
            nullspace_stiffness=[
                checks.nonnegative_scalar("nullspace_stiffness", nullspace_stiffness)
            ],
            filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)],
        )
        self._bind_views()

    def _bind_views(self) -> None:
        v = self._values
        self._p_t, self._quat_t, self._qn_t = v[0:3], v[3:7], v[7:14]
        self._K_t = v[14:50].reshape(6, 6)

    def set_control(self, position: Any, orientation: Any, q_nullspace: Any = START_POSE) -> None:
        """Desired end-effector position [m] and orientation (quaternion x, y, z, w) in the
        base frame, and the joint positions the nullspace term pulls toward [rad]."""
        # the common case inline (float64 arrays, finite, a unit quaternion), else the
        # checks that name what is wrong
        if (
            type(position) is np.ndarray
            and type(orientation) is np.ndarray
            and position.dtype is _F64
            and orientation.dtype is _F64
            and position.shape == (3,)
            and orientation.shape == (4,)
        ):
            p = position.tolist()
            o = orientation.tolist()
        else:
            p = _fast("position", position, 3, "[m]")
            o = _fast("orientation", orientation, 4, "(quaternion x, y, z, w)")
        x, y, z, w = o
        nn = x * x + y * y + z * z + w * w
        s = p[0] + p[1] + p[2] + nn
        # |o|^2 - 1 ~ 2 (|o| - 1): within the tolerance, and finite, or the full check
        if not (abs(nn - 1.0) <= _NORM2_TOL and s - s == 0.0):
            p = _fast("position", position, 3, "[m]")
            o = checks.quaternion("orientation", orientation)  # raises, naming the norm
        if q_nullspace is START_POSE:
            n = _START_LIST
        else:
            n = _fast("q_nullspace", q_nullspace, 7, "[rad]")
        self._send(0, p + o + n)

    def set_impedance(self, impedance: Any) -> None:
        """The Cartesian stiffness ``K``, a 6x6 matrix [N/m, Nm/rad] (translation, then
        rotation)."""
        self._write(impedance=checks.matrix6("impedance", impedance, "[N/m, Nm/rad]"))

    def set_damping_ratio(self, damping: float) -> None:
        """The damping ratio [-] of ``D = 2 damping_ratio sqrt(K)``, >= 0."""
        self._write(damping_ratio=[checks.nonnegative_scalar("damping", damping)])

    def set_nullspace_stiffness(self, nullspace_stiffness: float) -> None:
        """The stiffness ``k_n`` [Nm/rad] of the joint impedance toward ``q_nullspace`` in the
        task's nullspace, >= 0."""
        value = checks.nonnegative_scalar("nullspace_stiffness", nullspace_stiffness)
        self._write(nullspace_stiffness=[value])

    def set_filter(self, filter_coeff: float) -> None:
        """The low-pass coefficient in (0, 1] by which the target, the impedance and the
        nullspace stiffness move toward new values each tick (1: at once)."""
        self._write(filter_coeff=[checks.unit_interval("filter_coeff", filter_coeff)])

    def _damping_target(self) -> FloatArray:
        K, ratio = self._K_t, self._scalar("damping_ratio")
        if self._Kd_key is None or not (
            np.array_equal(K, self._Kd_key[0]) and ratio == self._Kd_key[1]
        ):
            # C-ordered: the fused step is compiled for that layout
            self._Kd_target = np.ascontiguousarray(2.0 * ratio * _sqrtm_psd(K))
            self._Kd_key = (K.copy(), ratio)
        return self._Kd_target

    def start(self, state: StateView, model: ControlModel) -> None:
        T = state.O_T_EE
        self.initial_signals(
            position=T[12:15], orientation=laws.quat_from_matrix(T), q_nullspace=state.q
        )
        # the filtered inputs, in one buffer (views by name) as the fused step takes them
        f = self._filtered = np.empty(_FILTERED_SIZE)
        self._K, self._Kd = f[0:36].reshape(6, 6), f[36:72].reshape(6, 6)
        self._p, self._quat, self._qn = f[72:75], f[75:79], f[79:86]
        self._p[:], self._quat[:], self._qn[:] = self._p_t, self._quat_t, self._qn_t
        self._Kd_key = None
        self._K[:] = self._K_t
        self._Kd[:] = self._damping_target()
        f[86] = self._scalar("nullspace_stiffness")
        layout = self._sig_layout
        self._at = np.array([layout[name][0] for name in _FUSED_SIGNALS], dtype=np.int64)
        self._J = np.empty((1, 6, 7))

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Its ticks in ``rt._tick_laws.cartesian_impedance_ticks``: the fused step (where numba
        runs it) on its own buffers, the impedance and the damping ratio guarded (the
        damping target is computed here)."""
        if laws.fused() is None or type(model) is not ControlModel or self._Kd_key is None:
            return None
        chain, arm = model.kernel_arrays(state)
        K, ratio = self._Kd_key
        layout = self._sig_layout
        guard = np.array([[layout["impedance"][0], 36], [layout["damping_ratio"][0], 1]])
        key = np.concatenate((K.reshape(36), [ratio]))
        arrays = (
            self._values, guard, key, readonly(self._values), readonly(self._at),
            self._filtered, readonly(self._Kd_target), chain, *arm, self._J,
        )  # fmt: skip
        return CompiledTicks("cartesian_impedance_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        # the damping's target depends on the inputs only: redone when they changed
        Kd_t = self._damping_target() if self.inputs_changed else self._Kd_target
        fused = laws.fused()
        if fused is not None and type(model) is ControlModel:  # all of it in one call
            chain, arm = model.kernel_arrays(state)
            tau = np.empty(7)
            fused.cartesian_impedance_step(self._values, self._at, self._filtered, Kd_t,
                                           state.O_T_EE, state.q, state.dq, chain, *arm,
                                           self._J, tau)  # fmt: skip
            return tau
        a = self._scalar("filter_coeff")
        kernels = laws.compiled()
        if kernels is not None:  # the same filter, compiled, in place
            kernels.pose_filter(a, self._K, self._K_t, self._Kd, Kd_t, self._p, self._p_t,
                                self._qn, self._qn_t, self._quat, self._quat_t)  # fmt: skip
        else:
            laws.ema(self._K, self._K_t, a)
            laws.ema(self._Kd, Kd_t, a)
            laws.ema(self._p, self._p_t, a)
            laws.ema(self._qn, self._qn_t, a)
            self._quat[:] = laws.slerp(self._quat, self._quat_t, a)
        f = self._filtered
        f[86] += a * (self._scalar("nullspace_stiffness") - f[86])
        kn = float(f[86])
        q, dq = state.q, state.dq
        J = model.ee_jacobian(state)
        if kernels is not None:  # the same law, compiled
            tau = np.empty(7)
            kernels.cartesian_impedance_torque(
                state.O_T_EE, J, q, dq, self._p, self._quat, self._K, self._Kd, self._qn, kn, tau
            )
            return tau + model.coriolis_of(state)
        err = laws.cartesian_error(state.O_T_EE, self._p, self._quat)
        tau = J.T @ (-(self._K @ err) - self._Kd @ (J @ dq))
        tau += laws.nullspace_projector(J) @ (kn * (self._qn - q) - 2.0 * math.sqrt(kn) * dq)
        return tau + model.coriolis_of(state)
