"""The robot arm: MuJoCo model and data, the velocity controller C and F_ext at the handle.

:class:`Arm` loads an MJCF (our UR5 by default), finds the handle site, the arm joints and their
velocity actuators by name, and runs one 500 Hz control tick per :meth:`Arm.step`:

1. **Cartesian command.** ``v_ref`` is clipped to ``max_hand_speed``. A reference point
   ``x_ref`` integrates the commanded velocity and a proportional term ``position_gain *
   (x_ref - x)`` (clamped to ``max_tracking_error``, which also bounds wind-up) removes the drift
   a pure velocity servo would accumulate under a steady ``F_ext``; the sum is clipped to
   ``max_hand_speed`` again, so the arm never commands a faster hand. The orientation held since
   :meth:`Arm.reset` gives an angular velocity command ``orientation_gain * e_R`` with
   ``e_R = 1/2 sum_i r_i x r0_i`` (``r_i``, ``r0_i``: columns of the current and held rotation;
   equal to the rotation vector for small errors). ``e_R`` is linear in the current rotation
   matrix, so it is one precomputed (3, 9) matrix-vector product per tick.
2. **Damped least squares.** ``qdot = J^T (J J^T + lambda^2 I)^-1 xdot`` on the (6, n) site
   Jacobian (one ``mj_jacSite`` per tick); the 6x6 system is solved in place with MuJoCo's
   Cholesky routines (no allocation, ~1 us).
3. **Joint limits.** A joint within ``joint_limit_margin`` of a limit and moving towards it is
   slowed linearly to zero at the limit: the system is solved again with that joint's Jacobian
   column weighted by ``distance / margin``, so the other joints take over its share of the motion.
4. **Joint speed limit.** If any ``|qdot_i| > max_joint_speed_i``, all joints are scaled by the
   same factor (the hand keeps its direction, only slower).
5. **Actuation.** ``qdot`` is the ``ctrl`` of one MuJoCo ``<velocity>`` actuator per joint
   (``force = kv (ctrl - qdot)``, limited to the joint torque limits). The implicitfast
   integrator treats the ``kv`` damping implicitly, so stiff servos are stable at the 2 ms step
   without a hand-written computed-torque loop.
6. **F_ext.** ``qfrc_applied = J_p^T F_ext``: exactly what ``mj_applyFT`` computes for a force at
   the site point, reusing the Jacobian already at hand (overwritten, hence cleared, every tick).

The tick is split as ``mj_step2`` (integrate the state the controller saw) followed by
``mj_step1`` and ``mj_jacSite`` for the new state, so after :meth:`Arm.step` (and
:meth:`Arm.reset`) the kinematics, :meth:`Arm.hand_position` and :meth:`Arm.hand_velocity` are
those of the current state, and the cost is one ``mj_step`` plus the controller. If you change
``data.qpos``/``data.qvel`` yourself, call :meth:`Arm.forward` before the next step.

Neighbours: the MJCF is loaded and its names resolved in :mod:`langenv.robot.handles`, the reset's
inverse kinematics is :mod:`langenv.robot.ik`, the orientation-hold math
:mod:`langenv.robot.rotation`, and off-screen rendering :mod:`langenv.robot.camera`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from langenv import vec
from langenv.errors import ActionError, ConfigError
from langenv.layout import Layout, field_table
from langenv.robot.handles import ArmHandles, shared_model
from langenv.robot.ik import IK_ACCEPT, solve_ik
from langenv.robot.rotation import rotation_error_matrix, rotation_vector
from langenv.robot.safety import DEFAULT_MAX_SPEED, SafetyStop
from langenv.validation import as_vec3, finite_positive

if TYPE_CHECKING:
    from langenv.robot.camera import SceneRenderer

UR5_XML = Path(__file__).with_name("ur5.xml")
"""Path of our UR5 (CB-series) MJCF."""

UR5_JOINTS: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow",
    "wrist_1",
    "wrist_2",
    "wrist_3",
)
"""Joint names of the UR5 model, base to flange."""

_LIMIT_CHECK_MAX = 25  # ticks, longest interval between two joint-limit checks


ARM = Layout(
    "arm",
    field_table(
        """
        v_max            the hand's speed limit (m/s)
        kp               position gain (1/s)
        e_max            largest tracking error (m)
        e_max2           its square
        lambda2          the damping's square
        dt               the control period (s)
        task:int         task size: 6 (orientation held) or 3
        n:int            controlled joints
        nv:int           the model's degrees of freedom
        has_limits:bool  whether any joint is limited
        countdown:int    ticks until the joint margins are checked again
        full_dofs:bool   whether the joints are the model's dofs in order
        max_qd           the highest joint speed limit (rad/s)
        x_ref[3]         the reference point (m); the Arm's own ``x_ref`` is a view of it
        rot_b[27]        the orientation hold's (3, 9) matrix
        a[36]            work: the damped system's matrix
        xdot[6]          work: the task velocity
        y[6]             work: the system's solution
        v[3]             the clipped hand velocity command (m/s)
        """
    ),
)
"""The compiled controller's settings, state and work (:mod:`langenv.robot.arm_kernels`); after
``ARM.size`` come the per-joint blocks of :data:`ARM_JOINTS` (``n`` entries each) and the task
Jacobian (``task * n``)."""
ARM_JOINTS = Layout(
    "arm_joints",
    field_table(
        """
        inv_qd_max    1 / the joint's speed limit (s/rad)
        lower         lower limit (rad)
        upper         upper limit (rad)
        lower_margin  lower limit plus the margin (rad)
        upper_margin  upper limit minus the margin (rad)
        qdot          the joint speed command (rad/s)
        """
    ),
)
"""Per-joint blocks of the compiled controller's array: block ``j`` of field ``f`` starts at
``ARM.size + ARM_JOINTS.at.f * n``."""


def _joint_speed_limits(max_joint_speed: float | ArrayLike, n: int) -> NDArray[np.float64]:
    """``max_joint_speed`` (scalar or one per joint) as (n,) finite positive limits."""
    qdmax = np.broadcast_to(np.asarray(max_joint_speed, dtype=np.float64), (n,)).copy()
    if not np.all(np.isfinite(qdmax)) or np.any(qdmax <= 0.0):
        raise ConfigError(f"max_joint_speed must be finite and > 0, got {max_joint_speed!r}")
    return qdmax


class Arm:
    """A MuJoCo arm whose handle tracks a commanded Cartesian velocity (the paper's controller C).

    Args:
        model_path: MJCF file; ``None`` loads our UR5 (:data:`UR5_XML`).
        handle_site: name of the site where the human force acts and whose velocity is controlled.
        max_hand_speed: hand speed limit (m/s); ``|v_ref|`` and the whole Cartesian command
            are clipped to it (default: the safety limit,
            :data:`langenv.robot.safety.DEFAULT_MAX_SPEED`).
        joints: names of the controlled joints (hinge or slide); ``None`` takes every 1-dof joint
            on the kinematic chain from the world to the handle site, base first.
        actuators: names of the velocity actuators driving ``joints`` (same order); ``None``
            finds, for each joint, the actuator whose transmission is that joint.
        home_keyframe: keyframe loaded by :meth:`reset` before its IK; ``None`` uses ``qpos0``.
        hold_orientation: hold the handle orientation captured at reset (6-D task); ``False``
            controls the position only (3-D task, e.g. planar arms with fewer than 6 joints).
        max_joint_speed: joint speed limit (rad/s or m/s), scalar or one per joint. Default: the
            UR5's 180 deg/s.
        position_gain: gain (1/s) of the correction towards the integrated reference point.
        orientation_gain: gain (1/s) of the orientation hold.
        damping: damping ``lambda`` of the least-squares solve (m; must be > 0).
        joint_limit_margin: distance to a joint limit (rad or m) below which motion towards the
            limit is slowed linearly to zero.
        max_tracking_error: clamp (m) on ``|x_ref - x|``; bounds the correction and its wind-up.
        kv_scale: multiplies the velocity gains ``kv`` of the actuators (0 leaves the arm limp,
            moved by ``F_ext`` alone: a fully compliant robot).

    Attributes:
        model: the ``mujoco.MjModel``, shared by every arm of the same file in the process
            (:func:`~langenv.robot.handles.shared_model`; an arm with ``kv_scale != 1`` has a
            copy): read it, write to a copy.
        data: the ``mujoco.MjData``, this arm's own.
        dt: control and physics period (s), the model timestep.
        path: the MJCF file loaded.
        joint_names: names of the controlled joints.
        actuator_names: names of their actuators.
        max_hand_speed: hand speed limit (m/s).

    Raises:
        ConfigError: unreadable MJCF, missing site/joint/actuator/keyframe (naming it and the
            file), an actuator that is not a velocity actuator, or an invalid keyword argument.
    """

    fault: SafetyStop | None = None
    """Robot-side stops: never on the simulated arm (see :class:`~langenv.robot.io_arm.IOArm`)."""

    def __init__(
        self,
        model_path: str | Path | None = None,
        handle_site: str = "handle",
        *,
        max_hand_speed: float = DEFAULT_MAX_SPEED,
        joints: Sequence[str] | None = None,
        actuators: Sequence[str] | None = None,
        home_keyframe: str | None = "home",
        hold_orientation: bool = True,
        max_joint_speed: float | ArrayLike = math.pi,
        position_gain: float = 10.0,
        orientation_gain: float = 10.0,
        damping: float = 0.01,
        joint_limit_margin: float = 0.1,
        max_tracking_error: float = 0.01,
        kv_scale: float = 1.0,
    ) -> None:
        self.path = Path(UR5_XML if model_path is None else model_path)
        self.model = shared_model(self.path)
        self.data = mujoco.MjData(self.model)
        self.dt = float(self.model.opt.timestep)

        self.max_hand_speed = finite_positive("max_hand_speed", max_hand_speed, ConfigError)
        self._kp = finite_positive("position_gain", position_gain, ConfigError, allow_zero=True)
        self._kr = finite_positive(
            "orientation_gain", orientation_gain, ConfigError, allow_zero=True
        )
        self._lambda2 = finite_positive("damping", damping, ConfigError) ** 2
        self._margin = finite_positive(
            "joint_limit_margin", joint_limit_margin, ConfigError, allow_zero=True
        )
        self._emax = finite_positive("max_tracking_error", max_tracking_error, ConfigError)
        self._emax2 = self._emax * self._emax
        self._limit_countdown = 0
        kv_scale = finite_positive("kv_scale", kv_scale, ConfigError, allow_zero=True)
        self.hold_orientation = bool(hold_orientation)

        h = ArmHandles.resolve(self.model, self.path, handle_site, joints, actuators, home_keyframe)
        self._handles = h
        self.site_id = h.site_id
        self.handle_site = handle_site
        self.joint_names = h.joint_names
        self.actuator_names = h.actuator_names
        self.n_joints = h.n_joints
        self._home_key = h.home_key
        if kv_scale != 1.0:  # velocity gains of its own: the shared model is never written
            self.model = copy.copy(self.model)
            self.data = mujoco.MjData(self.model)
            self.model.actuator_gainprm[h.act_ids, 0] *= kv_scale
            self.model.actuator_biasprm[h.act_ids, 2] *= kv_scale
        self._inv_qdmax = 1.0 / _joint_speed_limits(max_joint_speed, h.n_joints)

        self._dofs = h.dofs
        self._qadr = h.qadr
        self._act_ids = h.act_ids
        self._lo = h.lower
        self._hi = h.upper
        self._lo_m = self._lo + self._margin
        self._hi_m = self._hi - self._margin
        self._has_limits = h.has_limits
        self._allocate_work_arrays()
        self._renderer: SceneRenderer | None = None
        self.reset()

    def _allocate_work_arrays(self) -> None:
        """Preallocate the controller's work arrays and views (the hot path allocates nothing)."""
        m, d = self.model, self.data
        n, nv = self.n_joints, m.nv
        dofs, qadr, acts = self._dofs, self._qadr, self._act_ids
        self._task = 6 if self.hold_orientation else 3
        k = self._task
        self._jac = np.zeros((6, nv))
        self._jacp = self._jac[:3]
        self._jacr = self._jac[3:]
        self._full_dofs = bool(nv == n and np.array_equal(dofs, np.arange(nv)))
        self._jac_arm = self._jac[:k] if self._full_dofs else np.zeros((k, n))
        self._a = np.zeros((k, k))
        self._a_diag = self._a.reshape(-1)[:: k + 1]
        self._xdot = np.zeros(k)
        self._xdot_lin = self._xdot[:3]
        self._xdot_rot = self._xdot[3:]
        self._y = np.zeros(k)
        self._qdot = np.zeros(n)
        self._tmp_n = np.zeros(n)
        self._tmp_3 = np.zeros(3)
        self._err = np.zeros(3)
        self._x_ref = np.zeros(3)
        self._rot_b = np.zeros((3, 9))
        self._r_held = np.eye(3)
        self._site_xpos = d.site_xpos[self.site_id]
        self._site_xmat = d.site_xmat[self.site_id]
        self._qfrc = d.qfrc_applied
        self._qpos_view: NDArray[np.float64] | None = None
        if np.array_equal(qadr, np.arange(qadr[0], qadr[0] + n)):
            self._qpos_view = d.qpos[qadr[0] : qadr[0] + n]
        self._ctrl_view: NDArray[np.float64] | None = None
        if np.array_equal(acts, np.arange(acts[0], acts[0] + n)):
            self._ctrl_view = d.ctrl[acts[0] : acts[0] + n]

    # ------------------------------------------------------------------ compiled controller
    def compiled_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The controller packed for :mod:`langenv.robot.arm_kernels`: ``aw`` (:data:`ARM`,
        then the :data:`ARM_JOINTS` blocks and the task Jacobian) and ``ai`` (the joints' dof
        and qpos addresses and their actuators, int64, ``3 n``). From then on the arm's
        reference point is a view of ``aw``, so the Python step and the kernel move the same
        three numbers."""
        n, nv, k = self.n_joints, self.model.nv, self._task
        aw = np.zeros(ARM.size + len(ARM_JOINTS.fields) * n + k * n)
        ARM.pack(
            aw,
            {
                "v_max": self.max_hand_speed, "kp": self._kp, "e_max": self._emax,
                "e_max2": self._emax2, "lambda2": self._lambda2, "dt": self.dt, "task": k,
                "n": n, "nv": nv, "has_limits": self._has_limits, "full_dofs": self._full_dofs,
                "max_qd": float(np.max(1.0 / self._inv_qdmax)), "x_ref": self._x_ref,
            },
        )  # fmt: skip
        j = ARM_JOINTS.at
        for block, values in (
            (j.inv_qd_max, self._inv_qdmax), (j.lower, self._lo), (j.upper, self._hi),
            (j.lower_margin, self._lo_m), (j.upper_margin, self._hi_m),
        ):  # fmt: skip
            aw[ARM.size + block * n : ARM.size + (block + 1) * n] = values
        self._x_ref = aw[ARM.at.x_ref : ARM.at.x_ref + 3]
        ai = np.concatenate([self._dofs, self._qadr, self._act_ids]).astype(np.int64)
        return aw, ai

    def compiled_views(self) -> dict[str, np.ndarray]:
        """The MuJoCo arrays the compiled tick reads and writes, by name: ``jac`` (the site
        Jacobian, flat (6 nv)), ``jacp``/``jacr`` (its halves, what ``mj_jacSite`` writes),
        ``xpos``/``xmat`` (the handle site's), ``qpos``, ``qvel``, ``ctrl``, ``qfrc``
        (``qfrc_applied``); views, valid as long as the arm."""
        d = self.data
        return {
            "jac": self._jac.reshape(-1), "jacp": self._jacp, "jacr": self._jacr,
            "xpos": self._site_xpos, "xmat": self._site_xmat, "qpos": d.qpos, "qvel": d.qvel,
            "ctrl": d.ctrl, "qfrc": d.qfrc_applied,
        }  # fmt: skip

    @property
    def full_dofs(self) -> bool:
        """Whether the controlled joints are the model's degrees of freedom, in order (the
        compiled ticks of the env need it)."""
        return self._full_dofs

    def load_compiled_state(self, aw: np.ndarray) -> None:
        """Copy the controller's state after a reset into ``aw`` (the countdown to the next
        joint-margin check and the orientation hold)."""
        ARM.pack(aw, {"countdown": self._limit_countdown, "rot_b": self._rot_b})

    def store_compiled_state(self, aw: np.ndarray) -> None:
        """Take the controller's state back from ``aw`` (before a Python tick)."""
        self._limit_countdown = int(aw[ARM.at.countdown])

    def avoid_limits_compiled(self, aw: np.ndarray) -> None:
        """The compiled controller found a joint inside its margin: re-solve ``aw``'s joint
        speeds in Python (:meth:`step`'s 3, the reference) before the compiled ``apply``."""
        n, k = self.n_joints, self._task
        qdot = aw[ARM.size + ARM_JOINTS.at.qdot * n : ARM.size + (ARM_JOINTS.at.qdot + 1) * n]
        self._qdot[:] = qdot
        self._xdot[:] = aw[ARM.at.xdot : ARM.at.xdot + k]
        q = self._qpos_view if self._qpos_view is not None else self.data.qpos[self._qadr]
        self._avoid_limits(q)
        qdot[:] = self._qdot

    def update_jacobian(self) -> None:
        """Recompute the handle's Jacobian for the current kinematics (after MuJoCo's step)."""
        self._update_jacobian()

    # ------------------------------------------------------------------ state

    def forward(self) -> None:
        """Recompute kinematics and the Jacobian after ``data.qpos``/``data.qvel`` were edited."""
        mujoco.mj_forward(self.model, self.data)
        self._limit_countdown = 0
        self._update_jacobian()

    def _update_jacobian(self) -> None:
        mujoco.mj_jacSite(self.model, self.data, self._jacp, self._jacr, self.site_id)
        if not self._full_dofs:
            np.take(self._jac[: self._task], self._dofs, axis=1, out=self._jac_arm)

    def _arm_jacobian(self) -> NDArray[np.float64]:
        """The (k, n) site Jacobian of the controlled joints at the current kinematics."""
        self._update_jacobian()
        return self._jac_arm

    def _hold(self, rotation: NDArray[np.float64]) -> None:
        """Hold ``rotation`` (3, 3) from now on and restart the reference point at the hand."""
        self._r_held = rotation.copy()
        self._rot_b = rotation_error_matrix(self._r_held, self._kr)
        self._x_ref[:] = self._site_xpos

    def reset(self, hand_position: ArrayLike | None = None) -> None:
        """Load the home keyframe and, if given, move the handle to ``hand_position`` by IK.

        The IK keeps the home orientation of the handle (when ``hold_orientation``) and the home
        branch (elbow up); joint velocities, controls and applied forces are zeroed.

        Args:
            hand_position: (3,) target of the handle site (m, base frame), or ``None`` for home.

        Raises:
            ConfigError: ``hand_position`` is not a finite (3,) vector, is out of reach with the
                home orientation (residual > 0.1 mm), or puts the arm in contact.
        """
        m, d = self.model, self.data
        if self._home_key is not None:
            mujoco.mj_resetDataKeyframe(m, d, self._home_key)
        else:
            mujoco.mj_resetData(m, d)
        mujoco.mj_forward(m, d)
        if hand_position is not None:
            target = as_vec3(hand_position, "hand_position", ConfigError)
            rotation = self._site_xmat.reshape(3, 3).copy() if self._task == 6 else None
            residual = solve_ik(m, d, self._handles, self._arm_jacobian, target, rotation)
            if residual > IK_ACCEPT:
                raise ConfigError(
                    f"hand_position {target.tolist()} is out of reach of {self.path.name} with "
                    f"the home orientation (residual {residual:.3g} m)"
                )
            d.qvel[:] = 0.0
            d.ctrl[:] = 0.0
            d.qfrc_applied[:] = 0.0
            mujoco.mj_forward(m, d)
            if d.ncon > 0:
                g1, g2 = int(d.contact.geom1[0]), int(d.contact.geom2[0])
                raise ConfigError(
                    f"hand_position {target.tolist()} puts {self.path.name} in contact "
                    f"(geoms {m.geom(g1).name!r} and {m.geom(g2).name!r})"
                )
        d.qfrc_applied[:] = 0.0
        self._limit_countdown = 0
        self._update_jacobian()
        self._hold(self._site_xmat.reshape(3, 3))

    def hand_position(self) -> NDArray[np.float64]:
        """Handle site position.

        Returns:
            (3,) float64, m, base frame (a copy).
        """
        return self._site_xpos.copy()

    def hand_velocity(self) -> NDArray[np.float64]:
        """Handle site linear velocity ``J_p qdot``.

        Returns:
            (3,) float64, m/s, base frame.
        """
        v = np.empty(3)
        mujoco.mju_mulMatVec(v, self._jacp, self.data.qvel)  # MuJoCo's order, not BLAS's
        return v

    def hand_rotation(self) -> NDArray[np.float64]:
        """Handle site orientation.

        Returns:
            (3, 3) float64 rotation matrix, columns = site axes in the base frame (a copy).
        """
        return self._site_xmat.reshape(3, 3).copy()

    def orientation_error(self) -> float:
        """Angle (rad) between the handle orientation and the one held since :meth:`reset`."""
        return vec.norm(rotation_vector(self._site_xmat.reshape(3, 3), self._r_held))

    def joint_positions(self) -> NDArray[np.float64]:
        """Positions of the controlled joints, (n,) rad or m (a copy)."""
        return self.data.qpos[self._qadr].copy()

    def joint_velocities(self) -> NDArray[np.float64]:
        """Velocities of the controlled joints, (n,) rad/s or m/s (a copy)."""
        return self.data.qvel[self._dofs].copy()

    @property
    def joint_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper ends of the controlled joints' ranges, each (n,) rad or m (copies;
        ``-inf``/``inf`` for an unlimited joint)."""
        return self._lo.copy(), self._hi.copy()

    @property
    def reference_position(self) -> NDArray[np.float64]:
        """The integrated reference point ``x_ref`` the controller corrects towards, (3,) m."""
        return self._x_ref.copy()

    # ------------------------------------------------------------------ control tick

    def step(self, v_ref: NDArray[np.float64], f_ext: NDArray[np.float64]) -> None:
        """One control tick: controller C, F_ext at the handle, one physics step of ``dt``.

        Args:
            v_ref: (3,) commanded handle velocity (m/s, base frame); clipped to max_hand_speed.
            f_ext: (3,) external (human) force on the handle (N, base frame).

        Raises:
            ActionError: ``v_ref`` or ``f_ext`` is not a finite (3,) vector (names which).
        """
        v_ref = _vec3(v_ref, "v_ref")
        f_ext = _vec3(f_ext, "f_ext")
        s2 = vec.sumsq(v_ref)
        f2 = vec.sumsq(f_ext)
        if not (s2 < math.inf and f2 < math.inf):  # NaN fails the comparison too
            as_vec3(v_ref, "v_ref", ActionError)
            as_vec3(f_ext, "f_ext", ActionError)
        m, d = self.model, self.data
        vmax = self.max_hand_speed
        if s2 > vmax * vmax:
            v_ref = v_ref * (vmax / math.sqrt(s2))

        # Cartesian command: v_ref + kp (x_ref - x), orientation hold.
        err = self._err
        x_ref = self._x_ref
        xdot_lin = self._xdot_lin
        np.subtract(x_ref, self._site_xpos, out=err)
        e2 = vec.sumsq(err)
        if e2 > self._emax2:
            err *= self._emax / math.sqrt(e2)
            np.add(self._site_xpos, err, out=x_ref)  # anti-wind-up
        np.multiply(err, self._kp, out=xdot_lin)
        xdot_lin += v_ref
        if math.sqrt(s2) + self._kp * math.sqrt(min(e2, self._emax2)) > vmax:  # may exceed it
            c2 = vec.sumsq(xdot_lin)
            if c2 > vmax * vmax:
                xdot_lin *= vmax / math.sqrt(c2)
        if self._task == 6:
            mujoco.mju_mulMatVec(self._xdot_rot, self._rot_b, self._site_xmat)

        # Damped least squares on the cached site Jacobian.
        jac = self._jac_arm
        a = self._a
        qdot = self._qdot
        mujoco.mju_mulMatMatT(a, jac, jac)
        self._a_diag += self._lambda2
        mujoco.mju_cholFactor(a, 0.0)
        mujoco.mju_cholSolve(self._y, a, self._xdot)
        mujoco.mju_mulMatTVec(qdot, jac, self._y)

        # Joint-limit margins: checked only when a joint could have reached one.
        self._limit_countdown -= 1
        if self._limit_countdown <= 0:
            self._check_limits()

        # Uniform joint speed limit (the 2-norm bounds the max-norm: exact check only if > 1).
        tmp = self._tmp_n
        np.multiply(qdot, self._inv_qdmax, out=tmp)
        scale = self.dt
        if vec.sumsq(tmp) > 1.0:
            ratio = float(np.abs(tmp).max())
            if ratio > 1.0:
                qdot *= 1.0 / ratio
                scale /= ratio
        np.multiply(v_ref, scale, out=self._tmp_3)
        x_ref += self._tmp_3

        if self._ctrl_view is not None:
            self._ctrl_view[:] = qdot
        else:
            d.ctrl[self._act_ids] = qdot

        # F_ext at the handle site: qfrc_applied = J_p^T F (same as mj_applyFT at the site).
        mujoco.mju_mulMatTVec(self._qfrc, self._jacp, f_ext)

        mujoco.mj_step2(m, d)
        mujoco.mj_step1(m, d)
        self._update_jacobian()

    def _check_limits(self) -> None:
        """Apply joint-limit avoidance if a joint is inside a margin; schedule the next check.

        Joints outside every margin cannot enter one within ``slack / (bound * dt)`` ticks, where
        ``bound`` is a generous bound on the joint speeds (twice the larger of the joint speed
        limit and the current joint speed), so the check (a few microseconds) is skipped until
        then, but for at most ``_LIMIT_CHECK_MAX`` ticks. Inside a margin it runs every tick.
        """
        if not self._has_limits:
            self._limit_countdown = 1 << 62
            return
        q = self._qpos_view if self._qpos_view is not None else self.data.qpos[self._qadr]
        slack = float(np.min(np.minimum(q - self._lo_m, self._hi_m - q)))
        if slack <= 0.0:
            self._avoid_limits(q)
            self._limit_countdown = 1
            return
        qvel = np.abs(self.data.qvel[self._dofs]) * self._inv_qdmax
        bound = 2.0 * max(1.0, float(qvel.max())) * float(np.max(1.0 / self._inv_qdmax))
        self._limit_countdown = max(1, min(_LIMIT_CHECK_MAX, int(slack / (bound * self.dt))))

    def _avoid_limits(self, q: NDArray[np.float64]) -> None:
        """Re-solve with the columns of joints moving into a limit margin weighted down."""
        qdot = self._qdot
        # Weight 1 at the margin, 0 a hair (2 % of the margin) inside the limit, so actuator lag
        # cannot carry the joint onto MuJoCo's limit constraint.
        margin = max(self._margin, 1e-12)
        buffer = 0.02 * margin
        w = np.ones_like(qdot)
        up = (qdot > 0.0) & (q > self._hi_m)
        lo = (qdot < 0.0) & (q < self._lo_m)
        w[up] = np.clip((self._hi[up] - buffer - q[up]) / (margin - buffer), 0.0, 1.0)
        w[lo] = np.clip((q[lo] - self._lo[lo] - buffer) / (margin - buffer), 0.0, 1.0)
        if not (np.any(up) or np.any(lo)):
            return
        jw = self._jac_arm * w
        k = jw.shape[0]
        a = np.empty((k, k))
        mujoco.mju_mulMatMatT(a, jw, jw)  # the same routines as the main solve: no BLAS/LAPACK
        a[np.diag_indices_from(a)] += self._lambda2
        mujoco.mju_cholFactor(a, 0.0)
        y = np.empty(k)
        mujoco.mju_cholSolve(y, a, self._xdot)
        mujoco.mju_mulMatTVec(qdot, jw, y)
        qdot *= w

    # ------------------------------------------------------------------ rendering

    def render(
        self,
        width: int = 640,
        height: int = 480,
        camera: str = "overview",
        path: ArrayLike | None = None,
        force: ArrayLike | None = None,
    ) -> NDArray[np.uint8]:
        """Render the scene off-screen (needs an OpenGL backend, e.g. ``MUJOCO_GL=egl``).

        Args:
            width: image width (px).
            height: image height (px).
            camera: name of a camera in the model.
            path: optional (N, 3) points (m) drawn as a thin polyline (the exercise path).
            force: optional (3,) force (N) drawn as an arrow at the handle (1 cm per N).

        Returns:
            (height, width, 3) uint8 RGB image.

        Raises:
            ConfigError: unknown camera, bad size, or malformed ``path``/``force``.
        """
        from langenv.robot.camera import SceneRenderer

        if self._renderer is None or self._renderer.size != (width, height):
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = SceneRenderer(self.model, width, height)
        return self._renderer.render(
            self.data, camera, path=path, force=force, force_at=self._site_xpos
        )

    def close(self) -> None:
        """Release the renderer's GL context, if any."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _vec3(x: ArrayLike, name: str) -> np.ndarray:
    """``x`` itself when it is already a contiguous float64 (3,) array (the per-tick case), else
    :func:`~langenv.validation.as_vec3` of it (an ActionError naming ``name`` if it is not a
    3-vector)."""
    if type(x) is np.ndarray and x.shape == (3,) and x.dtype == np.float64 and x.flags.c_contiguous:
        return x
    return as_vec3(x, name, ActionError)
