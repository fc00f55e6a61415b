"""How fast a Cartesian plan asks the arm's torques to change, and the smoothing that keeps
that within what the control loop delivers.

The loop finishes every law's torques as panda-py runs its controllers
(:mod:`panda_py.controllers.finalize`): saturated to ``laws.DTAU_MAX_PER_TICK`` (1 Nm)
around the last command, then libfranka's 100 Hz low-pass filter from it. So a torque
moves by at most ``FILTER_GAIN`` of the saturation a tick: 0.386 Nm, 386 Nm/s, where the
robot itself takes 1000 Nm/s. A plan whose feed-forward torque has to change faster is not
what the arm gets. Measured on the FER's short fast Cartesian move (random seed 46's
fourth, 0.29 s): where accelerating turns into braking, joint 2's torque had to turn by 18
Nm within the plan's 30 ms smoothing (0.6 Nm a tick). The command fell up to 3 Nm behind
(a first-order filter alone lags by 1 Nm there), and the arm ended its trajectory 5 mrad
off along the direction its Cartesian impedance holds weakest (joints 2, 4 and 6 together,
a few Nm/rad of joint stiffness), which the settling took 216 ms to close. The same move
planned with its smoothing widened until its torque rate fits ends 3 ms after its
trajectory, 30 ms later in all.

The smoothing's width for a plan (:func:`smoothing_width`) is the narrowest that keeps the
feed-forward torque's rate along the plan (:func:`feedforward_torques`: ``M(q) ddq +
C(q, dq) dq`` with the drives' rotor inertia, on the configurations the arm passes
through) within ``TORQUE_RATE_SHARE`` of that bound, the rest left to the tracking's
feedback. A moving average of width ``w`` ramps each acceleration step over ``w``, so the
rate of its inertial part falls as ``1 / w``: the width grows in that proportion, a few
times at most.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers.finalize import FILTER_GAIN
from panda_py.controllers.laws import DTAU_MAX_PER_TICK
from panda_py.fci import PERIOD
from panda_py.motion.cartesian import CartesianSamples
from panda_py.motion.rotation import transforms
from panda_py.motion.smoothing import box_filter, smooth_quaternions
from panda_py.robots.params import FRANKA_HAND, RobotSpec

__all__ = [
    "MAX_SMOOTHING_FACTOR",
    "PLAN_TORQUE_RATE",
    "TORQUE_RATE_SHARE",
    "feedforward_torques",
    "load_of",
    "loaded_arm",
    "smoothed",
    "smoothing_width",
]

FloatArray = NDArray[np.float64]

# of the torque rate the loop delivers that a plan's feed-forward may ask for: the tracking's
# feedback reacts to what the plan does not foresee (the wrist's friction, the smoothing's
# offset from the profile's path) on top
TORQUE_RATE_SHARE = 0.8
#: [Nm per tick] the rate a plan's feed-forward torque is kept within
PLAN_TORQUE_RATE = TORQUE_RATE_SHARE * FILTER_GAIN * DTAU_MAX_PER_TICK
# the widest smoothing as a multiple of the default: beyond, a plan's torque rate comes from
# its speed (the Coriolis torques, the mass matrix changing) more than from its ramps
MAX_SMOOTHING_FACTOR = 4
# the widths tried at most (each one more pass along the plan)
WIDTH_TRIES = 3


Load = tuple[float, tuple[float, ...], tuple[float, ...]]  # m_total, F_x_Ctotal, I_total (9,)


@functools.lru_cache(maxsize=8)
def loaded_arm(spec: RobotSpec, load: Load | None) -> Any:
    """The arm of ``spec`` with the end effector and payload ``load`` (libfranka's total:
    mass [kg], centre of mass [m] on the flange, inertia (9,) column-major [kg m^2] about
    it; None: the Franka Hand's), prepared once (:class:`~panda_py.dynamics.LoadedArm`)."""
    from panda_py import dynamics

    if load is None:
        hand = FRANKA_HAND.inertial
        ixx, iyy, izz, ixy, ixz, iyz = hand.inertia
        load = (hand.mass, tuple(hand.com), (ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz))
    m, c, inertia = load
    return dynamics.LoadedArm(spec, m_load=m, F_x_Cload=c,
                              I_load=np.array(inertia).reshape(3, 3, order="F"))  # fmt: skip


def load_of(state: Any) -> Load:
    """A robot state's total load (``m_total``, ``F_x_Ctotal``, ``I_total``) as
    :func:`loaded_arm` keys it."""
    return (float(state.m_total), tuple(np.asarray(state.F_x_Ctotal, dtype=float).tolist()),
            tuple(np.asarray(state.I_total, dtype=float).tolist()))  # fmt: skip


Smoothed = tuple[FloatArray, FloatArray, FloatArray, FloatArray]


def smoothed(s: CartesianSamples, width: int) -> Smoothed:
    """A Cartesian profile's samples (every PERIOD) smoothed over ``width``
    (:mod:`panda_py.motion.smoothing`): positions, orientations, twists and the twists'
    rate (central differences, so that it starts and ends at rest as the twist does)."""
    twist = box_filter(np.hstack([s.velocities, s.angular_velocities]), width)
    return (box_filter(s.positions, width), smooth_quaternions(s.orientations, width), twist,
            np.gradient(twist, PERIOD, axis=0))  # fmt: skip


def feedforward_torques(q: FloatArray, dq: FloatArray, arm: Any,
                        armature: FloatArray) -> FloatArray:  # fmt: skip
    """The torques (N, 7) [Nm] that move the arm along ``q``, ``dq`` (N, 7) sampled every
    PERIOD: ``M(q) ddq + C(q, dq) dq`` (``arm``: a :class:`~panda_py.dynamics.LoadedArm`
    with the end effector's and the payload's load) plus the drives' rotor inertia
    ``armature`` (7,) times ``ddq`` (central differences of ``dq``); gravity left out, the
    robot compensates it. Rows where ``q`` is not finite are NaN."""
    ok = np.asarray(np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1), dtype=bool)
    out = np.full(q.shape, np.nan)
    if len(q) < 2 or not ok.any():
        return out
    ddq = np.gradient(np.where(ok[:, None], dq, 0.0), PERIOD, axis=0)
    out[ok] = arm.motion_torques(q[ok], dq[ok], ddq[ok]) + armature * ddq[ok]
    return out


def _peak_rate(torques: FloatArray) -> float:
    """The largest change of a joint's torque from one sample to the next [Nm]."""
    rate = np.abs(np.diff(torques, axis=0))
    return float(np.max(rate, initial=0.0, where=np.isfinite(rate)))


def smoothing_width(s: CartesianSamples, width: int, joints: Any, arm: Any,
                    armature: FloatArray) -> tuple[int, float, Smoothed]:  # fmt: skip
    """The narrowest smoothing from ``width`` up (at most MAX_SMOOTHING_FACTOR times it, in
    WIDTH_TRIES tries) whose plan's feed-forward torque changes by no more than
    PLAN_TORQUE_RATE a tick on the arm (``joints``:
    :class:`~panda_py.panda.planning.ArmJoints`, its configurations along the plan;
    ``arm``, ``armature``: as :func:`feedforward_torques`), that plan's peak rate [Nm per
    tick] and its samples (:func:`smoothed`)."""
    widest = MAX_SMOOTHING_FACTOR * width
    for tries_left in range(WIDTH_TRIES - 1, -1, -1):
        samples = smoothed(s, width)
        position, orientation, twist, _ = samples
        q = joints.configurations(transforms(position, orientation))
        rate = _peak_rate(feedforward_torques(q, joints.rates_at(q, twist), arm, armature))
        if rate <= PLAN_TORQUE_RATE or width >= widest or not tries_left:
            return width, rate, samples
        width = min(widest, math.ceil(width * rate / PLAN_TORQUE_RATE))
    raise AssertionError("unreachable")  # (WIDTH_TRIES >= 1)
