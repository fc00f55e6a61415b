"""Episode recording (robomimic's HDF5 layout): what is written is read back bit for bit,
states, actions and camera frames, from a policy run on the lockstep simulator too; bad
steps are refused and a file never holds half an episode."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import CAMERA_SIZE, Rig

from panda_py.learning import DroidActions, EpisodeWriter, PolicyRunner, read_recording

pytestmark = pytest.mark.timeout(300)


def steps(rng: np.random.Generator, n: int) -> list[tuple[dict, np.ndarray, np.ndarray]]:
    return [
        (
            {
                "observation/joint_position": rng.normal(size=7),
                "observation/gripper_position": rng.uniform(size=1),
                "observation/front": rng.integers(0, 256, (12, 16, 3), dtype=np.uint8),
                "time": 0.1 * i,
                "prompt": "stack the cube",  # a text: kept out of the arrays
            },
            rng.normal(size=8),
            rng.normal(size=7),
        )
        for i in range(n)
    ]


def test_episodes_round_trip_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(20)
    path = tmp_path / "episodes.hdf5"
    written = [steps(rng, 5), steps(rng, 3)]
    with EpisodeWriter(path, env_args={"env_kwargs": {"rate": 15.0}}) as writer:
        for i, episode in enumerate(written):
            writer.begin(prompt="stack the cube", seed=i)
            for obs, action, target in episode:
                writer.add(obs, action, joint_target=target)
            assert len(writer) == len(episode)
            assert writer.end() == i
        writer.begin()
        writer.add(*written[0][0][:2], joint_target=written[0][0][2])  # never ended
    with EpisodeWriter(path, append=True) as writer:  # a third, after the two
        for obs, action, target in written[0]:
            writer.add(obs, action, joint_target=target)
        assert writer.end() == 2
        assert writer.end() == -1  # nothing under way: nothing written
    recording = read_recording(path)
    assert recording.env_args["env_kwargs"] == {"rate": 15.0}
    assert recording.env_args["env_name"] == "panda_py"
    assert [e.name for e in recording.episodes] == ["demo_0", "demo_1", "demo_2"]
    for episode, steps_written in zip(recording.episodes, [*written, written[0]], strict=True):
        assert len(episode) == len(steps_written)
        np.testing.assert_array_equal(episode.actions, [a for _, a, _ in steps_written])
        np.testing.assert_array_equal(
            episode.action_dict["joint_target"], [t for _, _, t in steps_written]
        )
        assert sorted(episode.obs) == ["front", "gripper_position", "joint_position", "time"]
        for key in ("joint_position", "gripper_position", "front", "time"):
            name = key if key == "time" else f"observation/{key}"
            np.testing.assert_array_equal(episode.obs[key], [o[name] for o, _, _ in steps_written])
        assert episode.obs["front"].dtype == np.uint8
        assert episode.dones.tolist() == [0] * (len(episode) - 1) + [1]
        assert not episode.rewards.any()
    assert recording.episodes[1].attrs == {"prompt": "stack the cube", "seed": 1}
    with h5py.File(path) as f:  # robomimic's bookkeeping
        assert f["data"].attrs["total"] == 5 + 3 + 5
        assert f["data/demo_1"].attrs["num_samples"] == 3


def test_bad_steps_are_refused_and_nothing_half_written(tmp_path: Path) -> None:
    rng = np.random.default_rng(21)
    path = tmp_path / "bad.hdf5"
    (obs, action, target), *_ = steps(rng, 1)
    with EpisodeWriter(path) as writer:
        writer.add(obs, action, joint_target=target)
        with pytest.raises(ValueError, match=r"'joint_position' expected shape \(7,\)"):
            writer.add({**obs, "observation/joint_position": np.zeros(6)}, action,
                       joint_target=target)  # fmt: skip
        with pytest.raises(ValueError, match=r"expected the entries of the episode's first"):
            writer.add({"observation/joint_position": np.zeros(7)}, action, joint_target=target)
        with pytest.raises(ValueError, match="finite action"):
            writer.add(obs, [0.0, np.nan], joint_target=target)
        with pytest.raises(ValueError, match="expected numbers"):
            writer.add({**obs, "observation/name": "text"}, action, joint_target=target)
        with pytest.raises(ValueError, match="without '/'"):
            writer.add({"observation/a/b": 1.0}, action)
        assert len(writer) == 1  # the refused steps were not added
        with pytest.raises(TypeError):
            writer.begin(seed=object())  # not JSON-able
        assert writer.end() == 0
    assert len(read_recording(path).episodes) == 1
    with pytest.raises(TypeError):
        EpisodeWriter(tmp_path / "never.hdf5", env_args={"x": object()})
    assert not (tmp_path / "never.hdf5").exists()


def test_a_policy_run_on_the_simulator_is_recorded_with_its_frames(
    rig: Rig, tmp_path: Path
) -> None:
    drawn: list[np.ndarray] = []

    def camera() -> np.ndarray:
        drawn.append(rig.sim.render())
        return drawn[-1]

    chunk = np.zeros((10, 8))
    chunk[:, 0] = 0.2  # DROID's normalised: 0.04 rad a step, joint 1 turns the arm
    chunk[5:, 7] = 1.0  # closing the hand half way through
    path = tmp_path / "run.hdf5"
    with (
        EpisodeWriter(path, env_args={"env_kwargs": {"rate": 15.0}}) as writer,
        DroidActions(
            rig.panda, rig.gripper, from_measured=False, cameras={"front": camera}
        ) as actions,
    ):
        writer.begin(prompt="turn")
        stats = PolicyRunner(actions, lambda obs: chunk, prompt="turn", recorder=writer).run(10)
        last_target = actions.target.copy()
        writer.end()
    episode = read_recording(path).episodes[0]
    assert episode.attrs == {"prompt": "turn"}
    n = len(episode)
    assert n == len(stats.latency) == 10 - stats.skipped  # a step for every action sent
    assert len(drawn) == n + stats.held  # a frame for every observation
    frames = episode.obs["front"]
    assert frames.shape == (n, CAMERA_SIZE[1], CAMERA_SIZE[0], 3)
    np.testing.assert_array_equal(frames, drawn[: len(frames)])  # bit for bit
    moved = np.abs(frames[0].astype(int) - frames[-1].astype(int)).max(axis=2) > 30
    print(f"\n{moved.sum()} pixels changed; {stats.summary()}")
    assert moved.sum() > 20  # the arm turned
    q = episode.obs["joint_position"]
    assert np.all(np.diff(q[:, 0]) >= -1e-4) and q[-1, 0] - q[0, 0] > 0.05
    assert np.all(np.diff(episode.obs["time"]) > 0)
    targets = episode.action_dict["joint_target"]
    np.testing.assert_array_equal(targets[-1], last_target)
    # each target one step of the chunk further (0.04 rad), integrated from the last
    np.testing.assert_allclose(np.diff(targets[:, 0]), 0.04, atol=1e-12)
    assert episode.actions[-1, 7] == 1.0
