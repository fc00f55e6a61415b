"""``PandaVectorEnv`` (``gymnasium.make_vec``'s default for the ids): the same
observations, rewards, end flags and infos as Gymnasium's ``SyncVectorEnv`` of the same
environments, bit for bit, autoresets included; bad actions refused with nothing
stepped; a worker that dies named; no worker outlives the vector or its caller."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import gymnasium
import numpy as np
import pytest

import panda_py.learning  # noqa: F401  (registers the ids)
from panda_py.learning import PandaVectorEnv, pick_and_place_policy, reach_policy

pytestmark = pytest.mark.timeout(300)


def _policy(policy, obs, n):  # type: ignore[no-untyped-def]
    return np.stack([policy({k: v[i] for k, v in obs.items()}) for i in range(n)])


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie has ended
        return f.read().split()[2] != "Z"


@pytest.mark.parametrize(("env_id", "policy", "steps"), [
    ("PandaReach-v0", reach_policy, 60),
    ("PandaPickAndPlace-v0", pick_and_place_policy, 25),
])  # fmt: skip
def test_it_steps_as_gymnasiums_sync_vector_does(env_id, policy, steps) -> None:  # type: ignore[no-untyped-def]
    n = 3
    ours = gymnasium.make_vec(env_id, num_envs=n, workers=2, max_episode_steps=20)
    assert isinstance(ours, PandaVectorEnv)
    theirs = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="sync",
                                max_episode_steps=20)  # fmt: skip
    try:
        assert ours.observation_space == theirs.observation_space
        assert ours.action_space == theirs.action_space
        assert ours.metadata["autoreset_mode"] == theirs.metadata["autoreset_mode"]
        (o1, i1), (o2, i2) = ours.reset(seed=7), theirs.reset(seed=7)
        ended = 0
        for step in range(steps):
            for k in o2:
                np.testing.assert_array_equal(o1[k], o2[k], err_msg=f"{k} at step {step}")
            assert sorted(i1) == sorted(i2)
            for k in i2:
                np.testing.assert_array_equal(i1[k], i2[k], err_msg=f"info {k} at step {step}")
            actions = _policy(policy, o2, n)
            o1, r1, te1, tr1, i1 = ours.step(actions)
            o2, r2, te2, tr2, i2 = theirs.step(actions)
            np.testing.assert_array_equal(r1, r2)
            np.testing.assert_array_equal(te1, te2)
            np.testing.assert_array_equal(tr1, tr2)
            assert r1.dtype == r2.dtype and te1.dtype == te2.dtype
            ended += int((te2 | tr2).sum())
        assert ended > 0  # the episodes' ends (and so the autoresets) were compared too
    finally:
        ours.close()
        theirs.close()


def test_bad_actions_are_refused_with_nothing_stepped() -> None:
    envs = PandaVectorEnv("PandaReach-v0", 2, workers=2)
    try:
        obs, _ = envs.reset(seed=0)
        good = _policy(reach_policy, obs, 2)
        _, _, _, _, info = envs.step(good)
        t = info["time"].copy()
        bad_nan, bad_far = good.copy(), good.copy()
        bad_nan[1, 2] = np.nan
        bad_far[1, 0] = 1.5
        for actions, match in (
            (bad_nan, r"environment 1's value 2 is nan: expected a finite value"),
            (bad_far, r"environment 1's value 0 is 1.5: .*within \[-1.0, 1.0\]"),
            (good[:1], r"expected shape \(2, 3\), got shape \(1, 3\)"),
            ("go", r"expected \(2, 3\) numbers"),
        ):
            with pytest.raises(ValueError, match=match):
                envs.step(actions)
        _, _, _, _, info = envs.step(good)
        np.testing.assert_allclose(info["time"], t + 0.05)  # one step on, not two
    finally:
        envs.close()


def test_its_arguments_are_checked_before_any_process_starts() -> None:
    from panda_py.learning import RobotArm

    cases = [
        ({"env_id": "PandaPush-v9"}, r"env_id: expected one of"),
        ({"num_envs": 0}, r"num_envs: expected a whole number >= 1, got 0"),
        ({"workers": 0}, r"workers: expected a whole number >= 1, got 0"),
        ({"spin": -1}, r"spin: expected a time in \[0, 1\] s"),
        ({"action": "fly"}, r"action: expected one of"),
        ({"backend": object.__new__(RobotArm)}, r"runs the fast world only.*sync"),
    ]
    for kwargs, match in cases:
        with pytest.raises(ValueError, match=match):
            PandaVectorEnv(**kwargs)  # type: ignore[arg-type]
    # what only an environment checks comes back from the workers as its own error
    with pytest.raises(ValueError, match=r"policy_rate: expected a rate in \[1, 100\] Hz"):
        PandaVectorEnv("PandaReach-v0", 2, workers=2, policy_rate=1000.0)


def test_a_reflex_truncates_its_episode_alone_with_the_reason_in_the_infos() -> None:
    envs = PandaVectorEnv("PandaReach-v0", 2, workers=2)
    try:
        obs, _ = envs.reset(seed=1)
        envs._local.envs[0].unwrapped.backend.inject_reflex("cartesian_reflex")  # type: ignore[union-attr]
        obs, _, terminated, truncated, info = envs.step(_policy(reach_policy, obs, 2))
        assert list(truncated) == [True, False] and not terminated[0]
        assert list(info["_reflex"]) == [True, False]
        assert "cartesian_reflex" in info["reflex"][0]
        # next-step autoreset: the episode starts again, the other goes on
        obs, reward, _, truncated, info = envs.step(_policy(reach_policy, obs, 2))
        assert not truncated.any() and reward[0] == 0.0 and "reflex" not in info
        assert info["time"][0] == 0.0 and info["time"][1] == pytest.approx(0.1)
    finally:
        envs.close()


def test_call_reads_each_environments_attribute() -> None:
    envs = PandaVectorEnv("PandaReach-v0", 3, workers=2, policy_rate=25.0)
    try:
        assert envs.get_attr("policy_rate") == (25.0, 25.0, 25.0)
        zero = np.zeros((2, 3))
        far = np.ones((2, 3))
        assert envs.call("compute_reward", zero, far, None)[2].tolist() == [-1.0, -1.0]
        with pytest.raises(AttributeError):
            envs.call("no_such_attribute")
        assert envs.get_attr("policy_rate") == (25.0, 25.0, 25.0)  # it keeps serving
    finally:
        envs.close()


def test_a_worker_that_dies_is_named_and_close_ends_the_rest() -> None:
    envs = PandaVectorEnv("PandaReach-v0", 3, workers=3)
    pids = [p.pid for p in envs._procs]
    try:
        obs, _ = envs.reset(seed=0)
        os.kill(pids[0], signal.SIGKILL)
        with pytest.raises(RuntimeError, match=r"worker process 1 \(environments 1..1\) ended"):
            envs.step(_policy(reach_policy, obs, 3))
    finally:
        envs.close()
    assert not any(_alive(pid) for pid in pids)
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((3, 3)))


def test_no_worker_outlives_its_caller() -> None:
    code = (
        "import os, gymnasium, panda_py.learning\n"
        "envs = gymnasium.make_vec('PandaReach-v0', num_envs=2, workers=2)\n"
        "print(*[p.pid for p in envs._procs], flush=True)\n"
        "os._exit(0)\n"  # no close, no exit handlers: as a crash
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)  # fmt: skip
    pids = [int(p) for p in out.stdout.split()]
    assert pids, out.stderr
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in pids)
