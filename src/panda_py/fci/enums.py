"""Version-independent names of the robot protocol: commands, statuses, modes, error flags.

Enums whose numbers are the same on the wire in every protocol version are ``IntEnum``
(the value *is* the wire value). Enums whose numbering changed between versions (commands,
most statuses) are plain ``Enum``: translate them with a :class:`~panda_py.fci.Dialect`
(``command_ids``, ``encode_status``/``decode_status``), never with ``.value``.

Source: libfranka-common ``research_interface/robot/{service_types,rbk_types,error}.h``
at the commits pinned by libfranka 0.4.0-0.21.x (see ``robot.py``).
"""

from __future__ import annotations

import enum

__all__ = [
    "ERROR_NAMES",
    "ERROR_STRINGS",
    "STATE_GENERATOR_OF_MOVE",
    "Command",
    "CommandBaseStatus",
    "ConnectStatus",
    "ControllerMode",
    "ErrorRecoveryStatus",
    "GetterSetterStatus",
    "LoadModelLibraryArchitecture",
    "LoadModelLibraryStatus",
    "LoadModelLibrarySystem",
    "ModelLibraryArchitecture",
    "ModelLibrarySystem",
    "MotionGeneratorMode",
    "MoveControllerMode",
    "MoveMotionGeneratorMode",
    "MoveStatus",
    "RobotMode",
    "StopMoveStatus",
]


class Command(enum.Enum):
    """Robot TCP commands. The value is libfranka's display name (``CommandTraits::kName``)
    as used in its exception messages, e.g. "Set Joint Impedance command rejected: ..."."""

    CONNECT = "Connect"
    MOVE = "Move"
    STOP_MOVE = "Stop Move"
    GET_CARTESIAN_LIMIT = "Get Cartesian Limit"  # v3-v5
    SET_COLLISION_BEHAVIOR = "Set Collision Behavior"
    SET_JOINT_IMPEDANCE = "Set Joint Impedance"
    SET_CARTESIAN_IMPEDANCE = "Set Cartesian Impedance"
    SET_GUIDING_MODE = "Set Guiding Mode"
    SET_EE_TO_K = "Set EE to K"
    SET_F_TO_EE = "Set F to EE"  # v3 only; replaced by SET_NE_TO_EE in v4
    SET_NE_TO_EE = "Set NE to EE"  # v4+
    SET_LOAD = "Set Load"
    SET_FILTERS = "Set Filters"  # v3-v5
    AUTOMATIC_ERROR_RECOVERY = "Automatic Error Recovery"
    LOAD_MODEL_LIBRARY = "Load Model Library"  # v3-v9
    GET_ROBOT_MODEL = "Get Robot Model"  # v8+


# --- statuses (u8 on the wire). Values are libfranka-common's enumerator names. ---------


class ConnectStatus(enum.IntEnum):
    """Connect response status; identical numbering in every version."""

    SUCCESS = 0
    INCOMPATIBLE_LIBRARY_VERSION = 1
    #: panda-sim only: another client holds the robot. A robot admits one client at a
    #: time but publishes no status for refusing a second one; libfranka reports any
    #: status but 0 and 1 as a protocol error, this package's client as "robot busy".
    ROBOT_BUSY = 2


class ModelLibraryArchitecture(enum.IntEnum):
    """LoadModelLibrary's architecture field. Source: libfranka research_interface
    ``robot/service_types.h``, ``LoadModelLibrary::Architecture``."""

    X64 = 0
    X86 = 1
    ARM = 2
    ARM64 = 3


class ModelLibrarySystem(enum.IntEnum):
    """LoadModelLibrary's system field (``LoadModelLibrary::System`` in libfranka)."""

    LINUX = 0
    WINDOWS = 1


class LoadModelLibraryStatus(enum.IntEnum):
    """LoadModelLibrary response status (v3-v9); identical numbering in every version."""

    SUCCESS = 0
    ERROR = 1


class MoveStatus(enum.Enum):
    """Move response status (two responses per Move). v6 inserted the two safety codes
    after PREEMPTED, shifting everything behind them by two."""

    SUCCESS = "kSuccess"
    MOTION_STARTED = "kMotionStarted"
    PREEMPTED = "kPreempted"
    PREEMPTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = "kPreemptedDueToActivatedSafetyFunctions"
    COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = (
        "kCommandRejectedDueToActivatedSafetyFunctions"
    )
    COMMAND_NOT_POSSIBLE_REJECTED = "kCommandNotPossibleRejected"
    START_AT_SINGULAR_POSE_REJECTED = "kStartAtSingularPoseRejected"
    INVALID_ARGUMENT_REJECTED = "kInvalidArgumentRejected"
    REFLEX_ABORTED = "kReflexAborted"
    EMERGENCY_ABORTED = "kEmergencyAborted"
    INPUT_ERROR_ABORTED = "kInputErrorAborted"
    ABORTED = "kAborted"


class GetterSetterStatus(enum.Enum):
    """Status of the setters and GetCartesianLimit (v6 appended the safety code)."""

    SUCCESS = "kSuccess"
    COMMAND_NOT_POSSIBLE_REJECTED = "kCommandNotPossibleRejected"
    INVALID_ARGUMENT_REJECTED = "kInvalidArgumentRejected"
    COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = (
        "kCommandRejectedDueToActivatedSafetyFunctions"
    )


class StopMoveStatus(enum.Enum):
    """StopMove status (v6 inserted the safety code at 2)."""

    SUCCESS = "kSuccess"
    COMMAND_NOT_POSSIBLE_REJECTED = "kCommandNotPossibleRejected"
    COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = (
        "kCommandRejectedDueToActivatedSafetyFunctions"
    )
    EMERGENCY_ABORTED = "kEmergencyAborted"
    REFLEX_ABORTED = "kReflexAborted"
    ABORTED = "kAborted"


class ErrorRecoveryStatus(enum.Enum):
    """AutomaticErrorRecovery status (v6 inserted the safety code at 2)."""

    SUCCESS = "kSuccess"
    COMMAND_NOT_POSSIBLE_REJECTED = "kCommandNotPossibleRejected"
    COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = (
        "kCommandRejectedDueToActivatedSafetyFunctions"
    )
    MANUAL_ERROR_RECOVERY_REQUIRED_REJECTED = "kManualErrorRecoveryRequiredRejected"
    REFLEX_ABORTED = "kReflexAborted"
    EMERGENCY_ABORTED = "kEmergencyAborted"
    ABORTED = "kAborted"


class CommandBaseStatus(enum.Enum):
    """Status of commands without their own enum (GetRobotModel, v8+)."""

    SUCCESS = "kSuccess"
    COMMAND_NOT_POSSIBLE_REJECTED = "kCommandNotPossibleRejected"
    COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS = (
        "kCommandRejectedDueToActivatedSafetyFunctions"
    )


class LoadModelLibraryArchitecture(enum.IntEnum):
    """LoadModelLibrary request: the client's CPU (X86 from libfranka 0.6, ARM* from 0.7.1)."""

    X64 = 0
    X86 = 1
    ARM = 2
    ARM64 = 3


class LoadModelLibrarySystem(enum.IntEnum):
    """LoadModelLibrary request: the client's OS (WINDOWS from libfranka 0.6)."""

    LINUX = 0
    WINDOWS = 1


# --- modes ---------------------------------------------------------------------------


class MoveControllerMode(enum.IntEnum):
    """Controller requested by a Move (u32 in the request)."""

    JOINT_IMPEDANCE = 0
    CARTESIAN_IMPEDANCE = 1
    EXTERNAL_CONTROLLER = 2


class MoveMotionGeneratorMode(enum.IntEnum):
    """Motion generator requested by a Move (u32). Note: no IDLE here, unlike the state's
    :class:`MotionGeneratorMode`, so every number is one less. NONE exists from v7 on."""

    JOINT_POSITION = 0
    JOINT_VELOCITY = 1
    CARTESIAN_POSITION = 2
    CARTESIAN_VELOCITY = 3
    NONE = 4


class RobotMode(enum.IntEnum):
    """``RobotState.robot_mode`` (u8)."""

    OTHER = 0
    IDLE = 1
    MOVE = 2
    GUIDING = 3
    REFLEX = 4
    USER_STOPPED = 5
    AUTOMATIC_ERROR_RECOVERY = 6


class MotionGeneratorMode(enum.IntEnum):
    """``RobotState.motion_generator_mode`` (u8). NONE exists from v7 on."""

    IDLE = 0
    JOINT_POSITION = 1
    JOINT_VELOCITY = 2
    CARTESIAN_POSITION = 3
    CARTESIAN_VELOCITY = 4
    NONE = 5


class ControllerMode(enum.IntEnum):
    """``RobotState.controller_mode`` (u8)."""

    JOINT_IMPEDANCE = 0
    CARTESIAN_IMPEDANCE = 1
    EXTERNAL_CONTROLLER = 2
    OTHER = 3


# --- error flags ----------------------------------------------------------------------

#: The 41 ``errors``/``reflex_reason`` flags in wire order (v5+), named like the attributes
#: of libfranka's ``franka::Errors``. v3/v4 carry only the first 37 (the last four were
#: appended in v5); see ``Dialect.error_names``.
ERROR_NAMES: tuple[str, ...] = (
    "joint_position_limits_violation",
    "cartesian_position_limits_violation",
    "self_collision_avoidance_violation",
    "joint_velocity_violation",
    "cartesian_velocity_violation",
    "force_control_safety_violation",
    "joint_reflex",
    "cartesian_reflex",
    "max_goal_pose_deviation_violation",
    "max_path_pose_deviation_violation",
    "cartesian_velocity_profile_safety_violation",
    "joint_position_motion_generator_start_pose_invalid",
    "joint_motion_generator_position_limits_violation",
    "joint_motion_generator_velocity_limits_violation",
    "joint_motion_generator_velocity_discontinuity",
    "joint_motion_generator_acceleration_discontinuity",
    "cartesian_position_motion_generator_start_pose_invalid",
    "cartesian_motion_generator_elbow_limit_violation",
    "cartesian_motion_generator_velocity_limits_violation",
    "cartesian_motion_generator_velocity_discontinuity",
    "cartesian_motion_generator_acceleration_discontinuity",
    "cartesian_motion_generator_elbow_sign_inconsistent",
    "cartesian_motion_generator_start_elbow_invalid",
    "force_controller_desired_force_tolerance_violation",
    "start_elbow_sign_inconsistent",
    "communication_constraints_violation",
    "power_limit_violation",
    "cartesian_motion_generator_joint_position_limits_violation",
    "cartesian_motion_generator_joint_velocity_limits_violation",
    "cartesian_motion_generator_joint_velocity_discontinuity",
    "cartesian_motion_generator_joint_acceleration_discontinuity",
    "cartesian_position_motion_generator_invalid_frame",
    "controller_torque_discontinuity",
    "joint_p2p_insufficient_torque_for_planning",
    "tau_J_range_violation",
    "instability_detected",
    "joint_move_in_wrong_direction",
    "cartesian_spline_motion_generator_violation",
    "joint_via_motion_generator_planning_joint_limit_violation",
    "base_acceleration_initialization_timeout",
    "base_acceleration_invalid_reading",
)

#: The same flags as libfranka *prints* them (``getErrorName`` in libfranka-common's
#: error.h, used by ``std::string(franka::Errors)`` and so in "motion aborted by reflex!
#: [...]" messages). It differs from :data:`ERROR_NAMES` in one entry: index 31 is printed
#: "cartesian_position_motion_generator_invalid_frame_flag".
ERROR_STRINGS: tuple[str, ...] = tuple(
    name + "_flag" if name == "cartesian_position_motion_generator_invalid_frame" else name
    for name in ERROR_NAMES
)


#: The state's ``motion_generator_mode`` once a Move with this generator runs.
STATE_GENERATOR_OF_MOVE: dict[MoveMotionGeneratorMode, MotionGeneratorMode] = {
    MoveMotionGeneratorMode.JOINT_POSITION: MotionGeneratorMode.JOINT_POSITION,
    MoveMotionGeneratorMode.JOINT_VELOCITY: MotionGeneratorMode.JOINT_VELOCITY,
    MoveMotionGeneratorMode.CARTESIAN_POSITION: MotionGeneratorMode.CARTESIAN_POSITION,
    MoveMotionGeneratorMode.CARTESIAN_VELOCITY: MotionGeneratorMode.CARTESIAN_VELOCITY,
    MoveMotionGeneratorMode.NONE: MotionGeneratorMode.NONE,
}
