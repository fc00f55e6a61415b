"""What the loop's finishing of a law's torques delivers (controllers.finalize): panda-py's
saturation to 1 Nm around the last command, then libfranka's 100 Hz filter from it, so a
torque moves by at most FILTER_GAIN Nm a tick; a ramp the filter trails by FILTER_LAG
ticks, which a plan's samples taken that much ahead (ahead_at) make up for."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py.controllers import laws
from panda_py.controllers.finalize import FILTER_GAIN, FILTER_LAG, ahead_at

_TAU_MAX = np.array([87.0] * 4 + [12.0] * 3)


def _led(samples: np.ndarray) -> np.ndarray:
    """Every sample of ``samples`` as a move feeds it forward (ahead_at)."""
    return np.array([ahead_at(samples, k) for k in range(len(samples))])


def _delivered(wanted: np.ndarray, start: float = 0.0) -> np.ndarray:
    """The commands (N, 7) the loop sends for the law's torques ``wanted`` (N, 7), each
    tick finished around the previous command (``start`` [Nm] before the first), as the
    robot reports it in tau_J_d."""
    walls = laws.JointWalls(np.full(7, -3.0), np.full(7, 3.0))  # far: no wall torque
    z, out = np.zeros(7), np.empty(7)
    sent, last = [], np.full(7, start)
    for tau in wanted:
        assert walls.finalize(tau, z, z, last, _TAU_MAX, out, FILTER_GAIN)
        last = out.copy()
        sent.append(last)
    return np.array(sent)


def test_a_torque_moves_at_most_the_filters_gain_of_the_saturation_a_tick() -> None:
    """Far from the command (a step of 20 Nm) the command moves FILTER_GAIN Nm a tick
    (386 Nm/s, where the robot takes 1000): the saturation comes before the filter."""
    sent = _delivered(np.full((30, 7), 20.0))
    steps = np.diff(sent[:, 0])
    assert FILTER_GAIN == pytest.approx(0.3859, abs=1e-4)
    np.testing.assert_allclose(steps[:20], FILTER_GAIN * laws.DTAU_MAX_PER_TICK, rtol=1e-12)


@pytest.mark.parametrize("slope", [0.1, 0.3])
def test_a_ramp_within_the_rate_arrives_on_time_when_led_by_the_filters_lag(slope: float) -> None:
    """A torque ramp of ``slope`` Nm a tick (within FILTER_GAIN): sent as it is, the
    command trails it by FILTER_LAG ticks (1.59, ``slope * FILTER_LAG`` Nm); its samples
    taken FILTER_LAG ticks ahead arrive on time (to 1e-6 Nm once the filter settled)."""
    n = round(20.0 / slope)  # from -10 to 10 Nm: within every joint's torque limit
    ramp = np.outer(-10.0 + np.arange(n) * slope, np.ones(7))
    settled = slice(n // 2, n - 3)
    late = _delivered(ramp, -10.0)
    np.testing.assert_allclose((ramp - late)[settled], slope * FILTER_LAG, atol=1e-6)
    led = _delivered(_led(ramp), -10.0)
    np.testing.assert_allclose(led[settled], ramp[settled], atol=1e-6)


def test_a_ramp_beyond_the_rate_falls_ever_further_behind() -> None:
    """At 0.6 Nm a tick (joint 2's torque where the FER's short fast Cartesian move turns
    from accelerating to braking, with its default 30 ms smoothing) the command falls
    behind by 0.21 Nm more each tick, lead or not (panda_py.panda.plan_torques)."""
    ramp = np.outer(-10.0 + np.arange(34) * 0.6, np.ones(7))
    led = _delivered(_led(ramp), -10.0)
    behind = ramp[:, 0] - led[:, 0]
    np.testing.assert_allclose(np.diff(behind)[5:30], 0.6 - FILTER_GAIN, rtol=1e-9)


def test_ahead_at_holds_the_last_sample() -> None:
    x = np.arange(5.0)[:, None] * np.ones((1, 2))
    led = _led(x)
    assert led.shape == x.shape
    np.testing.assert_allclose(led[:, 0], [FILTER_LAG, 1 + FILTER_LAG, 2 + FILTER_LAG, 4, 4])
    np.testing.assert_array_equal(ahead_at(np.ones((1, 6)), 0), np.ones(6))  # a single sample
