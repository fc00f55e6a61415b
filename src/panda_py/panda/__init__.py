"""The high-level interface (panda-py's ``Panda``): the user's side of a robot whose 1 kHz
loop runs in a control process of its own.

* :mod:`~panda_py.panda.core`: ``Panda`` (state, moves, controllers, logging);
* :mod:`~panda_py.panda.motions`: ``JointMotion``, ``PoseMotion``, what ``Panda.move`` runs;
* :mod:`~panda_py.panda.move_args`: panda-py's move arguments bound and checked;
* :mod:`~panda_py.panda.planning`: the sampled plans;
* :mod:`~panda_py.panda.context`: ``PandaContext``, a fixed-frequency user loop;
* :mod:`~panda_py.panda.proxy`: ``Panda.get_robot()``'s libfranka interface.
"""

from __future__ import annotations

from panda_py.panda.context import PandaContext
from panda_py.panda.core import Panda, realtime_priority_available
from panda_py.panda.handle import MotionHandle
from panda_py.panda.motions import JointMotion, PoseMotion
from panda_py.panda.proxy import RobotProxy

__all__ = [
    "JointMotion",
    "MotionHandle",
    "Panda",
    "PandaContext",
    "PoseMotion",
    "RobotProxy",
    "realtime_priority_available",
]
