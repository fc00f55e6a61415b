"""The demo: pick up the cube and draw the paper's two paths, on panda_py's public API.

    panda-py-demo                   # an embedded lockstep simulator (robust on a loaded machine)
    panda-py-demo --realtime        # the simulator keeps 1 kHz wall-clock time like a robot
    panda-py-demo --robot fr3       # a simulated FR3
    panda-py-demo --host 172.16.0.2 # the same demo on a real robot (a cube at 0.5, 0, 0)

Everything below is what a user writes: ``panda_py.Panda``, ``libfranka.Gripper`` and
``fk``/``ik``. The simulator is only started (and always stopped, on Ctrl-C too) when no
``--host`` is given. The paper's figure (the logged end-effector path of ``move_to_pose``,
a straight line, against ``move_to_joint_position``'s curve, seen from above and from the
front) is drawn with matplotlib and written as a PNG.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import panda_py
from panda_py import constants, libfranka

# Where panda-sim's scene places the cube; put one there on a real robot's table.
CUBE_POSITION = np.array([0.5, 0.0, 0.02])  # [m] its centre, in the robot's base frame
CUBE_SIZE = 0.04  # [m] edge length
HOVER = 0.15  # [m] approach height above the grasp
# [m] the TCP this far above the cube's centre: the finger pads hold most of its side
GRASP_HEIGHT = 0.005
GRASP_FORCE = 30.0  # [N]
# [m] the cube is let go this far above where it was grasped: pressed onto the table by a
# stiff arm through a firm grasp, a cube that slipped a millimetre would stop the arm with
# a reflex
RELEASE_HEIGHT = 0.003
BAR_WIDTH = 30  # characters


class DemoError(RuntimeError):
    """A step of the demo did not succeed (the message says which and why)."""


def _bar(fraction: float) -> str:
    n = round(max(0.0, min(1.0, fraction)) * BAR_WIDTH)
    return "[" + "#" * n + "." * (BAR_WIDTH - n) + f"] {100 * fraction:3.0f}%"


class Steps:
    """Runs the demo's motions one at a time with a progress bar each, and keeps their
    times for the summary."""

    def __init__(self, panda: panda_py.Panda, *, tty: bool) -> None:
        self.panda = panda
        self.tty = tty
        self.times: list[tuple[str, float]] = []

    def move(self, label: str, motion: Callable[[], bool], goal: Callable[[], float]) -> None:
        """Run ``motion`` (a blocking move) in a thread and show its progress, measured by
        ``goal()``, the distance left (any unit), against where it started."""
        start = max(goal(), 1e-9)
        result: dict[str, Any] = {}

        def run() -> None:
            try:
                result["ok"] = motion()
            except BaseException as exc:  # re-raised in the main thread below
                result["error"] = exc

        t0 = time.monotonic()
        worker = threading.Thread(target=run, name=f"demo: {label}", daemon=True)
        worker.start()
        while worker.is_alive():
            worker.join(0.1)
            if self.tty:
                print(f"\r  {_bar(1.0 - goal() / start)} {label}", end="", flush=True)
        elapsed = time.monotonic() - t0
        if "error" in result:
            print()
            raise DemoError(f"{label}: {result['error']}") from result["error"]
        ok = bool(result.get("ok"))
        done = 1.0 if ok else 1.0 - goal() / start
        print(f"\r  {_bar(done)} {label} ({elapsed:.1f} s)", flush=True)
        self.times.append((label, elapsed))
        if not ok:
            raise DemoError(f"{label}: the motion did not reach its goal (see the log above)")

    def to_pose(self, label: str, pose: np.ndarray, **kwargs: Any) -> None:
        target = pose[:3, 3]
        self.move(
            label,
            lambda: self.panda.move_to_pose(pose, **kwargs),
            lambda: float(np.linalg.norm(self.panda.get_position() - target)),
        )

    def to_joints(self, label: str, q: np.ndarray, **kwargs: Any) -> None:
        self.move(
            label,
            lambda: self.panda.move_to_joint_position(q, **kwargs),
            lambda: float(np.linalg.norm(self.panda.q - q)),
        )


def _tcp_at(position: np.ndarray) -> np.ndarray:
    """The start pose's orientation (pointing down) with the TCP at ``position`` [m]."""
    T = panda_py.fk(constants.JOINT_POSITION_START)
    T[:3, 3] = position
    return T


# --- the figure -----------------------------------------------------------------------------

PATH_STYLES = (  # (motion, shape, colour): the paper's two motions
    ("move_to_pose", "straight", "tab:blue"),
    ("move_to_joint_position", "curved", "tab:orange"),
)
MIN_SPAN = 0.1  # [m] each view shows at least this much along each axis
PAD = 0.02  # [m] margin around the paths in each view
WIDTH = 8.0  # [in] of the figure; its height follows from the views' spans (to scale)
DPI = 120  # pixels per inch of the PNG


def write_figure(path: Path, pose_path: np.ndarray, joint_path: np.ndarray) -> Figure:
    """The paper's figure as a PNG at ``path``: the logged end-effector positions (N, 3)
    [m] of ``move_to_pose`` (a straight line) and ``move_to_joint_position`` (a curve),
    seen from above (x-y) and from the front (z-y), both to scale, both paths in each.
    Drawn on matplotlib's Agg canvas (no display needed); returns the figure, written."""
    paths = [np.asarray(p, dtype=np.float64) for p in (pose_path, joint_path)]
    for name, p in zip(("pose_path", "joint_path"), paths, strict=True):
        if p.ndim != 2 or p.shape[0] < 2 or p.shape[1] != 3 or not np.isfinite(p).all():
            raise ValueError(
                f"{name}: expected finite end-effector positions of shape (N >= 2, 3) [m], "
                f"got an array of shape {p.shape}"
            )
    both = np.concatenate(paths)
    mid = (both.min(axis=0) + both.max(axis=0)) / 2
    span = np.maximum(np.ptp(both, axis=0) + 2 * PAD, MIN_SPAN)
    lo, hi = mid - span / 2, mid + span / 2
    # axes about WIDTH - 1 in wide; titles, labels and the legend take about 2.4 in
    height = float(np.clip((WIDTH - 1.0) * (span[0] + span[2]) / span[1] + 2.4, 3.0, 12.0))
    fig = Figure(figsize=(WIDTH, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    top, front = fig.subplots(2, 1, sharex=True, height_ratios=[span[0], span[2]])
    # Third-angle projection: the top view above the front view, y across both; seen
    # from above with the robot's front towards the front view, x grows downwards.
    for ax, k, title, flip in ((top, 0, "Top view", True), (front, 2, "Front view", False)):
        for p, (motion, shape, colour) in zip(paths, PATH_STYLES, strict=True):
            off = deviation_from_line(p) * 1000
            label = f"{motion}: {shape}, at most {off:.1f} mm from the line $T_0 T_1$"
            ax.plot(p[:, 1], p[:, k], color=colour, lw=2, label=label)
        for point, name in ((paths[0][0], "$T_0$"), (paths[0][-1], "$T_1$")):
            ax.plot(point[1], point[k], "o", color="black", ms=4)
            ax.annotate(name, (point[1], point[k]), xytext=(0, 6), textcoords="offset points",
                        ha="center", va="bottom")  # fmt: skip
        ax.set_ylim((hi[k], lo[k]) if flip else (lo[k], hi[k]))
        ax.set_aspect("equal")
        ax.set_title(title)
        # (in the label, not on the plot, where a path's end could sit under it)
        ax.set_ylabel("x [m], \u2191 to the robot's base" if flip else f"{'xyz'[k]} [m]")
        ax.grid(True, alpha=0.3)
    front.set_xlim(lo[1], hi[1])
    front.set_xlabel("y [m]")
    handles, labels = top.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize="small")
    fig.suptitle("The end effector from $T_0$ to $T_1$, logged at 1 kHz")
    fig.savefig(path)
    return fig


def deviation_from_line(path: np.ndarray) -> float:
    """Largest distance [m] of a path (N, 2 or 3) from the straight line between its
    ends (from its start, if it ends where it started)."""
    rel = path - path[0]
    d = rel[-1]
    if float(d @ d) > 0.0:
        rel = rel - np.outer(rel @ d / float(d @ d), d)
    return float(np.max(np.linalg.norm(rel, axis=1)))


# --- the demo ---------------------------------------------------------------------------------


@contextlib.contextmanager
def _robot(args: argparse.Namespace) -> Iterator[tuple[str, Any]]:
    """The robot's address: ``--host``, or an embedded simulator started here and stopped
    on the way out, whatever the way out is."""
    if args.host:
        yield args.host, None
        return
    from panda_py.sim import Simulator, free_loopback_host

    host = free_loopback_host()
    mode = "realtime" if args.realtime else "lockstep"
    print(f"Starting a simulated {args.robot.upper()} on {host} ({mode})", flush=True)
    with Simulator(host, robot=args.robot, lockstep=not args.realtime) as sim:
        yield host, sim


def run(
    panda: panda_py.Panda,
    gripper: libfranka.Gripper,
    figure: Path,
    *,
    tty: bool,
    cube: Callable[[], np.ndarray] | None = None,
) -> dict:
    """The demo's motions; returns what the summary reports. ``cube``: where the cube
    is [m], if someone can tell (the simulator can)."""
    steps = Steps(panda, tty=tty)
    above = _tcp_at(CUBE_POSITION + np.array([0.0, 0.0, HOVER]))
    at_cube = _tcp_at(CUBE_POSITION + np.array([0.0, 0.0, GRASP_HEIGHT]))

    print("1. Pick up the cube")
    steps.to_joints("move to start", np.asarray(constants.JOINT_POSITION_START))
    gripper.move(0.08, 0.1)
    steps.to_pose("above the cube", above)
    steps.to_pose("down to the cube", at_cube)
    if not gripper.grasp(CUBE_SIZE, 0.05, GRASP_FORCE, 0.005, 0.005):
        raise DemoError(f"grasp: no {CUBE_SIZE * 1000:.0f} mm cube between the fingers")
    print("  grasped")
    steps.to_pose("lift", above)
    if cube is not None:
        print(f"  the cube is {(cube()[2] - CUBE_POSITION[2]) * 100:.1f} cm above the table")

    print("2. The paper's two paths, logged (its code block 5), the cube in the hand")
    T_0 = panda_py.fk(constants.JOINT_POSITION_START)
    T_0[1, 3] = 0.25
    T_1 = T_0.copy()
    T_1[1, 3] = -0.25
    steps.to_pose("to T_0", T_0)
    panda.enable_logging(40_000)
    steps.to_pose("move_to_pose(T_1), logged", T_1, speed_factor=0.1)
    panda.disable_logging()
    log = panda.get_log()
    steps.to_pose("back to T_0", T_0)
    panda.enable_logging(40_000)
    steps.to_joints("move_to_joint_position(ik(T_1)), logged", panda_py.ik(T_1))
    panda.disable_logging()
    joint_log = panda.get_log()
    if cube is not None:
        height = (cube()[2] - CUBE_POSITION[2]) * 100
        print(f"  the cube, still in the hand, is {height:.1f} cm above the table")

    print("3. Put the cube back")
    steps.to_joints("move to start", np.asarray(constants.JOINT_POSITION_START))
    steps.to_pose("above the cube", above)
    steps.to_pose("down to the table", _tcp_at(at_cube[:3, 3] + [0.0, 0.0, RELEASE_HEIGHT]))
    gripper.move(0.08, 0.1)
    steps.to_pose("retreat", above)
    steps.to_joints("move to start", np.asarray(constants.JOINT_POSITION_START))
    # O_T_EE is column-major: [12:15] is the end effector's position
    pose_path = np.array(log["O_T_EE"])[:, 12:15]
    joint_path = np.array(joint_log["O_T_EE"])[:, 12:15]
    write_figure(figure, pose_path, joint_path)
    return {
        "times": steps.times,
        "pose_deviation": deviation_from_line(pose_path),
        "joint_deviation": deviation_from_line(joint_path),
        "samples": (len(pose_path), len(joint_path)),
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="panda-py-demo", description=__doc__.splitlines()[0])
    parser.add_argument("--host", help="a real robot's FCI address (default: a simulator)")
    parser.add_argument("--realtime", action="store_true", help="run the simulator in realtime")
    parser.add_argument("--robot", default="fer", choices=["fer", "fr3"], help="simulated robot")
    parser.add_argument(
        "--figure", type=Path, default=Path("panda_py_demo_paths.png"), help="the PNG to write"
    )
    args = parser.parse_args(argv)
    t0 = time.monotonic()
    try:
        with _robot(args) as (host, sim):
            try:
                panda = panda_py.Panda(host)
                gripper = libfranka.Gripper(host)
            except Exception as exc:
                raise DemoError(f"no robot answers at {host}: {exc}") from exc
            with panda:
                print(f"Connected to {host}")
                watch = None if sim is None else lambda: np.asarray(sim.state()["cube_position"])
                summary = run(panda, gripper, args.figure, tty=sys.stdout.isatty(), cube=watch)
            if sim is not None:
                cube = np.asarray(sim.state()["cube_position"])
                summary["cube"] = cube
    except DemoError as exc:
        print(f"panda-py-demo: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("\npanda-py-demo: interrupted; the simulator is stopped", file=sys.stderr)
        return 130
    total = time.monotonic() - t0
    print("Summary")
    for label, seconds in summary["times"]:
        print(f"  {seconds:5.1f} s  {label}")
    n_pose, n_joint = summary["samples"]
    print(
        f"  move_to_pose: {n_pose} states logged, at most "
        f"{summary['pose_deviation'] * 1000:.1f} mm from the straight line"
    )
    print(
        f"  move_to_joint_position: {n_joint} states logged, up to "
        f"{summary['joint_deviation'] * 1000:.1f} mm away from it"
    )
    if "cube" in summary:
        moved = np.linalg.norm(summary["cube"][:2] - CUBE_POSITION[:2])
        print(
            f"  cube back at {np.round(summary['cube'], 3).tolist()} m "
            f"({moved * 1000:.0f} mm from where it was)"
        )
    print(f"  total {total:.1f} s")
    print(f"Figure: {args.figure.resolve()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
