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
