"""``PandaVectorEnv``: many fast-world environments of one registered task, stepped in
parallel by worker processes, with the batch in shared memory.

``gymnasium.make_vec("PandaReach-v0", num_envs=8)`` makes one (the ids register it as
their vector entry point; ``vectorization_mode="sync"`` or ``"async"`` still give
Gymnasium's own). Each worker owns a contiguous share of the environments (made with
``gymnasium.make``, as ``AsyncVectorEnv``'s are) and steps them one after the other; by
default there are as many workers as cores, at most one per environment. The first
worker is the calling process itself (it would otherwise wait while the others step),
the rest are processes. What differs from ``AsyncVectorEnv`` is the traffic: the
actions, observations, rewards, the end flags and the infos' numbers live in one shared
block that both sides index in place, and a step is one byte to each worker and one back,
so the process that runs the policy spends a few microseconds of its own a step instead
of tens per environment.

Semantics are ``AsyncVectorEnv``'s: next-step autoreset (the step after an episode ended
returns the new episode's first observation, reward 0, the reset's info, and ignores that
environment's action); ``reset(seed=s)`` seeds environment ``i`` with ``s + i`` (or takes
a list); infos are a dict of arrays with ``_key`` masks. Actions are checked for every
environment before any is sent (a ``ValueError`` naming the environment and the value,
nothing stepped). The workers start warm (:mod:`panda_py.warmstart`), ignore Ctrl-C (the
caller's ``close`` ends them) and end when the caller's process does.
"""

from __future__ import annotations

import functools
import inspect
import mmap
import os
import pickle
import signal
import socket
import time
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from panda_py import warmstart
from panda_py.learning.actions import ActionKind
from panda_py.learning.registry import ENVIRONMENTS, env_class, register
from panda_py.robots.params import get_robot
from panda_py.rt.shm import anonymous_file

__all__ = ["PandaVectorEnv", "pick_and_place", "reach"]

# the infos every step and reset of these tasks has, kept in the shared block
_INFO_NUMBERS = {"is_success": np.bool_, "distance": np.float64, "time": np.float64}
_OK, _EXTRAS, _ERROR = b"K", b"X", b"E"  # a worker's answers
_STEP, _RESET, _CALL, _QUIT = b"S", b"R", b"C", b"Q"  # the caller's requests
SPIN = 0.002  # [s] how long a side waiting for the other looks before it sleeps


class PandaVectorEnv(VectorEnv):
    """``num_envs`` environments of ``env_id`` (a registered id, e.g. ``"PandaReach-v0"``)
    on the fast world, shared by ``workers`` (default: one per core, at most one per
    environment): this process steps the first share, ``workers - 1`` processes the
    others. ``max_episode_steps``: the episodes' length (default: the id's);
    ``**kwargs`` go to each environment (``action``, ``policy_rate``, ``speed_factor``,
    ``reward``, ``distance_threshold``, ``robot``); a robot backend cannot be shared by
    processes (use ``vectorization_mode="sync"`` for environments on robots)."""

    def __init__(
        self,
        env_id: str = "PandaReach-v0",
        num_envs: int = 1,
        *,
        workers: int | None = None,
        max_episode_steps: int | None = None,
        spin: float = SPIN,
        **kwargs: Any,
    ) -> None:
        task = env_class(env_id)
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs: expected a whole number >= 1, got {num_envs!r}")
        if workers is None:
            workers = min(num_envs, os.cpu_count() or 1)
        if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers:
            raise ValueError(f"workers: expected a whole number >= 1, got {workers!r}")
        workers = min(workers, num_envs)
        if not (isinstance(spin, (int, float)) and 0.0 <= spin <= 1.0):
            raise ValueError(f"spin: expected a time in [0, 1] s, got {spin!r}")
        # (looking without sleeping only where every worker has a core of its own)
        self._spin = float(spin) if workers <= (os.cpu_count() or 1) else 0.0
        backend = kwargs.get("backend", "fast")
        if not (isinstance(backend, str) and backend == "fast"):
            raise ValueError(
                f"backend: a PandaVectorEnv runs the fast world only, got {backend!r} (for "
                'environments on robots: gymnasium.make_vec(..., vectorization_mode="sync"))'
            )
        if max_episode_steps is None:
            max_episode_steps = ENVIRONMENTS[env_id][1]
        defaults = inspect.signature(task.__init__).parameters
        kind = ActionKind.parse(kwargs.get("action", defaults["action"].default))
        spec = get_robot(kwargs.get("robot", defaults["robot"].default))
        self._map, single_actions, single_obs = task._spaces(kind, spec)
        self.env_id, self.num_envs = env_id, num_envs
        self.single_action_space, self.single_observation_space = single_actions, single_obs
        self.action_space = batch_space(single_actions, num_envs)
        self.observation_space = batch_space(single_obs, num_envs)
        self.metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
        self.render_mode = None
        self.closed = False
        self._keys = tuple(single_obs.keys())
        fields: list[tuple[Any, ...]] = [("action", np.float64, (self._map.size,))]
        fields += [(k, np.float32, single_obs[k].shape) for k in self._keys]
        fields += [("reward", np.float64), ("terminated", np.bool_), ("truncated", np.bool_)]
        fields += list(_INFO_NUMBERS.items())
        layout = np.dtype(fields, align=True)
        size = max(layout.itemsize * num_envs, 1)
        self._procs: list[Any] = []
        self._conns: list[Connection] = []
        self._shares: list[tuple[int, int]] = []
        self._local: _Served | None = None
        make = {"max_episode_steps": max_episode_steps, **kwargs}
        counts = [num_envs // workers + (w < num_envs % workers) for w in range(workers)]
        fd = anonymous_file(size, "panda_py-vector")
        try:
            self._mm = mmap.mmap(fd, size)
            self._rec = np.frombuffer(self._mm, dtype=layout, count=num_envs)
            start = counts[0]
            for w in range(1, workers):
                self._start(w, fd, size, layout, make, start, counts[w])
                start += counts[w]
            envs = [gymnasium.make(env_id, **make) for _ in range(counts[0])]
            self._local = _Served(envs, self._rec[: counts[0]], 0)
            for w in range(len(self._conns)):
                self._answer(w)  # each made its environments (or says why not)
        except BaseException:
            self.close()  # (no worker started is left behind)
            raise
        finally:
            os.close(fd)

    def _start(self, w: int, fd: int, size: int, layout: np.dtype[Any], make: dict[str, Any],
               first: int, count: int) -> None:  # fmt: skip
        mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        proc = warmstart.context().Process(
            target=warmstart.run_with_environ,
            args=(dict(os.environ), "panda_py.learning.vector:_worker",
                  warmstart.InheritedFd(theirs.fileno()), warmstart.InheritedFd(fd), size,
                  layout, self.env_id, make, first, count, self.num_envs, self._spin),
            name=f"panda_py-vector-{w}",
            daemon=True,
        )  # fmt: skip
        try:
            warmstart.start(proc)
        finally:
            theirs.close()
        self._procs.append(proc)
        self._conns.append(Connection(mine.detach()))
        self._shares.append((first, count))

    # --- talking to the workers -----------------------------------------------------------

    def _answer(self, w: int) -> Any:
        """Worker process ``w``'s answer: None, the extras it sent, or its error raised."""
        try:
            msg = _receive(self._conns[w], self._spin)
        except (EOFError, OSError):
            proc = self._procs[w]
            proc.join(1.0)
            first, count = self._shares[w]
            raise RuntimeError(
                f"PandaVectorEnv: worker process {w + 1} (environments {first}.."
                f"{first + count - 1}) ended (exit code {proc.exitcode})"
            ) from None
        kind, body = msg[:1], msg[1:]
        if kind == _OK:
            return None
        value = pickle.loads(body)
        if kind == _ERROR:
            raise value
        return value

    def _all(self, request: bytes) -> list[Any]:
        """Send ``request`` to every worker process, serve it here on this process's share,
        then gather every answer (the first error is raised after all have answered: none
        is left mid-request)."""
        local = self._local
        if self.closed or local is None:
            raise RuntimeError("PandaVectorEnv: closed")
        for conn in self._conns:
            conn.send_bytes(request)
        answers: list[Any] = []
        error: BaseException | None = None
        try:
            answers.append(local.serve(request))
        except Exception as exc:
            answers.append(None)
            error = exc
        for w in range(len(self._conns)):
            try:
                answers.append(self._answer(w))
            except Exception as exc:
                answers.append(None)
                error = error or exc
        if error is not None:
            raise error
        return answers

    # --- gymnasium ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:  # fmt: skip
        """Reset every environment (``seed``: an int seeds environment ``i`` with ``seed +
        i``; a list gives each its own, None for none); ``options`` go to each."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        elif isinstance(seed, Sequence) and len(seed) == n:
            seeds = list(seed)
        else:
            raise ValueError(f"seed: expected None, an int or {n} seeds, got {seed!r}")
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options: expected a dict or None, got {options!r}")
        answers = self._all(_RESET + pickle.dumps((seeds, options)))
        return self._observations(), self._infos(answers)

    def step(
        self, actions: Any
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every environment with its row of ``actions`` (num_envs, action size)."""
        self._rec["action"] = self._map.check_rows(actions, self.num_envs)
        answers = self._all(_STEP)
        rec = self._rec
        return (self._observations(), rec["reward"].copy(), rec["terminated"].copy(),
                rec["truncated"].copy(), self._infos(answers))  # fmt: skip

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Each environment's attribute ``name`` (called with ``args`` where it is callable):
        a tuple with one result per environment."""
        if not isinstance(name, str):
            raise ValueError(f"name: expected an attribute's name, got {name!r}")
        answers = self._all(_CALL + pickle.dumps((name, args, kwargs)))
        return tuple(r for results in answers for r in results)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Each environment's attribute ``name``."""
        return self.call(name)

    def close_extras(self, **kwargs: Any) -> None:
        for conn in self._conns:
            try:
                conn.send_bytes(_QUIT)
            except OSError:
                pass
        for proc in self._procs:
            proc.join(5.0)
            if proc.is_alive():
                proc.kill()
                proc.join(5.0)
        for conn in self._conns:
            conn.close()
        self._conns, self._procs = [], []
        local, self._local = self._local, None
        if local is not None:
            for env in local.envs:
                env.close()

    def __del__(self) -> None:
        if not getattr(self, "closed", True) and hasattr(self, "_local"):
            self.close()

    # --- the batch --------------------------------------------------------------------------

    def _observations(self) -> dict[str, np.ndarray]:
        rec = self._rec
        return {k: rec[k].copy() for k in self._keys}

    def _infos(self, answers: list[Any]) -> dict[str, Any]:
        rec, mask = self._rec, np.ones(self.num_envs, dtype=np.bool_)
        infos: dict[str, Any] = {}
        for key in _INFO_NUMBERS:
            infos[key], infos["_" + key] = rec[key].copy(), mask.copy()
        for extras in answers:
            for i, info in (extras or {}).items():
                infos = self._add_info(infos, info, i)
        return infos


# the ids' vector entry points (gymnasium.make_vec calls them with num_envs=...)
reach = functools.partial(PandaVectorEnv, "PandaReach-v0")
pick_and_place = functools.partial(PandaVectorEnv, "PandaPickAndPlace-v0")


# --- the worker's side ------------------------------------------------------------------------


def _worker(conn_fd: warmstart.InheritedFd, shm_fd: warmstart.InheritedFd, size: int,
            layout: np.dtype[Any], env_id: str, make: dict[str, Any], first: int, count: int,
            num_envs: int, spin: float) -> None:  # fmt: skip
    """A worker process: make environments ``first .. first + count - 1`` and serve the
    caller's requests on them until it quits or is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the caller's to handle
    conn = Connection(conn_fd.fd)
    mm = mmap.mmap(shm_fd.fd, size)
    os.close(shm_fd.fd)
    rec = np.frombuffer(mm, dtype=layout, count=num_envs)[first : first + count]
    try:
        register()
        envs = [gymnasium.make(env_id, **make) for _ in range(count)]
    except Exception as exc:
        conn.send_bytes(_ERROR + _pickled(exc))
        return
    conn.send_bytes(_OK)
    served = _Served(envs, rec, first)
    try:
        while True:
            try:
                msg = _receive(conn, spin)
            except (EOFError, OSError):
                return  # the caller is gone
            if msg[:1] == _QUIT:
                return
            try:
                extras = served.serve(msg)
            except Exception as exc:
                conn.send_bytes(_ERROR + _pickled(exc))
                continue
            conn.send_bytes(_OK if extras is None else _EXTRAS + pickle.dumps(extras))
    finally:
        for env in envs:
            env.close()


def _receive(conn: Connection, spin: float) -> bytes:
    """The next message on ``conn``, looked for without sleeping for up to ``spin`` [s]
    first: waking a process that sleeps between steps costs more than the wait (on a
    2-core VM an empty request's round trip to a sleeping worker took 59 us; two workers
    ran 1.15-1.6x one without the spin, 1.43-1.75x with it)."""
    if spin > 0.0 and not conn.poll(0.0):
        end = time.perf_counter() + spin
        while not conn.poll(0.0) and time.perf_counter() < end:
            pass
    return conn.recv_bytes()


def _pickled(exc: BaseException) -> bytes:
    try:
        return pickle.dumps(exc)
    except Exception:  # an error that does not pickle: its text
        return pickle.dumps(RuntimeError(f"{type(exc).__name__}: {exc}"))


class _Served:
    """A worker's environments over their rows of the shared block."""

    def __init__(self, envs: list[Any], rec: np.ndarray, first: int) -> None:
        self.envs, self.first = envs, first
        self.keys = tuple(envs[0].observation_space.keys())
        self.done = [False] * len(envs)
        self.rows = [rec[i] for i in range(len(envs))]  # (each a view of its record)

    def serve(self, msg: bytes) -> Any:
        op = msg[:1]
        if op == _STEP:
            return self._step()
        if op == _RESET:
            seeds, options = pickle.loads(msg[1:])
            extras = None
            for i, env in enumerate(self.envs):
                obs, info = env.reset(seed=seeds[self.first + i], options=options)
                extras = self._write(i, obs, 0.0, False, False, info, extras)
                self.done[i] = False
            return extras
        if op == _CALL:
            name, args, kwargs = pickle.loads(msg[1:])
            results = []
            for env in self.envs:
                value = env.get_wrapper_attr(name)
                results.append(value(*args, **kwargs) if callable(value) else value)
            return results
        raise ValueError(f"PandaVectorEnv worker: unknown request {op!r}")

    def _step(self) -> Any:
        extras = None
        for i, env in enumerate(self.envs):
            if self.done[i]:  # next-step autoreset: this step starts the next episode
                obs, info = env.reset()
                extras = self._write(i, obs, 0.0, False, False, info, extras)
                self.done[i] = False
                continue
            obs, reward, terminated, truncated, info = env.step(self.rows[i]["action"])
            extras = self._write(i, obs, reward, terminated, truncated, info, extras)
            self.done[i] = bool(terminated or truncated)
        return extras

    def _write(self, i: int, obs: dict[str, np.ndarray], reward: float, terminated: bool,
               truncated: bool, info: dict[str, Any], extras: Any) -> Any:  # fmt: skip
        row = self.rows[i]
        for k in self.keys:
            row[k] = obs[k]
        row["reward"], row["terminated"], row["truncated"] = reward, terminated, truncated
        rest = {}
        for key, value in info.items():
            if key in _INFO_NUMBERS:
                row[key] = value
            else:
                rest[key] = value
        if rest:
            extras = extras or {}
            extras[self.first + i] = rest
        return extras
