"""Conditions for guarded moves (``until=``): see :mod:`panda_py.controllers.conditions`.

from panda_py.conditions import Elapsed, Force

panda.move_to_pose(below, until=(Force.z < -10.0) | (Elapsed > 5.0))
"""

from __future__ import annotations

from panda_py.controllers import conditions as _conditions
from panda_py.controllers.conditions import *  # noqa: F403  (the public names, once)

__all__ = list(_conditions.__all__)
