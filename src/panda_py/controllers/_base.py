"""``TorqueController``: a control law defined once, run in the control process, fed from
the user's process through shared memory.

A controller declares its inputs (``signals``: name -> number of float64) and outputs
(``outputs``). The object the user holds is a handle: ``set_signals`` (and the built-in
controllers' ``set_control``/``set_*``) checks the values and writes them into the
running controller's input slot; ``get_time``/``get_output`` read what the loop
published. ``Panda.start_controller`` pickles the object into the control process, where
``start(state, model)`` runs once and ``step(state, model) -> tau`` at 1 kHz on the
newest consistent copy of the inputs (``signal(name)``).

A user-written controller subclasses :class:`TorqueController` in Python, declares its
``signals`` and implements ``step``; it runs at 1 kHz in the control process, never in the
user's interpreter, so nothing the user's process does can make it miss a tick. Its
class is sent by value if it lives in a script (``__main__``), by reference otherwise.
"""

from __future__ import annotations

import struct
import threading
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.controllers.law import ControlLaw, SignalSlot, StateView
from panda_py.controllers.model import ControlModel
from panda_py.libfranka.errors import InvalidOperationException

__all__ = ["TorqueController"]

FloatArray = NDArray[np.float64]


_PACKERS: dict[int, struct.Struct] = {}


def packer(n: int) -> struct.Struct:
    """The (shared) packer of ``n`` float64 values."""
    p = _PACKERS.get(n)
    if p is None:
        p = _PACKERS[n] = struct.Struct(f"<{n}d")
    return p


def _offsets(decl: dict[str, int], first: int = 0) -> tuple[dict[str, tuple[int, int]], int]:
    out, pos = {}, first
    for name, size in decl.items():
        if not isinstance(size, int) or size < 1:
            raise TypeError(f"declared size of {name!r}: expected an int >= 1, got {size!r}")
        out[name] = (pos, size)
        pos += size
    return out, pos


class TorqueController(ControlLaw):
    """Base class of all torque controllers: they give the robot joint torques at 1 kHz
    (gravity is compensated by the robot) and the user an asynchronous interface for
    control signals (panda-py's ``TorqueController``)."""

    #: the controller's inputs: name -> number of float64 values (override in subclasses)
    signals: ClassVar[dict[str, int]] = {}
    #: values the loop publishes besides the time: name -> number of float64 values
    outputs: ClassVar[dict[str, int]] = {}

    def __init__(self) -> None:
        super().__init__()
        sig, n_sig = _offsets(type(self).signals)
        out, n_out = _offsets(type(self).outputs, 1)  # outputs[0] is the time
        self._sig_layout = sig
        self._out_layout = out
        self._values = np.zeros(n_sig)  # the inputs (user side: as last set)
        self._out = np.zeros(n_out)
        self._slot: SignalSlot | None = None  # set while running (either side)
        self._in_seq = -1  # the input slot's sequence number of the last copy taken
        #: inside ``step``: whether the inputs changed since the previous tick (True where
        #: unknown), so a law can redo what depends on them only then
        self.inputs_changed = True
        self._lock = threading.Lock()
        self._views: dict[str, FloatArray] = {}
        self._bounds: list[FloatArray] | None = None  # user side: published at start
        self._make_views()

    # --- declared data --------------------------------------------------------------

    def _scalar(self, name: str) -> float:
        """The current value of the one-value input ``name`` (by its declared layout)."""
        return float(self._values[self._sig_layout[name][0]])

    def _make_views(self) -> None:
        self._views = {n: self._values[o : o + s] for n, (o, s) in self._sig_layout.items()}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        for key in ("_slot", "_lock", "_views"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._slot = None
        self._lock = threading.Lock()
        self._make_views()
        self._bind_views()

    def _bind_views(self) -> None:
        """Hook: built-in controllers keep attribute views of their signals."""

    def _check_initialized(self) -> None:
        if "_values" not in self.__dict__:
            raise TypeError(
                f"{type(self).__name__}.__init__ must call super().__init__() "
                "(TorqueController keeps its signals there)"
            )

    # --- user side ------------------------------------------------------------------

    def set_signals(self, **values: Any) -> None:
        """Set declared inputs by name (each a number or an array of its declared size);
        all are checked before any is written, and the loop sees them together."""
        self._check_initialized()
        checked: dict[str, list[float]] = {}
        for name, value in values.items():
            if name not in self._sig_layout:
                raise ValueError(
                    f"{name}: expected one of the signals {sorted(self._sig_layout)} "
                    f"of {type(self).__name__}"
                )
            checked[name] = checks.floats(name, value, self._sig_layout[name][1])
        self._write(**checked)

    def _write(self, **checked: list[float]) -> None:
        """Write checked values of signals (by name): while running into the shared input
        slot, all under one seqlock write; before, into this object."""
        layout = self._sig_layout
        with self._lock:
            block = self._slot
            if block is None:
                for name, vals in checked.items():
                    offset = layout[name][0]
                    self._values[offset : offset + len(vals)] = vals
                return
            block.write_packed_many(
                (packer(len(vals)), layout[name][0], vals) for name, vals in checked.items()
            )

    def _send(self, offset: int, values: list[float]) -> None:
        """The fast path of ``set_control``: checked, contiguous values at ``offset``.

        No lock here (it would cost a third of the call): two threads calling
        ``set_control`` at once can at worst make the loop see one's position with the
        other's orientation, both complete and checked, never a torn number."""
        block = self._slot
        if block is None:
            with self._lock:
                self._values[offset : offset + len(values)] = values
            return
        block.write_packed(_PACKERS.get(len(values)) or packer(len(values)), offset, values)

    # --- binding to a running loop (Panda and the control process call these) ---------

    def attach(self, slot: SignalSlot, values: FloatArray) -> None:
        """User side: from now on this handle writes into and reads from ``slot``, the
        running controller's shared inputs and outputs; ``values`` are its inputs as the
        control process started it (``start`` may have set some)."""
        self._check_initialized()
        with self._lock:
            self._values[:] = values
            self._out[:] = 0.0
            self._slot = slot
            self._bounds = None  # the robot's, as this start publishes them

    def detach(self) -> None:
        """User side: the controller stopped; keep its last inputs and outputs here, so
        ``get_signal``/``get_time`` go on answering with them."""
        with self._lock:
            slot, self._slot = self._slot, None
            if slot is None:
                return
            try:
                self._out[:] = slot.read_outputs(len(self._out))
                self._values[:] = slot.signals[: len(self._values)]
            except (OSError, ValueError):  # the shared memory is gone with its process
                pass

    def open_slot(self, slot: SignalSlot) -> FloatArray:
        """Control-process side, after ``start``: publish the starting inputs and outputs
        into ``slot``, read this controller's inputs from it every tick, and return the
        starting inputs (for the user's handle)."""
        self.t = self.dt = 0.0
        slot.write_signal_array(self._values)
        self._out[0] = 0.0
        slot.write_outputs(self._out)
        self._slot = slot
        self._in_seq = -1
        return self._values.copy()

    def tick(self, dt: float) -> None:
        """The inputs of this tick: the slot's newest consistent copy (the last one when
        the user's process is writing just now)."""
        slot = self._slot
        if slot is not None:
            seq = slot.read_signals(self._values, self._in_seq)
            self.inputs_changed = seq != self._in_seq
            self._in_seq = seq
        self.t += dt
        self.dt = dt

    def compiled_io(self) -> tuple[FloatArray, int]:
        return self._out, self._in_seq

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        self.t, self.dt = float(time[0]), float(time[1])
        self._in_seq = in_seq

    def published(self) -> None:
        """Publish the time and the declared outputs for the user's handle."""
        self._out[0] = self.t
        slot = self._slot
        if slot is not None:
            slot.write_outputs(self._out)

    def get_signal(self, name: str) -> FloatArray:
        """The input ``name`` as last set (a copy)."""
        if name not in self._sig_layout:
            raise ValueError(f"{name}: expected one of the signals {sorted(self._sig_layout)}")
        offset, size = self._sig_layout[name]
        block = self._slot
        if block is not None:
            return block.signals[offset : offset + size].copy()
        return self._values[offset : offset + size].copy()

    def _outputs(self) -> FloatArray:
        block = self._slot
        if block is not None:
            return block.read_outputs(len(self._out))
        return self._out

    def _published_bounds(self, names: tuple[str, ...]) -> list[FloatArray]:
        """User side: the outputs ``names`` the control process published at start (the
        robot's bounds a target is checked against; read once a start)."""
        bounds = self._bounds
        if bounds is None:
            bounds = [self.get_output(n) for n in names]
            if not any(v.any() for v in bounds):
                raise InvalidOperationException(
                    f"{type(self).__name__}.set_target: the controller is not running; start "
                    "it with Panda.start_controller first (its target starts where the arm is)"
                )
            self._bounds = bounds
        return list(bounds)

    def _joint_target(self, q: Any) -> list[float]:
        """User side: joint positions ``q`` [rad] checked against the joint limits the
        control process published (outputs ``q_min``, ``q_max``); ValueError otherwise."""
        values = checks.fast_floats("q", q, 7, "[rad]")
        low, high = self._published_bounds(("q_min", "q_max"))
        for i, v in enumerate(values):
            if not low[i] <= v <= high[i]:
                raise ValueError(
                    f"q: expected joint positions within the robot's joint limits; joint {i + 1}"
                    f" is {v} rad, outside [{low[i]}, {high[i]}] rad"
                )
        return values

    def get_time(self) -> float:
        """Time since this controller was started [s] (of the robot's clock)."""
        return float(self._outputs()[0])

    def get_output(self, name: str) -> FloatArray:
        """The declared output ``name`` as the loop last published it."""
        if name not in self._out_layout:
            raise ValueError(f"{name}: expected one of the outputs {sorted(self._out_layout)}")
        offset, size = self._out_layout[name]
        return self._outputs()[offset : offset + size].copy()

    # --- control-process side (override start/step/stop) --------------------------------

    def step(self, state: StateView, model: ControlModel) -> Any:
        """Joint torques (7,) [Nm] for ``state`` (gravity is compensated by the robot);
        runs at 1 kHz in the control process. Inside it, ``self.t`` is the controller's
        time and ``self.dt`` the time since the previous tick [s]; the state's arrays are
        this tick's, decoded once and read-only (copy one to change it)."""
        raise NotImplementedError(f"{type(self).__name__} must implement step(state, model)")

    def signal(self, name: str) -> FloatArray:
        """Inside ``step``: the input ``name`` of this tick (a view; do not keep it)."""
        return self._views[name]

    def set_output(self, name: str, value: Any) -> None:
        """Inside ``step``: publish the output ``name``."""
        offset, size = self._out_layout[name]
        self._out[offset : offset + size] = value

    def initial_signals(self, **values: Any) -> None:
        """Inside ``start``: set inputs the user has not set (e.g. the target to the
        current pose); the user's handle sees them once the controller runs."""
        for name, value in values.items():
            offset, size = self._sig_layout[name]
            self._values[offset : offset + size] = np.asarray(value, dtype=np.float64).ravel()
