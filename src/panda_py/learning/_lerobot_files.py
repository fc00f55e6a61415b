"""The files of a LeRobot dataset (codebase v3.0) as :class:`~panda_py.learning.lerobot.
LeRobotWriter` writes them and :mod:`~panda_py.learning.lerobot_convert` reads them: lerobot's
paths, sizes and default features (its ``datasets/utils.py``, ``utils/constants.py``), its
statistics (``datasets/compute_stats.py``), and the growing Parquet and MP4 files (its
video settings: ``configs/video.py``, ``datasets/video_utils.py``)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.learning.recording import INSTALL_HINT

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE, DATA_MB, VIDEO_MB = 1000, 100, 200  # lerobot's: files a chunk, sizes of files
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
OURS_PATH = "meta/panda_py.json"
STATE = ("joint_position", "gripper_position")  # observation.state, in this order
IMAGES = "observation.images."
#: the video codecs (encoders of PyAV's FFmpeg) and their options: libsvtav1 (AV1, what
#: LeRobot writes, at its settings) or h264 (libx264: plays anywhere, larger files)
CODECS: dict[str, dict[str, int]] = {
    "libsvtav1": {"g": 2, "crf": 30, "preset": 12},
    "h264": {"g": 2, "crf": 23},
}
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  # lerobot's q01 ... q99
STAT_FRAMES, STAT_SIDE = 100, 150  # image statistics: <= frames an episode, ~pixels a side
DEFAULT_FEATURES = {  # lerobot's, after a dataset's own
    name: {"dtype": dtype, "shape": [1], "names": None}
    for name, dtype in (("timestamp", "float32"), ("frame_index", "int64"),
                        ("episode_index", "int64"), ("index", "int64"), ("task_index", "int64"))
}  # fmt: skip


def modules() -> tuple[Any, Any, Any]:
    """(pyarrow, pyarrow.parquet, av), imported on first use."""
    try:
        import av
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise ImportError(f"LeRobot datasets need pyarrow and av: {INSTALL_HINT}") from exc
    os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1: its errors, not its banner
    return pa, pq, av


@contextmanager
def own_scheduling() -> Iterator[None]:
    """Keep the calling thread's scheduling policy: SVT-AV1 starts its encoder by putting
    the thread that encodes the first frame under SCHED_FIFO 99 where it may (as root, or
    with the rtprio limit) and leaves it there, so a recording script's Python would run at
    realtime priority above the robot's own loop."""
    try:
        policy, priority = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    except (AttributeError, OSError):  # not on Linux
        yield
        return
    try:
        yield
    finally:
        if (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) != (policy, priority):
            os.sched_setscheduler(0, policy, os.sched_param(priority))


def is_image(v: np.ndarray) -> bool:
    return v.dtype == np.uint8 and v.ndim == 3 and v.shape[-1] == 3


def feature_stats(x: np.ndarray, count: int) -> dict[str, np.ndarray]:
    """LeRobot's statistics of the samples ``x`` (n, d), each (d,) (quantiles exact where
    lerobot estimates them from histograms)."""
    x = x.astype(np.float64)
    out = {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0)}
    out.update({f"q{round(q * 100):02d}": np.quantile(x, q, axis=0) for q in QUANTILES})
    return {**out, "count": np.array([count])}


def aggregate(stats: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The episodes' statistics pooled as lerobot's ``aggregate_feature_stats`` pools them
    (quantiles: their means weighted by count)."""
    n = np.array([s["count"][0] for s in stats], dtype=np.float64)
    w = list((n / n.sum()).reshape(-1, *[1] * stats[0]["mean"].ndim))
    mean = sum(wi * s["mean"] for wi, s in zip(w, stats, strict=True))
    out = {"min": np.min([s["min"] for s in stats], 0), "max": np.max([s["max"] for s in stats], 0),
           "mean": mean, "count": np.array([int(n.sum())])}  # fmt: skip
    out["std"] = np.sqrt(sum(wi * (s["std"] ** 2 + (s["mean"] - mean) ** 2)
                             for wi, s in zip(w, stats, strict=True)))  # fmt: skip
    for q in (k for k in stats[0] if k[0] == "q"):
        out[q] = sum(wi * s[q] for wi, s in zip(w, stats, strict=True))
    return out


class Files:
    """A growing file of LeRobot's (data, or one camera's video): the next file once it
    passes ``limit`` MB, files numbered chunk-CCC/file-FFF."""

    def __init__(self, root: Path, pattern: str, limit: int, **names: str) -> None:
        self.root, self.pattern, self.limit, self.names = root, pattern, limit, names
        self.chunk, self.file, self.count = 0, 0, 0
        self.handle: Any = None  # the open file's writer

    def path(self, chunk: int = -1, file: int = -1) -> Path:
        chunk, file = (self.chunk, self.file) if chunk < 0 else (chunk, file)
        return self.root / self.pattern.format(chunk_index=chunk, file_index=file, **self.names)

    def ready(self) -> bool:
        """Whether the current file is open; closes it (for the next) when full."""
        if self.handle is not None and self.path().exists():
            if self.path().stat().st_size > self.limit << 20:
                self.close()
                self.file = (self.file + 1) % CHUNKS_SIZE
                self.chunk += self.file == 0
        if self.handle is None:
            self.path().parent.mkdir(parents=True, exist_ok=True)
            self.count = 0
        return self.handle is not None

    def close(self) -> None:
        handle, self.handle = self.handle, None
        if handle is not None:
            handle.close()


class Video(Files):
    """A camera's video: episodes' frames one after another, ``fps`` a second."""

    def __init__(self, root: Path, key: str, fps: int, codec: str, av: Any) -> None:
        super().__init__(root, VIDEO_PATH, VIDEO_MB, video_key=key)
        self.fps, self.codec, self.av = fps, codec, av
        self.stream: Any = None

    def add(self, frames: np.ndarray) -> dict[str, Any]:
        """Encode an episode's frames; where they are (lerobot's videos/<key>/ columns)."""
        av, tick = self.av, Fraction(1, self.fps)
        if not self.ready():
            self.handle = av.open(str(self.path()), "w")
            options = {k: str(v) for k, v in CODECS[self.codec].items()}
            self.stream = self.handle.add_stream(self.codec, rate=self.fps, options=options)
            self.stream.pix_fmt, self.stream.time_base = "yuv420p", tick
            self.stream.height, self.stream.width = frames.shape[1:3]
        start = self.count
        for k, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts, frame.time_base = start + k, tick
            with own_scheduling():
                self.handle.mux(self.stream.encode(frame))
        self.count += len(frames)
        where = {
            "chunk_index": self.chunk,
            "file_index": self.file,
            "from_timestamp": start / self.fps,
            "to_timestamp": self.count / self.fps,
        }
        return {f"videos/{self.names['video_key']}/{k}": v for k, v in where.items()}

    def close(self) -> None:
        if self.handle is not None:
            try:
                with own_scheduling():
                    self.handle.mux(self.stream.encode(None))  # the frames the encoder holds
            finally:
                super().close()

    def info(self) -> dict[str, Any]:
        """The feature's ``info`` in info.json, from its first file (lerobot's
        ``get_video_info`` with its encoder's settings)."""
        with self.av.open(str(self.path(0, 0))) as container:
            s = container.streams.video[0]
            return {"video.height": s.height, "video.width": s.width,
                    "video.codec": s.codec.canonical_name, "video.pix_fmt": s.pix_fmt,
                    "video.fps": self.fps, "video.channels": 3, "has_audio": False,
                    **{f"video.{k}": v for k, v in CODECS[self.codec].items()},
                    "video.fast_decode": 0, "video.video_backend": "pyav",
                    "video.extra_options": {}, "is_depth_map": False}  # fmt: skip
