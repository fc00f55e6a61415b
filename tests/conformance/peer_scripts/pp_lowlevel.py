"""panda-python 1.1.1 (libfranka 0.9.2, protocol v5): the low-level ``libfranka`` API.

Usage: pp_lowlevel.py HOST. Scenarios run in order on one connection; see
test_conf_pandapy.py for what is asserted.
"""

from __future__ import annotations

import math
import sys
import time

from peer_io import Scenarios, event, floats

from panda_py import libfranka

HOST = sys.argv[1]
robot = libfranka.Robot(HOST)


def fresh():
    """A state sent after everything done so far. libfranka's read_once returns the newest
    datagram queued in its UDP socket, and while nobody reads the kernel keeps the oldest
    ~100 ms and drops the rest (a real robot's states queue the same way); a state queued
    before a setter's reply also predates the setter. The first read empties the queue,
    the second waits for the next tick."""
    robot.read_once()
    return robot.read_once()


def gripper_fresh(g):
    """The gripper's newest state (its datagrams queue like the robot's, see fresh())."""
    g.read_once()
    return g.read_once()


def cosine_move(joint: int, delta: float, duration: float, on_tick=None):
    """A libfranka-example style motion: q0 + delta (1 - cos(pi t / T)) / 2."""
    info = {"n": 0, "t": 0.0, "q0": None}

    def cb(state, dt):
        info["t"] += dt.to_sec()
        info["n"] += 1
        if info["q0"] is None:
            info["q0"] = list(state.q_d)
        if on_tick is not None:
            on_tick(info["n"])
        t = min(info["t"], duration)
        q = list(info["q0"])
        q[joint] += delta * (1.0 - math.cos(math.pi * t / duration)) / 2.0
        out = libfranka.JointPositions(q)
        if info["t"] >= duration:
            out.motion_finished = True
        return out

    robot.control_joint_position(cb)
    return info


def read_once():
    s = fresh()
    return {
        "server_version": robot.server_version(),
        "q": floats(s.q),
        "robot_mode": s.robot_mode.name,
        "O_T_EE": floats(s.O_T_EE),
        "errors": bool(s.current_errors),
    }


def joint_position():
    q_before = floats(fresh().q)
    start = time.monotonic()
    info = cosine_move(0, 0.2, 2.0)
    wall = time.monotonic() - start
    s = fresh()
    return {
        "q_before": q_before,
        "q_after": floats(s.q),
        "callbacks": info["n"],
        "sim_time": info["t"],
        "wall": wall,
        "robot_mode": s.robot_mode.name,
    }


def torque():
    s0 = fresh()
    q0 = floats(s0.q)
    kp, kd = [60.0, 60.0, 60.0, 60.0, 25.0, 15.0, 5.0], [5.0, 5.0, 5.0, 5.0, 2.0, 2.0, 1.0]
    phase = {"name": "hold", "t": 0.0, "n": 0, "max_dev": 0.0}

    def cb(state, dt):
        phase["t"] += dt.to_sec()
        phase["n"] += 1
        q, dq = state.q, state.dq
        tau = [-kp[i] * (q[i] - q0[i]) - kd[i] * dq[i] for i in range(7)]
        if phase["name"] == "hold":
            phase["max_dev"] = max(phase["max_dev"], max(abs(q[i] - q0[i]) for i in range(7)))
        else:  # joint 1 free, pushed by a full-period sine (net impulse zero) of more
            # than its dry friction (a FER: 0.27 Nm)
            tau[0] = 2.0 * math.sin(2.0 * math.pi * min(phase["t"], 1.0))
        out = libfranka.Torques(tau)
        if phase["t"] >= 1.0:
            out.motion_finished = True
        return out

    robot.control(cb)
    hold = {"callbacks": phase["n"], "max_dev": phase["max_dev"]}
    q_hold_end = floats(fresh().q)
    phase.update(name="push", t=0.0, n=0)
    robot.control(cb)
    s = fresh()
    time.sleep(0.2)  # the arm must stay where the torque motion left it
    q_settled = floats(fresh().q)
    return {
        "q_settled": q_settled,
        "q0": q0,
        "hold": hold,
        "q_hold_end": q_hold_end,
        "push_callbacks": phase["n"],
        "q_push_end": floats(s.q),
        "robot_mode": s.robot_mode.name,
    }


def reflex_recovery():
    def on_tick(n):
        if n == 300:
            event("in_motion", {"callbacks": n})

    out = {}
    try:
        cosine_move(0, -0.1, 10.0, on_tick)
        out["exception_type"] = None
    except Exception as exc:  # the peer's own ControlException type
        out["exception_type"] = type(exc).__name__
        out["exception"] = str(exc)
    s = fresh()
    out["mode_after_reflex"] = s.robot_mode.name
    out["errors_after_reflex"] = str(s.current_errors)
    out["last_motion_errors"] = str(s.last_motion_errors)
    robot.automatic_error_recovery()
    s = fresh()
    out["mode_after_recovery"] = s.robot_mode.name
    out["errors_after_recovery"] = bool(s.current_errors)
    q_before = floats(s.q)
    info = cosine_move(0, -0.05, 0.5)
    out["q_before_new_motion"] = q_before
    out["q_after_new_motion"] = floats(fresh().q)
    out["new_motion_callbacks"] = info["n"]
    return out


def setters():
    lower_t, upper_t = [20.0] * 7, [40.0] * 7
    lower_f, upper_f = [20.0] * 6, [40.0] * 6
    robot.set_collision_behavior(lower_t, upper_t, lower_t, upper_t,
                                 lower_f, upper_f, lower_f, upper_f)  # fmt: skip
    robot.set_collision_behavior(lower_t, upper_t, lower_f, upper_f)
    robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    robot.set_cartesian_impedance([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])
    NE_T_EE = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.01, 0.0, 0.02, 1.0]
    EE_T_K = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.0, 0.0, 0.05, 1.0]
    robot.set_ee(NE_T_EE)
    robot.set_k(EE_T_K)
    robot.set_load(0.5, [0.0, 0.0, 0.05], [0.001, 0, 0, 0, 0.001, 0, 0, 0, 0.001])
    robot.set_guiding_mode([True, True, True, False, False, False], False)
    s = fresh()
    out = {  # panda-python's RobotState has no NE_T_EE; F_T_EE = F_T_NE NE_T_EE shows it
        "F_T_EE": floats(s.F_T_EE),
        "EE_T_K": floats(s.EE_T_K),
        "m_load": float(s.m_load),
        "F_x_Cload": floats(s.F_x_Cload),
        "robot_mode": s.robot_mode.name,
    }
    event("setters_applied")
    identity = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]
    robot.set_ee(identity)
    robot.set_k(identity)
    robot.set_load(0.0, [0.0, 0.0, 0.0], [0.0] * 9)
    out["F_T_EE_restored"] = floats(fresh().F_T_EE)
    return out


def gripper():
    g = libfranka.Gripper(HOST)
    out = {"server_version": g.server_version()}
    out["homing"] = g.homing()
    st = gripper_fresh(g)
    out["width_homed"], out["max_width"] = st.width, st.max_width
    out["move"] = g.move(0.05, 0.1)
    out["width_moved"] = gripper_fresh(g).width
    out["grasp_air"] = g.grasp(0.03, 0.1, 20.0, 0.005, 0.005)
    out["width_air"] = gripper_fresh(g).width
    out["open"] = g.move(0.08, 0.1)
    event("teleport_to_cube")
    out["grasp_cube"] = g.grasp(0.04, 0.05, 20.0, 0.01, 0.01)
    st = gripper_fresh(g)
    out["width_cube"], out["is_grasped"] = st.width, st.is_grasped
    out["release"] = g.move(0.08, 0.1)
    out["width_released"] = gripper_fresh(g).width
    event("teleport_home")
    return out


runs = Scenarios()
runs.run("read_once", read_once)
runs.run("joint_position", joint_position)
runs.run("torque", torque)
runs.run("reflex_recovery", reflex_recovery)
runs.run("setters", setters)
runs.run("gripper", gripper)
runs.finish()
