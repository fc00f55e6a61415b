"""The model the laws see (``ControlModel``): the feed-forward's inertia is the links' and
the rotors', reused only while the arm stays within ``DRIVEN_MASS_REUSE`` of where it was
computed and the load is unchanged."""

from __future__ import annotations

import numpy as np
from test_law_steps import Q0, make_state

from panda_py import dynamics, fci
from panda_py.controllers.model import DRIVEN_MASS_REUSE, ControlModel
from panda_py.libfranka import RobotState


def _exact(model: ControlModel, q: np.ndarray) -> np.ndarray:
    return dynamics.LoadedArm(model.spec).mass_matrix(q) + np.diag(model.spec.drives.armature)


def test_the_driven_inertia_is_reused_within_its_tolerance_and_recomputed_beyond() -> None:
    model = ControlModel("fer")
    first = model.driven_mass_of(make_state(Q0))
    np.testing.assert_allclose(first, _exact(model, Q0), rtol=1e-12, atol=1e-12)
    near = Q0 + 0.8 * DRIVEN_MASS_REUSE
    again = model.driven_mass_of(make_state(near))
    assert again is first  # reused: the same matrix, not recomputed
    far = Q0 + np.array([0, 0, 0, 1.5 * DRIVEN_MASS_REUSE, 0, 0, 0])
    moved = model.driven_mass_of(make_state(far))
    assert moved is not first
    np.testing.assert_allclose(moved, _exact(model, far), rtol=1e-12, atol=1e-12)
    # a reused matrix errs by what the tolerance allows, and no more (the comment's bound)
    assert np.abs(again - _exact(model, near)).max() < 0.024
    assert not moved.flags.writeable  # shared between ticks: nobody may change it


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
