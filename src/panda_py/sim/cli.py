"""``panda-sim``: run a simulated Franka until interrupted.

    panda-sim --host 127.0.0.1 --robot fer --lockstep
    panda-sim --end-effector cobot-pump

Clients connect to HOST (FCI on 1337, the gripper on 1338, or with the Cobot Pump the
vacuum gripper on 1339) as to a real robot.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from collections.abc import Sequence
from types import FrameType

from panda_py import checks, fci
from panda_py.robots.end_effectors import END_EFFECTOR_CHOICES
from panda_py.robots.params import ROBOTS
from panda_py.sim.desk.launch import add_desk_arguments, start_desk
from panda_py.sim.drawing import DrawingProcess
from panda_py.sim.drawings import start_drawing, stop_drawing
from panda_py.sim.video import DEFAULT_FPS, check_record


def _cpu_list(text: str) -> tuple[int, ...]:
    """``--cpus``: a CPU list as the kernel and taskset write it (checked against the
    machine's by SimConfig)."""
    try:
        return tuple(sorted(checks.cpu_set(text)))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected CPU numbers separated by commas (e.g. 1, 0,1 or 0-3), got {text!r}"
        ) from None


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="panda-sim",
        description="A simulated Franka robot (FER or FR3) speaking the real FCI protocol.",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default %(default)s)")
    p.add_argument("--robot", default="fer", choices=sorted(ROBOTS), help="arm (default fer)")
    p.add_argument(
        "--end-effector",
        default="hand",
        choices=END_EFFECTOR_CHOICES,
        metavar="EE",
        help="what the flange carries: hand (the Franka Hand, TCP 1338) or cobot-pump "
        "(Franka's Cobot Pump, TCP 1339) (default hand)",
    )
    p.add_argument(
        "--lockstep",
        action="store_true",
        help="advance simulated time one tick per received command during motions",
    )
    p.add_argument(
        "--lockstep-timeout",
        type=float,
        default=2.0,
        metavar="S",
        help="lockstep: seconds to wait for a command before counting it lost",
    )
    p.add_argument(
        "--lockstep-spin",
        type=float,
        default=300.0,
        metavar="US",
        help="lockstep: microseconds to poll for a command before sleeping (0: never poll)",
    )
    p.add_argument(
        "--lockstep-max-speed",
        type=float,
        default=None,
        metavar="X",
        help="lockstep: run simulated time at most X times as fast as the wall clock "
        "(1: never ahead of it; default: as fast as the client answers)",
    )
    p.add_argument(
        "--cpus",
        type=_cpu_list,
        default=None,
        metavar="LIST",
        help="run on these CPUs only, e.g. 1 or 0-1 (the core the client's control loop is "
        "pinned to)",
    )
    p.add_argument(
        "--version",
        type=int,
        action="append",
        dest="versions",
        choices=fci.SUPPORTED_VERSIONS,
        metavar="N",
        help="accept only this FCI protocol version (repeatable; default: those the robot's "
        "systems speak: fer 3-5, fr3 10, fr3-pre-5.9 6-9)",
    )
    p.add_argument("--no-scene", action="store_true", help="no table and cube")
    p.add_argument("--scene", metavar="MJCF", help="add the bodies of this MJCF file")
    p.add_argument(
        "--viewer",
        action="store_true",
        help="open MuJoCo's viewer on the robot (needs a display: $DISPLAY, or xvfb-run)",
    )
    p.add_argument(
        "--record",
        metavar="FILE.mp4",
        help="write a video of the run, drawn offscreen (needs panda-py-pure[video])",
    )
    p.add_argument(
        "--record-fps",
        type=float,
        default=DEFAULT_FPS,
        metavar="FPS",
        help="video frames per simulated second (default %(default)g)",
    )
    p.add_argument("--log-level", default="INFO", help="logging level (default %(default)s)")
    add_desk_arguments(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="panda-sim %(levelname)s: %(message)s")
    from panda_py.sim.server import SimConfig, SimServer, pin

    desk = None
    drawing: list[DrawingProcess] = []
    try:
        if args.record is not None:
            check_record(args.record, args.record_fps)
        config = SimConfig(
            host=args.host,
            robot=args.robot,
            lockstep=args.lockstep,
            lockstep_timeout=args.lockstep_timeout,
            lockstep_spin=args.lockstep_spin * 1e-6,
            lockstep_max_speed=args.lockstep_max_speed,
            cpus=args.cpus,
            versions=tuple(args.versions) if args.versions else None,
            scene=not args.no_scene,
            extra=args.scene,
            end_effector=args.end_effector,
        )
        drawing = start_drawing(
            config, viewer=args.viewer, record=args.record, fps=args.record_fps, timeout=60.0
        )
        desk, config.desk_link = start_desk(args, config.host, config.robot)
        pin(config.cpus)
        server = SimServer(config)
    except (ValueError, OSError, RuntimeError) as exc:  # DrawingError too: one line
        print(f"panda-sim: {exc}", file=sys.stderr)
        if desk is not None:
            desk.stop()
        stop_drawing(drawing)
        return 2

    def stop(signum: int, frame: FrameType | None) -> None:
        server.shutdown()

    if not args.lockstep:
        from panda_py.sim.server import raise_priority

        raise_priority()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    mode = "lockstep" if args.lockstep else "realtime"
    tool = "gripper 1338" if server.pump is None else "cobot pump 1339"
    logging.getLogger("panda_py.sim").info(
        "simulated %s on %s (FCI 1337, %s), %s; Ctrl-C to stop",
        server.spec.name,
        args.host,
        tool,
        mode,
    )
    try:
        server.serve_forever()
    finally:
        if desk is not None:
            desk.stop()
        stop_drawing(drawing)  # the video is finished here, after the last tick
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
