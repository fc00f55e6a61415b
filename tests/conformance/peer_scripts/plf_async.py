"""pylibfranka 0.21.3 (protocol v10): asynchronous position control
(``AsyncPositionControlHandler``) as its example program documents it: from the start
pose, targets start pose +/- 0.25 rad on every joint, sent at 50 Hz, the sign flipping
every second of loop time; feedback read before each target; stop_control after DURATION
seconds of loop time. Then a reflex during async control must surface as feedback with an
error message.

Usage: plf_async.py HOST [DURATION]. See test_conf_pylibfranka_async.py for the asserts.
"""

from __future__ import annotations

import math
import sys
import time

import pylibfranka as plf
from peer_io import Scenarios, event, floats

HOST = sys.argv[1]
DURATION = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
MAX_VELOCITY = [0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315]  # the example's values
INITIAL = [0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]
PERIOD = 0.020  # [s] 50 Hz

robot = plf.Robot(HOST, plf.RealtimeConfig.kIgnore)


def default_behaviour() -> None:
    """The example's setDefaultBehaviour: thresholds and impedances."""
    robot.set_collision_behavior([20.0] * 7, [40.0] * 7, [10.0] * 6, [20.0] * 6)
    robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    robot.set_cartesian_impedance([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])


def configure(goal_tolerance: float):
    config = plf.AsyncPositionControlHandler.Configuration(
        maximum_joint_velocities=MAX_VELOCITY, goal_tolerance=goal_tolerance
    )
    return plf.AsyncPositionControlHandler.configure(robot, config)


def target(direction: float):
    q = [q0 + direction * 0.25 for q0 in INITIAL]
    return plf.AsyncPositionControlHandler.JointPositionTarget(joint_positions=q)


def fresh_q() -> list:
    """Joint positions of a state sent after everything so far (the first read empties
    the queued states, the second waits for the next)."""
    robot.read_once()
    return floats(robot.read_once().q)


def example_loop() -> dict:
    default_behaviour()
    result = configure(10.0)  # the example's (generous) goal tolerance
    if result.error_message is not None:
        return {"configure_error": result.error_message}
    handler = result.handler
    elapsed, since_flip, direction = 0.0, 0.0, 1.0
    feedback_errors, command_errors, unsuccessful, iterations = [], [], 0, 0
    flips = []
    while True:
        start = time.monotonic()
        feedback = handler.get_target_feedback()
        if feedback.error_message is not None:
            feedback_errors.append(feedback.error_message)
            break
        elapsed += PERIOD
        since_flip += PERIOD
        next_target = target(direction)
        if since_flip >= 1.0:
            # the test looks at the robot just before the direction changes
            flips.append({"direction": direction, "iteration": iterations})
            event("flip", direction)
            direction *= -1.0
            since_flip = 0.0
        command = handler.set_joint_position_target(next_target)
        iterations += 1
        if command.error_message is not None:
            command_errors.append(command.error_message)
            break
        unsuccessful += not command.was_successful
        if elapsed > DURATION:
            handler.stop_control()
            break
        pause = PERIOD - (time.monotonic() - start)
        if pause > 0:
            time.sleep(pause)
    robot.read_once()
    state = robot.read_once()
    return {
        "iterations": iterations,
        "feedback_errors": feedback_errors,
        "command_errors": command_errors,
        "unsuccessful": unsuccessful,
        "flips": flips,
        "mode_after_stop": state.robot_mode.name,
        "errors_after_stop": bool(state.current_errors),
        "q_after_stop": floats(state.q),
        "dq_after_stop": floats(state.dq),
    }


def reflex_surfaces() -> dict:
    result = configure(0.001)
    if result.error_message is not None:
        return {"configure_error": result.error_message}
    handler = result.handler
    before = handler.get_target_feedback().error_message
    q = fresh_q()
    q[0] += 0.05
    sent = handler.set_joint_position_target(
        plf.AsyncPositionControlHandler.JointPositionTarget(joint_positions=q)
    )
    time.sleep(0.1)
    event("reflex")
    message = None
    for _ in range(100):  # the reflex shows in the next states
        message = handler.get_target_feedback().error_message
        if message is not None:
            break
        time.sleep(PERIOD)
    again = handler.set_joint_position_target(
        plf.AsyncPositionControlHandler.JointPositionTarget(joint_positions=q)
    )
    del handler, result  # ends the active control and frees the robot for recovery
    robot.automatic_error_recovery()
    robot.read_once()
    state = robot.read_once()
    return {
        "before": before,
        "sent": sent.was_successful,
        "message": message,
        "again_error": again.error_message,
        "mode_after_recovery": state.robot_mode.name,
    }


scenarios = Scenarios()
scenarios.run("example_loop", example_loop)
scenarios.run("reflex_surfaces", reflex_surfaces)
scenarios.finish()
