"""``panda-sim --record FILE.mp4``: a video of the simulated robot, drawn offscreen.

The recorder is a process of its own (:mod:`.drawing`): the simulator's tick copies the
world's joint positions into a ring at ``fps`` frames per simulated second
(:class:`~panda_py.sim.frames.FrameTaps`), the recorder draws each with
``mujoco.Renderer`` (``MUJOCO_GL=egl`` unless set: headless, no display needed) and pipes
it to ffmpeg (H.264 in MP4, the binary that ``imageio-ffmpeg`` ships). The file is
finished when the simulator ends, however it ends (stop, Ctrl-C, SIGTERM, its parent
gone): the frames still queued are encoded first.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.sim.config import SimConfig
from panda_py.sim.drawing import DrawingProcess, child_setup, parent_alive
from panda_py.sim.frames import FrameFeed, FrameReader, build_model, offscreen

WIDTH, HEIGHT = 640, 480  # [px] MuJoCo's default offscreen buffer
DEFAULT_FPS = 30.0  # frames per simulated second
_IDLE_POLL = 0.002  # [s] the recorder's sleep when no frame waits
INSTALL_HINT = 'pip install "panda-py-pure[video]"'


def check_record(path: str | os.PathLike[str], fps: float) -> Path:
    """Validate ``record=`` and ``record_fps=`` before anything starts; the path."""
    out = Path(path)
    if out.suffix.lower() != ".mp4":
        raise ValueError(f"record: expected a file name ending in .mp4, got {str(path)!r}")
    if not out.parent.is_dir():
        raise ValueError(f"record: the directory {str(out.parent)!r} does not exist")
    if not 1 <= fps <= 120:
        raise ValueError(f"record_fps: expected 1..120 frames per second, got {fps}")
    if importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ValueError(f"record: needs the video extra (imageio-ffmpeg): {INSTALL_HINT}")
    return out


class Recorder(DrawingProcess):
    """Records ``config``'s simulator into ``path``; its ``feed`` goes into the
    simulator's ``SimConfig.frame_feeds``."""

    name = "record"

    def __init__(self, config: SimConfig, path: str | os.PathLike[str], fps: float) -> None:
        self.path = check_record(path, fps)
        nq = build_model(config, meshes=False).nq  # the meshes add no joint
        super().__init__(
            FrameFeed.create(nq, fps, latest=False), _recorder_main, (config, str(self.path))
        )


def _recorder_main(feed: FrameFeed, conn: Any, config: SimConfig, path: str) -> None:
    child_setup()
    ending = []  # SIGTERM (e.g. multiprocessing ending its daemons): finish the file now
    signal.signal(signal.SIGTERM, lambda *_: ending.append(True))
    try:
        model, renderer, cam = offscreen(config, WIDTH, HEIGHT, "record")
    except RuntimeError as exc:  # no GL here: the parent reports it
        conn.send(("error", str(exc)))
        return
    import mujoco

    try:
        import imageio_ffmpeg

        writer = imageio_ffmpeg.write_frames(
            path, (WIDTH, HEIGHT), fps=feed.fps, codec="libx264", quality=7,
            ffmpeg_log_level="error", macro_block_size=16,
        )  # fmt: skip
        writer.send(None)
    except Exception as exc:
        conn.send(("error", f"record: cannot start the encoder for {path!r}: {exc} "
                            f"({INSTALL_HINT})"))  # fmt: skip
        return
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    renderer.update_scene(data, cam)
    renderer.render()  # the first frame sets up OpenGL (hundreds of ms): not in the video's time
    reader = FrameReader(feed)
    conn.send(("ready", None))
    costs: list[float] = []
    error = None
    try:
        while True:
            row = reader.next()
            if row is None:
                if reader.closed or ending or not parent_alive():
                    break
                time.sleep(_IDLE_POLL)
                continue
            t0 = time.perf_counter()
            data.time = row[0]
            data.qpos[:] = row[1:]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, cam)
            writer.send(renderer.render())
            costs.append(time.perf_counter() - t0)
    except Exception as exc:  # the encoder died (disk full, ...): reported at stop
        error = f"{type(exc).__name__}: {exc}"
    finally:
        reader.mark_gone()
        writer.close()
        renderer.close()
    c = np.asarray(costs) * 1e3
    result = {
        "path": path, "frames": len(costs), "dropped": reader.dropped, "error": error,
        "ms_per_frame": {
            "median": float(np.median(c)) if c.size else None,
            "p99": float(np.percentile(c, 99)) if c.size else None,
            "worst": float(c.max()) if c.size else None,
        },
    }  # fmt: skip
    try:
        conn.send(result)
    except (OSError, EOFError):
        pass


__all__ = ["DEFAULT_FPS", "HEIGHT", "INSTALL_HINT", "WIDTH", "Recorder", "check_record"]
