"""LeRobot datasets (codebase v3.0) to and from our recordings: :func:`read_lerobot` reads
one into :class:`~panda_py.learning.recording.Recording`'s episodes, as
:func:`~panda_py.learning.recording.read_recording` reads an HDF5 file;
:func:`hdf5_to_lerobot` converts an HDF5 recording into one (and
``python -m panda_py.learning.lerobot_convert convert SRC.hdf5 DST --fps 15`` does from a shell).

A dataset of :class:`~panda_py.learning.lerobot.LeRobotWriter`'s comes back under the names
it was recorded with (``observation.state`` split into ``joint_position`` and
``gripper_position``, every entry in the shape it was added). Another's (lerobot's own,
or one from the Hugging Face Hub) maps ``observation.images.<c>`` to ``obs[<c>]``,
``observation.<key>`` to ``obs[<key>]`` (``observation.state`` to ``obs["state"]``),
``action.<key>`` to ``action_dict[<key>]`` and ``next.reward``/``next.done`` to rewards and
dones. Frames (videos, decoded with PyAV, or lerobot's "image" features) come back as
(N, H, W, 3) uint8; like ``read_recording``, the whole dataset is read into memory.
"""

from __future__ import annotations

import argparse
import io
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.learning._lerobot_files import (
    CODEBASE_VERSION,
    CODECS,
    IMAGES,
    OURS_PATH,
    modules,
)
from panda_py.learning.lerobot import LeRobotWriter
from panda_py.learning.recording import Episode, Recording, read_recording

__all__ = ["hdf5_to_lerobot", "main", "read_lerobot"]


def _column(table: Any, name: str, shape: list[int], image: bool) -> np.ndarray:
    """A column as an array (rows, *shape): a number a row, a vector (a list), or an
    image (lerobot's "image" features: PNG files' bytes) as (H, W, 3) uint8."""
    values = table.column(name).combine_chunks()
    if image:
        from PIL import Image  # matplotlib's dependency, so ours

        files = values.field("bytes").to_pylist()
        return np.stack([np.asarray(Image.open(io.BytesIO(f)).convert("RGB")) for f in files])
    if hasattr(values, "flatten"):
        return values.flatten().to_numpy(zero_copy_only=False).reshape(len(values), *shape)
    return values.to_numpy(zero_copy_only=False).reshape(len(values), *shape)


def _frames(path: Path, fps: int, av: Any) -> tuple[np.ndarray, list[np.ndarray]]:
    """A video's frames: their numbers (time * fps) and images (H, W, 3) uint8."""
    with av.open(str(path)) as container:
        decoded = [(f.time, f.to_ndarray(format="rgb24"))
                   for f in container.decode(container.streams.video[0])]  # fmt: skip
    return np.round(np.array([t for t, _ in decoded]) * fps).astype(int), [f for _, f in decoded]


def read_lerobot(root: str | os.PathLike[str]) -> Recording:
    """Read every episode of the LeRobot dataset at ``root`` (the directory holding
    ``meta/info.json``), in order. ``Recording.env_args``: what the writer was given
    (another's dataset: its ``fps`` and ``robot_type``); ``Episode.attrs``: the episode's
    :meth:`~panda_py.learning.lerobot.LeRobotWriter.begin` attributes (another's:
    ``{"prompt": its task}``); ``Episode.name``: ``episode_<index>``."""
    pa, pq, av = modules()
    root = Path(root)
    try:
        info = json.loads((root / "meta/info.json").read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"root: expected a LeRobot dataset (its meta/info.json), got "
                         f"{str(root)!r} ({exc})") from exc  # fmt: skip
    if info.get("codebase_version") != CODEBASE_VERSION:
        raise ValueError(f"root: expected a LeRobot dataset of codebase {CODEBASE_VERSION}, got "
                         f"{info.get('codebase_version')!r} in {str(root)!r}")  # fmt: skip
    fps, features = info["fps"], info["features"]
    ours = json.loads((root / OURS_PATH).read_text()) if (root / OURS_PATH).exists() else {}
    shapes, state = ours.get("shapes", {}), ours.get("state", [])

    def table(where: str) -> Any:
        paths = sorted((root / where).glob("*/*.parquet"))
        if not paths:
            raise ValueError(f"root: expected Parquet files in {where}/, found none in {root}")
        return pa.concat_tables([pq.read_table(str(p)) for p in paths])

    meta = table("meta/episodes")
    meta = meta.select([c for c in meta.column_names if not c.startswith("stats/")])
    data = table("data")
    data = data.take(np.argsort(data.column("index").to_numpy(), kind="stable"))
    index = data.column("index").to_numpy()
    columns = {}  # a number a step: (N,), unless we know better
    for name, ft in features.items():
        if name in data.column_names:
            shape = shapes.get(name, [] if ft["shape"] == [1] else ft["shape"])
            columns[name] = _column(data, name, shape, ft["dtype"] == "image")
    videos: dict[Path, tuple[np.ndarray, list[np.ndarray]]] = {}
    episodes = []
    for e in sorted(meta.to_pylist(), key=lambda e: e["episode_index"]):
        n, i = e["length"], e["episode_index"]
        a, b = np.searchsorted(index, [e["dataset_from_index"], e["dataset_to_index"]])
        if b - a != n:
            raise ValueError(f"episode {i}: expected {n} rows in data/, found {b - a}")
        rows = {name: v[a:b] for name, v in columns.items()}
        obs: dict[str, np.ndarray] = {}
        if state and "observation.state" in rows:
            sizes = np.cumsum([int(np.prod(shape)) for _, shape in state])[:-1]
            for (key, shape), part in zip(state, np.split(rows.pop("observation.state"), sizes, 1),
                                          strict=True):  # fmt: skip
                obs[key] = part.reshape(n, *shape)
        for name in (name for name, ft in features.items() if ft["dtype"] == "video"):
            p = f"videos/{name}/"
            path = root / info["video_path"].format(
                video_key=name, chunk_index=e[p + "chunk_index"], file_index=e[p + "file_index"]
            )
            if path not in videos:
                videos[path] = _frames(path, fps, av)
            numbers, decoded = videos[path]
            first = round(e[p + "from_timestamp"] * fps)
            a, b = np.searchsorted(numbers, [first, first + n])
            if b - a != n:
                raise ValueError(f"{path}: expected {n} frames from frame {first}, found {b - a}")
            obs[name.removeprefix(IMAGES)] = np.stack(decoded[a:b])
        obs.update({k.removeprefix(IMAGES).removeprefix("observation."): v
                    for k, v in rows.items() if k.startswith("observation.")})  # fmt: skip
        tasks = list(e["tasks"])
        attrs = ours["episodes"][i] if ours else {"prompt": tasks[0]} if len(tasks) == 1 else {
            "tasks": tasks}  # fmt: skip
        episodes.append(Episode(
            name=f"episode_{i}", actions=rows["action"], obs=obs,
            action_dict={k.removeprefix("action."): v for k, v in rows.items()
                         if k.startswith("action.")},
            rewards=rows.get("next.reward", np.zeros(n)),
            dones=rows.get("next.done", (np.arange(n) == n - 1).astype(np.int64)), attrs=attrs,
        ))  # fmt: skip
    env_args = ours["env_args"] if ours else {"fps": fps, "robot_type": info.get("robot_type")}
    return Recording(dict(env_args), episodes)


def hdf5_to_lerobot(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    fps: int,
    robot_type: str = "franka",
    codec: str = "libsvtav1",
) -> int:
    """Convert the HDF5 recording ``src`` (robomimic's layout, as
    :class:`~panda_py.learning.recording.EpisodeWriter` writes it) into a new LeRobot
    dataset at ``dst`` recorded at ``fps`` steps a second; returns how many episodes. All
    are converted or nothing is written."""
    recording = read_recording(src)
    writer = LeRobotWriter(dst, fps=fps, robot_type=robot_type, codec=codec,
                           env_args=recording.env_args)  # fmt: skip
    try:
        for episode in recording.episodes:
            writer.begin(**episode.attrs)
            for i in range(len(episode)):
                writer.add({k: v[i] for k, v in episode.obs.items()}, episode.actions[i],
                           **{k: v[i] for k, v in episode.action_dict.items()})  # fmt: skip
            writer.end()
    except BaseException:
        writer.discard()
        raise
    writer.close()
    return len(recording.episodes)


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m panda_py.learning.lerobot_convert convert SRC.hdf5 DST --fps 15``."""
    parser = argparse.ArgumentParser(prog="python -m panda_py.learning.lerobot_convert",
                                     description="LeRobot datasets of our recordings")  # fmt: skip
    commands = parser.add_subparsers(dest="command", required=True)
    convert = commands.add_parser("convert", help="an HDF5 recording to a LeRobot dataset")
    convert.add_argument("src", help="the HDF5 file (robomimic's layout)")
    convert.add_argument("dst", help="the dataset's directory (not there yet)")
    convert.add_argument("--fps", type=int, required=True, help="steps a second (DROID: 15)")
    convert.add_argument("--robot-type", default="franka", help="info.json's robot_type")
    convert.add_argument("--codec", default="libsvtav1", choices=sorted(CODECS))
    args = parser.parse_args(argv)
    try:
        n = hdf5_to_lerobot(args.src, args.dst, fps=args.fps, robot_type=args.robot_type,
                            codec=args.codec)  # fmt: skip
    except (ValueError, OSError) as exc:
        parser.exit(2, f"error: {exc}\n")
    print(f"{n} episodes of {args.src} written to {args.dst}")


if __name__ == "__main__":
    main()
