"""Episode recording: robot states, actions and camera frames, to robomimic's HDF5 layout.

Why this format: one file per dataset that robomimic (and the tools built on it:
robosuite, MimicGen, LIBERO's loaders) trains on as it is, that ``h5py``, HDFView or any
HDF5 library reads, and that needs one small dependency (``h5py``, the ``learning``
extra). Images are stored losslessly inside the file (uint8, gzip), so a recording
round-trips bit for bit. Beside it, :class:`~panda_py.learning.lerobot.LeRobotWriter`
records to LeRobot's dataset format (Parquet, MP4 and JSON metadata: what LeRobot's
policies and openpi fine-tune on) with the same recorder interface, its images as lossy
video; :func:`~panda_py.learning.lerobot_convert.hdf5_to_lerobot` converts a file of these
into one.

The layout (robomimic's "Dataset Structure", robomimic.github.io/docs/datasets/overview)::

    data                       attrs: total (samples in all episodes), env_args (JSON)
      demo_0                   attrs: num_samples, and the episode's own (JSON values)
        actions                (N, 8) float64: the policy's actions (DROID's layout)
        rewards, dones         (N,) zeros; dones[-1] = 1
        obs/<key>              (N, ...) one per observation entry, the ``observation/``
                               prefix dropped: joint_position, gripper_position, ...,
                               time [s of the robot's clock], camera images (N, H, W, 3)
        action_dict/<key>      (N, ...) what the actions became: joint_target [rad], ...
      demo_1 ...

robomimic reads ``next_obs`` only when asked (``train.hdf5_load_next_obs``); these files
have none: set it false.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["INSTALL_HINT", "Episode", "EpisodeWriter", "Recording", "read_recording"]

INSTALL_HINT = 'pip install "panda-py-pure[learning]"'
PREFIX = "observation/"  # openpi's DROID names (panda_py.learning.deploy.observation)
FORMAT_VERSION = 1  # data.attrs["panda_py_format"]


def _h5py() -> Any:
    try:
        import h5py
    except ImportError as exc:
        raise ImportError(f"episode recording needs h5py: {INSTALL_HINT}") from exc
    return h5py


def _key(name: str) -> str:
    key = name[len(PREFIX) :] if name.startswith(PREFIX) else name
    if not key or "/" in key or key in (".", ".."):
        raise ValueError(
            f"observation: expected entry names without '/' (besides the '{PREFIX}' "
            f"prefix), got {name!r}"
        )
    return key


Step = tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]


def _check_step(
    observation: Mapping[str, Any],
    action: Any,
    extras: Mapping[str, Any],
    first: list[Step],
    label: str = "the episode's first step",
) -> Step:
    """A step as arrays (``observation`` without its ``prompt`` and its names' prefix),
    checked: numbers only, a finite action vector, and (``first``: ``[step]`` to match,
    ``label`` saying which) the same entries and shapes as that step. Raises ValueError."""
    obs = {_key(k): np.asarray(v) for k, v in observation.items() if k != "prompt"}
    act = np.asarray(action, dtype=np.float64)
    if act.ndim != 1 or not np.isfinite(act).all():
        raise ValueError(f"action: expected a finite action vector, got {action!r}")
    more = {k: np.asarray(v) for k, v in extras.items()}
    for what, entries in (("observation", obs), ("extras", more)):
        for k, v in entries.items():
            if v.dtype.kind not in "biuf":
                raise ValueError(
                    f"{what}: {k!r} expected numbers (an array or a number), got "
                    f"{v.dtype} (a text belongs in begin()'s attributes)"
                )
    if first:
        first_obs, first_act, first_more = first[0]
        for what, now, then in (("observation", obs, first_obs), ("extras", more, first_more)):
            if now.keys() != then.keys():
                raise ValueError(
                    f"{what}: expected the entries of {label} {sorted(then)}, got {sorted(now)}"
                )
            for k, v in now.items():
                if v.shape != then[k].shape:
                    raise ValueError(
                        f"{what}: {k!r} expected shape {then[k].shape} as in {label}, got {v.shape}"
                    )
        if act.shape != first_act.shape:
            raise ValueError(f"action: expected shape {first_act.shape}, got {act.shape}")
    return obs, act, more


class EpisodeWriter:
    """Writes episodes to the HDF5 file ``path`` (a new file; ``append``: after the
    episodes it has). ``env_args`` (JSON-able, robomimic's: ``env_name``, ``type``,
    ``env_kwargs``) says what ran: robot, action space, rate. Steps are kept in memory
    and an episode is written whole at :meth:`end`, so a file never holds half an
    episode."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        env_args: Mapping[str, Any] | None = None,
        append: bool = False,
    ) -> None:
        h5py = _h5py()
        args = {"env_name": "panda_py", "type": 2, "env_kwargs": {}, **(env_args or {})}
        text = json.dumps(args)  # not JSON-able: TypeError before the file is touched
        self.path = os.fspath(path)
        self._file = h5py.File(self.path, "a" if append else "w")
        data = self._file.require_group("data")
        if env_args is not None or "env_args" not in data.attrs:  # appending keeps its own
            data.attrs["env_args"] = text
        data.attrs["panda_py_format"] = FORMAT_VERSION
        data.attrs.setdefault("total", 0)
        self.episodes = sum(1 for k in data if k.startswith("demo_"))
        self._steps: list[Step] = []
        self._attrs: dict[str, Any] = {}

    def begin(self, **attrs: Any) -> None:
        """Start an episode (dropping steps added since the last :meth:`end`); ``attrs``
        (JSON-able: a prompt, a seed) are stored with it."""
        json.dumps(attrs)
        self._steps, self._attrs = [], dict(attrs)

    def add(self, observation: Mapping[str, Any], action: Any, **extras: Any) -> None:
        """Add a step: the observation the action was chosen on (arrays or numbers under
        the same names, of the same shapes, every step), the action (8,) and ``extras``
        of it (``joint_target=...``) for ``action_dict``."""
        self._steps.append(_check_step(observation, action, extras, self._steps[:1]))

    def __len__(self) -> int:
        """Steps of the episode under way."""
        return len(self._steps)

    def end(self) -> int:
        """Write the episode under way as ``demo_<n>`` and return n; an empty one is
        not written (returns -1)."""
        steps, self._steps = self._steps, []
        if not steps:
            return -1
        data = self._file["data"]
        n = self.episodes
        group = data.create_group(f"demo_{n}")
        try:
            count = len(steps)
            group.attrs["num_samples"] = count
            for k, v in self._attrs.items():
                group.attrs[k] = json.dumps(v)
            group.create_dataset("actions", data=np.stack([a for _, a, _ in steps]))
            group.create_dataset("rewards", data=np.zeros(count))
            dones = np.zeros(count, dtype=np.int64)
            dones[-1] = 1
            group.create_dataset("dones", data=dones)
            for name, index in (("obs", 0), ("action_dict", 2)):
                sub = group.create_group(name)
                for k in steps[0][index]:
                    values = np.stack([s[index][k] for s in steps])
                    image = values.dtype == np.uint8 and values.ndim == 4
                    sub.create_dataset(
                        k,
                        data=values,
                        compression="gzip" if image else None,
                        chunks=(1, *values.shape[1:]) if image else None,
                    )
        except BaseException:
            del data[f"demo_{n}"]
            raise
        data.attrs["total"] = int(data.attrs["total"]) + count
        self._file.flush()
        self.episodes = n + 1
        return n

    def close(self) -> None:
        """Close the file (an episode under way and not ended is dropped)."""
        self._steps = []
        self._file.close()

    def __enter__(self) -> EpisodeWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class Episode:
    """One recorded episode, as :func:`read_recording` returns it."""

    name: str  # "demo_0", ...
    actions: np.ndarray  # (N, 8)
    obs: dict[str, np.ndarray]
    action_dict: dict[str, np.ndarray]
    rewards: np.ndarray
    dones: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.actions)


@dataclass
class Recording:
    """A recording file: what ran (``env_args``) and its episodes, in order."""

    env_args: dict[str, Any]
    episodes: list[Episode]


def read_recording(path: str | os.PathLike[str]) -> Recording:
    """Read every episode of the HDF5 file ``path`` (written by :class:`EpisodeWriter`,
    or any file of robomimic's layout)."""
    h5py = _h5py()
    with h5py.File(os.fspath(path), "r") as f:
        if "data" not in f:
            raise ValueError(f"path: expected an HDF5 file with a 'data' group, got {path!r}")
        data = f["data"]
        names = sorted((k for k in data if k.startswith("demo_")), key=lambda k: int(k[5:]))
        episodes = []
        for name in names:
            g = data[name]
            attrs = {k: _attribute(v) for k, v in g.attrs.items() if k != "num_samples"}
            groups = {s: {k: v[()] for k, v in g[s].items()} if s in g else {}
                      for s in ("obs", "action_dict")}  # fmt: skip
            episodes.append(
                Episode(
                    name=name,
                    actions=g["actions"][()],
                    obs=groups["obs"],
                    action_dict=groups["action_dict"],
                    rewards=g["rewards"][()] if "rewards" in g else np.zeros(0),
                    dones=g["dones"][()] if "dones" in g else np.zeros(0),
                    attrs=attrs,
                )
            )
        env_args = _attribute(data.attrs.get("env_args", "{}"))
    return Recording(env_args if isinstance(env_args, dict) else {}, episodes)


def _attribute(value: Any) -> Any:
    """An attribute as written (JSON text), or as another writer left it."""
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str):
        try:
            return json.loads(value)
        except ValueError:
            return value
    return value.tolist() if isinstance(value, np.ndarray | np.generic) else value
