"""A move described before it runs: :class:`JointMotion` and :class:`PoseMotion`, what
:meth:`Panda.move <panda_py.Panda.move>` runs and ``then=`` continues with.

Each is built by typed constructors (:meth:`JointMotion.to`, :meth:`JointMotion.through`,
:meth:`PoseMotion.to`, :meth:`PoseMotion.through`, :meth:`PoseMotion.to_position`,
:meth:`PoseMotion.through_positions`), or from panda-py's own arguments
(``JointMotion(*args, **kwargs)`` takes ``move_to_joint_position``'s, ``PoseMotion``
``move_to_pose``'s): the one place where those overloads are bound
(:func:`panda_py.overloads.bind`, as ``ik``'s) and checked. Everything is checked when the
motion is made: a bad target or option is an error naming the argument, before anything
is sent.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panda_py.panda.move_args import (
    JOINT_MOVE_DEFAULTS,
    POSE_MOVE_DEFAULTS,
    JointMoveOptions,
    PoseMoveOptions,
    joint_options,
    joint_waypoints,
    parse_joint_targets,
    parse_pose_targets,
    pose_options,
    pose_waypoints,
    position_waypoints,
)

__all__ = ["JointMotion", "PoseMotion"]

FloatArray = NDArray[np.float64]


def _changed(values: dict[str, Any], defaults: dict[str, Any]) -> dict[str, Any]:
    """The options among a typed constructor's arguments (its ``locals()``) that are not
    the defaults' own objects (those take the defaults' options, checked once)."""
    return {k: v for k, v in values.items() if k in defaults and v is not defaults[k]}


_J, _P = JOINT_MOVE_DEFAULTS, POSE_MOVE_DEFAULTS


class JointMotion:
    """A joint move described now and run later, by :meth:`Panda.move
    <panda_py.Panda.move>` or as ``then=`` of a guarded move: ``waypoints`` (N, 7) [rad]
    and its checked ``options``. ``JointMotion(*args, **kwargs)`` takes
    ``move_to_joint_position``'s arguments; :meth:`to` and :meth:`through` are the typed
    forms."""

    waypoints: FloatArray
    options: JointMoveOptions

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.waypoints, self.options = parse_joint_targets(args, kwargs)

    @classmethod
    def _of(cls, waypoints: FloatArray, options: JointMoveOptions) -> JointMotion:
        motion = cls.__new__(cls)
        motion.waypoints, motion.options = waypoints, options
        return motion

    @classmethod
    def to(
        cls, positions: ArrayLike, *, speed_factor: float = _J["speed_factor"],
        stiffness: ArrayLike = _J["stiffness"], damping: ArrayLike = _J["damping"],
        dq_threshold: float = _J["dq_threshold"],
        success_threshold: float = _J["success_threshold"],
    ) -> JointMotion:  # fmt: skip
        """To the joint positions ``positions`` (7,) [rad] on a time-optimal trajectory at
        ``speed_factor`` of the robot's limits, tracked by joint impedance (``stiffness``
        [Nm/rad], ``damping`` [Nm s/rad]); it succeeds at rest (every joint below
        ``dq_threshold`` [rad/s]) within ``success_threshold`` [rad] of the goal."""
        waypoints = joint_waypoints(positions)
        if len(waypoints) != 1:
            raise ValueError(f"positions: expected 7 joint positions [rad], got {len(waypoints)} "
                             "waypoints (JointMotion.through takes them)")  # fmt: skip
        return cls._of(waypoints, joint_options(_changed(locals(), _J)))

    @classmethod
    def through(
        cls, waypoints: Sequence[ArrayLike] | ArrayLike, *,
        speed_factor: float = _J["speed_factor"], stiffness: ArrayLike = _J["stiffness"],
        damping: ArrayLike = _J["damping"], dq_threshold: float = _J["dq_threshold"],
        success_threshold: float = _J["success_threshold"],
        max_deviation: float = _J["max_deviation"],
    ) -> JointMotion:  # fmt: skip
        """Through ``waypoints`` (N, 7) [rad], stopping at each (panda-py's) or cutting
        each intermediate one's corner by up to ``max_deviation`` [rad]; the rest as
        :meth:`to`."""
        return cls._of(joint_waypoints(waypoints), joint_options(_changed(locals(), _J)))

    def __repr__(self) -> str:
        return f"JointMotion({np.round(self.waypoints[-1], 4).tolist()})"


class PoseMotion:
    """A Cartesian move described now and run later, by :meth:`Panda.move
    <panda_py.Panda.move>` or as ``then=`` of a guarded move: the end effector's
    ``positions`` (N, 3) [m] and ``orientations`` (N, 4) (unit quaternions x, y, z, w) and
    the checked ``options``. ``PoseMotion(*args, **kwargs)`` takes ``move_to_pose``'s
    arguments; :meth:`to`, :meth:`through`, :meth:`to_position` and
    :meth:`through_positions` are the typed forms."""

    positions: FloatArray
    orientations: FloatArray
    options: PoseMoveOptions

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.positions, self.orientations, self.options = parse_pose_targets(args, kwargs)

    @classmethod
    def _of(cls, targets: tuple[FloatArray, FloatArray], options: PoseMoveOptions) -> PoseMotion:
        motion = cls.__new__(cls)
        motion.positions, motion.orientations = targets
        motion.options = options
        return motion

    @classmethod
    def to(
        cls, pose: ArrayLike, *, speed_factor: float = _P["speed_factor"],
        impedance: ArrayLike = _P["impedance"], damping_ratio: float = _P["damping_ratio"],
        nullspace_stiffness: float = _P["nullspace_stiffness"],
        dq_threshold: float = _P["dq_threshold"],
        success_threshold: float = _P["success_threshold"],
        orientation_threshold: float = _P["orientation_threshold"],
    ) -> PoseMotion:  # fmt: skip
        """To the end-effector pose ``pose`` (4, 4) on a straight, time-optimal segment at
        ``speed_factor`` of the robot's Cartesian limits, tracked by Cartesian impedance
        (``impedance`` (6, 6) [N/m, Nm/rad], ``damping_ratio``, ``nullspace_stiffness``
        [Nm/rad]); it succeeds at rest (every joint below ``dq_threshold`` [rad/s]) within
        ``success_threshold`` [m] and ``orientation_threshold`` [rad] of the goal."""
        targets = pose_waypoints(pose)
        if len(targets[0]) != 1:
            raise ValueError(f"pose: expected one 4x4 pose, got {len(targets[0])} "
                             "(PoseMotion.through takes them)")  # fmt: skip
        return cls._of(targets, pose_options(_changed(locals(), _P)))

    @classmethod
    def to_position(
        cls, position: ArrayLike, orientation: ArrayLike, *,
        speed_factor: float = _P["speed_factor"], impedance: ArrayLike = _P["impedance"],
        damping_ratio: float = _P["damping_ratio"],
        nullspace_stiffness: float = _P["nullspace_stiffness"],
        dq_threshold: float = _P["dq_threshold"],
        success_threshold: float = _P["success_threshold"],
        orientation_threshold: float = _P["orientation_threshold"],
    ) -> PoseMotion:  # fmt: skip
        """To ``position`` (3,) [m] with ``orientation`` (4,) (a unit quaternion x, y, z,
        w); the rest as :meth:`to`."""
        targets = position_waypoints(position, orientation)
        if len(targets[0]) != 1:
            raise ValueError(f"position: expected one position (3,) [m], got {len(targets[0])} "
                             "(PoseMotion.through_positions takes them)")  # fmt: skip
        return cls._of(targets, pose_options(_changed(locals(), _P)))

    @classmethod
    def through(
        cls, poses: Sequence[ArrayLike] | ArrayLike, *,
        speed_factor: float = _P["speed_factor"], impedance: ArrayLike = _P["impedance"],
        damping_ratio: float = _P["damping_ratio"],
        nullspace_stiffness: float = _P["nullspace_stiffness"],
        dq_threshold: float = _P["dq_threshold"],
        success_threshold: float = _P["success_threshold"],
        orientation_threshold: float = _P["orientation_threshold"],
        max_deviation: float = _P["max_deviation"],
    ) -> PoseMotion:  # fmt: skip
        """Through ``poses`` (N, 4, 4), stopping at each (panda-py's) or cutting each
        intermediate one's corner by up to ``max_deviation`` [m]; the rest as :meth:`to`."""
        return cls._of(pose_waypoints(poses), pose_options(_changed(locals(), _P)))

    @classmethod
    def through_positions(
        cls, positions: Sequence[ArrayLike] | ArrayLike,
        orientations: Sequence[ArrayLike] | ArrayLike, *,
        speed_factor: float = _P["speed_factor"], impedance: ArrayLike = _P["impedance"],
        damping_ratio: float = _P["damping_ratio"],
        nullspace_stiffness: float = _P["nullspace_stiffness"],
        dq_threshold: float = _P["dq_threshold"],
        success_threshold: float = _P["success_threshold"],
        orientation_threshold: float = _P["orientation_threshold"],
        max_deviation: float = _P["max_deviation"],
    ) -> PoseMotion:  # fmt: skip
        """Through ``positions`` (N, 3) [m] with ``orientations`` (N, 4) (unit
        quaternions x, y, z, w); the rest as :meth:`through`."""
        return cls._of(position_waypoints(positions, orientations),
                       pose_options(_changed(locals(), _P)))  # fmt: skip

    def __repr__(self) -> str:
        return f"PoseMotion({np.round(self.positions[-1], 4).tolist()})"
