"""franky-control 2.0.0: its documented guarded stop (README, "Reactions") onto the table at
given speeds: a Cartesian motion 10 cm down (along the end effector's z, which points
down) with ``Reaction(Measure.FORCE_Z < -5.0, CartesianStopMotion())``, the collision
thresholds at 60 N / 60 Nm as for any contact task. Before each run the test places the arm
above the table (event ``place``).

Two ways to set the speed (``MODE``):

* ``robot``: the README's way, ``robot.relative_dynamics_factor``, which scales the stop
  motion too: it brakes as gently as the approach accelerated;
* a number: the approach's own ``relative_dynamics_factor``, the robot's at 1, and the stop
  motion's own factor that number (``CartesianStopMotion(relative_dynamics_factor=...)``).

Per speed: whether the reaction fired and the force then, the error the move ended with
(a reflex), the largest push on the table the robot's estimate showed (``-O_F_ext_hat_K``
z, every tick, through motion callbacks), the fastest descent [m/s] and how far the
commanded pose went on after the reaction fired [m].

Usage: franky_guarded.py HOST MODE SPEED [SPEED ...]   (speeds in m/s)
"""

from __future__ import annotations

import itertools
import sys
import time

from franky import (
    Affine,
    CartesianMotion,
    CartesianStopMotion,
    Measure,
    Reaction,
    RealtimeConfig,
    ReferenceType,
    Robot,
)
from peer_io import Scenarios, event, floats

THRESHOLD = 60.0  # [N], [Nm] the collision thresholds, as for a contact task
DRAIN = 0.5  # [s] for franky's callback thread to deliver the last ticks' states

robot = Robot(sys.argv[1], realtime_config=RealtimeConfig.Ignore)
MODE = sys.argv[2]
LIMIT = float(robot.translation_velocity_limit.get())  # [m/s] what the factors scale


def approach(speed: float) -> dict:
    event("place", speed)
    robot.recover_from_errors()
    robot.set_collision_behavior(THRESHOLD, THRESHOLD)
    factor = speed / LIMIT
    robot.relative_dynamics_factor = factor if MODE == "robot" else 1.0
    own = 1.0 if MODE == "robot" else factor
    braking = 1.0 if MODE == "robot" else float(MODE)
    seen: list[tuple[float, float, float]] = []  # push [N], z, commanded z [m] per tick

    def record(state, *_):
        seen.append((
            -float(state.O_F_ext_hat_K[2]),
            float(state.O_T_EE.translation[2]),
            float(state.O_T_EE_c.translation[2]),
        ))  # fmt: skip

    fired: list[list[float]] = []
    stop = CartesianStopMotion(braking)
    stop.register_callback(record)
    motion = CartesianMotion(Affine([0.0, 0.0, 0.10]), ReferenceType.Relative, own)
    motion.register_callback(record)
    reaction = Reaction(Measure.FORCE_Z < -5.0, stop)
    reaction.register_callback(
        lambda state, *_: fired.append([*floats(state.O_F_ext_hat_K), len(seen)])
    )
    motion.add_reaction(reaction)
    error = None
    try:
        robot.move(motion)
    except Exception as exc:  # a reflex instead of the reaction: reported
        error = f"{type(exc).__name__}: {exc}"
    time.sleep(DRAIN)
    heights = [z for _, z, _ in seen]
    descent = max(((a - b) / 1e-3 for a, b in itertools.pairwise(heights)), default=0.0)
    overtravel = 0.0
    if fired:
        at = min(int(fired[0][-1]), len(seen) - 1)
        overtravel = seen[at][2] - min(c for _, _, c in seen[at:])
    return {
        "speed": speed,
        "factor": factor,
        "fired": [f[:6] for f in fired[:1]],
        "error": error,
        "has_errors": bool(robot.has_errors),
        "peak": max((f for f, _, _ in seen), default=0.0),
        "ticks": len(seen),
        "descent": descent,
        "overtravel": overtravel,
    }


runs = Scenarios()
for arg in sys.argv[3:]:
    runs.run(f"approach {arg}", lambda s=float(arg): approach(s))
runs.finish()
