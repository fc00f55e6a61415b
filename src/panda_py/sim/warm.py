"""Imported by the server the simulator's processes are forked from
(:mod:`panda_py.warmstart`): the simulator's modules and MuJoCo, the compiled kinematics
loaded (or compiled, once after installing), and a robot core built and ticked once on a
state datagram of each dialect, so that its compiled tick is loaded too, with the compiled
tick of a torque motion and the lockstep kernel that runs it. A simulator then
starts, and serves its first client, without doing any of it again. Nothing here may fail
the server: what does not load here loads in the child, as in a spawned one."""

from __future__ import annotations

import gc

try:
    import numpy as np

    from panda_py import fci, kinematics
    from panda_py.robots.params import START_POSE, get_robot
    from panda_py.sim.fast_tick import compiled_tick
    from panda_py.sim.physics import Physics
    from panda_py.sim.robot import RobotCore
    from panda_py.sim.server import SimServer  # noqa: F401  (the simulator's modules)
    from panda_py.sim.wire import StateWire

    kinematics.warmup()
    spec = get_robot("fer")
    core = RobotCore(spec, Physics(spec), np.asarray(START_POSE, dtype=float))
    for version in fci.SUPPORTED_VERSIONS:
        StateWire(fci.dialect(version), core).fill(0, 1.0)
    core.tick(None)
    fast = compiled_tick(core)
    if fast is not None:
        from panda_py.sim.lockstep import LockstepTicks

        fast.warm(None)
        LockstepTicks(fast, core.state_buffer.size).warm(None)
    del core, fast
except Exception:  # (the child does it again, and reports what fails)
    pass
# the collector of a forked child leaves what is here alone: its passes would touch every
# object, and so copy every page shared with this server
gc.freeze()
