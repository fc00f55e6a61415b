"""Shared by the examples: the robot an example runs on.

``python examples/03_joint_motion_ik.py`` starts a simulated robot (panda-sim, in lockstep)
for the example and stops it afterwards; ``--host 172.16.0.2`` runs the same code on the
robot at that address instead. Each example's own code only ever sees a hostname.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator, Sequence

import panda_py


def _speed(text: str) -> float:
    """``--max-speed``'s value: a speed factor > 0."""
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not 0 < x < 1e6:
        raise argparse.ArgumentTypeError(f"expected a speed factor > 0, got {text!r}")
    return x


def _parser(
    description: str | None, options: Callable[[argparse.ArgumentParser], None] | None
) -> argparse.ArgumentParser:
    """The options every example shares (the simulated robot's), then the example's own."""
    parser = argparse.ArgumentParser(description=(description or "").strip().splitlines()[0])
    parser.add_argument("--robot", default="fer", choices=["fer", "fr3"], help="simulated robot")
    parser.add_argument("--realtime", action="store_true", help="simulate on the wall clock")
    parser.add_argument(
        "--max-speed",
        type=_speed,
        metavar="X",
        help="lockstep: the simulated robot's time runs at most X times as fast as the wall "
        "clock (1: the robot's own pace, still waiting for every command; default: as fast "
        "as the client answers, or 1 where the example's own loop keeps the wall clock)",
    )
    if options is not None:
        options(parser)
    return parser


def _check(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    if args.max_speed is not None and (args.realtime or args.host):
        parser.error("--max-speed: paces the lockstep simulator (not --realtime, not --host)")


def _max_speed(args: argparse.Namespace, paced: bool) -> float | None:
    """The lockstep robot's speed cap: ``--max-speed``, or the wall clock's pace for an
    example whose loop keeps the wall clock (``paced``)."""
    if args.max_speed is not None or args.realtime:
        return args.max_speed
    return 1.0 if paced else None


@contextlib.contextmanager
def robot_host(
    description: str | None,
    argv: Sequence[str] | None = None,
    options: Callable[[argparse.ArgumentParser], None] | None = None,
    *,
    desk: bool = False,
    camera: tuple[int, int] | None = None,
    paced: bool = False,
) -> Iterator[tuple[str, argparse.Namespace]]:
    """Parse the example's arguments and yield ``(hostname, args)``: ``--host`` if given,
    otherwise the address of a simulator started here (``--robot``, ``--realtime``,
    ``--max-speed``).
    ``desk``: the simulator also serves its Desk, locked as after power-up, and
    ``args.desk_host`` is its address (a real robot's Desk is at ``--host``).
    ``camera=(width, height)``: ``args.render()`` returns the simulator's image of the
    robot (None on a real robot: bring your own camera).
    ``paced``: the example's own loop keeps the wall clock (a ``PandaContext``), as it
    would beside a real robot, so the lockstep robot is held to the wall clock too
    (``--max-speed 1`` unless given): let loose, its time would run many times faster
    than the loop that feeds it, and every command would be held for many of the robot's
    milliseconds."""
    parser = _parser(description, options)
    parser.add_argument("--host", help="the robot's FCI address (default: a simulated robot)")
    args = parser.parse_args(argv)
    _check(parser, args)
    args.render = None
    if args.host:
        args.desk_host = args.host
        yield args.host, args
        return
    from panda_py.sim import Simulator, free_loopback_host
    from panda_py.sim.desk import DeskConfig

    config = DeskConfig(port=0, locked=True) if desk else None  # port 0: any free port
    with Simulator(
        free_loopback_host(),
        robot=args.robot,
        lockstep=not args.realtime,
        lockstep_max_speed=_max_speed(args, paced),
        desk=config,
        camera_size=camera,
    ) as sim:
        print(f"(a simulated {args.robot.upper()} on {sim.host})")
        args.desk_host = sim.desk.hostname if sim.desk is not None else sim.host
        if camera is not None:
            args.render = sim.render
        yield sim.host, args


@contextlib.contextmanager
def robot_hosts(
    description: str | None,
    count: int,
    argv: Sequence[str] | None = None,
    options: Callable[[argparse.ArgumentParser], None] | None = None,
    *,
    paced: bool = False,
) -> Iterator[tuple[list[str], argparse.Namespace]]:
    """:func:`robot_host` for ``count`` robots: ``--host A --host B`` (one per robot), or
    that many simulated robots started here (each its own simulator, as each real arm
    is its own robot)."""
    parser = _parser(description, options)
    parser.add_argument(
        "--host", action="append", default=[], help=f"a robot's FCI address, {count} times"
    )
    args = parser.parse_args(argv)
    _check(parser, args)
    if args.host:
        if len(args.host) != count:
            parser.error(f"--host: expected {count} robot addresses, got {len(args.host)}")
        yield list(args.host), args
        return
    from panda_py.sim import Simulator, free_loopback_host

    with contextlib.ExitStack() as stack:
        hosts = []
        for _ in range(count):
            sim = stack.enter_context(
                Simulator(
                    free_loopback_host(),
                    robot=args.robot,
                    lockstep=not args.realtime,
                    lockstep_max_speed=_max_speed(args, paced),
                )
            )
            hosts.append(sim.host)
        print(f"({count} simulated {args.robot.upper()}s on {', '.join(hosts)})")
        yield hosts, args


def connect(hostname: str) -> panda_py.Panda:
    """``panda_py.Panda(hostname)``, or exit with a clear message if no robot answers."""
    try:
        return panda_py.Panda(hostname)
    except Exception as exc:
        sys.exit(f"No robot answers at {hostname} ({exc}). Is FCI active in Desk?")
