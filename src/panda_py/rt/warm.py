"""Imported by the server the control processes are forked from
(:mod:`panda_py.warmstart`): the loop's modules, the compiled kinematics, laws and model
loaded (or compiled, once after installing), and every law run once as the loop runs them
after connecting (:func:`panda_py.controllers.warmup.warm_up`) on a state a robot at rest in its
start pose would send, in the first and the newest protocol's layout, so that the kernels'
signatures for the loop's read-only states are loaded too. A ``Panda`` then connects
without doing any of it again. Nothing here may fail the server: what does not load here
loads in the child, as in a spawned one."""

from __future__ import annotations

import gc

try:
    import numpy as np

    from panda_py import fci, kinematics
    from panda_py.controllers import laws
    from panda_py.controllers.finalize import Finalize
    from panda_py.controllers.model import ControlModel
    from panda_py.controllers.warmup import warm_up
    from panda_py.libfranka.state import TickState
    from panda_py.robots.params import START_POSE, get_robot
    from panda_py.rt import fastloop

    laws.warmup()  # (connect's: the laws on writable arrays; warm_up loads the kinematics)
    spec = get_robot("fer")
    model = ControlModel(spec)
    for version in (fci.SUPPORTED_VERSIONS[0], fci.SUPPORTED_VERSIONS[-1]):
        dialect = fci.dialect(version)
        record = np.zeros((), dialect.state_dtype)
        record["q"] = record["q_d"] = START_POSE
        record["O_T_EE"] = kinematics.get_kinematics(spec).fk(START_POSE).reshape(16, order="F")
        record["F_T_EE"] = record["EE_T_K"] = np.eye(4).reshape(16)
        state = TickState(dialect, record.tobytes())
        finalize = Finalize(spec)
        warm_up(state, model, spec, finalize)
        fastloop.warm_up(state, model, spec, finalize)  # the compiled ticks' kernels
except Exception:  # (the child does it again, and reports what fails)
    pass
# the collector of a forked child leaves what is here alone: its passes would touch every
# object, and so copy every page shared with this server
gc.freeze()
