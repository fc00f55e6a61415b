"""What follows every law's step each tick, wherever a law runs (the control process's
loop, the fast training world): the joint walls, the torque-rate saturation, the torque
limits and libfranka's low-pass filter, compiled in one call
(:meth:`panda_py.controllers.laws.JointWalls.finalize`).

The filter is libfranka's on the torques as panda-py runs its controllers (100 Hz),
applied here (the same formula after the same checks) rather than by libfranka's command
path, so libfranka is asked for no filter.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from panda_py.controllers import laws
from panda_py.fci import PERIOD
from panda_py.libfranka.errors import ControlException
from panda_py.libfranka.limits import lowpass_filter
from panda_py.libfranka.state import RobotState
from panda_py.robots.params import RobotSpec

__all__ = [
    "CUTOFF_FREQUENCY", "FILTER_GAIN", "FILTER_LAG", "LAG_PART", "LAG_TICKS", "Finalize",
    "ahead_at",
]  # fmt: skip

CUTOFF_FREQUENCY = 100.0  # [Hz] libfranka's low-pass filter, as panda-py runs controllers
#: the filter's gain per tick at :data:`CUTOFF_FREQUENCY` [-]
FILTER_GAIN = float(lowpass_filter(PERIOD, 1.0, 0.0, CUTOFF_FREQUENCY))
#: [ticks] how far the filter's output trails a torque that ramps: (1 - gain) / gain (1.59)
FILTER_LAG = (1.0 - FILTER_GAIN) / FILTER_GAIN


# FILTER_LAG in whole ticks and the part of one (ahead_at; the compiled move ticks read them)
LAG_TICKS = int(FILTER_LAG)
LAG_PART = FILTER_LAG - LAG_TICKS


def ahead_at(samples: np.ndarray, k: int) -> np.ndarray:
    """A plan's sample FILTER_LAG ticks after sample ``k`` of ``samples`` (N, ...), one
    PERIOD apart (linearly between samples; the last one held): fed forward through the
    filter, a torque computed from it arrives when the plan gets there. Measured on the
    FER's Cartesian moves: fed forward on time, the planned deceleration's torque trailed
    it by 1.6 ms and the arm swung on past its goal for 20 ms after its trajectory (joints
    2 and 3 at 2-4 mrad/s, the hand within 0.03 mm); led, the moves ended within 2 ms."""
    last = len(samples) - 1
    i = min(k + LAG_TICKS, last)
    j = min(i + 1, last)
    return (1.0 - LAG_PART) * samples[i] + LAG_PART * samples[j]


class Finalize:
    """The finishing of ``limits``' robot: joint walls, torque-rate saturation, torque
    limits and the low-pass filter; refuses non-finite torques. Called with a law's
    torques and the tick's state, returns the command's seven torques."""

    def __init__(self, limits: RobotSpec) -> None:
        self.walls = laws.JointWalls(limits.joints.q_min, limits.joints.q_max)
        self.tau_max = np.array(limits.joints.tau_max)
        self.out = np.zeros(7)  # the command of this tick, finalized
        self.dtau_max = laws.DTAU_MAX_PER_TICK  # [Nm] the torque-rate bound per tick
        self.gain = FILTER_GAIN  # the low-pass filter's gain per tick

    def reset(self) -> None:
        """Forget the previous command (a new motion starts)."""
        self.walls.reset()

    def __call__(self, tau: ArrayLike, state: RobotState) -> list[float]:
        # contiguous float64: the compiled call has one signature, compiled before the loop
        values = np.ascontiguousarray(tau, dtype=np.float64).reshape(-1)
        if values.shape != (7,):
            raise ValueError(f"step: expected 7 joint torques [Nm], got shape {values.shape}")
        out = self.out
        if not self.walls.finalize(
            values, state.q, state.dq, state.tau_J_d, self.tau_max, out, self.gain
        ):
            raise ControlException(
                f"the controller commanded non-finite torques: {values.tolist()}"
            )
        return out.tolist()
