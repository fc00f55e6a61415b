"""Snapshots of the simulated world for the processes that draw it (the viewer, the video
recorder).

Drawing costs 10-60 ms a frame with software OpenGL: far too much for a 1 kHz tick. So
the tick only copies the world's joint positions (``qpos``, a few hundred bytes) into a
shared ring at the drawing's rate of simulated time, and a process of its own rebuilds
the scene from them (:func:`build_model`, ``mj_forward``) and draws it. The tick never
takes a lock and never waits on a drawing process, except a lockstep recorder whose ring
is full: lockstep time is the client's, and a video that follows simulated time must not
lose frames (a realtime simulator drops them instead, counted in ``dropped``).

Ring layout (float64): ``[written, read, closed, consumer_gone, dropped, hold]`` then
``slots`` rows of ``[time, qpos...]``. The writer owns ``written`` and ``dropped``, the
reader ``read`` and ``consumer_gone``; ``closed`` is set when the simulator ends. ``hold``
is the camera's (:mod:`.camera`): set while an image is asked for, drawn and handed over,
it stops a lockstep simulator's time (at its next tick), as the lockstep simulator waits
for its client: an image costs no simulated time.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.sim.config import SimConfig
from panda_py.sim.meshes import mesh_dir, with_meshes

log = logging.getLogger("panda_py.sim")

_WRITTEN, _READ, _CLOSED, _GONE, _DROPPED, _HOLD = range(6)
_HEADER = 6
# A lockstep simulator waits at most this long for a stalled recorder, then drops [s].
_FULL_WAIT = 10.0
_TICK_RATE = 1000  # ticks per simulated second (fci.PERIOD = 1 ms)


def build_model(config: SimConfig, *, meshes: bool = True) -> Any:
    """The MuJoCo model a simulator of ``config`` runs (the same generator, the same
    arguments as :class:`~panda_py.sim.physics.Physics`), for drawing it elsewhere: with
    ``meshes``, the arm's visual meshes where rtb-data ships them (:mod:`.meshes`; the
    same bodies, joints and collision geoms, so the same ``qpos``), else its capsules."""
    import mujoco

    from panda_py.robots.mjcf import model_xml
    from panda_py.robots.params import get_robot

    xml = model_xml(
        get_robot(config.robot),
        hand=True,
        scene=config.scene,
        extra=config.extra,
        end_effector=config.end_effector,
    )
    directory = mesh_dir() if meshes else None
    if directory is not None:
        xml = with_meshes(xml, config.robot, directory)
    return mujoco.MjModel.from_xml_string(xml)


def set_camera(cam: Any) -> None:
    """Look at the arm and the table from the front left, a little from above."""
    import mujoco

    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = (0.3, 0.0, 0.35)  # [m]
    cam.distance = 1.9  # [m]
    cam.azimuth = 140.0  # [deg]
    cam.elevation = -20.0  # [deg]


def offscreen(
    config: SimConfig, width: int, height: int, what: str, *, meshes: bool = True
) -> tuple[Any, Any, Any]:
    """In a drawing process: ``(model, renderer, camera)`` to draw ``config``'s world
    offscreen at ``width`` x ``height`` (EGL unless ``MUJOCO_GL`` says otherwise; shadows and
    reflections off, which triple a frame's cost with software OpenGL; ``meshes``: as
    :func:`build_model`), or raise
    RuntimeError naming ``what`` failed and the fix."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco's import reads it
    try:
        import mujoco

        model = build_model(config, meshes=meshes)
        renderer = mujoco.Renderer(model, height, width)
    except Exception as exc:  # no GL here
        why = " ".join(f"MUJOCO_GL={os.environ['MUJOCO_GL']}: {exc}".split())
        fix = "install EGL (Debian: libegl1 libegl-mesa0) or OSMesa (libosmesa6, MUJOCO_GL=osmesa)"
        raise RuntimeError(f"{what}: offscreen rendering failed ({why}): {fix}") from exc
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    cam = mujoco.MjvCamera()
    set_camera(cam)
    return model, renderer, cam


@dataclass
class FrameFeed:
    """One drawing process's ring: ``fps`` frames per simulated second; ``latest`` (the
    viewer) keeps only the newest, otherwise (the recorder) every frame is kept."""

    array: Any  # multiprocessing RawArray of float64
    nq: int
    fps: float
    latest: bool
    slots: int

    @classmethod
    def create(cls, nq: int, fps: float, *, latest: bool, slots: int = 256) -> FrameFeed:
        import multiprocessing

        array = multiprocessing.get_context("spawn").RawArray("d", _HEADER + slots * (1 + nq))
        return cls(array, nq, fps, latest, slots)

    def view(self) -> tuple[np.ndarray, np.ndarray]:
        """The header and the slots as numpy views onto the shared block."""
        flat = np.frombuffer(self.array, dtype=np.float64)
        return flat[:_HEADER], flat[_HEADER:].reshape(self.slots, 1 + self.nq)


class FrameReader:
    """The drawing process's end of a :class:`FrameFeed`."""

    def __init__(self, feed: FrameFeed) -> None:
        self.feed = feed
        self._head, self._rows = feed.view()

    @property
    def closed(self) -> bool:
        return bool(self._head[_CLOSED])

    @property
    def dropped(self) -> int:
        return int(self._head[_DROPPED])

    def next(self) -> np.ndarray | None:
        """The oldest frame not yet read (``[time, qpos...]``, a copy), or None."""
        read, written = int(self._head[_READ]), int(self._head[_WRITTEN])
        if read >= written:
            return None
        row = self._rows[read % self.feed.slots].copy()
        self._head[_READ] = read + 1
        return row

    def latest(self) -> np.ndarray | None:
        """The newest frame (a copy), or None before the first one. The writer may lap a
        slot while it is copied: the copy is kept only if it did not."""
        for _ in range(10):
            written = int(self._head[_WRITTEN])
            if written == 0:
                return None
            row = self._rows[(written - 1) % self.feed.slots].copy()
            if int(self._head[_WRITTEN]) - (written - 1) < self.feed.slots:
                return row
        return None

    def mark_gone(self) -> None:
        """The reader stopped: the writer no longer waits for room."""
        self._head[_GONE] = 1.0


def hold(feed: FrameFeed, on: bool = True) -> None:
    """Stop a lockstep simulator's time at its next tick until ``hold(feed, False)`` (a
    realtime simulator never waits)."""
    feed.view()[0][_HOLD] = float(on)


class FrameTaps:
    """The simulator's end: copies ``qpos`` into each feed at its frame instants.

    Frame ``k`` of a feed is the state after the first tick at or past ``k / fps`` of
    simulated time (the first tick for frame 0), so a run of ``n`` ticks has
    ``floor(n * fps / 1000) + 1`` frames."""

    def __init__(self, feeds: tuple[FrameFeed, ...], *, lockstep: bool) -> None:
        self._feeds = [(feed, *feed.view()) for feed in feeds]
        self._lockstep = lockstep
        self._frame = [0] * len(feeds)  # the next frame's number, per feed
        self._due = [0] * len(feeds)  # the tick it is due at
        self._next_due = 0  # the earliest of them: most ticks stop at one comparison

    def tick(self, tick: int, qpos: np.ndarray) -> None:
        """After tick number ``tick`` (1, 2, ...): write the frames that are due."""
        if tick < self._next_due:
            return
        for i, (feed, head, rows) in enumerate(self._feeds):
            if tick < self._due[i]:
                continue
            self._write(feed, head, rows, tick, qpos)
            k = self._frame[i] = self._frame[i] + 1
            self._due[i] = math.ceil(k * _TICK_RATE / feed.fps - 1e-9)
        self._next_due = min(self._due)
        if self._lockstep:
            for feed, head, _ in self._feeds:
                if head[_HOLD]:
                    self._wait_for_release(feed, head)

    def _write(
        self, feed: FrameFeed, head: np.ndarray, rows: np.ndarray, tick: int, qpos: np.ndarray
    ) -> None:
        written = int(head[_WRITTEN])
        if not feed.latest and written - int(head[_READ]) >= feed.slots:
            if not self._wait_for_room(feed, head):
                head[_DROPPED] += 1
                return
        row = rows[written % feed.slots]
        row[0] = tick / _TICK_RATE
        row[1:] = qpos
        head[_WRITTEN] = written + 1  # after the row: x86 keeps stores in order

    def _wait_for_room(self, feed: FrameFeed, head: np.ndarray) -> bool:
        """Lockstep: wait until the reader frees a slot (it is drawing: tens of ms).
        Realtime never waits (the tick is due in 1 ms)."""
        if not self._lockstep or head[_GONE]:
            return False
        deadline = time.monotonic() + _FULL_WAIT
        while int(head[_WRITTEN]) - int(head[_READ]) >= feed.slots:
            if head[_GONE]:
                return False
            if time.monotonic() > deadline:
                log.warning("the video recorder stalled for %g s; dropping its frames", _FULL_WAIT)
                head[_GONE] = 1.0  # never wait for it again
                return False
            time.sleep(0.001)
        return True

    def _wait_for_release(self, feed: FrameFeed, head: np.ndarray) -> None:
        """Lockstep: the camera draws the newest frame; time stands still meanwhile."""
        deadline = time.monotonic() + _FULL_WAIT
        while head[_HOLD] and not head[_GONE]:
            if time.monotonic() > deadline:
                log.warning("the camera stalled for %g s; not waiting for it", _FULL_WAIT)
                head[_GONE] = 1.0  # never wait for it again
                return
            time.sleep(0.0005)

    def close(self) -> None:
        """The simulator ends: readers finish with what they have."""
        for _, head, _ in self._feeds:
            head[_CLOSED] = 1.0


def close_feed(feed: FrameFeed) -> None:
    """Mark ``feed`` closed from outside the simulator (it died without closing it)."""
    feed.view()[0][_CLOSED] = 1.0


__all__ = [
    "FrameFeed",
    "FrameReader",
    "FrameTaps",
    "build_model",
    "close_feed",
    "hold",
    "set_camera",
]
