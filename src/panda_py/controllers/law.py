"""The one interface the control loop runs: a control law, whether a torque controller the
user feeds or a move tracking a planned trajectory.

The loop (:mod:`panda_py.rt.child`) drives every law the same way::

    law.start(state, model)              # once, with the state it starts from
    law.begin(state, model)              # at its first tick
    every tick (1 ms):
        law.tick(dt)                     # the robot's clock, and the inputs of this tick
        tau = law.step(state, model)     # joint torques [Nm] (gravity is the robot's)
        ... walls, rate saturation, limits ...
        if law.finished(state) and (after := law.next_law(state, model)):
            law = after                  # it goes on (a guarded move's then)
        ... the command is sent (the last one if the law finished) ...
        law.published()                  # after the command: publish outputs
    law.stop(state, model)               # once, with the last state
    law.result(state)                    # what a caller waiting for the law gets

A move that replaces the running one mid-motion takes over with ``new.replace(law,
state, model)`` (:attr:`ControlLaw.replaceable` laws); ``law.cancel(reason)`` brings it to
rest. Between the ticks Python must run, the loop runs the ticks a law offers compiled
(:meth:`ControlLaw.compiled`), with the same results. The loop never asks which kind
of law it runs. The laws' inputs from the user's process arrive through a
:class:`SignalSlot` (the shared memory's seqlock and latch,
:class:`panda_py.rt.shm.SharedBlock`), handed to the law as an object.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panda_py.controllers.state import StateView

if TYPE_CHECKING:
    from panda_py.controllers.model import ControlModel

__all__ = ["CompiledTicks", "ControlLaw", "SignalSlot", "StateView", "readonly"]

FloatArray = NDArray[np.float64]


class SignalSlot(Protocol):
    """Where a running controller's inputs and outputs live while it runs: written by the
    user's process under a seqlock, read by the loop without waiting (the loop keeps its
    last consistent copy), outputs published by the loop as a latch. Implemented once, by
    :class:`panda_py.rt.shm.SharedBlock`."""

    @property
    def signals(self) -> FloatArray: ...

    def write_packed(self, packer: struct.Struct, offset: int, values: Any) -> None: ...

    def write_packed_many(self, pieces: Iterable[tuple[struct.Struct, int, Any]]) -> None: ...

    def write_signal_array(self, values: FloatArray, offset: int = 0) -> None: ...

    def read_signals(self, out: FloatArray, last_seq: int) -> int: ...

    def write_outputs(self, values: FloatArray) -> None: ...

    def read_outputs(self, n: int) -> FloatArray: ...


class ControlLaw:
    """Base of everything the control loop runs (see the module's docstring).

    ``t`` is the time since the law started and ``dt`` the time since the previous tick
    [s], both of the robot's clock (``dt`` is 0 at the first tick)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.dt = 0.0

    @property
    def name(self) -> str:
        """A human-readable name of the law (error messages, logs)."""
        return type(self).__name__

    def start(self, state: StateView, model: ControlModel) -> None:
        """Called once, before the first tick, with the state the law starts from."""

    #: whether a move may replace it mid-motion (:meth:`replace`): the moves
    replaceable: ClassVar[bool] = False
    #: [s] how long its reference lasts (a move's; a controller runs until stopped)
    duration: float = math.inf

    def begin(self, state: StateView, model: ControlModel) -> None:
        """Called at its first tick, before :meth:`tick`, with that tick's state (a move
        planned while another ran, which ended meanwhile, leads in from where the arm
        rests)."""

    def replace(self, previous: ControlLaw, state: StateView, model: ControlModel) -> None:
        """Take over from ``previous`` mid-motion, from this tick's ``state`` (laws that
        are :attr:`replaceable` only)."""
        raise TypeError(f"{self.name} cannot take over from a running {previous.name}")

    def next_law(self, state: StateView, model: ControlModel) -> ControlLaw | None:
        """After the tick that finished it: the law that goes on in its place, already
        taken over (a guarded move's ``then`` once its condition held), or None: the
        motion ends."""
        return None

    def cancel(self, reason: str) -> None:
        """Come to rest as gently as the limits allow and end (a move); ``reason`` says
        why in its result. A controller ends when it is stopped instead."""

    def tick(self, dt: float) -> None:
        """Called first in every tick with the time since the previous one [s]."""
        self.t += dt
        self.dt = dt

    def step(self, state: StateView, model: ControlModel) -> ArrayLike:
        """Joint torques (7,) [Nm] for ``state`` (gravity is compensated by the robot)."""
        raise NotImplementedError(f"{type(self).__name__} must implement step(state, model)")

    def published(self) -> None:
        """Called in every tick after the command left: publish what the law outputs."""

    def finished(self, state: StateView) -> bool:
        """Whether the law is done after this tick (a controller runs until stopped)."""
        return False

    def stop(self, state: StateView | None, model: ControlModel) -> None:
        """Called once when the law ends (finished, stopped or aborted), with the last
        state (None if there was none)."""

    def result(self, state: StateView) -> Any:
        """What the caller waiting for this law gets when it ended (None by default)."""
        return None

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """The law's ticks as a compiled loop runs them (:mod:`panda_py.rt.fastloop`),
        from ``state`` on (the last one :meth:`step` saw), or None (the default): the loop
        then calls :meth:`tick`, :meth:`step` and :meth:`published` each tick. A law that
        returns them keeps running :meth:`step` for the ticks the compiled loop hands
        back, and must compute the same torques either way."""
        return None

    def compiled_io(self) -> tuple[FloatArray, int]:
        """For a compiled loop running this law's ticks: its outputs (time first) and the
        sequence number of the copy of its inputs it holds (the inputs themselves are
        among :meth:`compiled`'s arrays); none by default."""
        return _NONE, -1

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        """A compiled loop ran ticks of this law: its time and last dt [s] (``time``),
        and the inputs' sequence number of the copy it took last."""
        self.t, self.dt = float(time[0]), float(time[1])


_NONE = np.zeros(0)  # (writable: a compiled loop's kernels take one type)


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (the fused steps are compiled for read-only inputs)."""
    view = a.view()
    view.flags.writeable = False
    return view


@dataclass(frozen=True)
class CompiledTicks:
    """A law's part of a compiled loop's ticks (:meth:`ControlLaw.compiled`): the name of
    its loop kernel (in one of ``rt.fastloop.KERNEL_MODULES``, each a law's tick on the
    skeleton of :mod:`panda_py.rt._tick`), the law's arrays in the kernel's order (its
    inputs, their guard and the guard's key first, then what the law's tick unpacks),
    and the state's fields those arrays were made for (the end effector, the load: a
    state in which they changed goes to :meth:`ControlLaw.step`)."""

    kernel: str
    arrays: tuple[Any, ...]
    key_fields: tuple[str, ...]
    #: the law's time and last dt [s], advanced by the kernel (handed back to the law)
    time: FloatArray
