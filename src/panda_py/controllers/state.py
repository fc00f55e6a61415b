"""What a control law reads of a tick's state (:class:`StateView`), in one place: the laws
(:mod:`panda_py.controllers.law`) and their model (:mod:`panda_py.controllers.model`)
both read it."""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = ["StateView"]

FloatArray = NDArray[np.float64]


class StateView(Protocol):
    """What a law reads of a tick's state: libfranka's ``RobotState`` fields by their
    names, flat float64 arrays (transforms (16,) column-major, inertia tensors (9,)),
    read-only within the tick (:class:`~panda_py.libfranka.RobotState`, the loop's
    :class:`~panda_py.libfranka.state.TickState`, the fast training world's state)."""

    @property
    def q(self) -> FloatArray: ...  # [rad]

    @property
    def dq(self) -> FloatArray: ...  # [rad/s]

    @property
    def O_T_EE(self) -> FloatArray: ...  # the end effector in the base frame

    @property
    def F_T_EE(self) -> FloatArray: ...  # the end effector on the flange

    @property
    def tau_J(self) -> FloatArray: ...  # [Nm] measured

    @property
    def tau_J_d(self) -> FloatArray: ...  # [Nm] last commanded

    @property
    def m_ee(self) -> float: ...  # [kg] the end effector's mass

    @property
    def F_x_Cee(self) -> FloatArray: ...

    @property
    def I_ee(self) -> FloatArray: ...

    @property
    def m_load(self) -> float: ...  # [kg] the payload's

    @property
    def F_x_Cload(self) -> FloatArray: ...

    @property
    def I_load(self) -> FloatArray: ...

    @property
    def current_errors(self) -> object: ...  # libfranka's Errors: truthy when any is set

    def raw_fields(self, names: tuple[str, ...]) -> bytes:
        """The raw bytes of the fields ``names``: a cheap key of what they hold."""
        ...
