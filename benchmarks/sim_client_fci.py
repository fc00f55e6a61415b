"""A minimal pure-Python FCI torque client for benchmarking simulators (run as a script).

It speaks robot protocol v10 or v5 with nothing but :mod:`panda_py.fci` (no libfranka, no
``panda_py.libfranka``): Connect, wait for a state, Move (external controller; motion
generator NONE on v10, JointVelocity with zero velocities on v5, deviations
``fci.DEFAULT_DEVIATION``), then answer every state with a RobotCommand carrying its
``message_id`` and the torques of a weak joint PD holding the start pose for ``--duration``
wall seconds, finish (``torque_command_finished`` on v10, ``motion_generation_finished`` on
v5), keep answering until the robot leaves Move and read the Move's final response.

It prints one JSON object on stdout (times in milliseconds):

* ``periods``: state inter-arrival times at the client (the simulator's tick periods as
  seen on the wire), with ``late_share`` = share of periods > 1.5 ms;
* ``response``: receive -> command sent (this client's own work);
* ``round_trip``: command sent -> next state received (the simulator's side of the loop);
* ``rtf``: simulated time per wall time, from the state ``message_id`` (1 per ms);
* ``skipped``: states the client never answered (message_id gaps plus drained backlog).

Run: ``python benchmarks/sim_client_fci.py HOST [--version 10|5] [--duration S]``.
"""

from __future__ import annotations

import argparse
import gc
import json
import socket
import struct
import sys
import time
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import (
    Command,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveStatus,
    RobotMode,
)

LATE_PERIOD = 1.5e-3  # [s] a state arriving this long after the previous one counts as late


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    data = bytearray()
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("robot closed the TCP connection")
        data += chunk
    return bytes(data)


def _recv_message(sock: socket.socket) -> tuple[int, int, bytes]:
    """One TCP message: (command, command_id, payload)."""
    command, command_id, size = fci.decode_header(_recv_exact(sock, fci.HEADER.size))
    return command, command_id, _recv_exact(sock, size - fci.HEADER.size)


def _summary(values_s: np.ndarray) -> dict[str, float]:
    if values_s.size == 0:
        return {"n": 0}
    ms = values_s * 1e3
    return {
        "n": int(ms.size),
        "median": float(np.median(ms)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
    }


def run(host: str, version: int, duration: float, kp: float, kd: float) -> dict[str, Any]:
    d = fci.dialect(version)
    torque_only = d.has_motion_generator_none
    move_mg = (
        MoveMotionGeneratorMode.NONE if torque_only else MoveMotionGeneratorMode.JOINT_VELOCITY
    )
    state_mg = MotionGeneratorMode.NONE if torque_only else MotionGeneratorMode.JOINT_VELOCITY

    tcp = socket.create_connection((host, fci.COMMAND_PORT), timeout=10.0)
    tcp.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind((tcp.getsockname()[0], 0))  # the address the robot sees us at (loopback)
    # Blocking socket with a kernel receive timeout: MSG_DONTWAIT then really does not
    # wait (Python would poll on a socket with a Python-level timeout), and a vanished
    # robot still ends a blocking receive after 5 s (as BlockingIOError).
    udp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, struct.pack("ll", 5, 0))
    buf = bytearray(4096)
    state_size = d.state_size

    # Connect: the response layout is read leniently (status is its first byte) so that
    # simulators with a padded response can be benchmarked too.
    tcp.sendall(fci.encode_connect_request(version, udp.getsockname()[1], command_id=0))
    _, _, payload = _recv_message(tcp)
    if not payload or payload[0] != 0:
        raise RuntimeError(f"Connect rejected: response payload {payload.hex()}")

    def recv_state() -> tuple[np.void, tuple[str, int]]:
        try:
            n, addr = udp.recvfrom_into(buf)
        except BlockingIOError:
            raise TimeoutError("no robot state for 5 s") from None
        if n < state_size:
            raise RuntimeError(f"state datagram of {n} bytes, expected {state_size}")
        return d.decode_state(buf), addr

    state, robot_addr = recv_state()
    q0 = np.array(state["q"], dtype=float)

    move_id = 1
    tcp.sendall(
        d.encode_request(
            Command.MOVE,
            move_id,
            controller_mode=int(MoveControllerMode.EXTERNAL_CONTROLLER),
            motion_generator_mode=int(move_mg),
            maximum_path_deviation=fci.DEFAULT_DEVIATION,
            maximum_goal_pose_deviation=fci.DEFAULT_DEVIATION,
        )
    )
    _, cid, payload = _recv_message(tcp)
    status, _ = d.decode_response(Command.MOVE, payload)
    if cid != move_id or status is not MoveStatus.MOTION_STARTED:
        raise RuntimeError(f"Move not started: command_id {cid}, status {status}")

    # Wait for the first state that shows the motion's modes (drain the handshake backlog).
    deadline = time.monotonic() + 5.0
    while True:
        state, robot_addr = recv_state()
        if (
            int(state["robot_mode"]) == RobotMode.MOVE
            and int(state["motion_generator_mode"]) == state_mg
            and int(state["controller_mode"]) == ControllerMode.EXTERNAL_CONTROLLER
        ):
            break
        if time.monotonic() > deadline:
            raise RuntimeError("the robot never reported the motion's modes")

    cmd = d.new_command()
    finished_field = "torque_command_finished" if torque_only else "motion_generation_finished"
    t_recv: list[float] = []
    t_send: list[float] = []
    ids: list[int] = []
    drained = 0
    clock = time.perf_counter
    kp_v, kd_v = float(kp), float(kd)
    cpu0 = time.process_time()
    gc.collect()
    gc.disable()
    t_start = clock()
    t_end = t_start + duration
    finishing = False
    finish_deadline = float("inf")
    end_status: Any = None
    aborted: tuple[str, ...] = ()
    try:
        while True:
            tr = clock()
            mid = int(state["message_id"])
            if int(state["robot_mode"]) != RobotMode.MOVE:
                if not finishing:
                    aborted = d.active_errors(state["errors"]) or ("left Move",)
                break
            tau = kp_v * (q0 - state["q"]) - kd_v * state["dq"]
            cmd["message_id"] = mid
            cmd["tau_J_d"] = tau
            if not finishing and tr >= t_end:
                finishing = True
                cmd[finished_field] = True
                finish_deadline = tr + 2.0
            udp.sendto(cmd.tobytes(), robot_addr)
            ts = clock()
            if not finishing:
                t_recv.append(tr)
                t_send.append(ts)
                ids.append(mid)
            elif ts > finish_deadline:
                break
            state, _ = recv_state()
            # Answer the newest state only, like libfranka: drain any backlog.
            while True:
                try:
                    n = udp.recv_into(buf, 0, socket.MSG_DONTWAIT)
                except BlockingIOError:
                    break
                if n >= state_size:
                    drained += 1
                    state = d.decode_state(buf)
    finally:
        gc.enable()
    cpu = time.process_time() - cpu0
    tcp.settimeout(3.0)
    try:
        _, cid, payload = _recv_message(tcp)
        end_status, _ = d.decode_response(Command.MOVE, payload)
        end_status = end_status.name
    except (TimeoutError, ConnectionError, ValueError) as exc:
        end_status = f"no final Move response: {exc}"
    tcp.close()
    udp.close()

    tr_a, ts_a, id_a = np.array(t_recv), np.array(t_send), np.array(ids, dtype=np.int64)
    periods = np.diff(tr_a)
    wall = float(tr_a[-1] - tr_a[0]) if tr_a.size > 1 else 0.0
    sim_ms = int(id_a[-1] - id_a[0]) if id_a.size > 1 else 0
    return {
        "client": f"fci-v{version}",
        "states": int(tr_a.size),
        "wall_s": wall,
        "sim_s": sim_ms / 1000.0,
        "rtf": (sim_ms / 1000.0) / wall if wall > 0 else 0.0,
        "skipped": int(sim_ms + 1 - id_a.size) if id_a.size else 0,
        "drained": drained,
        "periods": {**_summary(periods), "late_share": float(np.mean(periods > LATE_PERIOD))}
        if periods.size
        else {"n": 0},
        "response": _summary(ts_a - tr_a),
        "round_trip": _summary(tr_a[1:] - ts_a[:-1]),
        "client_cpu_s": cpu,
        "final_status": end_status,
        "aborted": list(aborted),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("host", help="robot address (a loopback address)")
    parser.add_argument("--version", type=int, default=10, choices=(5, 10))
    parser.add_argument("--duration", type=float, default=10.0, help="control time [wall s]")
    parser.add_argument("--kp", type=float, default=10.0, help="PD stiffness [Nm/rad]")
    parser.add_argument("--kd", type=float, default=1.0, help="PD damping [Nm s/rad]")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s, got {args.duration}")
    result = run(args.host, args.version, args.duration, args.kp, args.kd)
    json.dump(result, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
