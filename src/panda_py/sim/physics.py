"""MuJoCo physics of the simulated arm and hand, and the robot's internal controllers.

The robot compensates gravity itself (``gravcomp`` in the model), so every torque handed
to :meth:`Physics.step` is gravity-free, exactly like ``tau_J_d`` on a real Franka.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from panda_py.fci import PERIOD
from panda_py.kinematics import get_kinematics, warmup
from panda_py.robots.end_effectors import EndEffector, end_effector_F_T_NE, get_end_effector
from panda_py.robots.mjcf import model_xml
from panda_py.robots.params import FRANKA_HAND, RobotSpec

DT = PERIOD  # [s] one control tick: one MuJoCo step

# Tracking bandwidth of the robot's internal joint controller at the default stiffness:
# a computed-torque law with natural frequency OMEGA [rad/s], critically damped.
OMEGA = 60.0  # [rad/s]
# Joint-space gains of the null-space posture task used by differential IK.
_IK_ITERATIONS = 3
_IK_DAMPING = 1e-6
_ELBOW_HELD = np.array([0, 1, 3, 4, 5, 6])  # the joints IK moves when joint 3 is commanded
# The robot's joint controllers compensate the drives' dry friction: on a joint moving
# faster than FRICTION_SPEED, all of it, along its velocity; on a joint at rest, in the
# direction the controller pushes, as much again as it pushes (up to the Coulomb level), so
# a joint breaks free at half the torque and its controller's gain at most doubles.
FRICTION_SPEED = 1e-3  # [rad/s]
# Constraint rows of contacts (frictionless, pyramidal, elliptic: the last of MuJoCo's kinds).
_CONTACT_ROWS = int(mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS)
# The smallest pivot of J J^T's factorisation when a wrench is fitted to torques [m^2]:
# where the arm is singular, the fit's wrench stays finite (the directions the arm cannot
# feel get next to nothing) instead of failing.
_WRENCH_MIN_PIVOT = 1e-12


class Physics:
    """One MuJoCo world: the arm, its end effector (the hand or the Cobot Pump) and the
    scene (the table, and with ``cube`` the cube on it), stepped at 1 kHz."""

    def __init__(
        self,
        spec: RobotSpec,
        *,
        scene: bool = True,
        extra: str | Path | None = None,
        end_effector: EndEffector | str = EndEffector.HAND,
        cube: bool = True,
    ) -> None:
        self.spec = spec
        self.end_effector = get_end_effector(end_effector)
        self.model = mujoco.MjModel.from_xml_string(
            model_xml(spec, hand=True, scene=scene, extra=extra, end_effector=self.end_effector,
                      cube=cube)
        )  # fmt: skip
        self.model.opt.timestep = DT
        self.data = mujoco.MjData(self.model)
        self.kin = mujoco.MjData(self.model)  # scratch data for kinematics of targets
        m = self.model
        jid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"joint{i}") for i in range(1, 8)]
        self.qadr = np.array([m.jnt_qposadr[j] for j in jid])
        self.vadr = np.array([m.jnt_dofadr[j] for j in jid])
        if not (np.all(np.diff(self.qadr) == 1) and np.all(np.diff(self.vadr) == 1)):
            raise RuntimeError("arm joints must be consecutive in the model")
        self.q0, self.v0 = int(self.qadr[0]), int(self.vadr[0])
        self.flange_site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "flange")
        self._hand_body = int(m.site_bodyid[self.flange_site])  # what the flange is fixed to
        # The hand's fingers (-1 with the pump: no fingers, no finger motor).
        self.finger_q = self.finger_q2 = self.finger_v = self.finger_act = -1
        if self.end_effector is EndEffector.HAND:
            j1 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "finger_joint1")
            j2 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "finger_joint2")
            self.finger_q, self.finger_q2 = int(m.jnt_qposadr[j1]), int(m.jnt_qposadr[j2])
            self.finger_v = int(m.jnt_dofadr[j1])
            self.finger_act = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "finger_motor")
        # Bodies of the robot (for telling robot contacts from others).
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "link0")
        self.robot_bodies = {b for b in range(m.nbody) if self._descends(b, root)}
        self._robot_geom = np.array(
            [int(m.geom_bodyid[g]) in self.robot_bodies for g in range(m.ngeom)]
        )
        self.link_body = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"link{i}") for i in range(8)
        ]
        links = self.link_body[1:7]
        # Consecutive bodies (as generated): a slice, i.e. a view, not a gathered copy.
        self._links_1_6: slice | np.ndarray = (
            slice(links[0], links[0] + 6) if links == list(range(links[0], links[0] + 6))
            else np.array(links)
        )  # fmt: skip
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))
        self._M = np.zeros((m.nv, m.nv))
        self._qfrc = np.zeros(m.nv)  # the contacts' torques on every dof
        self._JK, self._JJt, self._wrench = np.zeros((6, 7)), np.zeros((6, 6)), np.zeros(6)
        self.tau_applied = np.zeros(7)  # last gravity-free torque applied [Nm]
        self._coulomb = np.array(spec.drives.coulomb)  # [Nm] the plant's dry friction
        # Views onto MjData's arrays (MuJoCo never reallocates them).
        sl = slice(self.v0, self.v0 + 7)
        self._qpos_arm = self.data.qpos[self.q0 : self.q0 + 7]
        self._qvel_arm = self.data.qvel[sl]
        self._gravcomp_arm = self.data.qfrc_gravcomp[sl]
        self._applied_arm = self.data.qfrc_applied[sl]
        self._bias_arm = self.data.qfrc_bias[sl]
        self._constraint_arm = self.data.qfrc_constraint[sl]
        # The drives' part of the plant (motor side of the joints' torque sensors): the
        # reflected rotor inertia and the viscous friction, rows of ``drive_terms``.
        self._drive = np.array([m.dof_armature[sl], m.dof_damping[sl]])
        self._dq_before = np.zeros(7)  # the arm's joint velocities before the last step
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        self._xmat = self.data.xmat
        # Scratch of the robot's IK (flange kinematics of the same parameters).
        self._flange_kin = get_kinematics(spec, F_T_EE=np.eye(4))
        self._ik_err, self._ik_y, self._ik_JJt = np.zeros(6), np.zeros(6), np.zeros((6, 6))
        # Load (or compile, the first time after installing) every kinematics kernel now,
        # before the 1 kHz loop starts, not at the first Cartesian tick.
        warmup()
        # Contact pairs last seen without the robot in them (most ticks: cube on table).
        self._quiet_contacts = b""
        self.F_T_NE = end_effector_F_T_NE(self.end_effector)  # flange -> the tool's TCP

    def _descends(self, body: int, root: int) -> bool:
        while body > 0:
            if body == root:
                return True
            body = int(self.model.body_parentid[body])
        return False

    # -- state ---------------------------------------------------------------------------

    @property
    def q(self) -> np.ndarray:
        """Arm joint positions [rad] (a live view)."""
        return self._qpos_arm

    @property
    def dq(self) -> np.ndarray:
        """Arm joint velocities [rad/s] (a live view)."""
        return self._qvel_arm

    @property
    def robot_geoms(self) -> np.ndarray:
        """Which of the model's geoms belong to the robot (bool (ngeom,))."""
        return self._robot_geom

    @property
    def applied_arm(self) -> np.ndarray:
        """The arm's applied joint torques in MuJoCo's data [Nm] (a live view)."""
        return self._applied_arm

    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, q: np.ndarray, gripper_width: float | None = None) -> None:
        """Place the arm at ``q`` [rad] at rest (and the fingers at ``gripper_width`` [m])."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.q0 : self.q0 + 7] = q
        if self.finger_q >= 0:
            width = FRANKA_HAND.max_width if gripper_width is None else gripper_width
            self.data.qpos[self.finger_q] = width / 2
            self.data.qpos[self.finger_q2] = width / 2
        mujoco.mj_forward(self.model, self.data)
        self.tau_applied[:] = 0.0
        self._dq_before[:] = 0.0

    def place_body(self, name: str, position: np.ndarray) -> None:
        """Put the free body ``name`` (e.g. the cube), upright and at rest, with its origin
        at ``position`` [m]; ValueError if the scene has no such free body."""
        m, d = self.model, self.data
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        joint = int(m.body_jntadr[body]) if body >= 0 else -1
        if joint < 0 or m.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
            raise ValueError(f"name: expected a free body of the scene, got {name!r}")
        a, v = int(m.jnt_qposadr[joint]), int(m.jnt_dofadr[joint])
        d.qpos[a : a + 3] = position
        d.qpos[a + 3 : a + 7] = (1.0, 0.0, 0.0, 0.0)
        d.qvel[v : v + 6] = 0.0
        mujoco.mj_forward(m, d)

    def gripper_width(self) -> float:
        """The fingers' opening [m] (0 without the hand)."""
        if self.finger_q < 0:
            return 0.0
        qpos = self._qpos
        return float(qpos[self.finger_q] + qpos[self.finger_q2])

    def gripper_speed(self) -> float:
        return 2.0 * float(self._qvel[self.finger_v]) if self.finger_v >= 0 else 0.0

    def gravity_torque(self) -> np.ndarray:
        """Torque the robot spends holding the arm and hand against gravity [Nm]."""
        return self._gravcomp_arm

    @property
    def dq_before(self) -> np.ndarray:
        """The arm's joint velocities before the last step [rad/s] (a live buffer)."""
        return self._dq_before

    @property
    def constraint_arm(self) -> np.ndarray:
        """The constraint forces on the arm's joints over the last step [Nm] (a live view:
        the joints' dry friction and limits, and the contacts)."""
        return self._constraint_arm

    @property
    def drive_terms(self) -> np.ndarray:
        """The drives' reflected rotor inertia [kg m^2] and viscous friction [Nm s/rad] of
        the arm's joints, rows of a (2, 7) array (read only by convention)."""
        return self._drive

    def sensor_torque(self, out: np.ndarray) -> np.ndarray:
        """The link-side joint torques over the last step [Nm] without the contacts' part,
        into ``out``: what the drives deliver past the joints' torque sensors (the applied
        and the gravity-compensating torque, less the rotor inertia's and the viscous
        friction's share, with the dry friction's and the limits' constraint forces), as
        in MuJoCo's equation of motion for the implicit step: ``(M + B) a + D dq =
        tau + g - bias + f_constraint``, so ``M a + c + g = tau_J + tau_contacts``. The
        contacts' torques are the external ones; the caller takes them away
        (:meth:`contact_torques`). ``_tick_jit.fill_state`` computes the same."""
        B, D = self._drive
        dq = self._qvel_arm
        np.subtract(dq, self._dq_before, out=out)
        out *= -(1.0 / DT) * B
        out += self.tau_applied
        out += self._gravcomp_arm
        out -= D * dq
        out += self._constraint_arm
        return out

    def coriolis(self) -> np.ndarray:
        """C(q, dq) dq of the arm [Nm] (the bias force less gravity)."""
        return self._bias_arm - self._gravcomp_arm

    def mass_matrix(self) -> np.ndarray:
        mujoco.mj_fullM(self.model, self.data, self._M)
        sl = slice(self.v0, self.v0 + 7)
        return self._M[sl, sl]

    def flange_pose(self, data: mujoco.MjData | None = None) -> np.ndarray:
        d = self.data if data is None else data
        T = np.eye(4)
        T[:3, :3] = d.site_xmat[self.flange_site].reshape(3, 3)
        T[:3, 3] = d.site_xpos[self.flange_site]
        return T

    def link_z_rows(self) -> np.ndarray:
        """Third rows of the rotations of links 1..6 (6x3): base z in each link frame."""
        return self._xmat[self._links_1_6, 6:9]

    def contact_torques(self) -> np.ndarray | None:
        """Joint torques that contacts with the robot exert on the arm [Nm] (tau_ext: their
        forces and the pads' torsional friction), a buffer reused by the next call; None
        when nothing touches the robot (most ticks: no array to build or test)."""
        m, d = self.model, self.data
        if d.ncon == 0:
            return None
        # Most ticks only the cube rests on the table: the same pairs as last tick need
        # no look; otherwise select robot contacts vectorised.
        geom = d.contact.geom
        pairs = geom.tobytes()
        if pairs == self._quiet_contacts:
            return None
        on = self._robot_geom[geom]
        robot = on[:, 0] != on[:, 1]  # contact by contact: the robot and something else
        if not robot.any():
            self._quiet_contacts = pairs
            return None
        # The constraint force of those contacts' rows, J^T f: on the arm's dofs, the
        # torques they exert through the chain (the other body's dofs are not the arm's;
        # the robot's contacts with itself, its joint limits and the fingers' coupling
        # are left out). One product in MuJoCo instead of a contact force and a Jacobian
        # per contact: 8 us against 67 with a cube held in the hand.
        n = d.nefc
        contact = d.efc_type[:n] >= _CONTACT_ROWS  # (other rows' ids are not contacts')
        rows = contact & robot[np.where(contact, d.efc_id[:n], 0)]
        mujoco.mj_mulJacTVec(m, d, self._qfrc, np.where(rows, d.efc_force[:n], 0.0))
        return self._qfrc[self.v0 : self.v0 + 7]

    def wrench_explaining(self, tau: np.ndarray, point: np.ndarray) -> np.ndarray:
        """The wrench ``[f; m]`` at ``point`` (base frame) [N, Nm] whose joint torques
        ``J_point^T F`` come closest to ``tau`` [Nm]: least squares, through the normal
        equations (a singular arm gives a finite wrench rather than an error); a buffer
        reused by the next call."""
        sl = slice(self.v0, self.v0 + 7)
        mujoco.mj_jac(self.model, self.data, self._jacp, self._jacr, point, self._hand_body)
        J = self._JK
        J[:3], J[3:] = self._jacp[:, sl], self._jacr[:, sl]
        A = np.matmul(J, J.T, out=self._JJt)
        mujoco.mju_cholFactor(A, _WRENCH_MIN_PIVOT)
        mujoco.mju_cholSolve(self._wrench, A, J @ tau)
        return self._wrench

    # -- stepping ------------------------------------------------------------------------

    def step(self, tau: np.ndarray, finger_force: float) -> None:
        """Advance one tick with gravity-free arm torques ``tau`` [Nm] and the hand's motor
        force ``finger_force`` [N] (positive opens)."""
        self._applied_arm[:] = tau
        if self.finger_act >= 0:
            self._ctrl[self.finger_act] = finger_force
        self.tau_applied[:] = tau
        self._dq_before[:] = self._qvel_arm
        mujoco.mj_step(self.model, self.data)

    # -- internal controllers -----------------------------------------------------------

    def joint_tracking_torque(
        self,
        q_d: np.ndarray,
        dq_d: np.ndarray,
        ddq_d: np.ndarray,
        stiffness_scale: np.ndarray,
    ) -> np.ndarray:
        """The robot's joint impedance controller tracking (q_d, dq_d, ddq_d): computed
        torque with feed-forward, stiffness scaled per joint by K_theta / default."""
        kp = OMEGA * OMEGA * stiffness_scale
        kd = 2.0 * OMEGA * np.sqrt(stiffness_scale)
        acc = ddq_d + kp * (q_d - self.q) + kd * (dq_d - self.dq)
        tau = self.mass_matrix() @ acc + self.coriolis()
        return tau + self.friction_compensation(tau)

    def friction_compensation(self, push: np.ndarray) -> np.ndarray:
        """The torque [Nm] with which the robot's joint controllers cancel the joints' dry
        friction, for a controller pushing with ``push`` [Nm] (see ``FRICTION_SPEED``)."""
        c = self._coulomb
        moving = np.tanh(self.dq * (1.0 / FRICTION_SPEED))
        still = np.clip(push, -c, c)
        return c * moving + (1.0 - np.abs(moving)) * still

    def solve_ik(self, O_T_F: np.ndarray, q_seed: np.ndarray, elbow_q3: float | None) -> np.ndarray:
        """Joint positions placing the flange at ``O_T_F``: a few damped Newton steps from
        ``q_seed`` (the last desired configuration), with joint 3 held at ``elbow_q3`` when
        given (the commanded elbow) and the minimum-norm change otherwise. The arm's
        analytic kinematics (equal to this model's to 1e-15) and MuJoCo's Cholesky keep a
        step at a few microseconds."""
        kin, err, JJt, y = self._flange_kin, self._ik_err, self._ik_JJt, self._ik_y
        q = np.array(q_seed, dtype=float)
        cols = _ELBOW_HELD if elbow_q3 is not None else None
        if elbow_q3 is not None:
            q[2] = elbow_q3
        p, R = O_T_F[:3, 3], O_T_F[:3, :3]
        for _ in range(_IK_ITERATIONS):
            T = kin.fk(q)
            err[:3] = p - T[:3, 3]
            Re = R @ T[:3, :3].T
            err[3] = 0.5 * (Re[2, 1] - Re[1, 2])
            err[4] = 0.5 * (Re[0, 2] - Re[2, 0])
            err[5] = 0.5 * (Re[1, 0] - Re[0, 1])
            if float(np.abs(err).max()) < 1e-12:
                break
            J = kin.zero_jacobian(q)
            if cols is not None:
                J = J[:, cols]
            np.matmul(J, J.T, out=JJt)
            JJt.flat[::7] += _IK_DAMPING
            mujoco.mju_cholFactor(JJt, 0.0)
            mujoco.mju_cholSolve(y, JJt, err)
            if cols is None:
                q += J.T @ y
            else:
                q[cols] += J.T @ y
        return q

    def flange_pose_at(self, q: np.ndarray) -> np.ndarray:
        kin = self.kin
        kin.qpos[self.q0 : self.q0 + 7] = q
        mujoco.mj_kinematics(self.model, kin)
        return self.flange_pose(kin)
