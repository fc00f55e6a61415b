"""LeRobot datasets (codebase v3.0): episodes written by LeRobotWriter come back from
read_lerobot with their states, actions and times exact and their camera frames within
the video's loss; an HDF5 recording converts; bad input is refused and a failed dataset
leaves nothing; and lerobot's own LeRobotDataset (in its own environment) loads what we
write."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from peer_envs import PeerUnavailable, peer_environ, peer_python

from panda_py.learning import (
    EpisodeWriter,
    LeRobotWriter,
    hdf5_to_lerobot,
    read_lerobot,
    read_recording,
)
from panda_py.learning.lerobot_convert import main

pytestmark = pytest.mark.timeout(300)

FPS = 15  # DROID's
SIZE = (24, 32)  # [px] (H, W): small, so encoding takes milliseconds
# [levels of 255] how far decoded pixels may be from the images encoded, on average and at
# the 99th percentile (yuv420p halves the colours' resolution, and these images are tiny);
# measured on these: AV1 (CRF 30) mean 2.6-3.4, p99 15-22; H.264 (CRF 23) 2.7-3.1, 16
MEAN_ERROR, P99_ERROR = 5.0, 30


def image(i: int) -> np.ndarray:
    """A smooth camera image, a different one each step: a gradient whose brightness
    swings, and a blob going round."""
    y, x = np.mgrid[: SIZE[0], : SIZE[1]]
    cx, cy = 16 + 10 * np.sin(0.7 * i), 12 + 7 * np.cos(0.7 * i)
    blob = 120 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 20.0)
    base = np.stack([40 + 4 * x + 30 * np.sin(0.3 * i), 60 + 3 * y, 90 + 0 * x], axis=-1)
    return np.clip(base + blob[..., None] * [1, 0.5, -0.5], 0, 255).astype(np.uint8)


def steps(
    rng: np.random.Generator, n: int, start: int = 0
) -> list[tuple[dict, np.ndarray, np.ndarray]]:
    return [
        (
            {
                "observation/joint_position": rng.normal(size=7),
                "observation/gripper_position": rng.uniform(size=1),
                "observation/joint_velocity": rng.normal(size=7),
                "observation/exterior_image_1_left": image(start + i),
                "time": 1234.5 + i / FPS,
                "prompt": "stack the cube",  # a text: the task, kept out of the arrays
            },
            rng.normal(size=8),
            rng.normal(size=7),
        )
        for i in range(n)
    ]


def record(root: Path, episodes: list[tuple[str, list]], **options) -> None:
    with LeRobotWriter(root, fps=FPS, env_args={"env_kwargs": {"rate": 15.0}}, **options) as w:
        for i, (prompt, episode) in enumerate(episodes):
            w.begin(prompt=prompt, seed=i)
            for obs, action, target in episode:
                w.add(obs, action, joint_target=target)
            assert len(w) == len(episode)
            assert w.end() == i
        w.begin()
        w.add(*episodes[0][1][0][:2], joint_target=episodes[0][1][0][2])  # never ended
    assert not list(root.parent.glob(f".{root.name}.*"))  # the hidden directory: renamed


def check_frames(decoded: np.ndarray, written: np.ndarray) -> None:
    """Within the video's loss, and each frame its own (not its neighbour's)."""
    assert decoded.shape == written.shape and decoded.dtype == np.uint8
    error = np.abs(decoded.astype(int) - written.astype(int))
    p99 = np.percentile(error, 99)
    assert error.mean() < MEAN_ERROR and p99 <= P99_ERROR, (error.mean(), p99)
    for k in range(len(written)):  # not one step early or late
        own = np.abs(decoded[k].astype(int) - written[k]).mean()
        for j in (k - 1, k + 1):
            if 0 <= j < len(written):
                assert own < np.abs(decoded[k].astype(int) - written[j]).mean(), (k, j)


@pytest.mark.parametrize("codec", ["libsvtav1", "h264"])
def test_recording_leaves_the_threads_scheduling_as_it_was(tmp_path: Path, codec: str) -> None:
    # SVT-AV1 puts the thread that encodes its first frame under SCHED_FIFO 99 where it may
    # (root here): the script that records would then run above the robot's loop
    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    try:
        record(tmp_path / "dataset", [("stack the cube", steps(np.random.default_rng(1), 3))],
               codec=codec)  # fmt: skip
        assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    finally:
        os.sched_setscheduler(0, before[0], os.sched_param(before[1]))


@pytest.mark.parametrize("codec", ["libsvtav1", "h264"])
def test_episodes_round_trip(tmp_path: Path, codec: str) -> None:
    rng = np.random.default_rng(30)
    written = [("stack the cube", steps(rng, 6)), ("open the drawer", steps(rng, 4, 6)),
               ("stack the cube", steps(rng, 3, 10))]  # fmt: skip
    prompt, second = written[1]  # its entries in another order: the same columns
    written[1] = (prompt, [(dict(reversed(o.items())), a, t) for o, a, t in second])
    root = tmp_path / "dataset"
    record(root, written, codec=codec)
    recording = read_lerobot(root)
    assert recording.env_args == {"env_kwargs": {"rate": 15.0}}
    assert [e.name for e in recording.episodes] == ["episode_0", "episode_1", "episode_2"]
    for i, (episode, (prompt, steps_written)) in enumerate(
        zip(recording.episodes, written, strict=True)
    ):
        assert episode.attrs == {"prompt": prompt, "seed": i}
        assert len(episode) == len(steps_written)
        obs = [o for o, _, _ in steps_written]
        np.testing.assert_array_equal(episode.actions, [a for _, a, _ in steps_written])
        np.testing.assert_array_equal(
            episode.action_dict["joint_target"], [t for _, _, t in steps_written]
        )
        keys = ["joint_position", "gripper_position", "joint_velocity", "time"]
        assert sorted(episode.obs) == sorted([*keys, "exterior_image_1_left"])
        for key in keys:
            name = key if key == "time" else f"observation/{key}"
            np.testing.assert_array_equal(episode.obs[key], [o[name] for o in obs])  # exact
        check_frames(episode.obs["exterior_image_1_left"],
                     np.array([o["observation/exterior_image_1_left"] for o in obs]))  # fmt: skip
        assert episode.dones.tolist() == [0] * (len(episode) - 1) + [1]

    # LeRobot's own files, as lerobot's code reads them
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == FPS
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (3, 13, 2)
    features = info["features"]
    assert list(features) == [
        "observation.state", "observation.joint_velocity", "observation.time", "action",
        "action.joint_target", "observation.images.exterior_image_1_left", "timestamp",
        "frame_index", "episode_index", "index", "task_index",
    ]  # fmt: skip
    assert features["observation.state"]["shape"] == [8]
    assert features["observation.state"]["names"][6:] == ["joint_position.6", "gripper_position.0"]
    video = features["observation.images.exterior_image_1_left"]
    assert video["dtype"] == "video" and video["shape"] == [*SIZE, 3]
    assert video["info"]["video.codec"] == {"libsvtav1": "av1", "h264": "h264"}[codec]
    assert video["info"]["video.pix_fmt"] == "yuv420p"
    data = pq.read_table(root / "data/chunk-000/file-000.parquet")
    assert (
        data.num_rows == 13
        and pq.ParquetFile(root / "data/chunk-000/file-000.parquet").num_row_groups == 3
    )
    assert data.column("index").to_pylist() == list(range(13))
    assert data.column("episode_index").to_pylist() == [0] * 6 + [1] * 4 + [2] * 3
    assert data.column("frame_index").to_pylist() == [*range(6), *range(4), *range(3)]
    assert data.column("task_index").to_pylist() == [0] * 6 + [1] * 4 + [0] * 3
    np.testing.assert_allclose(
        data.column("timestamp").to_numpy()[6:10], np.arange(4) / FPS, rtol=1e-6
    )
    tasks = pq.read_table(root / "meta/tasks.parquet").to_pydict()
    assert tasks == {"task_index": [0, 1], "task": ["stack the cube", "open the drawer"]}
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert [(e["dataset_from_index"], e["dataset_to_index"], e["length"]) for e in episodes] == [
        (0, 6, 6), (6, 10, 4), (10, 13, 3)]  # fmt: skip
    key = "videos/observation.images.exterior_image_1_left/"
    assert [e[key + "from_timestamp"] * FPS for e in episodes] == pytest.approx([0, 6, 10])
    assert episodes[1]["tasks"] == ["open the drawer"]
    stats = json.loads((root / "meta/stats.json").read_text())
    actions = np.concatenate([e.actions for e in recording.episodes])
    np.testing.assert_allclose(stats["action"]["mean"], actions.mean(0))
    np.testing.assert_allclose(stats["action"]["std"], actions.std(0))
    np.testing.assert_allclose(stats["action"]["max"], actions.max(0))
    assert stats["action"]["count"] == [13] and len(stats["action"]["q99"]) == 8
    assert np.shape(stats["observation.images.exterior_image_1_left"]["mean"]) == (3, 1, 1)
    assert stats["observation.time"]["min"] == [1234.5]


def test_full_files_roll_over_to_the_next(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from panda_py.learning import _lerobot_files, lerobot

    monkeypatch.setattr(lerobot, "DATA_MB", 0)  # every file full once it has bytes
    monkeypatch.setattr(_lerobot_files, "VIDEO_MB", 0)
    monkeypatch.setattr(_lerobot_files, "CHUNKS_SIZE", 2)  # 2 files a chunk
    rng = np.random.default_rng(35)
    # 25 steps an episode: AV1's encoder holds 22 frames before it writes any
    written = [("stack the cube", steps(rng, 25, 25 * i)) for i in range(3)]
    root = tmp_path / "dataset"
    record(root, written)
    data = sorted(p.relative_to(root).as_posix() for p in root.glob("data/*/*.parquet"))
    assert data == ["data/chunk-000/file-000.parquet", "data/chunk-000/file-001.parquet",
                    "data/chunk-001/file-000.parquet"]  # fmt: skip
    assert len(list(root.glob("videos/*/*/*.mp4"))) >= 2  # full once its encoder wrote
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert [(e["data/chunk_index"], e["data/file_index"]) for e in episodes] == [
        (0, 0), (0, 1), (1, 0)]  # fmt: skip
    for episode, (_, steps_written) in zip(read_lerobot(root).episodes, written, strict=True):
        np.testing.assert_array_equal(episode.actions, [a for _, a, _ in steps_written])
        frames = [o["observation/exterior_image_1_left"] for o, _, _ in steps_written]
        check_frames(episode.obs["exterior_image_1_left"], np.array(frames))


def test_an_hdf5_recording_converts(tmp_path: Path) -> None:
    rng = np.random.default_rng(31)
    src = tmp_path / "episodes.hdf5"
    with EpisodeWriter(src, env_args={"env_kwargs": {"rate": 15.0}}) as writer:
        for i, episode in enumerate([steps(rng, 5), steps(rng, 3, 5)]):
            writer.begin(prompt=f"task {i}")
            for obs, action, target in episode:
                writer.add(obs, action, joint_target=target)
            writer.end()
    assert hdf5_to_lerobot(src, tmp_path / "dataset", fps=FPS) == 2
    hdf5, lerobot = read_recording(src), read_lerobot(tmp_path / "dataset")
    assert lerobot.env_args == hdf5.env_args
    for a, b in zip(hdf5.episodes, lerobot.episodes, strict=True):
        assert a.attrs == b.attrs and sorted(a.obs) == sorted(b.obs)
        np.testing.assert_array_equal(a.actions, b.actions)
        np.testing.assert_array_equal(a.action_dict["joint_target"], b.action_dict["joint_target"])
        for key, values in a.obs.items():
            if key == "exterior_image_1_left":
                check_frames(b.obs[key], values)
            else:
                np.testing.assert_array_equal(b.obs[key], values)
    # from a shell, with the codec that plays anywhere; an existing directory: an error
    main(["convert", str(src), str(tmp_path / "h264"), "--fps", "15", "--codec", "h264"])
    assert len(read_lerobot(tmp_path / "h264").episodes) == 2
    with pytest.raises(SystemExit) as exit_:
        main(["convert", str(src), str(tmp_path / "h264"), "--fps", "15"])
    assert exit_.value.code == 2
    # the shell's command runs the same main
    shell = [sys.executable, "-m", "panda_py.learning.lerobot_convert", "convert", "--help"]
    done = subprocess.run(shell, capture_output=True, text=True, timeout=60)
    assert (
        done.returncode == 0
        and "python -m panda_py.learning.lerobot_convert convert" in done.stdout
    )


def test_bad_input_is_refused_and_nothing_is_half_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(32)
    (obs, action, target), *_ = steps(rng, 1)
    root = tmp_path / "dataset"
    for fps in (0, 15.5, True, "15"):
        with pytest.raises(ValueError, match=r"fps: expected a whole number > 0"):
            LeRobotWriter(root, fps=fps)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"codec: expected one of \['h264', 'libsvtav1'\]"):
        LeRobotWriter(root, fps=FPS, codec="vp9")
    with pytest.raises(TypeError):
        LeRobotWriter(root, fps=FPS, env_args={"x": object()})  # not JSON-able
    (tmp_path / "taken").mkdir()
    with pytest.raises(FileExistsError, match="expected a path not there yet"):
        LeRobotWriter(tmp_path / "taken", fps=FPS)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]

    with LeRobotWriter(root, fps=FPS) as writer:
        with pytest.raises(ValueError, match=r"prompt: expected a text"):
            writer.begin(prompt=3)
        with pytest.raises(
            ValueError, match=r"'depth' expected a number, a vector or an \(H, W, 3\) uint8"
        ):
            writer.add({**obs, "observation/depth": np.zeros((4, 4))}, action)
        with pytest.raises(ValueError, match=r"extras: 'view' expected a number, a vector"):
            writer.add(obs, action, view=image(0))
        writer.add(obs, action, joint_target=target)
        with pytest.raises(
            ValueError, match=r"expected shape \(7,\) as in the episode's first step"
        ):
            writer.add(
                {**obs, "observation/joint_position": np.zeros(6)}, action, joint_target=target
            )
        assert writer.end() == 0
        with pytest.raises(
            ValueError, match=r"observation: expected the entries of the dataset's first step"
        ):
            writer.add({"observation/joint_position": np.zeros(7)}, action, joint_target=target)
        with pytest.raises(
            ValueError,
            match=r"'exterior_image_1_left' expected shape \(24, 32, 3\) as in the dataset's",
        ):
            writer.add({**obs, "observation/exterior_image_1_left": np.zeros((8, 8, 3), np.uint8)},
                       action, joint_target=target)  # fmt: skip
        assert not root.exists()  # not before close()
    assert len(read_lerobot(root).episodes) == 1
    with pytest.raises(ValueError, match="end: expected an open writer"):
        writer.end()

    # no episode, discarded, or an error while writing one: nothing at root, no hidden directory
    with LeRobotWriter(tmp_path / "empty", fps=FPS):
        pass
    with LeRobotWriter(tmp_path / "discarded", fps=FPS) as writer:
        writer.add(obs, action)
        writer.end()
        writer.discard()
    from panda_py.learning import _lerobot_files

    def broken(self: object, frames: np.ndarray) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(_lerobot_files.Video, "add", broken)
    with (
        pytest.raises(OSError, match="disk full"),
        LeRobotWriter(tmp_path / "failed", fps=FPS) as writer,
    ):
        writer.add(obs, action)
        writer.end()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset", "taken"]

    with pytest.raises(
        ValueError, match=r"root: expected a LeRobot dataset \(its meta/info.json\)"
    ):
        read_lerobot(tmp_path / "taken")
    (tmp_path / "taken/meta").mkdir()
    (tmp_path / "taken/meta/info.json").write_text(json.dumps({"codebase_version": "v2.1"}))
    with pytest.raises(
        ValueError, match=r"expected a LeRobot dataset of codebase v3.0, got 'v2.1'"
    ):
        read_lerobot(tmp_path / "taken")


# lerobot's LeRobotDataset on our dataset: what a training script sees, item by item
PEER_SCRIPT = """
import json, sys
import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset

root, fps = sys.argv[1], int(sys.argv[2])
ds = LeRobotDataset("local/panda_py", root=root, video_backend="pyav")
items = [ds[i] for i in range(len(ds))]
chunked = LeRobotDataset("local/panda_py", root=root, video_backend="pyav",
                         delta_timestamps={"action": [0, 1 / fps, 2 / fps]})
last = chunked[len(chunked) - 1]
out = {
    "len": len(ds), "episodes": ds.num_episodes, "fps": ds.fps,
    "tasks": {task: int(row.task_index) for task, row in ds.meta.tasks.iterrows()},
    "bounds": [[int(e["dataset_from_index"]), int(e["dataset_to_index"])]
               for e in ds.meta.episodes],
    "stats": sorted(ds.meta.stats),
    "chunk_first": chunked[0]["action"].tolist(),
    "chunk_last": last["action"].tolist(), "pad_last": last["action_is_pad"].tolist(),
}
for key in ("observation.state", "action", "action.joint_target", "observation.joint_velocity",
            "timestamp", "frame_index", "episode_index", "index", "task_index"):
    out[key] = [item[key].tolist() for item in items]
out["dtypes"] = {key: str(items[0][key].dtype) for key in ("observation.state", "index")}
out["task"] = [item["task"] for item in items]
frames = [item["observation.images.exterior_image_1_left"] for item in items]
out["frames"] = [np.round(f.permute(1, 2, 0).numpy() * 255).astype(int).tolist() for f in frames]
print(json.dumps(out))
"""


@pytest.mark.peer
@pytest.mark.timeout(1200)
def test_lerobot_loads_what_we_write(tmp_path: Path) -> None:
    try:
        python = peer_python("lerobot")
    except PeerUnavailable as exc:
        pytest.skip(str(exc))
    rng = np.random.default_rng(33)
    written = [("stack the cube", steps(rng, 5)), ("open the drawer", steps(rng, 4, 5))]
    root = tmp_path / "dataset"
    record(root, written)
    done = subprocess.run([str(python), "-c", PEER_SCRIPT, str(root), str(FPS)], env=peer_environ(),
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert (out["len"], out["episodes"], out["fps"]) == (9, 2, FPS)
    assert out["bounds"] == [[0, 5], [5, 9]]
    assert out["tasks"] == {"stack the cube": 0, "open the drawer": 1}
    assert out["task"] == ["stack the cube"] * 5 + ["open the drawer"] * 4
    assert out["episode_index"] == [0] * 5 + [1] * 4 and out["index"] == list(range(9))
    assert out["frame_index"] == [*range(5), *range(4)]
    assert out["task_index"] == [0] * 5 + [1] * 4
    np.testing.assert_allclose(
        out["timestamp"], [*range(5), *range(4)] / np.float64(FPS), rtol=1e-6
    )
    obs = [o for _, episode in written for o, _, _ in episode]
    actions = np.array([a for _, episode in written for _, a, _ in episode])
    state = [
        np.concatenate([o["observation/joint_position"], o["observation/gripper_position"]])
        for o in obs
    ]
    # lerobot hands float64 columns to torch as float32: ours, to float32
    assert out["dtypes"] == {"observation.state": "torch.float32", "index": "torch.int64"}
    np.testing.assert_array_equal(out["observation.state"], np.float32(state))
    np.testing.assert_array_equal(out["action"], np.float32(actions))
    velocities = [o["observation/joint_velocity"] for o in obs]
    np.testing.assert_array_equal(out["observation.joint_velocity"], np.float32(velocities))
    targets = [t for _, episode in written for _, _, t in episode]
    np.testing.assert_array_equal(out["action.joint_target"], np.float32(targets))
    # action chunks (pi0's, ACT's) stay within an episode: the last step's is padded
    np.testing.assert_array_equal(out["chunk_first"], np.float32(actions[:3]))
    assert out["pad_last"] == [False, True, True]
    np.testing.assert_array_equal(out["chunk_last"][0], np.float32(actions[-1]))
    # lerobot's decoder: the frames we encoded, and those our reader decodes
    frames = np.array(out["frames"], dtype=np.uint8)
    check_frames(frames, np.array([o["observation/exterior_image_1_left"] for o in obs]))
    ours = np.concatenate([e.obs["exterior_image_1_left"] for e in read_lerobot(root).episodes])
    assert np.abs(frames.astype(int) - ours).max() <= 2
    assert "observation.images.exterior_image_1_left" in out["stats"] and "action" in out["stats"]


# lerobot's own writer: a video camera, an "image" camera (PNG files in the rows), a reward
PEER_WRITER = """
import json, sys
import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset

data = json.load(sys.stdin)
image = {"dtype": "video", "shape": (24, 32, 3), "names": ["height", "width", "channels"]}
features = {
    "observation.state": {"dtype": "float32", "shape": (8,), "names": None},
    "action": {"dtype": "float32", "shape": (8,), "names": None},
    "observation.images.front": image,
    "observation.images.wrist": {**image, "dtype": "image"},
    "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
}
ds = LeRobotDataset.create("local/theirs", fps=data["fps"], features=features, root=data["root"],
                           robot_type="franka")
for episode in data["episodes"]:
    for step in episode["steps"]:
        ds.add_frame({
            "observation.state": np.float32(step["state"]), "action": np.float32(step["action"]),
            "observation.images.front": np.uint8(step["front"]),
            "observation.images.wrist": np.uint8(step["wrist"]),
            "next.reward": np.float32([step["reward"]]), "task": episode["task"],
        })
    ds.save_episode()
ds.finalize()
"""


@pytest.mark.peer
@pytest.mark.timeout(1200)
def test_we_read_what_lerobot_writes(tmp_path: Path) -> None:
    try:
        python = peer_python("lerobot")
    except PeerUnavailable as exc:
        pytest.skip(str(exc))
    rng = np.random.default_rng(34)
    episodes = []
    for task, ks in (("stack the cube", range(4)), ("open the drawer", range(4, 7))):
        steps_ = [{"state": rng.normal(size=8).tolist(), "action": rng.normal(size=8).tolist(),
                   "front": image(k).tolist(), "wrist": image(20 - k)[::-1].tolist(),
                   "reward": float(k == ks[-1])} for k in ks]  # fmt: skip
        episodes.append({"task": task, "steps": steps_})
    root = tmp_path / "theirs"
    payload = {"fps": FPS, "root": str(root), "episodes": episodes}
    done = subprocess.run([str(python), "-c", PEER_WRITER], env=peer_environ(), capture_output=True,
                          text=True, input=json.dumps(payload), timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    recording = read_lerobot(root)
    assert recording.env_args == {"fps": FPS, "robot_type": "franka"}
    assert [e.name for e in recording.episodes] == ["episode_0", "episode_1"]
    for ours, theirs in zip(recording.episodes, episodes, strict=True):
        steps_ = theirs["steps"]
        assert ours.attrs == {"prompt": theirs["task"]}
        assert sorted(ours.obs) == ["front", "state", "wrist"]
        np.testing.assert_array_equal(ours.obs["state"], np.float32([s["state"] for s in steps_]))
        np.testing.assert_array_equal(ours.actions, np.float32([s["action"] for s in steps_]))
        np.testing.assert_array_equal(ours.rewards, [s["reward"] for s in steps_])
        np.testing.assert_array_equal(ours.obs["wrist"], [s["wrist"] for s in steps_])  # PNG
        check_frames(ours.obs["front"], np.uint8([s["front"] for s in steps_]))
