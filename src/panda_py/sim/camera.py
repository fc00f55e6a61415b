"""``Simulator(camera_size=(w, h))``: images of the simulated robot on request, for policies
that see (``Simulator.render``) and for recorded episodes.

Drawn offscreen in a process of its own, as the video recorder draws (:mod:`.drawing`,
:mod:`.video`): a frame costs 10-60 ms with software OpenGL, far too much for the
simulator's 1 kHz tick, and MuJoCo picks its OpenGL backend (``MUJOCO_GL``, EGL here:
headless) once per process, when it is first imported. The tick copies the world's joint
positions into a ring every tick (``fps`` 1000, only the newest kept); ``render`` asks
the camera's process for an image of the newest of them. So an image shows the world as
it was when it was asked for, to the millisecond of simulated time. A lockstep simulator's
time stands still from the request until the image is in the caller's hands (the camera
holds its next tick, as lockstep waits for its client), so seeing costs a policy no
simulated time; a realtime one never waits.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from panda_py.sim.config import SimConfig
from panda_py.sim.drawing import DrawingProcess, child_setup, parent_alive
from panda_py.sim.frames import FrameFeed, FrameReader, build_model, hold, offscreen

# [px] the largest image: MuJoCo's default offscreen buffer (the model's <visual><global
# offwidth offheight>), which the generated model keeps
MAX_WIDTH, MAX_HEIGHT = 640, 480
MIN_SIZE = 16  # [px]
_TAP_FPS = 1000.0  # every tick: the newest state is at most a tick old
_POLL = 0.05  # [s] the camera's wait for a request before it checks the simulator ended
RENDER_TIMEOUT = 10.0  # [s] a frame takes tens of ms; a process this slow is stuck


def check_camera_size(size: Any) -> tuple[int, int]:
    """Validate ``camera_size=(width, height)`` [px] before anything starts."""
    try:
        width, height = (int(v) for v in size)
        ok = [float(v) for v in size] == [width, height]
    except (TypeError, ValueError):
        ok = False
    if not ok or not (MIN_SIZE <= width <= MAX_WIDTH and MIN_SIZE <= height <= MAX_HEIGHT):
        raise ValueError(
            f"camera_size: expected (width, height) in pixels, whole numbers within "
            f"{MIN_SIZE}..{MAX_WIDTH} x {MIN_SIZE}..{MAX_HEIGHT}, got {size!r}"
        )
    return width, height


class Camera(DrawingProcess):
    """The camera of ``config``'s simulator: ``render()`` returns an image of the newest
    state, (height, width, 3) uint8 RGB; its ``feed`` goes into the simulator's
    ``SimConfig.frame_feeds``."""

    name = "camera"

    def __init__(self, config: SimConfig, size: tuple[int, int]) -> None:
        self.width, self.height = check_camera_size(size)
        nq = build_model(config, meshes=False).nq  # the meshes add no joint
        feed = FrameFeed.create(nq, _TAP_FPS, latest=True, slots=4)
        super().__init__(feed, _camera_main, (config, self.width, self.height))
        self._render_lock = threading.Lock()  # one request and its answer at a time

    def render(self) -> np.ndarray:
        """An image of the simulated world as it is now, (height, width, 3) uint8 RGB."""
        with self._render_lock:
            conn = self._conn
            if conn is None or not self.running:
                raise RuntimeError("camera: its process is not running (the simulator stopped)")
            # lockstep: the world waits at its next tick until the image is here
            hold(self.feed)
            try:
                conn.send("render")
                if not conn.poll(RENDER_TIMEOUT):
                    raise RuntimeError(f"camera: no image within {RENDER_TIMEOUT:g} s")
                kind, value = conn.recv()
            except (OSError, EOFError) as exc:
                raise RuntimeError("camera: its process is gone") from exc
            finally:
                hold(self.feed, False)
        if kind != "frame":
            raise RuntimeError(f"camera: {value}")
        return np.frombuffer(value, np.uint8).reshape(self.height, self.width, 3).copy()


def _camera_main(feed: FrameFeed, conn: Any, config: SimConfig, width: int, height: int) -> None:
    child_setup()
    try:
        model, renderer, cam = offscreen(config, width, height, "camera")
    except RuntimeError as exc:  # no GL here: the parent reports it
        conn.send(("error", str(exc)))
        return
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:7] = config.q_start  # the world before its first tick
    mujoco.mj_forward(model, data)
    renderer.update_scene(data, cam)
    renderer.render()  # the first frame sets up OpenGL (hundreds of ms): not a request's
    reader = FrameReader(feed)
    conn.send(("ready", None))
    frames = 0
    error = None
    try:
        while True:
            if not conn.poll(_POLL):
                if reader.closed or not parent_alive():
                    break
                continue
            conn.recv()  # "render"
            row = reader.latest()
            if row is not None:
                data.time = row[0]
                data.qpos[:] = row[1:]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, cam)
            conn.send(("frame", renderer.render().tobytes()))
            frames += 1
    except (OSError, EOFError):
        pass  # the simulator's handle is gone
    except Exception as exc:  # reported to the request that is waiting, and at stop
        error = f"{type(exc).__name__}: {exc}"
        try:
            conn.send(("error", error))
        except (OSError, EOFError):
            pass
    finally:
        reader.mark_gone()  # the simulator never waits for it again
        renderer.close()
    try:
        conn.send({"frames": frames, "error": error})
    except (OSError, EOFError):
        pass


__all__ = ["MAX_HEIGHT", "MAX_WIDTH", "Camera", "check_camera_size"]
