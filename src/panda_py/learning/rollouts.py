"""Rollouts beyond one process and one machine: episodes of a registered environment run on
``n_workers`` Ray actors, each owning its own environment, and gathered as they finish.

What runs where: the caller (a learner, a script) hands out episodes and gathers results;
each actor is a process that makes one environment and runs whole episodes with the
policy it is sent. By default the environment runs on the fast world
(:class:`~panda_py.learning.world.FastWorld`) in the actor's process, wherever Ray places
it. With ``hosts=[...]`` actor ``k`` drives a :class:`~panda_py.learning.arm.RobotArm` on
``hosts[k]`` (a robot's FCI address or a ``panda-sim``): its control process, and so the
1 kHz loop, runs on the actor's node. On a lab cluster, start each robot PC's Ray node
with the resource ``robot:<host>`` and no CPUs, e.g. ``ray start --address=HEAD:6379
--num-cpus=0 --resources='{"robot:172.16.0.2": 1}'``: that robot's actor is placed there
(asking for no CPU) and no other actor is; without the resource the actor goes wherever
Ray has a free CPU (see ``docs/learning-cluster.md``).

Ray: with a cluster the caller joined (``ray.init(address=...)``) the actors run on it;
otherwise :class:`RolloutWorkers` starts a local Ray instance (``ray.init()``: Ray's
own rules, e.g. ``RAY_ADDRESS``) and shuts it down on :meth:`RolloutWorkers.close`.

Seeds: episode ``i`` is reset with seed ``seed + i`` whichever actor runs it, so the same
seeds give the same episodes whatever the number of workers (the fast world is
deterministic; a robot is not, bit for bit).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import os
import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

from panda_py.learning.registry import ENVIRONMENTS, env_class, register

__all__ = ["EpisodeResult", "RolloutWorkers", "run_rollouts"]

START_TIMEOUT = 120.0  # [s] for every actor to be placed and to have made its environment
CLOSE_TIMEOUT = 10.0  # [s] for the actors to close their environments before being killed
# episodes queued at each worker: the next is there when one ends, so a worker does not
# wait for the driver's round trip (milliseconds on a loaded machine) between episodes
QUEUED = 2
ROBOT_RESOURCE = "robot:{host}"  # the Ray resource of the node next to the robot at host


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """One episode: its index and seed, the sum of its rewards, whether it ended in
    success, its steps, its wall time [s], the node (host name) and worker that ran it."""

    index: int
    seed: int
    episode_return: float
    success: bool
    steps: int
    wall_time: float
    node: str
    worker: int


def _ray() -> Any:
    if importlib.util.find_spec("ray") is None:
        raise ImportError(
            'panda_py.learning.rollouts needs ray: pip install "panda-py-pure[learning]"'
        )
    import ray

    return ray


class _Worker:
    """The actor: one environment, whole episodes on it (runs in the actor's process)."""

    def __init__(self, worker: int, env_id: str, host: str | None, kwargs: dict) -> None:
        import gymnasium

        register()  # (the environments' ids, in the actor's process too)

        self.worker = worker
        self.node = socket.gethostname()
        self.arm = None
        if host is not None:
            from panda_py.learning.arm import RobotArm

            self.arm = RobotArm(host, hand=env_class(env_id).uses_hand)
            kwargs = {**kwargs, "backend": self.arm}
        try:
            self.env = gymnasium.make(env_id, **kwargs)
        except BaseException:
            if self.arm is not None:
                self.arm.close()
            raise

    def ready(self) -> tuple[str, int]:
        return self.node, os.getpid()

    def episode(self, policy: Callable[[Any], Any], index: int, seed: int) -> EpisodeResult:
        start = time.perf_counter()
        obs, info = self.env.reset(seed=seed)
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, terminated, truncated, info = self.env.step(policy(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        return EpisodeResult(index, seed, total, bool(info.get("is_success", False)), steps,
                             time.perf_counter() - start, self.node, self.worker)  # fmt: skip

    def close(self) -> None:
        self.env.close()
        if self.arm is not None:
            self.arm.close()


def _check_run(policy: Any, episodes: Any, seed: Any) -> None:
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: expected an integer >= 0, got {seed!r}")
    if not callable(policy):
        raise ValueError(f"policy: expected a callable (obs -> action), got {policy!r}")


class RolloutWorkers:
    """``n_workers`` Ray actors, each with its own ``env_id`` environment (made with
    ``env_kwargs``): on the fast world, or with ``hosts`` one actor per robot or
    ``panda-sim`` (then ``len(hosts)`` actors: ``n_workers`` is not used). Started here,
    ready to :meth:`run`; a context manager: :meth:`close` ends the actors (and the Ray instance
    started here, if any). Bad input raises ``ValueError`` before any actor starts."""

    def __init__(
        self,
        env_id: str,
        *,
        n_workers: int = 2,
        hosts: list[str] | None = None,
        env_kwargs: dict[str, Any] | None = None,
    ) -> None:
        if env_id not in ENVIRONMENTS:
            raise ValueError(f"env_id: expected one of {sorted(ENVIRONMENTS)}, got {env_id!r}")
        if hosts is not None:
            if not hosts or not all(isinstance(h, str) and h for h in hosts):
                raise ValueError(f"hosts: expected a non-empty list of host names, got {hosts!r}")
            if len(set(hosts)) < len(hosts):
                raise ValueError(f"hosts: expected distinct hosts (a worker each), got {hosts!r}")
            if env_class(env_id).uses_cube:
                raise ValueError(
                    "env_id: expected a task without the cube on hosts (PandaReach-v0: "
                    f"placing the cube needs a scene, not given on a host), got {env_id!r}"
                )
            n_workers = len(hosts)
        if isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1:
            raise ValueError(f"n_workers: expected an integer >= 1, got {n_workers!r}")
        if env_kwargs is not None and not isinstance(env_kwargs, dict):
            raise ValueError(f"env_kwargs: expected a dict of options, got {env_kwargs!r}")
        kwargs = dict(env_kwargs or {})
        if "backend" in kwargs:
            raise ValueError(
                "env_kwargs: expected the environment's options without 'backend' (hosts "
                f"chooses it), got {sorted(kwargs)}"
            )
        ray = self._ray = _ray()
        self._started_ray = not ray.is_initialized()
        if self._started_ray:
            ray.init(include_dashboard=False, log_to_driver=False)
        self.env_id = env_id
        self._actors: list[Any] = []
        try:
            resources = ray.cluster_resources()
            remote = ray.remote(num_cpus=1)(_Worker)
            for k in range(n_workers):
                host = None if hosts is None else hosts[k]
                options: dict[str, Any] = {}
                place = ROBOT_RESOURCE.format(host=host)
                if host is not None and place in resources:
                    # the robot PC's node: no CPU asked, so that a robot PC started with
                    # --num-cpus=0 gets its robot's worker and no fast-world workers
                    options.update(resources={place: 1}, num_cpus=0)
                self._actors.append(remote.options(**options).remote(k, env_id, host, kwargs))
            ready = [actor.ready.remote() for actor in self._actors]
            done, _ = ray.wait(ready, num_returns=len(ready), timeout=START_TIMEOUT)
            if len(done) < len(ready):
                raise RuntimeError(
                    f"{len(ready) - len(done)} of {len(ready)} rollout workers were not ready "
                    f"after {START_TIMEOUT:.0f} s: the cluster has {resources} (each worker "
                    "needs a CPU)"
                )
            where = ray.get(ready)
            #: the node (host name) and the process id of each worker
            self.nodes: list[str] = [node for node, _ in where]
            self.pids: list[int] = [pid for _, pid in where]
        except BaseException:
            self.close()
            raise

    @property
    def n_workers(self) -> int:
        """The running workers (0 once closed)."""
        return len(self._actors)

    def run(
        self, policy: Callable[[Any], Any], episodes: int, *, seed: int = 0
    ) -> Iterator[EpisodeResult]:
        """Run ``episodes`` episodes of ``policy`` (a callable: observation -> action,
        picklable: a function of ``__main__`` or of a module the workers can import, or
        an object holding its weights), episode ``i`` seeded ``seed + i``; yield each
        result as it finishes (in any order). An error in an episode closes all workers
        and is raised as the worker raised it (Ray's error, with the worker's traceback,
        as its cause); leaving the loop early drops the episodes not yet gathered and
        keeps the workers."""
        _check_run(policy, episodes, seed)
        if not self._actors:
            raise RuntimeError("these rollout workers are closed")
        return self._results(policy, episodes, seed)

    def _results(
        self, policy: Callable[[Any], Any], episodes: int, seed: int
    ) -> Iterator[EpisodeResult]:
        ray = self._ray
        try:
            shipped = ray.put(policy)  # serialised once, not once per episode
            pending: dict[Any, int] = {}  # episode's result -> the worker running it
            queue = iter(range(episodes))

            def hand_out(worker: int) -> None:
                index = next(queue, None)
                if index is not None:
                    actor = self._actors[worker]
                    pending[actor.episode.remote(shipped, index, seed + index)] = worker

            for _ in range(QUEUED):
                for worker in range(self.n_workers):
                    hand_out(worker)
            while pending:
                (ref,), _ = ray.wait(list(pending), num_returns=1)
                worker = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:
                    # the worker's own error (e.g. the environment's ValueError for a bad
                    # action), with Ray's, and so the worker's traceback, as its cause
                    cause = exc.cause if isinstance(exc.cause, Exception) else None
                    if cause is None:
                        raise
                    raise cause from exc
                hand_out(worker)  # the next episode before the caller sees this one
                yield result
        except GeneratorExit:
            # the caller left the loop early: the workers stay, and finish the episodes
            # queued at them (at most QUEUED each; their results are dropped). Not
            # ray.cancel: a cancelled task of an actor left the actor waiting for it in
            # its order of tasks (here, 30 s, then the actor was unavailable; Ray 2.58)
            raise
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Close the environments (a robot's connection too), end the actors, and shut
        down the Ray instance if it was started here. Idempotent."""
        ray = self._ray
        actors, self._actors = self._actors, []
        if actors:
            closing = [actor.close.remote() for actor in actors]
            ray.wait(closing, num_returns=len(closing), timeout=CLOSE_TIMEOUT)
            for actor in actors:
                ray.kill(actor)
        if self._started_ray:
            self._started_ray = False
            ray.shutdown()

    def __enter__(self) -> RolloutWorkers:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_rollouts(
    env_id: str,
    policy: Callable[[Any], Any],
    *,
    episodes: int,
    n_workers: int = 2,
    seed: int = 0,
    hosts: list[str] | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> list[EpisodeResult]:
    """Start :class:`RolloutWorkers`, run ``episodes`` episodes of ``policy`` on them and
    close them: the results in episode order (episode ``i`` seeded ``seed + i``)."""
    _check_run(policy, episodes, seed)
    with RolloutWorkers(env_id, n_workers=n_workers, hosts=hosts, env_kwargs=env_kwargs) as w:
        results = list(w.run(policy, episodes, seed=seed))
    return sorted(results, key=lambda r: r.index)
