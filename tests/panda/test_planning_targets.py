"""A move's single target on its way to the robot (panda.planning): parsed and checked in
scalars (a policy's targets meet cold caches), with the results and the errors of the
general path."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py.kinematics import get_kinematics
from panda_py.motion import rotation
from panda_py.panda import move_args, planning
from panda_py.robots.params import START_POSE, get_robot

# a configuration whose pose has no solution at Q_NOW's q7, only at its own (found by a
# seeded search)
Q = np.array([-2.400997, -0.927901, 1.745765, -1.324150, -2.351862, 1.615389, -0.121389])
Q_NOW = np.array([*Q[:6], -1.971677])


def test_one_joint_target_parses_as_the_general_path_and_is_refused_alike() -> None:
    q = np.array(START_POSE) + np.linspace(-0.1, 0.1, 7)
    fast, opts = move_args.parse_joint_targets((q,), {})  # a float64 (7,): in scalars
    general, general_opts = move_args.parse_joint_targets((q.tolist(),), {})  # a list: NumPy
    assert fast.shape == (1, 7) and fast.dtype == np.float64
    assert opts is general_opts  # panda-py's defaults, checked once
    np.testing.assert_array_equal(fast, general)
    q[3] = np.nan
    for target in (q, q.tolist()):
        with pytest.raises(ValueError, match=r"waypoints\[0\]\[3\]: expected a finite number"):
            move_args.parse_joint_targets((target,), {})
    q[3] = np.inf
    with pytest.raises(ValueError, match=r"waypoints\[0\]\[3\]: expected a finite number"):
        move_args.parse_joint_targets((q,), {})


def test_a_pose_reachable_only_at_another_q7_passes_and_one_out_of_reach_is_refused() -> None:
    spec = get_robot("fer")
    F_T_EE = np.eye(4)
    kin = get_kinematics(spec, F_T_EE)
    T = kin.fk(Q)
    positions, quats = T[:3, 3].reshape(1, 3), rotation.from_matrix(T).reshape(1, 4)
    # the premise: the current q7 alone finds none, the sweep over q7 must
    assert not np.isfinite(kin.ik_full(T, Q_NOW, float(Q_NOW[6]))).all(axis=1).any()
    planning.check_reachable(positions, quats, Q_NOW, spec, F_T_EE)
    far = np.array([[3.0, 0.0, 0.5]])
    with pytest.raises(ValueError, match=r"pose\[0\]: position \[3.0, 0.0, 0.5\].*out of reach"):
        planning.check_reachable(far, quats, Q_NOW, spec, F_T_EE)
    # the second of two, named
    with pytest.raises(ValueError, match=r"pose\[1\]: .*out of reach"):
        planning.check_reachable(np.vstack([positions, far]), np.vstack([quats, quats]), Q_NOW,
                                 spec, F_T_EE)  # fmt: skip
