"""``Model``: kinematics and dynamics of the arm, computed locally from
:mod:`panda_py.robots` (no model library download; works offline and without a robot).

Frames follow libfranka's ``Frame`` enum: the seven joint frames (modified DH, moving with
their joint), the flange, the end effector (flange * ``F_T_EE``) and the stiffness frame
(end effector * ``EE_T_K``). Like libfranka, results are flat arrays: poses (16,) and
mass matrices (49,) column-major, Jacobians (42,) column-major 6x7 (rows: linear velocity
[m/s], angular velocity [rad/s]; one column per joint). Dynamics pass end effector plus
payload as one load (``m_total``, ``F_x_Ctotal``, ``I_total``) to :mod:`panda_py.dynamics`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import dynamics
from panda_py.checks import vector as _vec
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import Frame
from panda_py.robots.params import GRAVITY, RobotKind, RobotSpec, get_robot

__all__ = ["Model"]

FloatArray = NDArray[np.float64]
_IDENTITY16 = np.eye(4).reshape(16)


def _frame(frame: Any) -> Frame:
    try:
        return Frame(frame)
    except ValueError:
        raise ValueError(f"frame: expected a Frame (kJoint1..kStiffness), got {frame!r}") from None


class Model:
    """The dynamics model of one arm (``robot``: "fer"/"panda", "fr3" or a RobotSpec)."""

    def __init__(self, robot: str | RobotKind | RobotSpec = "fer") -> None:
        self.spec = get_robot(robot)
        dh = self.spec.dh
        self._static = []
        for i in range(7):
            ca, sa = math.cos(dh.alpha[i]), math.sin(dh.alpha[i])
            # RotX(alpha) TransX(a): the part of each link transform that does not move
            self._static.append(
                np.array([[1.0, 0, 0, dh.a[i]], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1]])
            )
        self._d = dh.d
        self._flange = np.eye(4)
        self._flange[2, 3] = dh.flange_d

    def __repr__(self) -> str:
        return f"Model(robot={self.spec.name!r})"

    # --- kinematics -------------------------------------------------------------------

    def _frames(self, q: FloatArray, F_T_EE: FloatArray, EE_T_K: FloatArray) -> list[FloatArray]:
        """Base-frame poses (4x4) of the 10 frames of :class:`Frame`."""
        out = []
        T = np.eye(4)
        for i in range(7):
            c, s = math.cos(q[i]), math.sin(q[i])
            joint = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, self._d[i]], [0, 0, 0, 1]])
            T = T @ self._static[i] @ joint
            out.append(T)
        flange = T @ self._flange
        ee = flange @ F_T_EE.reshape(4, 4).T
        out += [flange, ee, ee @ EE_T_K.reshape(4, 4).T]
        return out

    def _kin_args(
        self, q: Any, F_T_EE: Any, EE_T_K: Any
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        if isinstance(q, RobotState):
            if F_T_EE is not None or EE_T_K is not None:
                raise ValueError("F_T_EE, EE_T_K: not with a RobotState (it carries them)")
            return q.q, q.F_T_EE, q.EE_T_K
        return (
            _vec("q", q, 7, "[rad]"),
            _IDENTITY16 if F_T_EE is None else _vec("F_T_EE", F_T_EE, 16, "(transform)"),
            _IDENTITY16 if EE_T_K is None else _vec("EE_T_K", EE_T_K, 16, "(transform)"),
        )

    def pose(self, frame: Frame, q: Any, F_T_EE: Any = None, EE_T_K: Any = None) -> FloatArray:
        """Pose of ``frame`` in the base frame, (16,) column-major [m], at ``q`` (7,)
        [rad] or a :class:`RobotState` (which supplies ``F_T_EE``/``EE_T_K``)."""
        f = _frame(frame)
        frames = self._frames(*self._kin_args(q, F_T_EE, EE_T_K))
        return frames[f].reshape(16, order="F")

    def _jacobian(self, frame: Any, args: tuple[FloatArray, FloatArray, FloatArray],
                  body: bool) -> FloatArray:  # fmt: skip
        f = _frame(frame)
        frames = self._frames(*args)
        target = frames[f]
        p = target[:3, 3]
        J = np.zeros((6, 7))
        n = min(int(f) + 1, 7)  # joint frames move with joints 1..k only
        for i in range(n):
            z = frames[i][:3, 2]
            J[:3, i] = np.cross(z, p - frames[i][:3, 3])
            J[3:, i] = z
        if body:
            Rt = target[:3, :3].T
            J = np.vstack((Rt @ J[:3], Rt @ J[3:]))
        return J.reshape(42, order="F")

    def zero_jacobian(self, frame: Frame, q: Any, F_T_EE: Any = None,
                      EE_T_K: Any = None) -> FloatArray:  # fmt: skip
        """Geometric Jacobian of ``frame`` in the base frame, (42,) column-major 6x7."""
        return self._jacobian(frame, self._kin_args(q, F_T_EE, EE_T_K), body=False)

    def body_jacobian(self, frame: Frame, q: Any, F_T_EE: Any = None,
                      EE_T_K: Any = None) -> FloatArray:  # fmt: skip
        """Geometric Jacobian of ``frame`` in ``frame`` itself, (42,) column-major 6x7."""
        return self._jacobian(frame, self._kin_args(q, F_T_EE, EE_T_K), body=True)

    # --- dynamics ---------------------------------------------------------------------

    def _load(
        self, I_total: Any, m_total: Any, F_x_Ctotal: Any
    ) -> tuple[FloatArray, float, FloatArray]:
        m = _vec("m_total", [m_total], 1, "[kg]")[0]
        if m < 0.0:
            raise ValueError(f"m_total: expected a mass >= 0 [kg], got {m}")
        inertia = np.zeros(9) if I_total is None else _vec("I_total", I_total, 9, "[kg m^2]")
        return inertia, float(m), _vec("F_x_Ctotal", F_x_Ctotal, 3, "[m]")

    def mass(self, q: Any, I_total: Any = None, m_total: Any = None,
             F_x_Ctotal: Any = None) -> FloatArray:  # fmt: skip
        """Joint-space mass matrix (49,) column-major [kg m^2] at ``q`` [rad] with the
        total load, or of a :class:`RobotState`."""
        if isinstance(q, RobotState):
            q, I_total, m_total, F_x_Ctotal = q.q, q.I_total, q.m_total, q.F_x_Ctotal
        inertia, m, c = self._load(I_total, m_total, F_x_Ctotal)
        M = dynamics.mass_matrix(q, m_load=m, F_x_Cload=c, I_load=inertia, robot=self.spec)
        return M.reshape(49, order="F")

    def coriolis(self, q: Any, dq: Any = None, I_total: Any = None, m_total: Any = None,
                 F_x_Ctotal: Any = None) -> FloatArray:  # fmt: skip
        """Coriolis and centrifugal torques ``C(q, dq) dq`` (7,) [Nm] (``dq`` [rad/s]),
        or of a :class:`RobotState`."""
        if isinstance(q, RobotState):
            q, dq, I_total, m_total, F_x_Ctotal = q.q, q.dq, q.I_total, q.m_total, q.F_x_Ctotal
        inertia, m, c = self._load(I_total, m_total, F_x_Ctotal)
        return dynamics.coriolis(q, dq, m_load=m, F_x_Cload=c, I_load=inertia, robot=self.spec)

    def gravity(self, q: Any, m_total: Any = None, F_x_Ctotal: Any = None,
                gravity_earth: Any = GRAVITY) -> FloatArray:  # fmt: skip
        """Torques (7,) [Nm] holding the arm and its total load against ``gravity_earth``
        [m/s^2] at ``q`` [rad]; or ``gravity(robot_state, gravity_earth)``."""
        if isinstance(q, RobotState):
            if m_total is not None and F_x_Ctotal is None:
                gravity_earth = m_total  # gravity(robot_state, gravity_earth)
            q, m_total, F_x_Ctotal = q.q, q.m_total, q.F_x_Ctotal
        _, m, c = self._load(None, m_total, F_x_Ctotal)
        g = _vec("gravity_earth", gravity_earth, 3, "[m/s^2]")
        return dynamics.gravity(q, m_load=m, F_x_Cload=c, gravity=g, robot=self.spec)
