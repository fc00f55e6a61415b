"""panda-sim: a simulated Franka (FER or FR3) that speaks the real FCI protocol.

Use :class:`Simulator` from Python, ``panda-sim`` from the shell, or the ``panda_sim``
pytest fixture (``panda_py.sim.testing``).
"""

from panda_py.sim.api import Simulator, SimulatorError, free_loopback_host
from panda_py.sim.server import SimConfig

__all__ = ["SimConfig", "Simulator", "SimulatorError", "free_loopback_host"]
