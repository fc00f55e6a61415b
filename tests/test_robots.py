import math

import pytest

from panda_py.robots import (
    FER,
    FR3,
    FR3_PRE_5_9,
    START_POSE,
    get_robot,
    position_based_velocity_limits,
)


def test_get_robot_names():
    assert get_robot("panda") is FER
    assert get_robot("FR3") is FR3
    assert get_robot(FR3_PRE_5_9) is FR3_PRE_5_9


def test_get_robot_rejects_unknown_name():
    with pytest.raises(ValueError, match="expected one of"):
        get_robot("ur5")


@pytest.mark.parametrize("spec", [FER, FR3, FR3_PRE_5_9])
def test_limits_are_consistent(spec):
    j = spec.joints
    for i in range(7):
        assert j.q_min[i] < START_POSE[i] < j.q_max[i]
        assert j.q_min[i] < j.q_max[i]
        assert j.dq_max[i] > 0 and j.ddq_max[i] > 0 and j.dddq_max[i] > 0


def test_fr3_position_based_velocity_limit_at_upper_limit_is_zero():
    upper, lower = position_based_velocity_limits(FR3, FR3.joints.q_max)
    assert upper == [0.0] * 7
    assert all(v < 0 for v in lower)
    upper, _ = position_based_velocity_limits(FR3, [0, 0, 0, -1.5, 0, 2.0, 0])
    assert upper[0] == pytest.approx(2.62)
    assert math.isclose(upper[5], min(4.18, -0.4878 + math.sqrt(2 * 5.5 * (4.6216 - 2.0))))
