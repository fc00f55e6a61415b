"""``PandaEnv``: a goal-conditioned Gymnasium environment on either backend, the fast
in-process world or any ``Panda``, with identical code.

A step sends the action's target to a streamed-target controller
(:class:`~panda_py.controllers.CartesianTarget` or :class:`~panda_py.controllers.JointTarget`,
which follows it at 1 kHz, smoothly and within the robot's limits), lets the robot's clock
run ``1 / policy_rate`` on (an absolute schedule: the n-th step ends at n periods, never
re-anchored to when the policy answered) and observes. Observations are dicts as
panda-gym's (``observation``, ``achieved_goal``, ``desired_goal``) and rewards come from
:meth:`PandaEnv.compute_reward`, so HER-style learners work unchanged.

A robot reflex ends the episode: ``truncated`` is True and ``info["reflex"]`` says why;
the next ``reset()`` recovers the robot. A bad action (outside the space, NaN) raises a
``ValueError`` and sends nothing.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, cast

import numpy as np

try:  # the one dependency of the environments (the learning extra)
    import gymnasium
    from gymnasium import spaces
    from gymnasium.envs.registration import EnvSpec
except ImportError as exc:
    raise ImportError(
        'panda_py.learning\'s environments need gymnasium: pip install "panda-py-pure[learning]"'
    ) from exc

from panda_py import controllers, kinematics
from panda_py.learning.actions import ActionKind, ActionMap
from panda_py.learning.backend import Backend, FloatArray, Snapshot
from panda_py.motion import rotation
from panda_py.robots.params import START_POSE, RobotSpec, get_robot

__all__ = ["PandaEnv", "Reward"]

POLICY_RATE = 20.0  # [Hz] default
SPEED_FACTOR = 0.3  # of the robot's limits, the streamed targets' default here
DISTANCE_THRESHOLD = 0.05  # [m] success within this (panda-gym's)
HOME = np.array(START_POSE)  # [rad] where every episode starts
# the streamed target brings the arm to rest after this many missed policy steps
STALE_STEPS = 10


class Reward:
    """Reward kinds: ``SPARSE`` -1 until the goal is within the threshold, then 0;
    ``DENSE`` minus the distance [m] (panda-gym's two)."""

    SPARSE = "sparse"
    DENSE = "dense"


def _box(n: int) -> spaces.Box:
    return spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)


class PandaEnv(gymnasium.Env[dict[str, np.ndarray], np.ndarray]):
    """The base of the tasks (:mod:`panda_py.learning.tasks`); they define the goal, the
    observation's task part and the cube's place.

    ``backend``: ``"fast"`` (a :class:`~panda_py.learning.world.FastWorld` of ``robot``,
    with the cube where the task uses it, made and closed by the environment) or a
    :class:`Backend` (e.g. a :class:`~panda_py.learning.arm.RobotArm`, which stays its
    owner's to close: several environments may run on one robot, one after the other).
    ``action``: an :class:`ActionKind` or its value. ``policy_rate`` [Hz], 1 to 100.
    ``speed_factor``: the share of the robot's velocity, acceleration and jerk limits the
    targets are followed with."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's convention)
    #: whether the task uses the hand (and the hand's value ends each action)
    uses_hand = False
    #: whether the task's scene has the cube placed at reset
    uses_cube = False
    #: the task part of the observation: its size
    task_size = 0
    _spec: EnvSpec | None = None

    def __init__(
        self,
        backend: Backend | str = "fast",
        *,
        action: ActionKind | str = ActionKind.CARTESIAN_DELTA,
        policy_rate: float = POLICY_RATE,
        speed_factor: float = SPEED_FACTOR,
        reward: str = Reward.SPARSE,
        distance_threshold: float = DISTANCE_THRESHOLD,
        robot: str = "fer",
    ) -> None:
        kind = ActionKind.parse(action)
        if not (isinstance(policy_rate, (int, float)) and 1.0 <= policy_rate <= 100.0):
            raise ValueError(f"policy_rate: expected a rate in [1, 100] Hz, got {policy_rate!r}")
        if reward not in (Reward.SPARSE, Reward.DENSE):
            raise ValueError(f"reward: expected 'sparse' or 'dense', got {reward!r}")
        if not (isinstance(distance_threshold, (int, float)) and distance_threshold > 0.0):
            raise ValueError(
                f"distance_threshold: expected a distance > 0 [m], got {distance_threshold!r}"
            )
        if not (isinstance(speed_factor, (int, float)) and 0.0 < speed_factor <= 1.0):
            raise ValueError(f"speed_factor: expected a value in (0, 1], got {speed_factor!r}")
        self._owns_backend = isinstance(backend, str)
        if isinstance(backend, str):
            if backend != "fast":
                raise ValueError(
                    f"backend: expected 'fast' or a Backend (e.g. RobotArm(hostname)), got "
                    f"{backend!r}"
                )
            from panda_py.learning.world import FastWorld

            backend = FastWorld(robot, cube=self.uses_cube)
        elif not isinstance(backend, Backend):
            raise ValueError(
                f"backend: expected 'fast' or a Backend (e.g. RobotArm(hostname)), got "
                f"{type(backend).__name__}"
            )
        if self.uses_hand and not backend.has_hand:
            raise ValueError(
                f"backend: {type(self).__name__} needs the hand; this backend has none "
                "(RobotArm(..., hand=True))"
            )
        if self.uses_cube and not backend.has_cube:
            raise ValueError(
                f"backend: {type(self).__name__} needs someone to place the cube and tell "
                "where it is; give the robot backend a scene (RobotArm(..., scene=sim))"
            )
        self.backend = backend
        spec = get_robot(backend.spec_name)
        self.kind = kind
        self.actions, self.action_space, self.observation_space = self._spaces(kind, spec)
        self.period = 1.0 / float(policy_rate)  # [s]
        self.policy_rate = float(policy_rate)
        self.speed_factor = float(speed_factor)
        self.reward_type = reward
        self.distance_threshold = float(distance_threshold)
        T = kinematics.fk(HOME, robot=spec.name)
        self._down = rotation.from_matrix(T[:3, :3])  # the fingers down: (x, y, z, w)
        self.goal = np.zeros(3)
        self._controller: controllers.JointTarget | controllers.CartesianTarget | None = None
        self._t0, self._steps = 0, 0  # the episode's start [ms], steps taken
        self._hand_open: bool | None = None
        self._ended: str | None = None  # why the episode ended early (a reflex)
        self._started = False
        self._snap: Snapshot | None = None  # the state the last step (or reset) observed

    @classmethod
    def _spaces(
        cls, kind: ActionKind, spec: RobotSpec
    ) -> tuple[ActionMap, spaces.Box, spaces.Space[dict[str, np.ndarray]]]:
        """The task's actions on robot ``spec`` with ``kind``: their map, the action space
        and the observation space (what a vector of these environments lays out before
        any is made)."""
        actions = ActionMap(kind, spec, hand=cls.uses_hand)
        action_space = spaces.Box(
            actions.low.astype(np.float32), actions.high.astype(np.float32), dtype=np.float32
        )
        # gymnasium 1.4 types Dict as a space of dicts of spaces; its samples are arrays
        observations = spaces.Dict({
            "observation": _box(21 + cls.task_size),
            "achieved_goal": _box(3),
            "desired_goal": _box(3),
        })  # fmt: skip
        return actions, action_space, cast("spaces.Space[dict[str, np.ndarray]]", observations)

    @property
    def spec(self) -> EnvSpec | None:
        """The registered spec (set by ``gymnasium.make``), marked nondeterministic where
        the backend is (a robot, ``panda-sim``): Gymnasium's checks then expect no bit-for-bit
        repeats there."""
        spec = self._spec
        backend = getattr(self, "backend", None)
        if spec is not None and backend is not None and not backend.deterministic:
            return dataclasses.replace(spec, nondeterministic=True)
        return spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        self._spec = value

    # --- the task's part (override) -----------------------------------------------------

    def _sample(self, rng: np.random.Generator) -> FloatArray | None:
        """Draw the goal (into ``self.goal``) and return where the cube goes (or None)."""
        raise NotImplementedError

    def _task_observation(self, snap: Snapshot) -> FloatArray:
        return np.zeros(0)

    def _achieved(self, snap: Snapshot) -> FloatArray:
        raise NotImplementedError

    # --- gymnasium ----------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Recover the robot if it needs it, bring the arm home with the hand open, draw
        the goal (and place the cube) from the environment's generator, start following
        targets."""
        super().reset(seed=seed)
        backend = self.backend
        backend.recover()
        cube = self._sample(self.np_random)
        backend.home(HOME, cube)
        timeout = max(controllers.streaming.TIMEOUT, STALE_STEPS * self.period)
        if self.kind.cartesian:
            ctrl: Any = controllers.CartesianTarget(self.speed_factor, timeout=timeout)
        else:
            ctrl = controllers.JointTarget(self.speed_factor, timeout=timeout)
        backend.start(ctrl)
        self._controller = ctrl
        self._hand_open = True if self.uses_hand else None
        self._ended = None
        self._started = True
        self._t0, self._steps = backend.time_ms(), 0
        snap = self._snap = backend.snapshot()
        return self._observe(snap), self._info(snap, None)

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Send the action's target (and the hand's command), let the robot's clock run to
        the end of this step, observe: ``(observation, reward, terminated, truncated,
        info)``. Terminated when the goal is reached (``info["is_success"]``, panda-gym's
        rule); truncated by a reflex (``info["reflex"]`` says which). A bad action raises
        ``ValueError`` and sends nothing."""
        if not self._started:
            raise RuntimeError("step: call reset() first")
        if self._ended is not None:
            raise RuntimeError(f"step: the episode ended ({self._ended}); call reset()")
        a = self.actions.check(action)
        backend, ctrl = self.backend, self._controller
        assert ctrl is not None
        snap = self._snap
        if snap is None or snap.time_ms != backend.time_ms():  # (a robot's clock ran on)
            snap = backend.snapshot()
        target = self.actions.target(a, snap.q, snap.O_T_EE[:3, 3])
        if isinstance(ctrl, controllers.CartesianTarget):
            ctrl.set_target(target, self._down)
        else:
            ctrl.set_target(target)
        wants_open = self.actions.hand_open(a)
        if wants_open is not None and wants_open != self._hand_open:
            backend.hand_open() if wants_open else backend.hand_close()
            self._hand_open = wants_open
        # the n-th step ends n periods after the start, to the ms of the robot's clock
        self._steps += 1
        backend.advance(self._t0 + round(self._steps * 1000.0 * self.period))
        failure = backend.failure()
        snap = self._snap = backend.snapshot()
        obs = self._observe(snap)
        info = self._info(snap, failure)
        reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
        if failure is not None:
            self._ended = failure
        return obs, reward, bool(info["is_success"]), failure is not None, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The reward of reaching ``achieved_goal`` for ``desired_goal`` (arrays of
        positions [m], batched on the first axes as HER relabels them)."""
        x = np.asarray(achieved_goal) - np.asarray(desired_goal)
        if not issubclass(x.dtype.type, (np.inexact, np.object_)):
            x = x.astype(float)
        # np.linalg.norm(x, axis=-1)'s arithmetic, without its dispatch (a tenth of a step)
        d = np.sqrt(np.add.reduce((x.conj() * x).real, axis=-1))
        if self.reward_type == Reward.SPARSE:
            return -(d > self.distance_threshold).astype(np.float32)
        return -d.astype(np.float32)

    def close(self) -> None:
        """Stop the controller; close the backend if the environment made it."""
        backend = getattr(self, "backend", None)
        if backend is not None:
            self.backend = None  # type: ignore[assignment]
            if self._owns_backend:
                backend.close()
            else:
                backend.stop()
        super().close()

    # --- observations -------------------------------------------------------------------

    def _observe(self, snap: Snapshot) -> dict[str, np.ndarray]:
        T = snap.O_T_EE
        task = self._task_observation(snap)
        # float32 straight from the parts (each rounded as astype rounds them)
        robot = np.empty(21 + task.shape[0], dtype=np.float32)
        robot[0:7] = snap.q
        robot[7:14] = snap.dq
        robot[14:17] = T[:3, 3]
        robot[17:21] = rotation.from_matrix(T)
        robot[21:] = task
        return {
            "observation": robot,
            "achieved_goal": self._achieved(snap).astype(np.float32),
            "desired_goal": self.goal.astype(np.float32),
        }

    def _info(self, snap: Snapshot, failure: str | None) -> dict[str, Any]:
        e = self._achieved(snap) - self.goal
        d = math.sqrt(float(e.dot(e)))  # (np.linalg.norm's arithmetic, for less)
        info: dict[str, Any] = {
            "is_success": bool(d <= self.distance_threshold) and failure is None,
            "distance": d,
            "time": snap.time_ms * 1e-3,
        }
        if failure is not None:
            info["reflex"] = failure
        return info

    @staticmethod
    def _uniform(rng: np.random.Generator, low: Any, high: Any) -> FloatArray:
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        return low + (high - low) * rng.random(low.shape)
