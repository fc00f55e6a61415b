"""The robot's state as a client sees it: one float64 buffer in the wire's field order
(named views per field), filled each tick from physics and the robot's internals
(measured, desired and commanded values, contacts, accelerometers) and by the setters
(end effector, load). A part of :class:`~panda_py.sim.robot.RobotCore`."""

from __future__ import annotations

from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import ControllerMode, MotionGeneratorMode, RobotMode
from panda_py.robots.params import GRAVITY, RobotSpec
from panda_py.sim import fastpath
from panda_py.sim.fastpath import TickKernels
from panda_py.sim.physics import DT, Physics
from panda_py.sim.safety import CartesianSignal, JointSignal
from panda_py.sim.settings import CollisionThresholds

# The robot's external torque estimate is its model's residual, low-pass filtered
# (libfranka's robot_state.h: tau_ext_hat_filtered is "the error between tau_J and the
# expected torques given by the robot model", "low-pass filtered"). The filter of a
# generalised-momentum observer, the estimator of joint-torque-sensing arms (S. Haddadin,
# A. De Luca, A. Albu-Schaeffer, "Robot Collisions: A Survey on Detection, Isolation, and
# Identification", IEEE T-RO 33(6), 2017), is first order, r = K_O / (s + K_O) tau_ext.
# Franka publishes neither its estimator nor its gain: K_O is a judgement (a 16 Hz
# corner, 10 ms time constant), discretised as the observer's rectangle rule.
OBSERVER_GAIN = 100.0  # [1/s] K_O
_EXT_FILTER = OBSERVER_GAIN * DT  # the observer's step per tick
_NO_TORQUE = np.zeros(7)  # tau_ext of no contact (read only)
_NO_TORQUE.flags.writeable = False

_JOINT_GENERATORS = (MotionGeneratorMode.JOINT_POSITION, MotionGeneratorMode.JOINT_VELOCITY)
_CARTESIAN_GENERATORS = (
    MotionGeneratorMode.CARTESIAN_POSITION,
    MotionGeneratorMode.CARTESIAN_VELOCITY,
)


# The state's float fields in the order every wire layout has them (v5+; older layouts
# lack some): name -> number of float64 values.
_STATE_SIZES = fci.state_float_fields()
# Fields that hold contact estimates (zero without contact).
CONTACT_FIELDS = (
    "joint_contact", "joint_collision", "tau_ext_hat_filtered", "cartesian_contact",
    "cartesian_collision", "O_F_ext_hat_K", "K_F_ext_hat_K",
)  # fmt: skip


class StateAssembly:
    """Builds and fills the state; the attributes it reads belong to ``RobotCore``."""

    spec: RobotSpec
    physics: Physics
    robot_mode: RobotMode
    mg_mode: MotionGeneratorMode
    ctrl_mode: ControllerMode
    thresholds: CollisionThresholds
    joint: JointSignal
    cart: CartesianSignal
    elbow_c: np.ndarray
    delbow_c: np.ndarray
    ddelbow_c: np.ndarray
    tau_J_d: np.ndarray
    tau_ext: np.ndarray
    contact_active: bool
    q_hold: np.ndarray
    F_T_NE: np.ndarray
    NE_T_EE: np.ndarray
    EE_T_K: np.ndarray
    F_T_EE: np.ndarray
    m_ee: float
    I_ee: np.ndarray
    F_x_Cee: np.ndarray
    m_load: float
    I_load: np.ndarray
    F_x_Cload: np.ndarray
    _kin: Any
    _filled_mode: MotionGeneratorMode | None

    def _new_state(self) -> None:
        """The state: named float64 views into one buffer laid out in the wire's field
        order (see :mod:`panda_py.sim.wire`), so a connection copies it in a few blocks."""
        self._fast: TickKernels | None = None
        self._tau_J_scratch = np.zeros(7)
        total = sum(_STATE_SIZES.values())
        self.state_buffer = np.zeros(total)
        self.state_offsets: dict[str, tuple[int, int]] = {}
        self.state: dict[str, np.ndarray] = {}
        start = 0
        for name, n in _STATE_SIZES.items():
            self.state_offsets[name] = (start, start + n)
            view = self.state_buffer[start : start + n]
            self.state[name] = view.reshape(6, 3) if name.startswith("accelerometer") else view
            start += n
        # 4x4 views onto the column-major transforms: writing T there stores T's columns.
        self._T_view = {
            name: self.state[name].reshape(4, 4).T
            for name in ("O_T_EE", "O_T_EE_d", "F_T_EE", "EE_T_K", "F_T_NE", "NE_T_EE",
                         "O_T_EE_c")
        }  # fmt: skip
        self._fast = fastpath.load(self)

    def _fill_static(self) -> None:
        """The state fields only setters change (end effector, load, gravity)."""
        s, T = self.state, self._T_view
        self.F_T_EE = self.F_T_NE @ self.NE_T_EE
        self._EE_T_F = np.linalg.inv(self.F_T_EE)
        self._NE_identity = bool(np.array_equal(self.NE_T_EE, np.eye(4)))
        T["F_T_EE"][:] = self.F_T_EE
        T["EE_T_K"][:] = self.EE_T_K
        T["F_T_NE"][:] = self.F_T_NE
        T["NE_T_EE"][:] = self.NE_T_EE
        s["m_ee"][0] = self.m_ee
        s["I_ee"][:] = self.I_ee.T.reshape(9)
        s["F_x_Cee"][:] = self.F_x_Cee
        s["m_load"][0] = self.m_load
        s["I_load"][:] = self.I_load.T.reshape(9)
        s["F_x_Cload"][:] = self.F_x_Cload
        s["O_ddP_O"][:] = GRAVITY

    def _elbow_sign(self, q4: float) -> float:
        # libfranka: elbow[1] is the flip direction of joint 4 relative to q_elbow-flip.
        return 1.0 if q4 > self.spec.elbow_flip_q else -1.0

    def _fill_state(self) -> None:
        """The per-tick fields (the static ones are written by :meth:`_fill_static`): the
        compiled kernel where the kinematics run compiled, else the NumPy reference."""
        fast = self._fast
        if fast is None or not fast.fill(self):
            self._fill_state_reference()

    def _fill_state_reference(self) -> None:
        """:meth:`_fill_state` in NumPy: the reference the compiled kernel equals."""
        ph, s, Tv = self.physics, self.state, self._T_view
        q, dq = ph.q, ph.dq
        mg = self.mg_mode
        moving_cart = mg in _CARTESIAN_GENERATORS
        moving = moving_cart or mg in _JOINT_GENERATORS
        # O_T_EE of the measured joints: the arm's own kinematics (the same as MuJoCo's
        # flange site times F_T_EE, to rounding; the tests hold them together).
        joint = self.joint
        O_T_EE = Tv["O_T_EE"]
        self._ee_pose(q, O_T_EE)
        if moving_cart:
            Tv["O_T_EE_d"][:] = self.cart.T
        else:
            self._ee_pose(joint.q, Tv["O_T_EE_d"])
        s["elbow"][:] = (q[2], self._elbow_sign(q[3]))
        elbow_d = s["elbow_d"]
        elbow_d[:] = (joint.q[2], self._elbow_sign(joint.q[3]))
        if moving_cart:
            s["elbow_c"][:] = self.elbow_c
            s["delbow_c"][:] = self.delbow_c
            s["ddelbow_c"][:] = self.ddelbow_c
            Tv["O_T_EE_c"][:] = self.cart.T
            s["O_dP_EE_d"][:] = self.cart.v
            s["O_dP_EE_c"][:] = self.cart.v
            s["O_ddP_EE_c"][:] = self.cart.a
        else:
            s["elbow_c"][:] = elbow_d
            s["O_T_EE_c"][:] = s["O_T_EE_d"]
            if self._filled_mode != mg:  # zeros stand until a Cartesian motion
                for name in ("delbow_c", "ddelbow_c", "O_dP_EE_d", "O_dP_EE_c", "O_ddP_EE_c"):
                    s[name][:] = 0.0
        # the link-side torque sensors: what the drives deliver, the contacts' torques
        # taken away in _fill_contacts (they act on the links, past the sensors)
        tau_J = ph.sensor_torque(self._tau_J_scratch)
        np.subtract(tau_J, s["tau_J"], out=s["dtau_J"])
        s["dtau_J"] *= 1.0 / DT
        s["tau_J"][:] = tau_J
        s["tau_J_d"][:] = self.tau_J_d
        s["q"][:] = q
        s["dq"][:] = dq
        s["theta"][:] = q
        s["dtheta"][:] = dq
        if moving:
            s["q_d"][:] = joint.q
            s["dq_d"][:] = joint.dq
            s["ddq_d"][:] = joint.ddq
        else:
            s["q_d"][:] = self.q_hold
            if self._filled_mode != mg:
                s["dq_d"][:] = 0.0
                s["ddq_d"][:] = 0.0
        self._filled_mode = mg
        self._fill_contacts(O_T_EE)
        # Accelerometers of joints 1..6 (v10): specific force at rest in each link frame,
        # R_i^T (0, 0, g) = g times the third row of each rotation.
        top = s["accelerometer_top"]
        np.multiply(ph.link_z_rows(), -GRAVITY[2], out=top)
        s["accelerometer_bottom"][:] = top

    def _ee_pose(self, q: np.ndarray, out: np.ndarray) -> None:
        """O_T_EE at joints ``q`` into ``out`` (4x4; fk of the nominal EE, then NE_T_EE)."""
        if self._NE_identity:
            out[:] = self._kin.fk(q)
        else:
            np.matmul(self._kin.fk(q), self.NE_T_EE, out=out)

    def _fill_contacts(self, O_T_EE: np.ndarray) -> None:
        """The contacts' part of the fill: their torques taken from the sensors' reading,
        and the robot's estimate of the external torques and wrench.

        The robot's model of its links is the plant's here (the drives' rotor inertia and
        friction are on the motor side of the sensors, outside the model, as on a real
        robot), so the residual tau_J - (M ddq + c + g) the robot filters is exactly the
        torques the contacts exert on the links (``Physics.sensor_torque``): they are
        taken from MuJoCo's contact forces rather than through the model's inverse
        dynamics each tick; ``tests/sim/test_sim_contact_estimate.py`` computes the
        residual from the published tau_J, q, dq and the client's model and finds the
        same estimate."""
        s, t = self.state, self.thresholds
        raw = self.physics.contact_torques()
        touching = raw is not None and bool(raw.any())
        if raw is not None and touching:
            s["tau_J"] -= raw
            s["dtau_J"] -= raw * (1.0 / DT)
        if not self.contact_active and not touching:
            return  # no contact now or lately: the zeros written last time stand
        self.tau_ext += _EXT_FILTER * ((_NO_TORQUE if raw is None else raw) - self.tau_ext)
        if not touching and np.abs(self.tau_ext).max() < 1e-9:
            self.tau_ext[:] = 0.0
            self.contact_active = False
            for name in CONTACT_FIELDS:
                s[name][:] = 0.0
            return
        self.contact_active = True
        # libfranka's robot_state.h: tau_ext_hat_filtered is "the error between tau_J and
        # the expected torques given by the robot model", and O_F_ext_hat_K / K_F_ext_hat_K
        # are the external wrench with "forces applied by the robot to the environment
        # positive, forces applied by the environment on the robot negative". self.tau_ext
        # is what the contacts exert on the arm (the part of tau_J the model does not
        # expect, with the opposite sign), so both publish its opposite: an arm pressing
        # down on the table reads O_F_ext_hat_K[2] < 0 (franky's FORCE_Z < -5 reaction).
        tau = s["tau_ext_hat_filtered"]
        np.negative(self.tau_ext, out=tau)
        s["joint_contact"][:] = np.abs(tau) > t.lower_torque_nom
        s["joint_collision"][:] = np.abs(tau) > t.upper_torque_nom
        # Wrench at K that explains tau_ext: least squares on tau = J_K^T F.
        O_T_K = O_T_EE @ self.EE_T_K
        F = self.physics.wrench_explaining(tau, np.ascontiguousarray(O_T_K[:3, 3]))
        s["O_F_ext_hat_K"][:] = F
        R = O_T_K[:3, :3]
        s["K_F_ext_hat_K"][:3] = R.T @ F[:3]
        s["K_F_ext_hat_K"][3:] = R.T @ F[3:]
        s["cartesian_contact"][:] = np.abs(F) > t.lower_force_nom
        s["cartesian_collision"][:] = np.abs(F) > t.upper_force_nom

    def state_modes(self) -> tuple[int, int, int]:
        return int(self.mg_mode), int(self.ctrl_mode), int(self.robot_mode)


__all__ = ["CONTACT_FIELDS", "StateAssembly"]
