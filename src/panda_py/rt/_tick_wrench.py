"""The control loop's compiled ticks of the laws that push with a force at the end
effector: ``AppliedForce`` (a wrench) and ``Force`` (its PI law on the measured joint
torques, aborting once the end effector moved past its threshold): each law's part of a
tick, on the skeleton of :mod:`panda_py.rt._tick` (``loop_kernel``: its wait, decoding,
finishing, sending and publishing around it), its torque the fused step Python's ``step``
calls (:mod:`panda_py.controllers._fused`).

``Force`` reads one field of the state the other laws do not, the measured torques
``tau_J`` (at ``lay[L_TAU_J]``), decoded here into the law's own array. The tick whose
state passes its threshold is Python's (PENDING, nothing changed): its step raises the
controller's error there, as it did when every tick was Python's.
"""

from __future__ import annotations

from pathlib import Path

from panda_py.controllers import laws
from panda_py.jit import cache
from panda_py.rt import _tick
from panda_py.rt._tick import DQ, L_TAU_J, LAW_T, PENDING, POSE, TAU, Q

_FUSED = laws.fused()
if _FUSED is None:  # plain Python: Python ticks (rt._tick refuses to load as well)
    raise ImportError("the control laws run without numba")
_applied_force_step = _FUSED.applied_force_step
_force_exceeded = _FUSED.force_exceeded
_force_step = _FUSED.force_step
_advance, _next_time, _decode_field = _tick.advance, _tick.next_time, _tick.decode_field

__all__ = ["applied_force_ticks", "force_ticks"]

KEY = cache.source_key([Path(__file__)]) + _tick.KEY[:20]


@cache.keyed_jit(KEY, nogil=True)
def _applied_force(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``AppliedForce`` (``controllers._fused.applied_force_step``): its inputs (at
    ``at``: force, damping, filter_coeff) filtered into ``applied`` and ``D``; ``tau =
    J^T applied - D dq``, the Jacobian of ``chain`` (the key's end effector) into ``J``."""
    values_in, at, applied, D, chain, J = law
    _advance(view)
    _applied_force_step(values_in, at, applied, D, view[Q], view[DQ], chain, J, view[TAU])
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _force(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``Force`` (``controllers._fused.force_step``) on its buffer ``buffer``, the measured
    torques decoded into ``tau_J`` (read by the step through ``tau_J_in``); a state past
    the threshold (``_fused.force_exceeded``, after the law's first tick) is Python's:
    PENDING, the law's buffer and time unchanged."""
    values_in, at, buffer, tau_J, tau_J_in, chain, origin, ca, sa, mass, h, inertia, J = law
    if _next_time(view) > 0.0 and _force_exceeded(values_in, at, buffer, view[POSE]) >= 0.0:
        return PENDING  # the controller aborts: its step raises, in Python
    _decode_field(view, L_TAU_J, 7, tau_J)
    _advance(view)
    law_t = view[LAW_T]
    _force_step(values_in, at, buffer, law_t[0], law_t[1], view[POSE], view[Q], view[DQ],
                tau_J_in, chain, origin, ca, sa, mass, h, inertia, J, view[TAU])  # fmt: skip
    return 0


applied_force_ticks = _tick.loop_kernel(_applied_force, "applied_force_ticks", 6)
force_ticks = _tick.loop_kernel(_force, "force_ticks", 13)
