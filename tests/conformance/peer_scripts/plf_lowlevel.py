"""pylibfranka 0.21.3 (libfranka 0.21.3, protocol v10): the active-control API
(start_*_control -> readOnce/writeOnce), setters, reflex recovery, Model, Gripper.

Usage: plf_lowlevel.py HOST. See test_conf_pylibfranka.py for what is asserted.
"""

from __future__ import annotations

import math
import sys
import time

import pylibfranka as plf
from peer_io import Scenarios, event, floats

HOST = sys.argv[1]
robot = plf.Robot(HOST, plf.RealtimeConfig.kIgnore)


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


def mode(state) -> str:
    return state.robot_mode.name


def cosine_move(joint: int, delta: float, duration: float, on_tick=None):
    """q0 + delta (1 - cos(pi t / T)) / 2 through readOnce/writeOnce."""
    ctrl = robot.start_joint_position_control(plf.ControllerMode.JointImpedance)
    t, n, q0 = 0.0, 0, None
    while True:
        state, dt = ctrl.readOnce()
        t += dt.to_sec()
        n += 1
        if q0 is None:
            q0 = list(state.q_d)
        if on_tick is not None:
            on_tick(n)
        q = list(q0)
        q[joint] += delta * (1.0 - math.cos(math.pi * min(t, duration) / duration)) / 2.0
        cmd = plf.JointPositions(q)
        if t >= duration:
            cmd.motion_finished = True
            ctrl.writeOnce(cmd)
            return {"n": n, "t": t}
        ctrl.writeOnce(cmd)


def read_once():
    s = fresh()
    return {
        "q": floats(s.q),
        "robot_mode": mode(s),
        "O_T_EE": floats(s.O_T_EE),
        "F_T_EE": floats(s.F_T_EE),
        "errors": bool(s.current_errors),
    }


def joint_position():
    q_before = floats(fresh().q)
    info = cosine_move(0, 0.2, 2.0)
    s = fresh()
    return {
        "q_before": q_before,
        "q_after": floats(s.q),
        "callbacks": info["n"],
        "sim_time": info["t"],
        "robot_mode": mode(s),
    }


def torque_phase(q0, push: bool):
    kp, kd = [60.0, 60.0, 60.0, 60.0, 25.0, 15.0, 5.0], [5.0, 5.0, 5.0, 5.0, 2.0, 2.0, 1.0]
    ctrl = robot.start_torque_control()
    t, n, max_dev = 0.0, 0, 0.0
    while True:
        state, dt = ctrl.readOnce()
        t += dt.to_sec()
        n += 1
        q, dq = state.q, state.dq
        tau = [-kp[i] * (q[i] - q0[i]) - kd[i] * dq[i] for i in range(7)]
        if push:  # joint 1 free, pushed by a full-period sine (net impulse zero) of more
            # than its dry friction (an FR3: 1.1 Nm)
            tau[0] = 4.0 * math.sin(2.0 * math.pi * min(t, 1.0))
        else:
            max_dev = max(max_dev, max(abs(q[i] - q0[i]) for i in range(7)))
        cmd = plf.Torques(tau)
        if t >= 1.0:
            cmd.motion_finished = True
            ctrl.writeOnce(cmd)
            return {"callbacks": n, "max_dev": max_dev}
        ctrl.writeOnce(cmd)


def torque():
    q0 = floats(fresh().q)
    hold = torque_phase(q0, push=False)
    q_hold_end = floats(fresh().q)
    push = torque_phase(q0, push=True)
    s = fresh()
    time.sleep(0.2)  # the arm must stay where the torque motion left it
    q_settled = floats(fresh().q)
    return {
        "q_settled": q_settled,
        "q0": q0,
        "hold": hold,
        "q_hold_end": q_hold_end,
        "push_callbacks": push["callbacks"],
        "q_push_end": floats(s.q),
        "robot_mode": mode(s),
    }


def reflex_recovery():
    def on_tick(n):
        if n == 300:
            event("in_motion", {"callbacks": n})

    out = {}
    try:
        cosine_move(0, -0.1, 10.0, on_tick)
        out["exception_type"] = None
    except Exception as exc:
        out["exception_type"] = type(exc).__name__
        out["exception"] = str(exc)
    s = fresh()
    out["mode_after_reflex"] = mode(s)
    out["errors_after_reflex"] = str(s.current_errors)
    out["last_motion_errors"] = str(s.last_motion_errors)
    robot.automatic_error_recovery()
    s = fresh()
    out["mode_after_recovery"] = mode(s)
    out["errors_after_recovery"] = bool(s.current_errors)
    out["q_before_new_motion"] = floats(s.q)
    info = cosine_move(0, -0.05, 0.5)
    out["q_after_new_motion"] = floats(fresh().q)
    out["new_motion_callbacks"] = info["n"]
    return out


def setters():
    robot.set_collision_behavior([20.0] * 7, [40.0] * 7, [20.0] * 6, [40.0] * 6)
    robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    robot.set_cartesian_impedance([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])
    NE_T_EE = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.01, 0.0, 0.02, 1.0]
    EE_T_K = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.0, 0.0, 0.05, 1.0]
    robot.set_EE(NE_T_EE)
    robot.set_K(EE_T_K)
    robot.set_load(0.5, [0.0, 0.0, 0.05], [0.001, 0, 0, 0, 0.001, 0, 0, 0, 0.001])
    s = fresh()
    out = {
        "NE_T_EE": floats(s.NE_T_EE),
        "F_T_EE": floats(s.F_T_EE),
        "EE_T_K": floats(s.EE_T_K),
        "m_load": float(s.m_load),
        "F_x_Cload": floats(s.F_x_Cload),
        "robot_mode": mode(s),
    }
    event("setters_applied")
    identity = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]
    robot.set_EE(identity)
    robot.set_K(identity)
    robot.set_load(0.0, [0.0, 0.0, 0.0], [0.0] * 9)
    out["NE_T_EE_restored"] = floats(fresh().NE_T_EE)
    return out


def model():
    m = robot.load_model()
    samples = []
    for i in range(3):
        event("model_pose", i)
        s = fresh()
        samples.append(
            {
                "q": floats(s.q),
                "O_T_EE": floats(s.O_T_EE),
                "F_T_EE": floats(s.F_T_EE),
                "m_total": float(s.m_total),
                "F_x_Ctotal": floats(s.F_x_Ctotal),
                "I_total": floats(s.I_total),
                "gravity": floats(m.gravity(s)),
                "mass": floats(m.mass(s)),
                "zero_jacobian": floats(m.zero_jacobian(s)),
            }
        )
    return {"samples": samples}


def gripper():
    g = plf.Gripper(HOST)
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
runs.run("model", model)
runs.run("gripper", gripper)
runs.finish()
