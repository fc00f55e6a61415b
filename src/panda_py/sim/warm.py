"""Imported by the server the simulator's processes are forked from
(:mod:`panda_py.warmstart`): the simulator's modules and MuJoCo, and the compiled
kinematics loaded (or compiled, once after installing), so that a simulator starts without
doing any of it again. Nothing here may fail the server: what does not load here loads in
the child, as in a spawned one."""

from __future__ import annotations

try:
    from panda_py import kinematics
    from panda_py.sim import server  # noqa: F401  (the simulator's modules, MuJoCo)

    kinematics.warmup()
except Exception:  # (the child does it again, and reports what fails)
    pass
