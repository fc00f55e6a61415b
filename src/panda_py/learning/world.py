"""The fast training world: the simulated robot in this process, driven at 1 kHz by the
same streamed-target controllers a ``Panda`` runs, with no network in between.

What runs is what ``panda-sim`` and a ``Panda`` run, minus the sockets: the simulator's
robot in this process (:class:`panda_py.sim.inprocess.InProcessRobot`: its mode machine,
limit checks and reflexes, MuJoCo physics, the hand); the state each tick is the robot's
wire datagram read through libfranka's ``TickState``, as the control process reads it;
the controller's torques pass the control process's finishing
(:class:`panda_py.controllers.finalize.Finalize`: joint walls, torque-rate saturation,
torque limits, libfranka's 100 Hz low-pass filter) before the robot checks and applies
them. Nothing is random: the same commands give the same episode.

Where numba runs, the ticks of the two streamed controllers (``JointTarget``,
``CartesianTarget``) run compiled, many in one call (:mod:`._world_jit`: the law, the
finishing and the robot's compiled tick, ``mj_step`` included). A tick with a new target
(or targets gone stale) has only its generator's step in Python first (ruckig calculates:
the controller's ``compiled_news``) and the rest in the kernel; a tick that needs more (a
reflex, a contact, the hand moving, a controller's first tick) runs in Python, and the
compiled ticks equal the Python ones (``tests/learning/test_world_compiled.py``).
``PANDA_PY_NO_JIT=1`` runs them all in Python.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.controllers import CartesianTarget, JointTarget, TorqueController, laws, tracking
from panda_py.controllers.finalize import FILTER_GAIN, Finalize
from panda_py.controllers.model import FRICTION_SPEED, ControlModel
from panda_py.fci import RobotMode
from panda_py.learning.backend import Backend, Snapshot
from panda_py.libfranka.errors import ControlException
from panda_py.libfranka.state import TickState
from panda_py.robots.params import FRANKA_HAND, START_POSE, robot_for_protocol
from panda_py.sim import InProcessRobot
from panda_py.sim.physics import DT

__all__ = ["FastWorld"]

_START_POSITION = np.array([0.31, 0.0, 0.48])  # [m] by the start pose's TCP (warm-up only)
_DOWN = np.array([1.0, 0.0, 0.0, 0.0])  # the fingers down (x, y, z, w)
GRIPPER_SPEED = 0.1  # [m/s] the hand's open and close speed
GRASP_FORCE = 20.0  # [N] the hand's grasp force
# the fields a law and its finishing read of a compiled tick's state, in _world_jit's order
_READ_FIELDS = ("q", "dq", "O_T_EE", "tau_J_d")


class FastWorld(Backend):
    """A simulated ``robot`` (``"fer"`` or ``"fr3"``) with the Franka Hand, the table and
    the 4 cm cube, stepped in this process at 1 kHz of simulated time (as fast as the
    computer goes); deterministic: the same start and actions give the same episode,
    bit for bit. It speaks the newest protocol version its robot's systems do (the
    state layout and limits a ``Panda`` on ``panda-sim`` would get). ``compiled``: run
    the streamed controllers' ticks compiled where numba runs (False: always in
    Python, the reference). ``cube``: False leaves the cube out (a task that never
    uses it, as reaching: the arm moves as it would beside the cube wherever it does
    not touch it, and a tick costs less: no contacts of the cube on the table to find
    and solve, and, compiled, no collision detection while the arm is clear of the
    table)."""

    deterministic = True

    def __init__(self, robot: str = "fer", *, compiled: bool = True, cube: bool = True) -> None:
        self.robot = InProcessRobot(robot, compiled=compiled, cube=cube)
        self.has_cube = self.robot.has_cube
        self.spec = self.robot.spec
        self.spec_name = self.spec.name
        self.version = self.robot.version
        self.dialect = self.robot.dialect
        self.model = ControlModel(self.spec)
        self._finalize = Finalize(robot_for_protocol(self.version))
        self._controller: TorqueController | None = None
        self._hand_id = 0
        self._fail: str | None = None  # why the running controller stopped
        self._fast: _CompiledLoop | None = None
        if compiled and self.robot.compiled_tick() is not None:
            try:
                self._fast = _CompiledLoop(self)
            except ImportError:  # the laws without numba
                self._fast = None
        self._warm_up()

    @property
    def ticks(self) -> int:
        """[ms] the robot's clock."""
        return self.robot.ticks

    def _warm_up(self) -> None:
        """Run both streamed controllers toward a new target for a few ticks (then
        power up again), so nothing compiles or loads in an episode's first step, as
        the control process warms its laws before its loop."""
        q = np.asarray(START_POSE, dtype=float)
        joint, pose = JointTarget(), CartesianTarget()
        for ctrl, target in ((joint, (q + 0.01,)), (pose, (_START_POSITION, _DOWN))):
            self.start(ctrl)
            ctrl.set_target(*target)
            self.advance(self.ticks + 20)
            self.stop()
            # (powered up again before the next: a motion started on the tick another
            # stopped reads that one's last torques in the state, which the robot has
            # zeroed, and its first command is refused as a torque jump)
            self.home(q, None)

    # --- the loop ---------------------------------------------------------------------

    def _read(self) -> TickState:
        return TickState(self.dialect, bytes(self.robot.read()))

    def start(self, controller: TorqueController) -> None:
        """Start ``controller`` as ``Panda.start_controller`` does: the robot begins a
        torque-controlled motion and the controller runs from the next tick."""
        mode = self.robot.robot_mode
        if mode != RobotMode.IDLE:
            raise RuntimeError(
                f"start: the robot must be idle, it is in mode {mode.name} (recover() after a "
                "reflex)"
            )
        status = self.robot.start_torque_control()
        if status != fci.MoveStatus.MOTION_STARTED:
            raise RuntimeError(f"start: the robot refused the motion ({status.name})")
        state = self._read()
        controller.t = controller.dt = 0.0
        controller.start(state, self.model)
        self._finalize.reset()
        self._controller = controller
        self._fail = None
        if self._fast is not None:
            self._fast.start(controller, state)

    def stop(self) -> None:
        """End the running controller's motion (the arm holds where it is)."""
        if self._controller is not None:
            self.robot.stop_motion()
        self._controller = None

    def _law(self) -> np.ndarray | None:
        """The running controller's tick: its torques finished, or None (no controller,
        or it failed: then it is stopped)."""
        ctrl = self._controller
        if ctrl is None or self.robot.robot_mode != RobotMode.MOVE:
            return None
        state = self._read()
        ctrl.tick(DT)
        tau = ctrl.step(state, self.model)
        try:
            out = self._finalize(tau, state)  # walls, saturations and the low-pass filter
        except ControlException as exc:
            self._failed(str(exc))
            return None
        ctrl.published()
        return np.array(out)

    def _failed(self, why: str) -> None:
        self._fail = why
        self.stop()

    def _robot_tick(self, command: np.ndarray | None) -> None:
        """The robot's part of a tick, and what its end means for the controller."""
        self.robot.tick(command)
        if (
            self._controller is not None
            and self.robot.robot_mode != RobotMode.MOVE
            and self._fail is None
        ):
            self._fail = "reflex: " + ", ".join(self.reflex_flags())
            self._controller = None

    def _tick(self) -> None:
        self._robot_tick(self._law())

    def advance(self, ms: int) -> None:
        """Run ticks (1 ms each) until the robot's clock reads ``ms``, or the controller
        stopped (a reflex)."""
        fast = self._fast
        while self.ticks < ms:
            if fast is not None and self._controller is not None and fast.run(ms - self.ticks):
                if self._fail is not None:
                    return
                continue
            self._tick()
            if self._fail is not None:
                return

    # --- Backend ----------------------------------------------------------------------

    def time_ms(self) -> int:
        return self.ticks

    def snapshot(self) -> Snapshot:
        r = self.robot
        cube = r.body_position("cube") if self.has_cube else None
        return Snapshot(q=r.q, dq=r.dq, O_T_EE=r.O_T_EE, gripper_width=r.gripper_width,
                        cube=cube, time_ms=self.ticks)  # fmt: skip

    def failure(self) -> str | None:
        return self._fail

    def reflex_flags(self) -> list[str]:
        """The error flags of the last reflex (libfranka's ``Errors`` names)."""
        return self.robot.reflex_flags()

    def inject_reflex(self, *flags: str) -> None:
        """Raise error flags (libfranka's ``Errors`` names) as a robot-side reflex, as
        ``Simulator.inject_reflex`` does (for fault tests)."""
        self.robot.inject_reflex(*flags)

    def home(self, q: np.ndarray, cube: np.ndarray | None) -> None:
        """Teleport: power-up state at ``q`` [rad] at rest, the hand open, the cube at
        ``cube`` [m] (its centre, upright; default where the scene puts it), the clock at
        0: every episode from the same start is the same."""
        self.stop()
        self.robot.reset(q)
        if cube is not None:
            self.place_cube(cube)
        self._fail = None

    def place_cube(self, position: Any) -> None:
        """Put the cube, upright and at rest, with its centre at ``position`` [m]
        (ValueError in a world without it)."""
        if not self.has_cube:
            raise ValueError("place_cube: this world has no cube (FastWorld(cube=True))")
        self.robot.place_body("cube", position)

    def recover(self) -> None:
        self.stop()
        self.robot.recover()
        self._fail = None

    def hand_open(self) -> None:
        self._hand_id += 1
        self.robot.hand_move(self._hand_id, FRANKA_HAND.max_width, GRIPPER_SPEED)

    def hand_close(self) -> None:
        self._hand_id += 1
        # close on whatever is between the fingers (any width counts as held)
        self.robot.hand_grasp(self._hand_id, 0.0, 0.005, FRANKA_HAND.max_width,
                              GRIPPER_SPEED, GRASP_FORCE)  # fmt: skip

    def close(self) -> None:
        self.stop()


class _CompiledLoop:
    """The streamed controllers' ticks in compiled runs (:mod:`._world_jit`) for one
    world: gathers the controller's, the finishing's and the robot's arrays and scalars
    for a run, and gives them back after it.

    A tick's news goes through the controllers' public hook (``compiled_news``); for the
    rest it reads the controllers' and their generators' inner state (their per-tick
    bookkeeping has no public view yet): the compiled steps replace exactly the calls
    ``CartesianTarget.step`` and ``JointTarget.step`` make after the news."""

    def __init__(self, world: FastWorld) -> None:
        from panda_py.learning import _world_jit

        self._k = _world_jit
        self.world = world
        robot = world.robot.compiled_tick()
        if robot is None:
            raise ImportError("the in-process robot runs without numba")
        self.robot = robot
        self._cull = robot.contact_cull
        core = world.robot.core
        fields = world.dialect.state_dtype.fields
        assert fields is not None
        self._reads = (
            core.state_buffer,
            np.array([core.state_offsets[n][0] for n in _READ_FIELDS], dtype=np.int64),
            np.array([fields[n][0].base.itemsize == 4 for n in _READ_FIELDS], dtype=np.int64),
        )  # fmt: skip
        self._buf = (np.zeros(7), np.zeros(7), np.zeros(16), np.zeros(7), np.zeros(7),
                     np.zeros(7))  # fmt: skip
        f = world._finalize
        self._walls = (*f.walls.kernel_state(), f.tau_max)
        s = self._s = np.zeros(_world_jit.SCALARS)
        s[_world_jit.S_DT] = DT
        s[_world_jit.S_GAIN] = FILTER_GAIN
        s[_world_jit.S_DTAU_MAX] = laws.DTAU_MAX_PER_TICK
        s[_world_jit.S_DAMPING_TICKS] = tracking.DAMPING_TICKS
        s[_world_jit.S_FRICTION_SPEED] = FRICTION_SPEED
        s[_world_jit.S_ERROR_RATE] = tracking.FRICTION_ERROR_RATE
        self._arm: tuple[Any, ...] = ()
        self._kind: type | None = None
        self._entries: dict[Any, Any] = {}
        self.compiled_ticks = 0  # ticks run compiled, in all (diagnostics)

    def _call(self, kernel: Any, *args: Any) -> tuple[int, int]:
        """``kernel(*args)``, by its compiled entry point once it has one signature (the
        dispatcher's type checks of these nested tuples cost more than many ticks)."""
        entry = self._entries.get(kernel)
        if entry is None:
            result = kernel(*args)
            if len(kernel.signatures) == 1:
                self._entries[kernel] = kernel.overloads[kernel.signatures[0]].entry_point
            return result
        return entry(*args)

    def start(self, controller: TorqueController, state: TickState) -> None:
        """A controller started: the model's arrays for its motion (its end effector and
        load do not change within it)."""
        kind = type(controller)
        self._kind = kind if kind in (CartesianTarget, JointTarget) else None
        if self._kind is not None:
            model = self.world.model
            chain, arm = model.kernel_arrays(state)
            self._chain, self._arm = chain, (*arm, model.armature, model.coulomb)

    def run(self, n: int) -> bool:
        """Up to ``n`` ticks compiled, the part of a tick the kernel left done; False
        where none ran (the next tick is the reference's)."""
        world = self.world
        running = world._controller
        if running is None or self._kind is None or type(running) is not self._kind:
            return False
        ctrl: Any = running
        args = self.robot.enter(world.robot.hand)
        if args is None:
            return False
        # a tick with news: its part before the law's compiled step in Python (ruckig)
        stepped = ctrl.compiled_news(DT, world.model)
        if not stepped and not self._ready(ctrl):
            return False
        k, s = self._k, self._s
        self._load(ctrl)
        s[k.S_STEPPED] = 1.0 if stepped else 0.0
        if self._kind is CartesianTarget:
            ticks, stop = self._call(k.pose_target_ticks, n, s, ctrl._tick,
                                     ctrl._gen.sampling(), ctrl._law.buffer,
                                     (self._chain, *self._arm), ctrl._target, ctrl._out,
                                     self._reads, self._walls, self._buf, args,
                                     self._cull)  # fmt: skip
        else:
            g = ctrl._gen
            gen = (g._packed, g.position, g.velocity, g.acceleration)
            ticks, stop = self._call(k.joint_target_ticks, n, s, gen,
                                     (ctrl.stiffness, ctrl.damping), self._arm,
                                     ctrl.signal("q"), ctrl._out, self._reads, self._walls,
                                     self._buf, args, self._cull)  # fmt: skip
        self._save(ctrl)
        self.compiled_ticks += ticks
        world.robot.ticks += ticks
        self.robot.leave(ticks, stop if stop in (k.Stop.FILL, k.Stop.CONTACTS) else 0,
                         world.robot.hand)  # fmt: skip
        if stop == k.Stop.ROBOT:  # the law ran; the robot's part of the tick in Python
            world._robot_tick(self._buf[5].copy())
        elif stop == k.Stop.NON_FINITE:
            tau = self._buf[4]
            world._failed(f"the controller commanded non-finite torques: {tau.tolist()}")
            world._robot_tick(None)
        elif ticks == 0:
            return False
        return True

    def _ready(self, ctrl: Any) -> bool:
        """No news for the law this tick that the kernel cannot take (a target that
        arrived before the law's first tick; a trajectory calculated, not packed)."""
        if float(ctrl._values[ctrl._count_at]) != ctrl._seen:
            return False
        if self._kind is CartesianTarget:
            g = ctrl._gen.gen
            return not (g._changed or g._fresh) and ctrl._law.J_prev is not None
        g = ctrl._gen
        return not (g._changed or g._fresh)

    def _generator(self, ctrl: Any) -> Any:
        return ctrl._gen.gen if self._kind is CartesianTarget else ctrl._gen

    def _load(self, ctrl: Any) -> None:
        k, s, g = self._k, self._s, self._generator(ctrl)
        s[k.S_T] = ctrl.t
        s[k.S_T_TARGET] = ctrl._t_target
        s[k.S_TIMEOUT] = math.inf if ctrl.timeout is None else ctrl.timeout
        s[k.S_STALE] = 1.0 if ctrl._stale else 0.0
        s[k.S_GEN_TIME] = g._time
        s[k.S_GEN_FINISHED] = 1.0 if g.finished else 0.0
        s[k.S_DURATION] = g.duration
        if self._kind is CartesianTarget:
            s[k.S_DAMPING_DUE] = ctrl._law._damping_due
        else:
            s[k.S_OUT] = ctrl._out_layout["q_d"][0]

    def _save(self, ctrl: Any) -> None:
        k, s, g = self._k, self._s, self._generator(ctrl)
        ctrl.t = float(s[k.S_T])
        ctrl.dt = DT
        if float(s[k.S_GEN_TIME]) != g._time:
            g._time = float(s[k.S_GEN_TIME])
            g._moved = True
        g.finished = bool(s[k.S_GEN_FINISHED])
        if self._kind is CartesianTarget:
            ctrl._law._damping_due = int(s[k.S_DAMPING_DUE])
