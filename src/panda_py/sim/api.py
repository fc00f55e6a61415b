"""Python API of the simulated robot: run one in a child process and talk to it.

    with panda_py.sim.Simulator(host="127.0.0.2", robot="fr3", lockstep=True) as sim:
        robot = SomeFrankaClient(sim.host)
        ...
        print(sim.state()["q"])

The simulator owns its own process so that the 1 kHz loop never competes with the
caller's Python code for the GIL. Requests (state, fault injection) travel over a pipe and
are served between two ticks.
"""

from __future__ import annotations

import logging
import os
import random
import socket
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from panda_py import checks, warmstart
from panda_py.robots.end_effectors import EndEffector, get_end_effector
from panda_py.robots.params import START_POSE
from panda_py.sim.camera import Camera, check_camera_size
from panda_py.sim.children import start_child, stop_child
from panda_py.sim.config import SimConfig
from panda_py.sim.desk import DeskConfig, DeskLink, DeskProcess
from panda_py.sim.drawing import DrawingError, DrawingProcess
from panda_py.sim.drawings import start_drawing, stop_drawing
from panda_py.sim.video import DEFAULT_FPS, check_record

log = logging.getLogger("panda_py.sim")


class SimulatorError(RuntimeError):
    """The simulator process failed to start, died, or refused a request."""


def _child_main(config: SimConfig, conn: Any, log_level: str) -> None:
    logging.basicConfig(level=log_level, format="panda-sim %(levelname)s: %(message)s")
    from panda_py.sim.server import SimServer, pin, raise_priority

    try:
        pin(config.cpus)
        if not config.lockstep:
            raise_priority()
        server = SimServer(config)
    except Exception as exc:  # reported to the parent as the start failure
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    server.attach_control(conn)
    conn.send(("ready", None))
    server.serve_forever()


def free_loopback_host(rng: random.Random | None = None) -> str:
    """A loopback address (127.x.y.z) whose robot, gripper and vacuum gripper ports are
    free, so that several simulators (and test runs) can work side by side."""
    rng = rng or random.Random()
    for _ in range(200):
        host = f"127.{rng.randint(1, 254)}.{rng.randint(1, 254)}.{rng.randint(2, 254)}"
        try:
            for port in (1337, 1338, 1339):
                with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                    s.bind((host, port))
        except OSError:
            continue
        return host
    raise SimulatorError("no free loopback address found for a simulator")


class Simulator:
    """A simulated Franka (FCI on ``host``:1337, gripper on ``host``:1338).

    ``end_effector`` is what its flange carries: ``"hand"`` (the Franka Hand, on 1338) or
    ``"cobot_pump"`` (Franka's Cobot Pump, its vacuum gripper protocol on 1339; 1338 is
    then closed, as on a robot without a hand). The robot's state reports the mounted
    one's TCP and load.

    ``lockstep`` makes simulated time advance one tick per command during motions (tests);
    otherwise it runs at 1 kHz on the wall clock like a real robot; in lockstep it polls
    for each answer ``lockstep_spin`` seconds before sleeping on it (0: sleep at once, less
    CPU; a torque motion's compiled ticks run about as fast either way, the Python ticks
    of other motions about 1.4x slower); ``lockstep_max_speed`` caps how fast its time runs
    against the wall clock (1.0: never ahead of it, so a user's loop on the wall clock sees
    the robot's timing and no CPU goes on running ahead, while every command is still
    waited for; None: as fast as the client answers). ``cpus`` pins its process to these
    CPUs (Linux), e.g. to the core ``Panda(host, cpus=...)`` pins the control loop to:
    where a core stalls now and then (a VM's host takes it), robot and loop then stall
    together, and no command is lost to it. By default it accepts the protocol versions the
    simulated robot's systems speak (a FER 3-5, an FR3 10, an ``"fr3-pre-5.9"`` 6-9),
    chosen from the client's Connect request; ``versions`` pins a subset of them (a real
    robot speaks exactly one). ``desk`` adds the simulated Desk (HTTPS/WSS on ``host``,
    see :class:`DeskConfig`), coupled to the FCI; without it the robot is always unlocked
    with the FCI active. ``connect_timeout`` [s]: a TCP connection that sends no Connect
    within it is closed (it would hold the robot from every other client).

    ``viewer=True`` opens MuJoCo's interactive viewer on the robot (needs a display:
    ``$DISPLAY``, e.g. under ``xvfb-run``); ``record="run.mp4"`` writes a video of the run,
    drawn offscreen at ``record_fps`` frames per simulated second and finished when the
    simulator stops (needs the ``video`` extra). Both draw in processes of their own and
    never make a tick late; :attr:`recording` then tells what was written.
    ``camera_size=(width, height)`` [px] lets :meth:`render` return images of the robot
    as it is (for policies that see, and recorded episodes), drawn the same way.
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        robot: str = "fer",
        *,
        lockstep: bool = False,
        lockstep_timeout: float = 2.0,
        lockstep_spin: float = 300e-6,
        lockstep_max_speed: float | None = None,
        cpus: Iterable[int] | None = None,
        versions: Sequence[int] | None = None,
        scene: bool = True,
        extra: str | Path | None = None,
        q_start: Sequence[float] = START_POSE,
        log_level: str = "WARNING",
        start_timeout: float = 60.0,
        desk: DeskConfig | None = None,
        connect_timeout: float = 5.0,
        end_effector: EndEffector | str = EndEffector.HAND,
        viewer: bool = False,
        record: str | Path | None = None,
        record_fps: float = DEFAULT_FPS,
        camera_size: tuple[int, int] | None = None,
    ) -> None:
        self.config = SimConfig(
            host=host,
            robot=robot,
            lockstep=lockstep,
            lockstep_timeout=lockstep_timeout,
            lockstep_spin=lockstep_spin,
            lockstep_max_speed=lockstep_max_speed,
            cpus=checks.cpus("cpus", cpus),
            versions=tuple(versions) if versions is not None else None,
            scene=scene,
            extra=str(extra) if extra is not None else None,
            q_start=tuple(float(x) for x in q_start),
            connect_timeout=connect_timeout,
            end_effector=end_effector,
        )
        self.log_level = log_level
        self.start_timeout = start_timeout
        self._process: Any = None
        self._conn: Any = None
        self._lock = threading.Lock()
        self.desk_config = desk
        self.desk: DeskProcess | None = None  # the running Desk's handle
        self.viewer = bool(viewer)
        self.record = check_record(record, record_fps) if record is not None else None
        self.record_fps = float(record_fps)
        self.camera_size = None if camera_size is None else check_camera_size(camera_size)
        self._drawing: list[DrawingProcess] = []  # the viewer's and recorder's processes
        # What the recorder wrote, after stop(): path, frames, dropped, error, ms_per_frame.
        self.recording: dict[str, Any] | None = None

    @property
    def host(self) -> str:
        """The address clients connect to."""
        return self.config.host

    address = host

    # -- lifecycle ---------------------------------------------------------------------

    def start(self) -> Simulator:
        """Start the simulated robot in a process of its own (and its Desk, viewer or recorder
        if asked for) and return it once it serves; raises :class:`SimulatorError` if it does
        not within ``start_timeout`` [s]."""
        if self._process is not None:
            raise SimulatorError("simulator already started")
        link = None
        if self.desk_config is not None:
            link = DeskLink.create(locked=self.desk_config.locked)
            self.config.desk_link = link.array
        self._start_drawing()
        ctx = warmstart.context()
        parent, child = ctx.Pipe()
        proc = ctx.Process(
            target=warmstart.run_with_environ,
            args=(dict(os.environ), _child_main, self.config, child, self.log_level),
            daemon=True,
        )
        start_child(proc)
        child.close()
        if not parent.poll(self.start_timeout):
            proc.kill()
            self._stop_drawing()
            raise SimulatorError(f"simulator did not start within {self.start_timeout} s")
        try:
            kind, detail = parent.recv()
        except EOFError as exc:
            proc.join(1)
            self._stop_drawing()
            raise SimulatorError(f"simulator process died on start (exit {proc.exitcode})") from exc
        if kind != "ready":
            proc.join(1)
            self._stop_drawing()
            raise SimulatorError(f"simulator failed to start on {self.host}: {detail}")
        self._process, self._conn = proc, parent
        if link is not None and self.desk_config is not None:
            desk = DeskProcess(
                self.host, self.config.robot, self.desk_config, link, self.log_level,
                end_effector=get_end_effector(self.config.end_effector).value,
            )  # fmt: skip
            try:
                self.desk = desk.start(self.start_timeout)
            except RuntimeError as exc:
                self.stop()
                raise SimulatorError(str(exc)) from exc
        return self

    def stop(self) -> None:
        """Stop the simulator and its Desk, viewer and recorder (a recording is then in
        ``recording``); nothing happens if it is not running."""
        desk, self.desk = self.desk, None
        if desk is not None:
            desk.stop()
        proc, conn = self._process, self._conn
        if proc is None:
            return
        self._process = self._conn = None
        stop_child(proc, conn, kill=True)
        self._stop_drawing()

    def kill(self) -> None:
        """End the simulator abruptly, as a robot that loses power (for failure tests)."""
        desk, self.desk = self.desk, None
        if desk is not None:
            desk.stop()
        proc = self._process
        if proc is not None:
            proc.kill()
            proc.join(5)
            self._process = None
            self._conn.close()
            self._conn = None
            self._stop_drawing()

    def _start_drawing(self) -> None:
        try:
            self._drawing = start_drawing(
                self.config, viewer=self.viewer, record=self.record, fps=self.record_fps,
                timeout=self.start_timeout, camera_size=self.camera_size,
            )  # fmt: skip
        except DrawingError as exc:
            raise SimulatorError(str(exc)) from exc

    def _stop_drawing(self) -> None:
        if self._drawing:
            self.recording = stop_drawing(self._drawing)
        self.config.frame_feeds = ()

    def __enter__(self) -> Simulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        """Whether the simulator's process is running."""
        return self._process is not None and self._process.is_alive()

    # -- requests ------------------------------------------------------------------------

    def _request(self, *request: Any) -> Any:
        with self._lock:
            if self._conn is None:
                raise SimulatorError("simulator is not running")
            try:
                self._conn.send(request)
                kind, value = self._conn.recv()
            except (OSError, EOFError) as exc:
                raise SimulatorError("simulator process is gone") from exc
        if kind == "error":
            raise ValueError(value)
        return value

    def state(self) -> dict[str, Any]:
        """The robot's current state: libfranka's field names (transforms as column-major
        16-vectors), modes, error flags, ``cube_position`` and ``end_effector``; with the
        hand ``gripper_width``, ``gripper_is_grasped``; with the Cobot Pump ``vacuum``
        [mbar], ``vacuum_sealed`` and ``vacuum_held`` (the name of the body it holds)."""
        return dict(self._request("state"))

    def q(self) -> np.ndarray:
        """The arm's joint positions [rad], (7,)."""
        return np.asarray(self.state()["q"])

    def inject_reflex(self, *flags: str) -> None:
        """Raise error flags (names of libfranka's ``Errors``) as a robot-side reflex."""
        self._request("inject_reflex", flags or ("joint_reflex",))

    def drop_commands(self, n: int) -> None:
        """Discard the next ``n`` command datagrams as if the network lost them."""
        self._request("drop_commands", n)

    def press_user_stop(self) -> None:
        """Press the user stop: the robot stops and enters the user-stopped mode, as a robot
        does."""
        self._request("user_stop", True)

    def release_user_stop(self) -> None:
        """Release the user stop: the robot returns to idle."""
        self._request("user_stop", False)

    def set_guiding(self, on: bool) -> None:
        """Press (True) or release the pilot's guiding button."""
        self._request("guiding", on)

    def set_joint_positions(self, q: Sequence[float]) -> None:
        """Teleport the (idle) arm to ``q`` [rad], at rest."""
        self._request("set_joint_positions", list(q))

    def place_cube(self, position: Sequence[float]) -> None:
        """Put the scene's cube, upright and at rest, with its centre at ``position`` [m]
        (base frame; the table top is z = 0, so 0.02 rests it on the table): a learning
        task's reset, or a test's setup. Anything in the way is pushed aside by physics."""
        self._request("place_cube", [float(x) for x in position])

    def cube_position(self) -> np.ndarray:
        """The centre of the scene's cube [m], (3,)."""
        position = self.state()["cube_position"]
        if position is None:
            raise SimulatorError("this simulator has no cube (Simulator(..., scene=True))")
        return np.asarray(position)

    def press_pilot_button(self, button: str = "circle") -> None:
        """Press and release a Pilot button on the simulated Desk (``circle`` confirms a
        forced take on the FER, ``top`` on the FR3)."""
        if self.desk is None:
            raise SimulatorError("this simulator has no Desk (Simulator(..., desk=DeskConfig()))")
        self.desk.press_pilot_button(button)

    def render(self) -> np.ndarray:
        """An image of the robot and its scene as they are now, (height, width, 3) uint8
        RGB, seen from the front left (``camera_size``'s width and height [px]); drawn
        offscreen in the camera's own process, so it never makes a tick late (tens of ms
        a frame with software OpenGL)."""
        if self.camera_size is None:
            raise SimulatorError(
                "this simulator has no camera (Simulator(..., camera_size=(320, 240)))"
            )
        camera = next((d for d in self._drawing if isinstance(d, Camera)), None)
        if camera is None or not self.running:
            raise SimulatorError("simulator is not running")
        try:
            return camera.render()
        except RuntimeError as exc:
            raise SimulatorError(str(exc)) from exc

    def stats(self) -> dict[str, Any]:
        """Tick counts, late ticks, lost commands, wall, simulated and CPU time."""
        return dict(self._request("stats"))

    def reset_stats(self) -> None:
        """Set the counts of :meth:`stats` back to zero."""
        self._request("reset_stats")
