"""Draw the documentation site's pictures into ``docs/_static``.

``python3 docs/pictures.py`` writes all three; ``--only architecture`` (or ``frame``,
``demo``) one of them:

* ``architecture.svg``: the package's layers and the processes a program runs in (drawn
  here with matplotlib, from the layers ``docs/architecture.md`` describes);
* ``robot.png``: a frame of the simulated robot, drawn by the simulator's own camera
  (``Simulator(camera_size=...)``, ``Simulator.render``) at the start pose;
* ``demo_paths.png``: the figure ``panda-py-demo`` writes, by running the demo once on its
  embedded simulator.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import matplotlib
import matplotlib.image
from matplotlib.figure import Figure  # Agg's canvas: no display needed
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

STATIC = Path(__file__).resolve().parent / "_static"

# (layer, units drawn side by side), top to bottom; imports point down only
LAYERS = [
    ("entry points", ["cli · demo · doctor", "panda-py's names", "learning"]),
    ("high level", ["panda: Panda, PandaContext"]),
    ("control process", ["rt: the 1 kHz loop, shared memory, requests"]),
    ("control laws", ["controllers: ControlLaw, compiled ticks"]),
    ("robot I/O", ["libfranka: Robot, Gripper, Model", "sim: the simulated robot"]),
    ("math", ["kinematics", "dynamics", "motion", "constants"]),
    ("data", ["robots: FER, FR3, the hand", "desk: the Desk client"]),
    ("ground", ["fci: wire formats", "checks", "jit", "progress · warmstart"]),
]
BLUE, ORANGE, GREY = "#dbe8f5", "#fde3c8", "#eeeeee"


def _box(ax, x: float, y: float, w: float, h: float, text: str, color: str, size=8.5) -> None:
    ax.add_patch(
        FancyBboxPatch(
            (x, y), w, h, boxstyle="round,pad=0.004,rounding_size=0.012",
            facecolor=color, edgecolor="#555555", linewidth=0.8,
        )
    )  # fmt: skip
    ax.text(x + w / 2, y + h / 2, text, ha="center", va="center", fontsize=size)


def _arrow(ax, start: tuple[float, float], end: tuple[float, float], text: str = "") -> None:
    ax.add_patch(
        FancyArrowPatch(start, end, arrowstyle="<|-|>", mutation_scale=9, color="#333333",
                        linewidth=0.9)
    )  # fmt: skip
    if text:
        mid = ((start[0] + end[0]) / 2, (start[1] + end[1]) / 2)
        ax.text(mid[0] + 0.012, mid[1], text, ha="left", va="center", fontsize=7.5)


def draw_architecture(path: Path) -> None:
    """The layers (left) and the processes (right), as an SVG with its text kept as text."""
    fig = Figure(figsize=(11.0, 5.6))
    layers = fig.add_axes((0.0, 0.0, 0.62, 1.0))
    procs = fig.add_axes((0.63, 0.0, 0.37, 1.0))
    for ax in (layers, procs):
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.axis("off")

    layers.text(0.5, 0.97, "The package in layers: each imports only those below it",
                ha="center", va="center", fontsize=10, weight="bold")  # fmt: skip
    top, row = 0.92, 0.105
    for i, (name, units) in enumerate(LAYERS):
        y = top - (i + 1) * row + 0.015
        layers.text(0.015, y + 0.035, name, ha="left", va="center", fontsize=8, style="italic")
        x0, x1, gap = 0.19, 0.99, 0.012
        width = (x1 - x0 - gap * (len(units) - 1)) / len(units)
        for j, unit in enumerate(units):
            color = ORANGE if unit.startswith("sim") else BLUE
            _box(layers, x0 + j * (width + gap), y, width, 0.07, unit, color)
    layers.text(0.59, 0.012, "sim and the client never import each other (tests/test_layers.py)",
                ha="center", va="bottom", fontsize=7.5, color="#444444")  # fmt: skip

    procs.text(0.5, 0.97, "The processes of one program", ha="center", va="center",
               fontsize=10, weight="bold")  # fmt: skip
    _box(procs, 0.08, 0.76, 0.84, 0.12, "your process\nPanda, your script, your own loop", BLUE)
    _box(procs, 0.08, 0.47, 0.84, 0.12, "the control process (panda_py.rt)\nthe 1 kHz loop",
         BLUE)  # fmt: skip
    _box(procs, 0.08, 0.12, 0.84, 0.18,
         "a Franka (FER, FR3)\nor panda-sim: MuJoCo at 1 kHz,\nits Desk in a process of its own",
         ORANGE)  # fmt: skip
    _arrow(procs, (0.5, 0.76), (0.5, 0.59), "shared memory (state, inputs, log),\nUnix socket")
    _arrow(procs, (0.5, 0.47), (0.5, 0.30), "FCI: UDP state and commands,\nTCP (protocol 3-10)")
    procs.text(0.5, 0.04, "a robot's Desk: HTTPS and WSS, from panda_py.desk",
               ha="center", va="center", fontsize=7.5, color="#444444")  # fmt: skip

    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "panda-py"}):
        fig.savefig(path, format="svg", metadata={"Date": None})


def draw_frame(path: Path) -> None:
    """The simulated robot at its start pose, the cube on the table, from the simulator's
    camera (drawn offscreen, EGL or OSMesa: ``MUJOCO_GL``)."""
    from panda_py.sim import Simulator, free_loopback_host

    with Simulator(free_loopback_host(), lockstep=True, camera_size=(640, 480)) as sim:
        image = sim.render()
    matplotlib.image.imsave(path, image)


def draw_demo(path: Path) -> None:
    """The figure of ``panda-py-demo``, by running it (lockstep, on its own simulator)."""
    subprocess.run([sys.executable, "-m", "panda_py.demo", "--figure", str(path)], check=True)


PICTURES = {
    "architecture": ("architecture.svg", draw_architecture),
    "frame": ("robot.png", draw_frame),
    "demo": ("demo_paths.png", draw_demo),
}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(PICTURES), help="draw this picture only")
    args = parser.parse_args(argv)
    STATIC.mkdir(exist_ok=True)
    for name, (filename, draw) in PICTURES.items():
        if args.only in (None, name):
            draw(STATIC / filename)
            print(STATIC / filename)


if __name__ == "__main__":
    main()
