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


def test_each_protocol_version_belongs_to_one_robot_system() -> None:
    """libfranka's compatibility matrix: FER systems speak 3-5, FR3 systems before 5.9
    speak 6-9, from 5.9 on 10; every version the client speaks belongs to exactly one."""
    from panda_py import fci
    from panda_py.robots import FER, FR3, FR3_PRE_5_9, robot_for_protocol

    assert FER.protocol_versions == (3, 4, 5)
    assert FR3_PRE_5_9.protocol_versions == (6, 7, 8, 9)
    assert FR3.protocol_versions == (10,)
    for version in fci.SUPPORTED_VERSIONS:
        owners = [s for s in (FER, FR3_PRE_5_9, FR3) if version in s.protocol_versions]
        assert owners == [robot_for_protocol(version)]
    with pytest.raises(ValueError, match=r"version: expected an FCI protocol version in"):
        robot_for_protocol(11)
