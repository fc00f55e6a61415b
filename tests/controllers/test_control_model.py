"""The model the laws see (``ControlModel``): the feed-forward's inertia is the links' and
the rotors', at each tick's state and load."""

from __future__ import annotations

import numpy as np
from test_law_steps import Q0, make_state

from panda_py import dynamics, fci
from panda_py.controllers.model import ControlModel
from panda_py.libfranka import RobotState


def _exact(model: ControlModel, q: np.ndarray) -> np.ndarray:
    return dynamics.LoadedArm(model.spec).mass_matrix(q) + np.diag(model.spec.drives.armature)


def test_the_driven_inertia_is_exact_at_each_state_and_computed_once_per_state() -> None:
    model = ControlModel("fer")
    state = make_state(Q0)
    first = model.driven_mass_of(state)
    np.testing.assert_allclose(first, _exact(model, Q0), rtol=1e-12, atol=1e-12)
    assert model.driven_mass_of(state) is first  # the same tick: not recomputed
    assert not first.flags.writeable  # shared within the tick: nobody may change it
    near = Q0 + np.array([0, 0, 0, 1e-4, 0, 0, 0])  # the next tick, barely moved
    moved = model.driven_mass_of(make_state(near))
    assert moved is not first
    np.testing.assert_allclose(moved, _exact(model, near), rtol=1e-12, atol=1e-12)


def test_a_new_load_recomputes_the_driven_inertia_at_once() -> None:
    model = ControlModel("fer")
    state = make_state(Q0)
    bare = model.driven_mass_of(state)
    dialect = fci.dialect(state.version)
    rec = np.frombuffer(state.raw, dialect.state_dtype).copy()
    rec["m_load"] = 2.0  # [kg]
    rec["F_x_Cload"] = [0.0, 0.0, 0.1]  # [m]
    loaded = model.driven_mass_of(RobotState(dialect, rec.tobytes()))
    assert loaded is not bare
    assert loaded[0, 0] > bare[0, 0] or loaded[1, 1] > bare[1, 1]


def test_the_compiled_laws_model_arrays_follow_the_end_effector_and_the_load() -> None:
    """kernel_arrays: the same arrays tick after tick while the end effector's frame and
    the load stay; new ones, equal to a fresh model's, as soon as either changes."""
    from panda_py import kinematics

    model = ControlModel("fer")
    state = make_state(Q0)
    dialect = fci.dialect(state.version)

    def changed(**fields: object) -> RobotState:
        rec = np.frombuffer(state.raw, dialect.state_dtype).copy()
        for name, value in fields.items():
            rec[name] = value
        return RobotState(dialect, rec.tobytes())

    chain, arm = model.kernel_arrays(state)
    same = model.kernel_arrays(make_state(Q0 + 1e-3))  # the next tick, moved
    assert same[0] is chain and same[1] is arm
    F_T_EE = np.eye(4)
    F_T_EE[2, 3] = 0.2
    moved_ee = changed(F_T_EE=F_T_EE.reshape(16, order="F"))
    chain2, arm2 = model.kernel_arrays(moved_ee)
    assert chain2 is not chain
    want = kinematics.get_kinematics(model.spec, F_T_EE).chain_constants
    np.testing.assert_array_equal(chain2, want)
    loaded = changed(F_T_EE=F_T_EE.reshape(16, order="F"), m_load=2.0,
                     F_x_Cload=[0.0, 0.0, 0.1])  # fmt: skip
    chain3, arm3 = model.kernel_arrays(loaded)
    assert arm3 is not arm2
    fresh = ControlModel("fer").kernel_arrays(loaded)
    np.testing.assert_array_equal(chain3, fresh[0])
    for got, expected in zip(arm3, fresh[1], strict=True):
        np.testing.assert_array_equal(got, expected)
    assert not all(np.array_equal(a, b) for a, b in zip(arm3, arm, strict=True))
