"""The simulated robot's tick under an external torque controller, compiled whole: the
command's checks, the hand's holding force, MuJoCo's ``mj_step`` (called into the
``libmujoco`` the ``mujoco`` wheel ships, on the same model and data) and the state's
fill, in one numba kernel (:func:`torque_tick`) that a caller's own compiled loop calls
once a tick, with no Python in between.

It does the common tick only, exactly as :meth:`RobotCore.tick` does it (the same
kernels of :mod:`._tick_jit`, the same arithmetic): a running torque-controlled motion
whose command passes every check, the hand idle or holding a grasp, nothing touching
the robot. Everything else it hands back before it changes anything, with a status that
says which part of the tick the Python reference must do (:class:`Tick`); the reference
then does that part and the compiled ticks go on from there (:class:`InProcessRobot`
keeps the two in step).

Imported only where the kinematics run compiled (numba installed, ``PANDA_PY_NO_JIT``
unset); cached on disk under a key over this file and the kernels it calls
(:mod:`panda_py.jit.cache`).
"""

from __future__ import annotations

import ctypes
import enum
import math
from pathlib import Path
from typing import Any

import llvmlite.binding
import mujoco
import numpy as np
from numba import types

from panda_py import kinematics
from panda_py.jit import cache
from panda_py.sim import _tick_jit

_KIN = kinematics.compiled_kernels()
if _KIN is None:  # plain Python: the robot ticks in NumPy
    raise ImportError("the kinematics run without numba")

__all__ = [
    "MAX_CONTACTS", "Tick", "clear_of_contacts", "contact_cull", "contact_views", "libmujoco_path",
    "torque_tick",
]  # fmt: skip


def libmujoco_path() -> Path:
    """The MuJoCo library the ``mujoco`` wheel ships (the one its bindings run on)."""
    folder = Path(mujoco.__file__).parent
    found = sorted(folder.glob("libmujoco.so*")) + sorted(folder.glob("libmujoco*.dylib"))
    if not found:
        raise ImportError(f"no libmujoco shared library in {folder}")
    return found[0]


# The library's symbols, for the compiled code to call by name (resolved when a kernel is
# compiled or loaded from the cache, so the cached code holds no address). Loading it
# again returns the handle the bindings already hold: one MuJoCo, one state.
ctypes.CDLL(str(libmujoco_path()), mode=ctypes.RTLD_GLOBAL)
llvmlite.binding.load_library_permanently(str(libmujoco_path()))
# mj_step(const mjModel*, mjData*): pointers passed as 64-bit integers (MjModel._address)
_mj_step = types.ExternalFunction("mj_step", types.void(types.intp, types.intp))

# The most contacts the compiled tick looks through; with more it lets the reference look.
MAX_CONTACTS = 64
_SEARCH = 1 << 20  # [bytes] how far into mjData the counts are looked for (160 kB in 4.0)


def _words(address: int, n: int, ctype: Any) -> np.ndarray:
    """A live view of ``n`` C values of ``ctype`` at ``address``."""
    return np.ctypeslib.as_array((ctype * n).from_address(address))


# A world with contacts whatever the robot's scene (mjData's layout, where the contacts'
# count and array are found, is the same for every model): a box resting on a plane (4
# contacts), and a double pendulum whose joints have dry friction and are coupled, so the
# counts side by side (ncon 4, ne 1, nf 2, nl 0, nefc 27) are found nowhere else
_PROBE = """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
<body pos="0 0 0.05"><freejoint/><geom type="box" size="0.1 0.1 0.1" condim="4"/></body>
<body pos="2 0 1"><joint name="a" frictionloss="1"/>
<geom type="sphere" size="0.1" contype="0" conaffinity="0"/>
<body pos="0 0 -0.3"><joint name="b" frictionloss="1"/>
<geom type="sphere" size="0.1" contype="0" conaffinity="0"/></body></body>
</worldbody><equality><joint joint1="a" joint2="b"/></equality></mujoco>"""


def contact_views(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, ...]:
    """Live views of what MuJoCo's Python API gives only as copies, for a compiled tick
    to see the contacts ``mj_step`` found: ``data``'s contact count (int32 (1,)), its
    ``contact`` pointer (int64 (1,)), and the geom pairs of the first
    :data:`MAX_CONTACTS` contacts (int32 (MAX_CONTACTS, 2)) at the address the pointer
    holds (the arena's start: MuJoCo allocates the contacts first), with that address
    (int64 (1,)). Found in mjData by what the API reports (the counts ncon, ne, nf, nl,
    nefc side by side; the pointers ``arena`` and ``qpos``, as mjdata.h lays them out),
    on the data of a world with contacts (:data:`_PROBE`: ``model``'s scene may have
    none); ImportError where they are not where they should be (another MuJoCo): the
    reference then looks."""
    probe = mujoco.MjModel.from_xml_string(_PROBE)
    scratch = mujoco.MjData(probe)
    mujoco.mj_forward(probe, scratch)
    if scratch.ncon == 0:
        raise ImportError("no contact to find MuJoCo's contact array by")
    counts = np.array([scratch.ncon, scratch.ne, scratch.nf, scratch.nl, scratch.nefc],
                      dtype=np.int32)  # fmt: skip
    at = -1
    step = 4096  # (never read past the structure: it goes on far beyond the counts)
    for start in range(0, _SEARCH, step):
        words = _words(scratch._address + start, step // 4 + 4, ctypes.c_int32)
        hits = [i for i in np.flatnonzero(words[:-4] == counts[0])
                if np.array_equal(words[i : i + 5], counts)]  # fmt: skip
        if hits:
            at = start + 4 * int(hits[0])
            break
    if at < 0:
        raise ImportError("MuJoCo's contact count not found in mjData")
    geom = scratch.contact.geom
    address = int(geom.__array_interface__["data"][0])  # contact 0's geom pair
    stride = int(geom.strides[0])  # sizeof(mjContact)
    # after the counts: ..., buffer, arena, qpos (pointers, 8-byte aligned); contact 0
    # lies at the arena's start
    start = (at + 7) // 8 * 8
    words64 = _words(scratch._address + start, 512, ctypes.c_int64)
    qpos = int(scratch.qpos.__array_interface__["data"][0])
    found = [
        i for i in np.flatnonzero(words64 == qpos)
        if i > 0 and 0 <= address - int(words64[i - 1]) < stride
    ]  # fmt: skip
    if not found:
        raise ImportError("MuJoCo's contacts are not at its arena's start")
    arena_at = int(found[0]) - 1
    arena = int(words64[arena_at])
    # the contact pointer: the first field after qpos that holds the arena's start
    later = np.flatnonzero(words64[arena_at + 2 :] == arena)
    if len(later) == 0:
        raise ImportError("MuJoCo's contact pointer not found in mjData")
    pointer_at = start + 8 * (arena_at + 2 + int(later[0]))
    # the same places in ``data``
    count = _words(data._address + at, 1, ctypes.c_int32)
    pointer = _words(data._address + pointer_at, 1, ctypes.c_int64)
    base = int(_words(data._address + start + 8 * arena_at, 1, ctypes.c_int64)[0])
    raw = _words(base, (stride * MAX_CONTACTS) // 4, ctypes.c_int32)
    pairs = np.lib.stride_tricks.as_strided(raw[(address - arena) // 4 :],
                                            shape=(MAX_CONTACTS, 2), strides=(stride, 4),
                                            writeable=False)  # fmt: skip
    return count, pointer, pairs, np.array([base], dtype=np.int64)


KEY = cache.source_key([
    Path(__file__), Path(_tick_jit.__file__), *Path(_KIN.__file__).parent.glob("*.py"),
])  # fmt: skip
_fk_one = _KIN.fk_one
_fill_state = _tick_jit.fill_state
_joint_limit_bits = _tick_jit.joint_limit_bits
_torque_in_limits = _tick_jit.torque_in_limits
_measured_in_limits = _tick_jit.measured_in_limits


# -- contacts that cannot happen this tick --------------------------------------------
# How far a geom of the model can move in one tick at most [m], with room to spare: the
# arm's fastest point moves under 25 mm in 1 ms at its joints' speed limits (a robot
# faster than them stops in a reflex: the measured-state check), its fingers far less.
CULL_MARGIN = 0.05
_DSBL_CONTACT = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


def _option_flags(model: mujoco.MjModel) -> np.ndarray:
    """A live view (int32 (1,)) of ``model.opt.disableflags``: found after the option's
    gravity (a view the API gives) as the one word that follows two values set through
    the API; ImportError where it is not there (another MuJoCo)."""
    start = int(model.opt.gravity.__array_interface__["data"][0])
    words = _words(start, 128, ctypes.c_int32)
    saved = model.opt.disableflags
    try:
        model.opt.disableflags = 0x15A5A
        first = set(np.flatnonzero(words == 0x15A5A).tolist())
        model.opt.disableflags = 0x0A5A5
        second = set(np.flatnonzero(words == 0x0A5A5).tolist())
    finally:
        model.opt.disableflags = saved
    both = sorted(first & second)
    if len(both) != 1:
        raise ImportError("MuJoCo's option flags not found in mjModel")
    return _words(start + 4 * both[0], 1, ctypes.c_int32)


def contact_cull(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, ...]:
    """What :func:`clear_of_contacts` reads to tell a tick in which no contact can arise,
    so that ``mj_step`` may skip its collision detection (``mjDSBL_CONTACT``; it would
    find none: the same step, for less): ``model.opt.disableflags`` (a live view), the
    data's geom positions and rotations, the geoms' bounding boxes (``geom_aabb``) and
    margins, the geoms that move (collidable, not fixed to the world) and (2,) the floor,
    the highest point [m] of the fixed geoms the moving ones may touch, with the count
    of ticks found clear (diagnostics). A moving
    geom may touch one only below the floor plus :data:`CULL_MARGIN`. Where the moving
    geoms may touch each other (a free object beside the robot), where explicit pairs
    or mocap bodies are, the floor is infinite: never clear."""
    m = model
    try:
        flags, found = _option_flags(m), True
    except ImportError:  # (never clear: the floor infinite)
        flags, found = np.zeros(1, dtype=np.int32), False
    body = m.geom_bodyid
    fixed = m.body_weldid[body] == 0
    collides = (m.geom_contype | m.geom_conaffinity) != 0
    moving = np.flatnonzero(collides & ~fixed).astype(np.int64)
    static = np.flatnonzero(collides & fixed)
    weld = m.body_weldid[body].tolist()  # each geom's rigid body
    movers = moving.tolist()

    def touch(a: int, b: int) -> bool:  # (geom indices)
        return bool(m.geom_contype[a] & m.geom_conaffinity[b]
                    or m.geom_contype[b] & m.geom_conaffinity[a])  # fmt: skip

    floor = -math.inf
    apart = all(not touch(a, b) for a in movers for b in movers if weld[a] != weld[b])
    if m.npair or m.nmocap or not apart or not found:
        floor = math.inf
    else:
        placed = mujoco.MjData(m)  # the fixed geoms' places (they never change)
        mujoco.mj_kinematics(m, placed)
        for g in static:
            if any(touch(int(g), a) for a in movers):
                R = placed.geom_xmat[g].reshape(3, 3)
                centre, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
                top = placed.geom_xpos[g, 2] + R[2] @ centre + np.abs(R[2]) @ half
                floor = max(floor, float(top + m.geom_margin[g]))
    return (flags, data.geom_xpos, data.geom_xmat, m.geom_aabb, m.geom_margin,
            moving, np.array([floor, 0.0]))  # fmt: skip


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def clear_of_contacts(cull):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether no contact can arise in the next ``mj_step`` (every moving geom's lowest
    point, where the last step left it, :data:`CULL_MARGIN` above the floor: see
    :func:`contact_cull`); where so, its collision detection is switched off until
    :func:`restore_contacts`."""
    flags, xpos, xmat, aabb, margin, moving, floor = cull
    if flags[0] & _DSBL_CONTACT:  # (off already: nothing to switch)
        return False
    level = floor[0] + CULL_MARGIN
    for k in range(moving.shape[0]):
        g = moving[k]
        low = xpos[g, 2] - margin[g]
        for j in range(3):
            r = xmat[g, 6 + j]
            low += r * aabb[g, j] - abs(r) * aabb[g, 3 + j]
        if not low > level:
            return False
    flags[0] |= _DSBL_CONTACT
    floor[1] += 1.0
    return True


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def restore_contacts(cull):  # type: ignore[no-untyped-def,unused-ignore]
    """Collision detection on again after :func:`clear_of_contacts` switched it off."""
    cull[0][0] &= ~_DSBL_CONTACT


# the state fields the fill writes (in the order of its offsets) and its flags
FILL_FIELDS = _tick_jit.FIELDS
MOVING_JOINT = _tick_jit.MOVING_JOINT


class Tick(enum.IntEnum):
    """What :func:`torque_tick` did, and what is left for the reference to do."""

    DONE = 0  # the whole tick
    WHOLE = 1  # nothing: the reference runs the whole tick (the law's part too)
    ROBOT = 2  # nothing of the robot's part: the reference runs it with this command
    FILL = 3  # all but the state's fill (the kernel's fk failed: joints not finite)
    CONTACTS = 4  # all but the contacts' part of the fill (something may touch the robot)


# the statuses as the kernel returns them (plain integers)
_DONE, _ROBOT, _FILL, _CONTACTS = (
    int(Tick.DONE),
    int(Tick.ROBOT),
    int(Tick.FILL),
    int(Tick.CONTACTS),
)

# indices of ``ints`` (int64) and ``hand`` (float64), see torque_tick
I_MODEL, I_DATA, I_FLAGS, I_FINGER_ACT, I_JOINT_GENERATOR, I_RECEIVED = 0, 1, 2, 3, 4, 5
I_SUCCESS_COUNT, I_SUCCESS_I, I_FINGER_Q, I_FINGER_Q2, I_FINGER_V = 6, 7, 8, 9, 10
INTS = 11
H_HOLD, H_FORCE, H_GRASP_FORCE, H_MAX_WIDTH = 0, 1, 2, 3
HAND = 4
# the hand's servo (gripper._KP, _KD, _MAX_FORCE, _FORCE_RATE * DT) and DT, in ``gains``
G_KP, G_KD, G_MAX_FORCE, G_FORCE_STEP, G_DT = 0, 1, 2, 3, 4  # (G_DT: DT [s])


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def torque_tick(  # type: ignore[no-untyped-def,unused-ignore]
    tau, ints, hand, gains, qpos, qvel, q0, v0, ctrl, applied, tau_applied, gravcomp,
    contacts, xmat, sb, off, tau_J_d, tau_max, dtau_step, sensor, q_hold, jq, jdq, jddq,
    jdddq, upper, lower, cart_T, cart_v, cart_a, elbow_c, delbow_c, ddelbow_c, success, fk,
    chain, links, const, scratch, measured,
):  # fmt: skip
    """The robot's tick with the torque command ``tau`` (7,) [Nm], as
    :meth:`RobotCore.tick` in a running external-controller motion, or a :class:`Tick`
    status saying what it left for the reference. ``ints``: the model's and the data's
    addresses, the fill's flags, the finger actuator (-1 none), whether a joint velocity
    generator runs (protocol < 7: zero velocities, checked), the received and success
    counters, the fingers' qpos and dof (updated in place); ``hand``: the hand's hold
    width, force, the held grasp's force (NaN: none), its max width (force updated);
    ``contacts``: :func:`contact_views`' and which geoms are the robot's (uint8);
    ``sensor``: the physics' joint velocities before the step (written), its drive terms
    and the arm's constraint forces, for tau_J (``Physics.sensor_torque``); the rest: the
    physics' arrays (MuJoCo's own), the state buffer, the core's arrays and the commanded
    joint signal (``jq`` .. ``jdddq``, updated), ``fk`` (2, 4, 4) and ``scratch`` (4, 7)
    buffers; ``measured``: the measured state's limits (q_min, q_max, |dq| max with the
    robot's tolerance)."""
    # -- the checks, before anything changes: the measured state's (RobotCore._motion_tick
    # after the command's: where they fail the reference reflexes), the command's
    # (RobotCore._accept)
    q_lo, q_hi, dq_hi = measured
    if not _measured_in_limits(qpos[q0 : q0 + 7], qvel[v0 : v0 + 7], q_lo, q_hi, dq_hi):
        return _ROBOT
    if not _torque_in_limits(tau, tau_J_d, tau_max, dtau_step):
        return _ROBOT
    velocity = ints[I_JOINT_GENERATOR] != 0
    if velocity:  # JointSignal.push_velocity(0) on a copy, then its limits
        dt = gains[G_DT]
        for i in range(7):
            dq_new = 0.0
            q_new = jq[i] + dq_new * dt
            ddq_new = (dq_new - jdq[i]) / dt
            scratch[3, i] = (ddq_new - jddq[i]) / dt
            scratch[2, i] = ddq_new
            scratch[1, i] = dq_new
            scratch[0, i] = q_new
        if _joint_limit_bits(scratch[0], scratch[1], scratch[2], scratch[3], upper, lower):
            return _ROBOT
    # -- the command accepted -----------------------------------------------------------
    ints[I_RECEIVED] += 1
    i = ints[I_SUCCESS_I]
    ints[I_SUCCESS_COUNT] += 1 - success[i]
    success[i] = 1
    ints[I_SUCCESS_I] = (i + 1) % success.shape[0]
    if velocity:
        jq[:] = scratch[0]
        jdq[:] = scratch[1]
        jddq[:] = scratch[2]
        jdddq[:] = scratch[3]
    for i in range(7):
        tau_J_d[i] = tau[i]
    # -- the hand (GripperCore.tick, no command running) --------------------------------
    fq, fq2 = ints[I_FINGER_Q], ints[I_FINGER_Q2]
    if fq >= 0:
        w = min(max(qpos[fq] + qpos[fq2], 0.0), hand[H_MAX_WIDTH])
        v = 2.0 * qvel[ints[I_FINGER_V]]
    else:
        w = 0.0
        v = 0.0
    grasp = hand[H_GRASP_FORCE]
    if grasp == grasp:  # a grasp held: squeeze, the force ramping up to the grasp's
        hand[H_FORCE] = max(-grasp, min(0.0, hand[H_FORCE]) - gains[G_FORCE_STEP])
    else:
        f = gains[G_KP] * (hand[H_HOLD] - w) + gains[G_KD] * (0.0 - v)
        limit = gains[G_MAX_FORCE]
        hand[H_FORCE] = max(-limit, min(limit, f))
    # -- the physics (Physics.step) -----------------------------------------------------
    dq_before, drive, constraint = sensor
    for i in range(7):
        applied[i] = tau_J_d[i]
        tau_applied[i] = tau_J_d[i]
        dq_before[i] = qvel[v0 + i]
    if ints[I_FINGER_ACT] >= 0:
        ctrl[ints[I_FINGER_ACT]] = hand[H_FORCE]
    _mj_step(ints[I_MODEL], ints[I_DATA])
    # -- the state (StateAssembly._fill_state) ------------------------------------------
    q = qpos[q0 : q0 + 7]
    if not _fk_one(q, chain, fk[0]):
        return _FILL
    flags = ints[I_FLAGS]
    if (flags & _tick_jit.MOVING_CARTESIAN) == 0 and not _fk_one(jq, chain, fk[1]):
        return _FILL
    _fill_state(sb, off, q, qvel[v0 : v0 + 7], tau_applied, gravcomp, dq_before, drive,
                constraint, tau_J_d, jq, jdq, jddq, q_hold, cart_T, cart_v, cart_a, elbow_c,
                delbow_c, ddelbow_c, fk, xmat, links, const,
                flags & ~_tick_jit.MODE_CHANGED)  # fmt: skip
    # Physics.contact_torques finds nothing where no contact is between the robot and
    # something else: then the reference's contact part does nothing (none was active)
    count, pointer, pairs, base, robot_geom = contacts
    if pointer[0] != base[0] or count[0] > pairs.shape[0]:
        return _CONTACTS
    for i in range(count[0]):
        if robot_geom[pairs[i, 0]] != robot_geom[pairs[i, 1]]:
            return _CONTACTS
    return _DONE
