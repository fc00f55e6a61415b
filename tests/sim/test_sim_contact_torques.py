"""The simulator's contact estimate, on its physics alone (no server): the torques that
contacts exert on the arm are each contact's force and torsional moment (MuJoCo's
``mj_contactForce``) carried through the touching body's Jacobian, contacts of the robot
with itself left out; the wrench fitted to torques is their least squares."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import panda_py
from panda_py.robots.params import START_POSE, get_robot
from panda_py.sim.physics import Physics

pytestmark = pytest.mark.timeout(120)


def per_contact(ph: Physics, moments: bool = True) -> np.ndarray:
    """The definition, one contact at a time: the force and moment on the robot's body at
    the contact point, through that body's Jacobian, for contacts of the robot with
    something else."""
    m, d = ph.model, ph.data
    sl = slice(ph.v0, ph.v0 + 7)
    tau, f6 = np.zeros(7), np.zeros(6)
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        if (b1 in ph.robot_bodies) == (b2 in ph.robot_bodies):
            continue
        mujoco.mj_contactForce(m, d, i, f6)
        frame = c.frame.reshape(3, 3)  # rows: the normal (geom1 -> geom2), the tangents
        force, moment = frame.T @ f6[:3], frame.T @ f6[3:]  # on geom2, in the world
        on2 = b2 in ph.robot_bodies
        mujoco.mj_jac(m, d, jacp, jacr, c.pos, b2 if on2 else b1)
        load = jacp[:, sl].T @ force + (jacr[:, sl].T @ moment if moments else 0.0)
        tau += (1.0 if on2 else -1.0) * load
    return tau


Seen = list[tuple[np.ndarray | None, np.ndarray, np.ndarray]]


def hold(ph: Physics, ticks: int, finger_force: float) -> Seen:
    """Hold the arm where it is for ``ticks`` with the fingers pushed by ``finger_force``;
    each tick's estimate, its definition, and the definition without the moments."""
    q0, seen = ph.q.copy(), []
    for _ in range(ticks):
        ph.step(300.0 * (q0 - ph.q) - 30.0 * ph.dq, finger_force)
        ph._quiet_contacts = b""  # judge every tick, not only the changed ones
        got = ph.contact_torques()
        seen.append((None if got is None else got.copy(), per_contact(ph), per_contact(ph, False)))
    return seen


def test_a_cube_held_in_the_hand_weighs_on_the_arm_as_its_contacts_say() -> None:
    ph = Physics(get_robot("fer"))
    ph.reset(np.array(START_POSE), gripper_width=0.08)
    ph.place_body("cube", ph.data.site("tcp").xpos.copy())  # between the open fingers
    seen = hold(ph, 600, -30.0)  # close on it
    held = [(got, want, forces) for got, want, forces in seen if got is not None]
    assert len(held) > 300, "the fingers never closed on the cube"
    for got, want, _ in held:
        np.testing.assert_allclose(got, want, atol=1e-6)
    # the 100 g cube hangs from the hand: its weight loads the shoulder and the elbow
    got = held[-1][0]
    assert abs(got[1]) > 0.1 and abs(got[3]) > 0.1
    # the pads' torsional friction (condim 4) is in it: the forces alone differ
    assert max(float(np.abs(want - forces).max()) for _, want, forces in held) > 1e-5


def test_the_hand_pressed_on_the_table_is_pushed_back_as_its_contacts_say() -> None:
    # (the table comes first in the model, the cube last: here the robot is a contact's
    # second body, holding the cube its first)
    ph = Physics(get_robot("fr3"))
    start = np.array(START_POSE)
    T = panda_py.fk(start)
    T[:3, 3] = (0.45, 0.2, -0.005)  # 5 mm into the table, beside the cube
    press = panda_py.ik(T, start)
    T[2, 3] = 0.05
    ph.reset(panda_py.ik(T, start))
    seen = []
    for _ in range(1500):
        ph.step(np.clip(300.0 * (press - ph.q) - 30.0 * ph.dq, -20.0, 20.0), 0.0)
        ph._quiet_contacts = b""
        got = ph.contact_torques()
        seen.append((None if got is None else got.copy(), per_contact(ph)))
    pressed = [(got, want) for got, want in seen if got is not None]
    assert len(pressed) > 500, "the hand never reached the table"
    for got, want in pressed:
        np.testing.assert_allclose(got, want, atol=1e-6)
    assert np.abs(pressed[-1][0]).max() > 1.0  # it pushes back


@pytest.mark.parametrize("seed", range(4))
def test_the_fitted_wrench_is_the_least_squares_one(seed: int) -> None:
    rng = np.random.default_rng(seed)
    spec = get_robot("fer")
    ph = Physics(spec)
    lo, hi = np.asarray(spec.joints.q_min), np.asarray(spec.joints.q_max)
    for _ in range(25):
        ph.reset(rng.uniform(lo, hi))
        point = ph.data.site("tcp").xpos + rng.normal(scale=0.05, size=3)
        tau = rng.normal(size=7)
        # the Jacobian at the point from MuJoCo itself, and a plain least squares
        jacp, jacr = np.zeros((3, ph.model.nv)), np.zeros((3, ph.model.nv))
        hand = int(ph.model.site_bodyid[ph.flange_site])
        mujoco.mj_jac(ph.model, ph.data, jacp, jacr, point, hand)
        J = np.vstack((jacp, jacr))[:, ph.v0 : ph.v0 + 7]
        want = np.linalg.lstsq(J.T, tau, rcond=None)[0]
        got = ph.wrench_explaining(tau, point)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6 * np.abs(want).max())
    ph.reset(np.zeros(7))  # stretched out: singular, the fit stays finite
    assert np.isfinite(ph.wrench_explaining(np.ones(7), ph.data.site("tcp").xpos)).all()
