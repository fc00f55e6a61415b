"""Time-optimal trajectories through waypoints, in joint space and in Cartesian space,
under the limits of the chosen robot (FER or FR3) (panda-py's ``panda_py.motion``)."""

from __future__ import annotations

from panda_py.motion.cartesian import CartesianSamples, CartesianTrajectory, JointMap
from panda_py.motion.errors import PlanningTimeoutError, TrajectoryError
from panda_py.motion.joint import JointSamples, JointTrajectory

__all__ = [
    "CartesianSamples",
    "CartesianTrajectory",
    "JointMap",
    "JointSamples",
    "JointTrajectory",
    "PlanningTimeoutError",
    "TrajectoryError",
]
