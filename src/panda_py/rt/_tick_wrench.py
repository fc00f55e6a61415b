"""The control loop's compiled ticks of the laws that push with a force at the end
effector: ``AppliedForce`` (a wrench) and ``Force`` (its PI law on the measured joint
torques, aborting once the end effector moved past its threshold), on the skeleton of
:mod:`panda_py.rt._tick` (its wait, decoding, finishing, sending and publishing; the same
arguments first, the same statuses), each law's torque the fused step Python's ``step``
calls (:mod:`panda_py.controllers._fused`).

``Force`` reads one field of the state the other laws do not, the measured torques
``tau_J`` (at ``lay[L_TAU_J]``), decoded here into the law's own array. The tick whose
state passes its threshold is Python's (PENDING, nothing changed): its step raises the
controller's error there, as it did when every tick was Python's.
"""

from __future__ import annotations

from pathlib import Path

from panda_py.controllers import laws
from panda_py.jit import cache, libc
from panda_py.rt import _tick
from panda_py.rt._tick import L_TAU_J, L_TAU_J_SIZE, PENDING, TICKS

_FUSED = laws.fused()
if _FUSED is None:  # plain Python: Python ticks (rt._tick refuses to load as well)
    raise ImportError("the control laws run without numba")
_applied_force_step = _FUSED.applied_force_step
_force_exceeded = _FUSED.force_exceeded
_force_step = _FUSED.force_step
_begin, _advance, _finish = _tick._begin, _tick._advance, _tick._finish
_decode, _next_time, _ends = _tick._decode, _tick._next_time, _tick._ends

__all__ = ["applied_force_ticks", "force_ticks"]

KEY = cache.source_key([Path(__file__)]) + _tick.KEY[:20]


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def applied_force_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, values_in, at, applied, D, chain, J,
):  # fmt: skip
    """``AppliedForce`` (``controllers._fused.applied_force_step``): its inputs (at
    ``at``: force, damping, filter_coeff) filtered into ``applied`` and ``D``; ``tau =
    J^T applied - D dq``, the Jacobian of ``chain`` (the key's end effector) into ``J``."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0:
            _advance(io, buf, law_t)
            _applied_force_step(values_in, at, applied, D, q_in, dq_in, chain, J, tau)
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def force_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, values_in, at, law, tau_J, tau_J_in, chain, origin, ca, sa, mass,
    h, inertia, J,
):  # fmt: skip
    """``Force`` (``controllers._fused.force_step``) on its buffer ``law``, the measured
    torques decoded into ``tau_J`` (read by the step through ``tau_J_in``); a state past
    the threshold (``_fused.force_exceeded``, after the law's first tick) is Python's:
    PENDING, the law's buffer and time unchanged."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if (
            status == 0
            and _next_time(io, buf, law_t) > 0.0
            and _force_exceeded(values_in, at, law, pose_in) >= 0.0
        ):
            status = PENDING  # the controller aborts: its step raises, in Python
        if status == 0:
            _decode(buf, lay[L_TAU_J], lay[L_TAU_J_SIZE], 7, tmp, tau_J)
            _advance(io, buf, law_t)
            _force_step(values_in, at, law, law_t[0], law_t[1], pose_in, q_in, dq_in, tau_J_in,
                        chain, origin, ca, sa, mass, h, inertia, J, tau)  # fmt: skip
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return
