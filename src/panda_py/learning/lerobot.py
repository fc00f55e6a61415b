"""Episode recording to LeRobot's dataset format, beside robomimic's HDF5
(:mod:`~panda_py.learning.recording`): codebase v3.0, what lerobot 0.4 to 0.6 write and load.

Why this format too: LeRobot's policies (ACT, Diffusion Policy, pi0, SmolVLA) and openpi's
fine-tuning train on it, and the Hugging Face Hub shows and streams it. It needs ``pyarrow``
(Parquet) and ``av`` (PyAV, whose wheel brings FFmpeg with the AV1 encoder ``libsvtav1``
and H.264's ``libx264``): the ``learning`` extra. What is lossy: camera images become
video (AV1 at LeRobot's own settings: yuv420p, CRF 30, a keyframe every 2 frames), so
pixels come back within a few levels, not bit for bit as from the HDF5 file. Every other
number is kept exactly, in its own dtype (LeRobot hands float64 columns to torch as
float32).

The layout (lerobot's ``datasets/utils.py``), a directory written whole::

    meta/info.json       codebase_version "v3.0", fps, robot_type, features, totals, paths
    meta/stats.json      per feature: min, max, mean, std, count, q01 ... q99
    meta/tasks.parquet   the tasks (the index) and their task_index
    meta/episodes/chunk-000/file-000.parquet  an episode a row: length, tasks, where its
                         rows and frames are (dataset_from_index, videos/<key>/...), stats
    meta/panda_py.json   ours: env_args, each episode's begin() attributes, the shapes
    data/chunk-000/file-000.parquet           a row a step, a row group an episode
    videos/observation.images.<camera>/chunk-000/file-000.mp4   the episodes' frames in turn

Observations in openpi's DROID names (:meth:`DroidActions.observation
<panda_py.learning.deploy.DroidActions.observation>`) become the features LeRobot's users
expect::

    observation/joint_position (7) + observation/gripper_position (1) -> observation.state
    observation/<camera>, (H, W, 3) uint8                       -> observation.images.<camera>
    observation/<key> (joint_velocity, ...), time               -> observation.<key>
    the action (8,) -> action; add()'s extras (joint_target=...) -> action.<key>
    begin(prompt=...) (else the observation's "prompt")         -> the episode's task

and LeRobot's own columns: ``timestamp`` (frame_index / fps, what its video lookup keys on;
the robot's clock is ``observation.time``), ``frame_index``, ``episode_index``, ``index``,
``task_index``. Files roll over at LeRobot's sizes (100 MB of rows, 200 MB of video).
:mod:`~panda_py.learning.lerobot_convert` reads a dataset back and converts HDF5 files.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.learning._lerobot_files import (
    CHUNKS_SIZE,
    CODEBASE_VERSION,
    CODECS,
    DATA_MB,
    DATA_PATH,
    DEFAULT_FEATURES,
    EPISODES_PATH,
    IMAGES,
    STAT_FRAMES,
    STAT_SIDE,
    STATE,
    VIDEO_MB,
    VIDEO_PATH,
    Files,
    Video,
    aggregate,
    feature_stats,
    is_image,
    modules,
)
from panda_py.learning.recording import Step, _check_step

__all__ = ["CODEBASE_VERSION", "CODECS", "LeRobotWriter"]


class LeRobotWriter:
    """Writes episodes to a new LeRobot dataset at ``root`` (a directory that must not
    exist yet) at ``fps`` steps a second (a whole number: DROID's 15), with the recorder
    interface of :class:`~panda_py.learning.recording.EpisodeWriter` (:meth:`begin`,
    :meth:`add`, :meth:`end`; ``PolicyRunner(..., recorder=writer)``).

    :meth:`end` writes an episode's rows and encodes its frames into a hidden directory
    beside ``root``; :meth:`close` writes the metadata and renames that directory to
    ``root``. So ``root`` never holds half a dataset: an error while writing leaves nothing
    there, an episode not ended is dropped, and :meth:`discard` drops all."""

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        fps: int,
        robot_type: str = "franka",
        codec: str = "libsvtav1",
        env_args: Mapping[str, Any] | None = None,
    ) -> None:
        if isinstance(fps, bool) or not isinstance(fps, int | np.integer) or fps <= 0:
            raise ValueError(f"fps: expected a whole number > 0 (LeRobot's), got {fps!r}")
        if codec not in CODECS:
            raise ValueError(f"codec: expected one of {sorted(CODECS)}, got {codec!r}")
        self.env_args = json.loads(json.dumps(dict(env_args or {})))  # JSON-able; a copy
        self.root = Path(root)
        if self.root.exists():
            raise FileExistsError(f"root: expected a path not there yet, got {str(root)!r}")
        self._pa, self._pq, self._av = modules()
        self.fps, self.robot_type, self.codec = int(fps), robot_type, codec
        self.root.parent.mkdir(parents=True, exist_ok=True)
        self._dir = Path(tempfile.mkdtemp(prefix=f".{self.root.name}.", dir=self.root.parent))
        umask = os.umask(0o22)
        os.umask(umask)
        self._dir.chmod(0o777 & ~umask)  # as a directory made the usual way
        self.episodes = self.frames = 0  # written
        self._steps: list[Step] = []
        self._attrs: dict[str, Any] = {}
        self._first: list[Step] = []  # the dataset's first step: the entries of every step
        self._features: dict[str, dict[str, Any]] = {}
        self._ours: dict[str, Any] = {"panda_py_format": 1, "env_args": self.env_args,
                                      "state": [], "shapes": {}, "episodes": []}  # fmt: skip
        self._rows: list[dict[str, Any]] = []  # meta/episodes
        self._stats: list[dict[str, dict[str, np.ndarray]]] = []  # an episode's each
        self._tasks: dict[str, int] = {}
        self._data = Files(self._dir, DATA_PATH, DATA_MB)
        self._videos: dict[str, Video] = {}
        self._closed = self._broken = False

    def begin(self, **attrs: Any) -> None:
        """Start an episode (dropping steps added since the last :meth:`end`); ``attrs``
        (JSON-able: a seed, ...) are kept with it; ``prompt`` (a text) is its task."""
        json.dumps(attrs)
        if not isinstance(attrs.get("prompt", ""), str):
            raise ValueError(f"prompt: expected a text (the task), got {attrs['prompt']!r}")
        self._steps, self._attrs = [], dict(attrs)

    def add(self, observation: Mapping[str, Any], action: Any, **extras: Any) -> None:
        """Add a step as :meth:`EpisodeWriter.add <panda_py.learning.recording.EpisodeWriter.
        add>` does, every step of the dataset with the same entries and shapes: images
        (H, W, 3) uint8, the other entries numbers or vectors."""
        first = self._steps[:1] or self._first
        which = "the episode's first step" if self._steps else "the dataset's first step"
        step = _check_step(observation, action, extras, first, which)
        for what, entries in (("observation", step[0]), ("extras", step[2])):
            for k, v in entries.items():
                if v.ndim > 1 and not (what == "observation" and is_image(v)):
                    raise ValueError(f"{what}: {k!r} expected a number, a vector or an (H, W, 3) "
                                     f"uint8 image, got shape {v.shape} {v.dtype}")  # fmt: skip
        if not self._steps and "prompt" not in self._attrs and "prompt" in observation:
            self._attrs["prompt"] = str(observation["prompt"])
        self._steps.append(step)

    def __len__(self) -> int:
        """Steps of the episode under way."""
        return len(self._steps)

    def end(self) -> int:
        """Write the episode under way (its rows; its frames encoded) and return its index;
        an empty one is not written (returns -1)."""
        if self._closed:
            raise ValueError("end: expected an open writer, got a closed one")
        steps, self._steps = self._steps, []
        if not steps:
            return -1
        try:
            self._write(steps)
        except BaseException:
            self._broken = True  # part of an episode is in the files: close() keeps nothing
            raise
        self._first = steps[:1]
        self.episodes, self.frames = self.episodes + 1, self.frames + len(steps)
        return self.episodes - 1

    def _columns(self, steps: list[Step]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """An episode's (rows, camera frames) under LeRobot's names; the first episode's
        make the dataset's features."""
        obs0 = steps[0][0]
        rows: dict[str, np.ndarray] = {}
        frames: dict[str, np.ndarray] = {}
        state = [k for k in STATE if k in obs0]
        if state:
            rows["observation.state"] = np.stack(
                [np.concatenate([np.ravel(o[k]) for k in state]) for o, _, _ in steps])  # fmt: skip
        for k in (k for k in obs0 if k not in state):
            (frames if is_image(obs0[k]) else rows)[
                (IMAGES if is_image(obs0[k]) else "observation.") + k
            ] = np.stack([o[k] for o, _, _ in steps])
        rows["action"] = np.stack([a for _, a, _ in steps])
        rows.update({f"action.{k}": np.stack([e[k] for _, _, e in steps]) for k in steps[0][2]})
        if not self._features:
            self._ours["state"] = [(k, list(obs0[k].shape)) for k in state]
            names = [f"{k}.{i}" for k in state for i in range(obs0[k].size)]
            for name, v in {**rows, **frames}.items():
                video = name in frames
                self._features[name] = {
                    "dtype": "video" if video else v.dtype.name,
                    "shape": list(v.shape[1:]) if video else [v[0].size],
                    "names": ["height", "width", "channels"] if video else
                             names if name == "observation.state" else None,
                }  # fmt: skip
                self._ours["shapes"][name] = list(v.shape[1:])
        # every episode in the first's order and dtypes (one schema for the Parquet files)
        rows = {k: rows[k].astype(f["dtype"], copy=False) for k, f in self._features.items()
                if k in rows}  # fmt: skip
        return rows, frames

    def _write(self, steps: list[Step]) -> None:
        pa, pq, n, i = self._pa, self._pq, len(steps), self.episodes
        rows, frames = self._columns(steps)
        task = self._attrs.get("prompt", "")
        rows["timestamp"] = (np.arange(n) / self.fps).astype(np.float32)
        rows["frame_index"] = np.arange(n)
        rows["episode_index"] = np.full(n, i)
        rows["index"] = self.frames + np.arange(n)
        rows["task_index"] = np.full(n, self._tasks.setdefault(task, len(self._tasks)))
        stats = {k: feature_stats(v.reshape(n, -1), n) for k, v in rows.items()}
        table = pa.Table.from_arrays(
            [pa.array(v.reshape(n)) if v.size == n else  # a number a step: a plain column
             pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1)), v[0].size)
             for v in rows.values()], names=list(rows))  # fmt: skip
        if not self._data.ready():
            self._data.handle = pq.ParquetWriter(str(self._data.path()), table.schema)
        self._data.handle.write_table(table)  # a row group an episode, as lerobot writes them
        row = {"episode_index": i, "tasks": [task], "length": n,
               "data/chunk_index": self._data.chunk, "data/file_index": self._data.file,
               "dataset_from_index": self.frames, "dataset_to_index": self.frames + n}  # fmt: skip
        for key, images in frames.items():
            if key not in self._videos:
                self._videos[key] = Video(self._dir, key, self.fps, self.codec, self._av)
            row.update(self._videos[key].add(images))
            pick = np.linspace(0, n - 1, min(n, STAT_FRAMES)).round().astype(int)
            step = max(1, max(images.shape[1:3]) // STAT_SIDE)  # lerobot's: ~150 px a side
            s = feature_stats(images[pick, ::step, ::step].reshape(-1, 3) / 255.0, len(pick))
            stats[key] = {k: v if k == "count" else v.reshape(3, 1, 1) for k, v in s.items()}
        row.update({f"stats/{k}/{s}": v.tolist() for k, d in stats.items() for s, v in d.items()})
        self._rows.append({**row, "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
        self._stats.append(stats)
        self._ours["episodes"].append(self._attrs)

    def _finalize(self) -> None:
        pa, pq = self._pa, self._pq
        self._data.close()
        for video in self._videos.values():
            video.close()
        features = {**self._features, **DEFAULT_FEATURES}
        for key, video in self._videos.items():
            features[key]["info"] = video.info()
        info = {
            "codebase_version": CODEBASE_VERSION, "robot_type": self.robot_type,
            "total_episodes": self.episodes, "total_frames": self.frames,
            "total_tasks": len(self._tasks), "chunks_size": CHUNKS_SIZE,
            "data_files_size_in_mb": DATA_MB, "video_files_size_in_mb": VIDEO_MB,
            "fps": self.fps, "splits": {"train": f"0:{self.episodes}"}, "data_path": DATA_PATH,
            "video_path": VIDEO_PATH if self._videos else None, "features": features,
        }  # fmt: skip
        stats = {k: {s: v.tolist() for s, v in aggregate([e[k] for e in self._stats]).items()}
                 for k in self._stats[0]}  # fmt: skip
        (self._dir / EPISODES_PATH).parent.mkdir(parents=True)
        for path, value in (("info", info), ("stats", stats), ("panda_py", self._ours)):
            (self._dir / f"meta/{path}.json").write_text(json.dumps(value, indent=4))
        pq.write_table(pa.Table.from_pylist(self._rows), str(self._dir / EPISODES_PATH))
        # lerobot reads it with pandas: the texts are the frame's index (pandas' metadata)
        columns = [
            {"name": n, "field_name": n, "pandas_type": t, "numpy_type": u, "metadata": None}
            for n, t, u in (("task_index", "int64", "int64"), ("task", "unicode", "object"))
        ]
        pandas = {"index_columns": ["task"], "column_indexes": [], "columns": columns}
        tasks = pa.table({"task_index": list(self._tasks.values()), "task": list(self._tasks)})
        pq.write_table(tasks.replace_schema_metadata({"pandas": json.dumps(pandas)}),
                       str(self._dir / "meta/tasks.parquet"))  # fmt: skip

    def close(self) -> None:
        """Write the dataset's metadata and move it to ``root`` (an episode under way is
        dropped; without an episode nothing is written)."""
        if self._closed:
            return
        self._closed, self._steps = True, []
        try:
            if self.episodes and not self._broken:
                self._finalize()
                if self.root.exists():
                    raise FileExistsError(f"root: {str(self.root)!r} appeared while writing")
                os.rename(self._dir, self.root)
        finally:
            for files in (self._data, *self._videos.values()):
                with contextlib.suppress(Exception):  # an error on the way: the files go
                    files.close()
            shutil.rmtree(self._dir, ignore_errors=True)

    def discard(self) -> None:
        """Drop every episode: nothing is written to ``root``."""
        self._broken = True
        self.close()

    def __enter__(self) -> LeRobotWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
