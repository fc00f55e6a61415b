"""The simulator's drawing processes started and stopped together (the viewer, the video
recorder, the camera: :mod:`~panda_py.sim.viewer`, :mod:`~panda_py.sim.video`,
:mod:`~panda_py.sim.camera`, each a :class:`~panda_py.sim.drawing.DrawingProcess`):
before the simulator starts, and after it ended.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from panda_py.sim.camera import Camera
from panda_py.sim.config import SimConfig
from panda_py.sim.drawing import DrawingProcess
from panda_py.sim.video import Recorder
from panda_py.sim.viewer import Viewer

__all__ = ["start_drawing", "stop_drawing"]

log = logging.getLogger("panda_py.sim")


def start_drawing(
    config: SimConfig,
    *,
    viewer: bool,
    record: str | Path | None,
    fps: float,
    timeout: float,
    camera_size: tuple[int, int] | None = None,
) -> list[DrawingProcess]:
    """Start the viewer's, the recorder's and the camera's processes, before the
    simulator (which writes into their feeds: ``config.frame_feeds`` is set). Raises
    :class:`DrawingError` (one line, with the fix) with none left running."""
    started: list[DrawingProcess] = []
    try:
        if viewer:
            started.append(Viewer(config).start(timeout))
        if record is not None:
            started.append(Recorder(config, record, fps).start(timeout))
        if camera_size is not None:
            started.append(Camera(config, camera_size).start(timeout))
    except BaseException:
        stop_drawing(started)
        raise
    config.frame_feeds = tuple(d.feed for d in started)
    return started


def stop_drawing(drawing: list[DrawingProcess]) -> dict[str, Any] | None:
    """After the simulator ended: the recorder encodes what is queued and closes its file.
    Returns the recorder's report (path, frames, dropped, error, ms_per_frame) if any."""
    recording = None
    for d in drawing:
        result = d.stop()
        if isinstance(d, Recorder):
            recording = result
            if result is None or result.get("error"):
                why = "it did not finish" if result is None else result["error"]
                log.warning("the video %s may be incomplete: %s", d.path, why)
            else:
                log.info("recorded %d frames to %s", result["frames"], d.path)
    drawing.clear()
    return recording
