"""``Panda.get_robot()``: libfranka's ``Robot`` interface for a robot whose connection the
control process owns. Each call is checked here (the same checks as
:class:`panda_py.libfranka.Robot`, so nothing malformed leaves this process) and then
runs in the control process between ticks.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from panda_py import checks
from panda_py.checks import vector as _vec
from panda_py.libfranka.model import Model
from panda_py.libfranka.robot import collision_thresholds
from panda_py.libfranka.state import RobotState
from panda_py.rt import requests as rq
from panda_py.rt.process import ControlProcess

__all__ = ["RobotProxy"]


def _collision_args(args: tuple[Any, ...], kwargs: dict[str, Any]) -> list[np.ndarray]:
    """The 8 checked threshold arrays, in the order of ``Robot.set_collision_behavior``;
    thresholds must not be negative."""
    arrays = collision_thresholds(args, kwargs)
    for name, arr in arrays.items():
        if (arr < 0.0).any():
            raise ValueError(f"{name}: expected thresholds >= 0, got {arr.tolist()}")
    return list(arrays.values())


class RobotProxy:
    """The ``libfranka.Robot`` of a :class:`~panda_py.Panda` (setters, error recovery,
    ``read_once``), forwarded to its control process."""

    def __init__(
        self,
        process: ControlProcess,
        server_version: int,
        model: Model,
        stop: Callable[[], None],
    ) -> None:
        self._process = process
        self._server_version = server_version
        self._model = model
        self._stop = stop

    def _call(self, method: str, *args: Any) -> Any:
        return self._process.call(rq.RobotCall(method, args))

    def server_version(self) -> int:
        """The robot's FCI protocol version, negotiated when the :class:`~panda_py.Panda`
        connected."""
        return self._server_version

    def read_once(self) -> RobotState:
        """A fresh robot state (newer than any returned before)."""
        state: RobotState = self._call("read_once")
        return state

    readOnce = read_once

    def load_model(self) -> Model:
        """The robot's :class:`~panda_py.libfranka.Model` (computed locally, in this process)."""
        return self._model

    def set_collision_behavior(self, *args: Any, **kwargs: Any) -> None:
        """Contact/collision thresholds: 4 or 8 arrays as libfranka's
        ``setCollisionBehavior`` (torques (7,) [Nm], forces (6,) [N, Nm])."""
        self._call("set_collision_behavior", *_collision_args(args, kwargs))

    def set_joint_impedance(self, K_theta: Any) -> None:
        """The stiffness of the robot's internal joint impedance controller, ``K_theta`` (7,)
        [Nm/rad], each >= 0 (libfranka's ``setJointImpedance``)."""
        arr = _vec("K_theta", K_theta, 7, "[Nm/rad]")
        if (arr < 0.0).any():
            raise ValueError(f"K_theta: expected stiffness >= 0 [Nm/rad], got {arr.tolist()}")
        self._call("set_joint_impedance", arr)

    def set_cartesian_impedance(self, K_x: Any) -> None:
        """The stiffness of the robot's internal Cartesian impedance controller, ``K_x``
        (6,) [N/m, Nm/rad], each >= 0 (libfranka's ``setCartesianImpedance``)."""
        arr = _vec("K_x", K_x, 6, "[N/m, Nm/rad]")
        if (arr < 0.0).any():
            raise ValueError(f"K_x: expected stiffness >= 0 [N/m, Nm/rad], got {arr.tolist()}")
        self._call("set_cartesian_impedance", arr)

    def set_guiding_mode(self, guiding_mode: Any, elbow: bool) -> None:
        """Which Cartesian axes (x, y, z, roll, pitch, yaw: 6 bools) can be moved by hand in
        guiding mode, and whether the elbow can (libfranka's ``setGuidingMode``)."""
        axes = np.asarray(guiding_mode)
        if axes.shape != (6,) or axes.dtype.kind not in "bi":
            raise ValueError(f"guiding_mode: expected 6 bools, got {guiding_mode!r}")
        if not isinstance(elbow, (bool, np.bool_)):
            raise ValueError(f"elbow: expected a bool, got {elbow!r}")
        self._call("set_guiding_mode", axes.astype(bool), bool(elbow))

    def _transform(self, name: str, value: Any) -> np.ndarray:
        arr = np.asarray(value, dtype=np.float64)
        flat = arr.reshape(4, 4).reshape(16, order="F") if arr.shape == (4, 4) else arr
        T = _vec(name, flat, 16, "(transform, column-major)")
        M = T.reshape(4, 4, order="F")
        err = float(checks.rigid_errors(M))
        if not err <= checks.RIGID_TOL:
            raise ValueError(checks.rigid_message(name, err) + f", got {M.tolist()}")
        return T

    def set_k(self, EE_T_K: Any) -> None:
        """The stiffness frame K relative to the end effector, ``EE_T_K`` (a 4x4 transform or 16
        values, column-major; libfranka's ``setK``)."""
        self._call("set_k", self._transform("EE_T_K", EE_T_K))

    def set_ee(self, NE_T_EE: Any) -> None:
        """The end effector frame relative to the nominal end effector, ``NE_T_EE`` (a 4x4
        transform or 16 values, column-major; libfranka's ``setEE``)."""
        self._call("set_ee", self._transform("NE_T_EE", NE_T_EE))

    set_K = set_k
    set_EE = set_ee

    def set_load(self, load_mass: float, F_x_Cload: Any, load_inertia: Any) -> None:
        """The load carried beyond the end effector: its mass ``load_mass`` [kg], centre of mass
        ``F_x_Cload`` (3,) [m] in the flange frame and inertia ``load_inertia`` (3x3 or 9
        values) [kg m^2] (libfranka's ``setLoad``)."""
        m = float(_vec("load_mass", [load_mass], 1, "[kg]")[0])
        if m < 0.0:
            raise ValueError(f"load_mass: expected a mass >= 0 [kg], got {m}")
        c = _vec("F_x_Cload", F_x_Cload, 3, "[m]")
        inertia = _vec("load_inertia", np.asarray(load_inertia, dtype=float).reshape(-1), 9,
                       "[kg m^2]")  # fmt: skip
        self._call("set_load", m, c, inertia)

    def set_filters(self, joint_position_filter_frequency: float,
                    joint_velocity_filter_frequency: float,
                    cartesian_position_filter_frequency: float,
                    cartesian_velocity_filter_frequency: float,
                    controller_filter_frequency: float) -> None:  # fmt: skip
        """Robot-side low-pass cut-offs [Hz] (1..1000; protocol v3-v5 only)."""
        frequencies = [joint_position_filter_frequency, joint_velocity_filter_frequency,
                       cartesian_position_filter_frequency, cartesian_velocity_filter_frequency,
                       controller_filter_frequency]  # fmt: skip
        values = _vec("filter frequencies", frequencies, 5, "[Hz]")
        if ((values < 1.0) | (values > 1000.0)).any():
            raise ValueError(f"filter frequencies: expected 1..1000 Hz, got {values.tolist()}")
        self._call("set_filters", *values.tolist())

    def automatic_error_recovery(self) -> None:
        """Clear the robot's error (reflex) so that it accepts motions again (libfranka's
        ``automaticErrorRecovery``); raises ``CommandException`` if it cannot."""
        self._call("automatic_error_recovery")

    def stop(self) -> None:
        """Stop whatever runs: the controller or move of the Panda."""
        self._stop()
