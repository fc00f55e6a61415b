"""panda-py 1.1.1's named control methods (``control_joint_position`` etc.), each a
:meth:`~panda_py.libfranka.Robot.control` with the motion type fixed."""

from __future__ import annotations

from panda_py.libfranka._control import Callback, ControlMixin
from panda_py.libfranka.commands import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
)
from panda_py.libfranka.types import (
    ControllerMode,
)

__all__ = ["NamedControlMixin"]


class NamedControlMixin(ControlMixin):
    """The ``control_*`` variants of panda-py 1.1.1."""

    def control_joint_position(
        self,
        motion_generator_callback: Callback,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Joint position motion generator (callback returns :class:`JointPositions`)."""
        self.control(
            motion_generator_callback,
            controller_mode=controller_mode,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=JointPositions,
        )

    def control_joint_velocity(
        self,
        motion_generator_callback: Callback,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Joint velocity motion generator (callback returns :class:`JointVelocities`)."""
        self.control(
            motion_generator_callback,
            controller_mode=controller_mode,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=JointVelocities,
        )

    def control_cartesian_pose(
        self,
        motion_generator_callback: Callback,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Cartesian pose motion generator (callback returns :class:`CartesianPose`)."""
        self.control(
            motion_generator_callback,
            controller_mode=controller_mode,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=CartesianPose,
        )

    def control_cartesian_velocity(
        self,
        motion_generator_callback: Callback,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Cartesian velocity generator (callback returns :class:`CartesianVelocities`)."""
        self.control(
            motion_generator_callback,
            controller_mode=controller_mode,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=CartesianVelocities,
        )

    def control_torque_joint_position(
        self,
        control_callback: Callback,
        motion_generator_callback: Callback,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Torques plus a joint position generator."""
        self.control(
            control_callback,
            motion_generator_callback,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=JointPositions,
        )

    def control_torque_joint_velocity(
        self,
        control_callback: Callback,
        motion_generator_callback: Callback,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Torques plus a joint velocity generator."""
        self.control(
            control_callback,
            motion_generator_callback,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=JointVelocities,
        )

    def control_torque_cartesian_pose(
        self,
        control_callback: Callback,
        motion_generator_callback: Callback,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Torques plus a Cartesian pose generator."""
        self.control(
            control_callback,
            motion_generator_callback,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=CartesianPose,
        )

    def control_torque_cartesian_velocity(
        self,
        control_callback: Callback,
        motion_generator_callback: Callback,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
    ) -> None:
        """Torques plus a Cartesian velocity generator."""
        self.control(
            control_callback,
            motion_generator_callback,
            limit_rate=limit_rate,
            cutoff_frequency=cutoff_frequency,
            motion=CartesianVelocities,
        )
