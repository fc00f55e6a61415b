"""What an environment needs of the robot it runs on: the few operations both backends
offer, the fast in-process world (:class:`~panda_py.learning.world.FastWorld`) and any
``Panda`` (:class:`~panda_py.learning.arm.RobotArm`: a robot or ``panda-sim``).

The environment feeds a streamed-target controller
(:class:`~panda_py.controllers.JointTarget` or
:class:`~panda_py.controllers.CartesianTarget`) through its own ``set_target``, on either
backend; the backend starts it, lets the robot's clock run to the next policy step, and
reports the state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import TorqueController

__all__ = ["Backend", "Snapshot"]

FloatArray = NDArray[np.float64]


@dataclass
class Snapshot:
    """The robot's state at a policy step: joint positions [rad] and velocities [rad/s]
    (7,), the end effector's pose ``O_T_EE`` (4, 4) [m], the fingers' opening [m], the
    cube's centre [m] (None where nothing tells it) and the robot's clock [ms]."""

    q: FloatArray
    dq: FloatArray
    O_T_EE: FloatArray
    gripper_width: float
    cube: FloatArray | None
    time_ms: int


class Backend:
    """The operations an environment runs on (override all)."""

    #: the robot's name (``robots.params``), e.g. "fer"
    spec_name: str
    #: whether the same start and actions give the same episode, bit for bit (a robot,
    #: and a simulator in another process, give nearly the same)
    deterministic = False
    #: whether it has the hand (picking needs it)
    has_hand = True
    #: whether it places the cube and reports where it is (picking needs it)
    has_cube = True

    def __deepcopy__(self, memo: dict[int, object]) -> Backend:
        # a backend is one robot (a connection, a world): copies of what holds it (e.g.
        # Gymnasium's copies of an environment's spec and its arguments) share it
        return self

    def __enter__(self) -> Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def time_ms(self) -> int:
        """The robot's clock [ms]."""
        raise NotImplementedError

    def snapshot(self) -> Snapshot:
        """The robot's newest state."""
        raise NotImplementedError

    def start(self, controller: TorqueController) -> None:
        """Start ``controller`` (the robot must be idle and without errors)."""
        raise NotImplementedError

    def stop(self) -> None:
        """Stop the running controller; the arm holds where it is."""
        raise NotImplementedError

    def advance(self, ms: int) -> None:
        """Let the robot's clock run until it reads ``ms`` (or the controller stopped)."""
        raise NotImplementedError

    def failure(self) -> str | None:
        """Why the running controller stopped (a reflex and its flags), or None."""
        raise NotImplementedError

    def home(self, q: FloatArray, cube: FloatArray | None) -> None:
        """Bring the arm to rest at ``q`` [rad] with the hand open, and the cube to
        ``cube`` [m] (its centre; None: leave it)."""
        raise NotImplementedError

    def recover(self) -> None:
        """Stop, and recover the robot from a reflex."""
        raise NotImplementedError

    def hand_open(self) -> None:
        """Start opening the hand (returns at once)."""
        raise NotImplementedError

    def hand_close(self) -> None:
        """Start closing the hand on whatever is between the fingers (returns at once)."""
        raise NotImplementedError

    def close(self) -> None:
        """Stop and release what the backend holds."""
        raise NotImplementedError
