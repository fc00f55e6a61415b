"""The real-time control process behind :class:`panda_py.Panda`: its shared memory
(:mod:`.shm`), request channel (:mod:`.channel`), the process itself (:mod:`.child`) and
the user's handle on it (:mod:`.process`)."""

from __future__ import annotations

from panda_py.rt.process import ControlProcessError

__all__ = ["ControlProcessError"]
