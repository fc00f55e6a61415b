"""Conditions for guarded moves (``until=``): see :mod:`panda_py.controllers.conditions`.

from panda_py.conditions import Elapsed, Force

panda.move_to_pose(below, until=(Force.z < -10.0) | (Elapsed > 5.0))
"""

from __future__ import annotations

from panda_py.controllers.conditions import (
    Condition,
    Distance,
    Elapsed,
    Errors,
    Field,
    Force,
    ForceEE,
    Moment,
    MomentEE,
    Progress,
    Quantity,
    Torque,
    when,
)

__all__ = [
    "Condition",
    "Distance",
    "Elapsed",
    "Errors",
    "Field",
    "Force",
    "ForceEE",
    "Moment",
    "MomentEE",
    "Progress",
    "Quantity",
    "Torque",
    "when",
]
