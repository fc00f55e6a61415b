"""``panda-sim --viewer``: MuJoCo's interactive viewer on the simulated robot.

The viewer (``mujoco.viewer.launch_passive``) runs in a process of its own
(:mod:`.drawing`), on its own copy of the world: at ``FPS`` frames per simulated second
the simulator's tick copies the joint positions into a ring, and the viewer shows the
newest (``mj_forward``, then ``sync`` under the viewer's lock) at up to ``FPS`` per wall
second. Not in the simulator's process: there the viewer's render thread (software
OpenGL on most headless machines, tens of ms a frame) would inherit the simulator's
SCHED_FIFO priority and share the GIL with the tick (whose ``sync`` calls took 51 us
median, 8.7 ms worst, in a 5 s trial here). A process of its own runs
below the simulator (``nice``) and never holds the tick's GIL
(``benchmarks/bench_drawing.py``: a realtime simulator had 0.06-0.19 % late ticks with
the viewer open, 0.10-0.20 % alone, on two loaded cores). Dragging a body in the window therefore
does not push the simulated robot: it is a view.

Without a display the viewer fails at start with one line naming the fix.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any

from panda_py.sim.config import SimConfig
from panda_py.sim.drawing import DrawingError, DrawingProcess, child_setup, parent_alive
from panda_py.sim.frames import FrameFeed, FrameReader, build_model, set_camera

FPS = 60.0  # [1/s] the viewer's refresh rate (of simulated and of wall time)
FIX = "run under xvfb-run, set DISPLAY to a running X server, or record a video with --record"


def check_display() -> None:
    """Raise :class:`DrawingError` (one line, with the fix) when no display is set."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise DrawingError(f"viewer: no display ($DISPLAY and $WAYLAND_DISPLAY are unset): {FIX}")


class Viewer(DrawingProcess):
    """MuJoCo's viewer on ``config``'s simulator; its ``feed`` goes into the simulator's
    ``SimConfig.frame_feeds``."""

    name = "viewer"

    def __init__(self, config: SimConfig) -> None:
        check_display()
        nq = build_model(config, meshes=False).nq  # the meshes add no joint
        super().__init__(FrameFeed.create(nq, FPS, latest=True, slots=4), _viewer_main, (config,))


def _viewer_main(feed: FrameFeed, conn: Any, config: SimConfig) -> None:
    child_setup()
    os.environ["MUJOCO_GL"] = "glfw"  # a window, whatever the recorder's backend is
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    try:
        import glfw

        glfw.ERROR_REPORTING = "ignore"  # its warnings are not one line: get_error() below
        if not glfw.init():
            code, why = glfw.get_error()
            raise RuntimeError(why.decode() if isinstance(why, bytes) else str(why or code))
    except Exception as exc:
        reason = " ".join(str(exc).split())  # one line
        conn.send(("error", f"viewer: cannot open a window on display {display!r} "
                            f"(GLFW: {reason}): {FIX}"))  # fmt: skip
        return
    import mujoco
    import mujoco.viewer

    model = build_model(config)
    data = mujoco.MjData(model)
    data.qpos[:7] = config.q_start
    handle = mujoco.viewer.launch_passive(model, data, show_left_ui=False, show_right_ui=False)
    with handle.lock():
        set_camera(handle.cam)
    reader = FrameReader(feed)
    conn.send(("ready", None))
    shown = -1.0
    frames = 0
    next_sync = time.monotonic()
    try:
        while handle.is_running() and not reader.closed and parent_alive():
            row = reader.latest()
            if row is not None and row[0] != shown:
                shown = row[0]
                with handle.lock():  # held for a copy and mj_forward (tens of us)
                    data.time = row[0]
                    data.qpos[:] = row[1:]
                    mujoco.mj_forward(model, data)
                handle.sync()
                frames += 1
            now = time.monotonic()
            next_sync = max(next_sync + 1.0 / FPS, now)  # late (a slow draw): no catching up
            time.sleep(next_sync - now)
    finally:
        reader.mark_gone()
    try:
        conn.send({"frames": frames})
    except (OSError, EOFError):
        pass
    # End here rather than close the window: MuJoCo's render thread can still swap the
    # buffers of a window its close destroyed, and Xlib's default handler then prints an
    # X error (GLXBadDrawable) and exits. Ending the process closes the window cleanly.
    os._exit(0)


__all__ = ["FIX", "FPS", "Viewer", "check_display"]
