"""A robot command as the simulated robot reads it (:class:`Command`, the same in every
protocol version), and its views onto a command datagram laid out in one dialect
(:func:`command_on`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from panda_py import fci

__all__ = ["Command", "command_on"]


@dataclass
class Command:
    """One decoded RobotCommand (version-independent view)."""

    message_id: int
    q_c: np.ndarray
    dq_c: np.ndarray
    O_T_EE_c: np.ndarray  # 16, column-major
    O_dP_EE_c: np.ndarray
    elbow_c: np.ndarray
    valid_elbow: bool
    motion_generation_finished: bool
    tau_J_d: np.ndarray
    torque_command_finished: bool


def command_on(d: fci.Dialect, buffer: bytearray) -> Command:
    """A :class:`Command` whose arrays are read-only views of ``buffer``, a command
    datagram of dialect ``d`` (its flags and message id are the reader's to set)."""
    dt = d.command_dtype

    def view(name: str) -> np.ndarray:
        field, offset = dt.fields[name][:2]  # type: ignore[index]
        out = np.ndarray(field.shape, field.base, buffer=buffer, offset=offset)
        out.flags.writeable = False
        return out

    return Command(
        message_id=0,
        q_c=view("q_c"),
        dq_c=view("dq_c"),
        O_T_EE_c=view("O_T_EE_c"),
        O_dP_EE_c=view("O_dP_EE_c"),
        elbow_c=view("elbow_c"),
        valid_elbow=False,
        motion_generation_finished=False,
        tau_J_d=view("tau_J_d"),
        torque_command_finished=False,
    )
