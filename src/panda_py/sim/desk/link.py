"""The one robot behind two faces: state shared by the Desk process and the FCI loop.

A block of shared doubles (``multiprocessing.RawArray``, no lock). The Desk writes the
brake and FCI switches; the loop reads them without waiting (one load each) when a client
connects or a motion starts. The loop publishes the arm's joint positions and end-effector
pose at 20 Hz under a sequence counter (a seqlock: odd while writing) for the Desk's page.

The Desk can also ask the loop to move the arm to joint positions (the pack pose): it
writes the target, then counts a request up; the loop, between motions, drives the arm
there and counts the request done. The Desk's end-effector configuration travels the
same way: the values, then a counter the loop compares with the last one it applied. One
writer per double, so no lock either.
"""

from __future__ import annotations

import multiprocessing
from typing import Any

import numpy as np

from panda_py.fci import PERIOD

BRAKES_OPEN, FCI_ACTIVE, SEQ, ROBOT_MODE, SIM_TIME = 0, 1, 2, 3, 4
MOVE_REQUESTED, MOVE_DONE = 5, 6  # counters: the Desk's requests, the loop's completions
Q = slice(8, 15)  # [rad]
O_T_EE = slice(16, 32)  # column-major 4x4
MOVE_TARGET = slice(32, 39)  # [rad] where the Desk asks the arm to go
EE_COUNT = 7  # end-effector configurations the Desk stored
EE_MASS = 40  # [kg]
EE_COM = slice(41, 44)  # [m] in the flange frame
EE_INERTIA = slice(44, 53)  # [kg m^2] about the centre of mass, row-major 3x3
EE_T = slice(53, 69)  # flange to EE (F_T_NE), column-major 4x4
SIZE = 72
PUBLISH_EVERY = 50  # [ticks] 20 Hz for the page's live view


class DeskLink:
    """Shared brake/FCI switches and the published arm pose (see the module docstring)."""

    def __init__(self, array: Any) -> None:
        self.array = array  # pickled into the child processes at spawn
        self.view = np.frombuffer(array, dtype=np.float64)

    @classmethod
    def create(cls, *, locked: bool) -> DeskLink:
        """A new block: a robot after power-up (``locked``) or unlocked with the FCI on."""
        array = multiprocessing.get_context("spawn").RawArray("d", SIZE)
        link = cls(array)
        link.view[BRAKES_OPEN] = link.view[FCI_ACTIVE] = 0.0 if locked else 1.0
        return link

    # -- the Desk's side ---------------------------------------------------------------

    def set_switches(self, *, brakes_open: bool, fci_active: bool) -> None:
        """Set the brake and FCI switches the simulator's loop reads (written by the Desk
        process)."""
        self.view[BRAKES_OPEN] = 1.0 if brakes_open else 0.0
        self.view[FCI_ACTIVE] = 1.0 if fci_active else 0.0

    def request_move(self, q: Any) -> None:
        """Ask the loop to place the arm at ``q`` [rad] (7 finite values)."""
        target = np.asarray(q, dtype=float)
        if target.shape != (7,) or not np.all(np.isfinite(target)):
            raise ValueError(f"q: expected 7 finite joint positions [rad], got {q!r}")
        self.view[MOVE_TARGET] = target
        self.view[MOVE_REQUESTED] += 1.0  # after the target: the loop reads it complete

    def publish_end_effector(self, mass: float, com: Any, inertia: Any, F_T_NE: Any) -> None:
        """Hand the loop a new end-effector configuration (written by the Desk process,
        checked there): ``mass`` [kg], ``com`` (3,) [m], ``inertia`` (3, 3) [kg m^2],
        ``F_T_NE`` (4, 4)."""
        v = self.view
        v[EE_MASS] = float(mass)
        v[EE_COM] = np.asarray(com, dtype=float).reshape(3)
        v[EE_INERTIA] = np.asarray(inertia, dtype=float).reshape(9)
        v[EE_T] = np.asarray(F_T_NE, dtype=float).reshape(16, order="F")
        v[EE_COUNT] += 1.0  # after the values: the loop reads them complete

    def move_done(self) -> bool:
        """Whether the loop has done every move asked for."""
        return bool(self.view[MOVE_DONE] == self.view[MOVE_REQUESTED])

    def snapshot(self) -> dict[str, Any] | None:
        """The newest published arm state, or None before the loop published any."""
        v = self.view
        for _ in range(100):
            seq = v[SEQ]
            if seq == 0.0 or seq % 2:
                if seq == 0.0:
                    return None
                continue
            q, pose = v[Q].tolist(), v[O_T_EE].tolist()
            mode, t = int(v[ROBOT_MODE]), float(v[SIM_TIME])
            if v[SEQ] == seq:
                return {"q": q, "O_T_EE": pose, "robot_mode": mode, "time": t}
        return None

    # -- the FCI loop's side (never waits) ---------------------------------------------

    def publish(self, tick: int, state: dict[str, np.ndarray], robot_mode: int) -> None:
        """Publish the arm's joint positions, end-effector pose, robot mode and simulated time
        for the Desk's page under the seqlock, every ``PUBLISH_EVERY`` ticks (20 Hz); called by
        the loop each tick."""
        if tick % PUBLISH_EVERY:
            return
        v = self.view
        v[SEQ] += 1.0
        v[Q] = state["q"]
        v[O_T_EE] = state["O_T_EE"]
        v[ROBOT_MODE] = robot_mode
        v[SIM_TIME] = tick * PERIOD
        v[SEQ] += 1.0

    def move_request(self) -> tuple[float, np.ndarray] | None:
        """(request, joint positions [rad]) the Desk asks the arm to go to, or None."""
        v = self.view
        request = float(v[MOVE_REQUESTED])
        if request == v[MOVE_DONE]:
            return None
        return request, v[MOVE_TARGET].copy()

    def end_effector_update(
        self, applied: float
    ) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray] | None:
        """The Desk's newest end-effector configuration if it is not the ``applied``
        one: (its count, mass [kg], centre of mass (3,) [m], inertia (3, 3) [kg m^2],
        F_T_NE (4, 4)); else None (one load)."""
        v = self.view
        count = float(v[EE_COUNT])
        if count == applied:
            return None
        return (count, float(v[EE_MASS]), v[EE_COM].copy(), v[EE_INERTIA].reshape(3, 3).copy(),
                v[EE_T].reshape(4, 4, order="F").copy())  # fmt: skip

    def move_finished(self, request: float) -> None:
        """The simulator moved the arm as the Desk's ``request`` asked (its number from
        :meth:`move_request`)."""
        self.view[MOVE_DONE] = request


def accept_fci_connect(link: DeskLink | None) -> bool:
    """Accept an FCI client? A robot refuses FCI connections while the FCI is inactive
    (panda-py #47). Without a Desk the robot is always ready."""
    return link is None or link.view[FCI_ACTIVE] != 0.0


def may_start_move(link: DeskLink | None) -> bool:
    """May a Move start? Not while the brakes are closed."""
    return link is None or link.view[BRAKES_OPEN] != 0.0


__all__ = ["DeskLink", "accept_fci_connect", "may_start_move"]
