"""Imported by the server the control processes are forked from
(:mod:`panda_py.warmstart`): the loop's modules, and the compiled kinematics, laws and
model loaded (or compiled, once after installing), so that a ``Panda`` connects without
doing any of it again. Nothing here may fail the server: what does not load here loads in
the child, as in a spawned one."""

from __future__ import annotations

try:
    from panda_py import kinematics
    from panda_py.controllers import laws
    from panda_py.controllers.model import ControlModel
    from panda_py.rt import child  # noqa: F401  (the loop's modules)

    kinematics.warmup()
    laws.warmup()
    ControlModel("fer")  # (its dynamics' kernels)
except Exception:  # (the child does it again, and reports what fails)
    pass
