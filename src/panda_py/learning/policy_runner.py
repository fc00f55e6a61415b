"""The policy loop: observe, ask the policy when its chunk runs out, act, once a period of
the robot's clock.

A policy that thinks longer than a period (a remote pi0 takes 50-300 ms) makes its step
late. ``late="in_order"`` (openpi's DROID client, ``examples/droid/main.py`` lines
100-156): the chunk's actions still run one a period, in order, the late step's action
first; the periods after it count from when it went out (openpi sleeps what is left of a
period after each step's start). ``late="fold"``: a chunk is a plan in time, action i for
the i-th period after the observation the policy saw; the actions whose periods passed
meanwhile are folded into the next one (joint velocities summed into its target, the
newest position and gripper command), so the arm stays on the plan's timeline on an
absolute schedule (``t0 + k / rate``). The periods are on the robot's clock: on a robot
that is the wall clock; on a lockstep simulator, its own time, so a run does not depend
on the machine's load.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from panda_py.learning.deploy import DroidActions

__all__ = ["PolicyRunner", "RunStats"]

# [s of wall time] the robot's clock standing still this long means the robot (or a
# lockstep simulator) stopped: the loop raises instead of waiting for ever
CLOCK_STALL = 10.0
_POLL = 2e-4  # [s] between two reads of the robot's clock while waiting
LATE = ("in_order", "fold")  # what a late step does (PolicyRunner's ``late``)


class Recorder(Protocol):
    """Where :class:`PolicyRunner` puts each step (an
    :class:`~panda_py.learning.recording.EpisodeWriter`)."""

    def add(self, observation: Any, action: Any, **extras: Any) -> None: ...


@dataclass
class RunStats:
    """How a run went: ``steps`` periods, of which ``late`` had their action go out after
    the period ended (the policy thought longer than a period), ``skipped`` chunk actions
    folded into a later step (``late="fold"``), ``clipped`` actions with a value out of
    range clipped (``DroidActions(out_of_range="clip")``), ``held`` periods without an
    action (the chunk ran out before the next call), ``policy_calls``; ``latency`` [s of
    robot time] from each step's due time to its target sent, ``policy_seconds`` [s of
    wall time] per call."""

    period: float  # [s]
    steps: int = 0
    late: int = 0
    skipped: int = 0
    clipped: int = 0
    held: int = 0
    policy_calls: int = 0
    latency: list[float] = field(default_factory=list)
    policy_seconds: list[float] = field(default_factory=list)

    def summary(self) -> str:
        """One line: counts, and the latency's mean, p99 and worst [ms]."""
        lat = np.asarray(self.latency) * 1e3 if self.latency else np.zeros(1)
        return (
            f"{self.steps} steps at {1.0 / self.period:g} Hz, {self.policy_calls} policy "
            f"calls; late {self.late}, skipped {self.skipped}, clipped {self.clipped}, held "
            f"{self.held}; latency "
            f"mean {lat.mean():.1f} ms, p99 {np.percentile(lat, 99):.1f} ms, worst "
            f"{lat.max():.1f} ms"
        )


class PolicyRunner:
    """Runs ``policy(observation) -> action (8,) | chunk (H, 8) | {"actions": chunk}``
    through ``actions`` (a started :class:`~panda_py.learning.deploy.DroidActions`).

    The policy is called when its chunk has run out, or every ``replan_every`` periods
    (openpi's ``open_loop_horizon``: 8 of its 10-15 actions). A chunk is checked whole
    before its first action is sent: a bad one raises ValueError and sends nothing.
    ``late``: ``"in_order"`` (openpi's) or ``"fold"`` (the module's docstring says how).
    ``prompt`` goes into every observation (openpi's ``"prompt"``); ``recorder`` gets
    every step that sent an action: the observation taken at that step, the action
    executed (a late step's: the newest of those it folded in) and the joint target it
    became."""

    def __init__(
        self,
        actions: DroidActions,
        policy: Callable[[dict[str, Any]], Any],
        *,
        replan_every: int | None = None,
        prompt: str | None = None,
        recorder: Recorder | None = None,
        late: str = "in_order",
    ) -> None:
        if late not in LATE:
            raise ValueError(f"late: expected one of {LATE}, got {late!r}")
        if not callable(policy):
            raise ValueError(f"policy: expected a callable observation -> actions, got {policy!r}")
        if replan_every is not None and not (isinstance(replan_every, int) and replan_every >= 1):
            raise ValueError(f"replan_every: expected a whole number >= 1, got {replan_every!r}")
        self.actions, self.policy = actions, policy
        self.replan_every, self.prompt, self.recorder = replan_every, prompt, recorder
        self.late = late

    def _clock(self) -> float:
        """The robot's time [s]."""
        return float(self.actions.panda.get_state().time.to_sec())

    def _wait_until(self, t: float) -> float:
        now, last, stalled = self._clock(), -1.0, time.monotonic()
        while now < t:
            if now != last:
                last, stalled = now, time.monotonic()
            elif time.monotonic() - stalled > CLOCK_STALL:
                self.actions.panda.raise_error()  # a reflex ended the controller: say so
                raise RuntimeError(
                    f"the robot's clock stood still for {CLOCK_STALL:g} s at {now:.3f} s"
                )
            time.sleep(_POLL)
            now = self._clock()
        return now

    def run(self, steps: int) -> RunStats:
        """Run ``steps`` policy periods (about ``steps / rate`` seconds of the robot's
        clock) and return their :class:`RunStats`. A reflex that ends the controller
        raises its :class:`~panda_py.libfranka.ControlException` before the next action
        (``panda.recover()``, then ``DroidActions.start()`` again)."""
        if not (isinstance(steps, int) and steps >= 1):
            raise ValueError(f"steps: expected a whole number >= 1, got {steps!r}")
        actions = self.actions
        T = actions.period
        stats = RunStats(T)
        in_order = self.late == "in_order"
        chunk: np.ndarray | None = None
        chunk_k = next_row = 0
        t0 = due = self._clock()
        k = 0
        while k < steps:
            self._wait_until(due)
            obs = actions.observation()
            if self.prompt is not None:
                obs["prompt"] = self.prompt
            horizon = self.replan_every or (0 if chunk is None else len(chunk))
            if chunk is None or k - chunk_k >= horizon:
                wall = time.perf_counter()
                chunk, clipped = actions.prepare(self.policy(obs))
                stats.policy_seconds.append(time.perf_counter() - wall)
                stats.policy_calls += 1
                stats.clipped += clipped
                chunk_k, next_row = k, 0
            # a reflex (or a lost connection) ended the controller: raise it, act no more
            actions.panda.raise_error()
            now = self._clock()
            if in_order:
                k_now = k
            else:  # the periods that passed meanwhile fold into this step
                k_now = min(steps - 1, max(k, math.floor((now - t0) / T + 1e-9)))
            if next_row < len(chunk):
                last = min(k_now - chunk_k, len(chunk) - 1) if not in_order else next_row
                rows = chunk[next_row : last + 1]
                target = actions.apply_checked(rows)
                sent = self._clock()
                stats.latency.append(sent - due)
                stats.late += (sent > due + T + 1e-9) if in_order else (k_now > k)
                stats.skipped += len(rows) - 1
                next_row = last + 1
                if self.recorder is not None:
                    self.recorder.add(obs, rows[-1], joint_target=target)
            else:
                stats.held += 1
            k = k_now + 1
            # openpi: the next step a period after this one's start, or now if later
            due = max(due + T, self._clock()) if in_order else t0 + k * T
        stats.steps = k
        return stats
