"""Checks of an exercise against the arm: reach, joint margins, manipulability, contacts.

The path is sampled every :data:`SAMPLE_SPACING` along each leg (``point`` ``j`` of a leg is its
``j``-th sample). At each sample the UR5's inverse kinematics (:func:`langenv.robot.ik.solve_ik`,
continued from the previous sample's solution from the arm's reset at the start, so the arm stays
on the branch it starts on) must place the handle at the point *with the tool orientation the
exercise asks for* (the home orientation turned by the legs' tool turns). Then:

* ``unreachable``: position residual above :data:`~langenv.robot.ik.IK_ACCEPT` (0.1 mm) or
  orientation residual above :data:`ROT_ACCEPT`;
* ``joint_margin``: a joint closer than :data:`JOINT_MARGIN` to the end of its range: twice the
  margin in which the arm's controller starts slowing a joint (0.1 rad), so the nominal path never
  leans on the joint-limit avoidance, and far from the safety monitor's stop (0.01 rad);
* ``singular``: the smallest singular value of the handle's 6-D Jacobian below
  :data:`MIN_SIGMA` (m/rad). A hand velocity ``v`` then needs joint speeds up to ``|v| / sigma``:
  with ``sigma >= MIN_SIGMA = 0.5 / pi`` even the safety limit's hand speed (0.5 m/s) needs no
  joint faster than the UR5's 180 deg/s, and the controller's damped least squares (damping
  0.01) loses under 0.4 % of the motion in any direction. The study's path stays above 0.2;
* ``collision``: the arm's collision geoms closer than :data:`CLEARANCE` to the table or to each
  other (MuJoCo's contacts on a copy of the model in which the links also collide with each
  other; pairs already in contact at the home pose, neighbours by construction, are left out).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from langenv.errors import ConfigError
from langenv.exercise.spec import Exercise, Problem
from langenv.robot.arm import Arm
from langenv.robot.handles import load_model
from langenv.robot.ik import IK_ACCEPT, solve_ik
from langenv.robot.rotation import rotation_vector
from langenv.safety import DEFAULT_MAX_SPEED

__all__ = [
    "CLEARANCE",
    "JOINT_MARGIN",
    "MIN_SIGMA",
    "ROT_ACCEPT",
    "SAMPLE_SPACING",
    "ReachReport",
    "reach_problems",
]

SAMPLE_SPACING = 0.01
"""Distance between the path's samples (m)."""
ROT_ACCEPT = 1e-3
"""Largest orientation residual of the IK (rad)."""
JOINT_MARGIN = 0.2
"""Smallest distance of a joint from the end of its range on the path (rad)."""
MIN_SIGMA = DEFAULT_MAX_SPEED / math.pi
"""Smallest singular value of the 6-D handle Jacobian on the path (m/rad): the safety limit's
hand speed over the UR5's joint speed limit (about 0.159)."""
CLEARANCE = 0.005
"""Smallest distance (m) between the arm's collision geoms and the table or each other."""
_COLLISION_GROUP = 3  # the MJCF's class "collision"


@dataclass(frozen=True, eq=False)
class ReachReport:
    """What the arm does along the path.

    Attributes:
        s: Arc length of each sample (m), shape (n,).
        qpos: The joint positions at each sample (rad), shape (n, 6).
        min_joint_margin: Smallest distance of a joint from its range's end (rad).
        min_sigma: Smallest singular value of the handle Jacobian (m/rad).
        min_clearance: Smallest distance between the arm and the table or itself (m), capped at
            the contact search's reach (``CLEARANCE``).
    """

    s: np.ndarray
    qpos: np.ndarray
    min_joint_margin: float
    min_sigma: float
    min_clearance: float


def _samples(exercise: Exercise) -> list[tuple[int, int, float]]:
    """``(leg, point, s)`` for every sample of the path."""
    out: list[tuple[int, int, float]] = []
    for k in range(len(exercise.legs)):
        a, b = exercise.leg_span(k)
        n = max(2, math.ceil((b - a) / SAMPLE_SPACING) + 1)
        out.extend((k, j, float(s)) for j, s in enumerate(np.linspace(a, b, n)))
    return out


def _turn_hint(exercise: Exercise, k: int, kind: str) -> str:
    """For a leg that turns the tool half a turn or more (an arc's default turn on a circle),
    what keeps it still, said with the orientation's problems."""
    turn = math.degrees(abs(exercise.legs[k].turn))
    if kind not in ("unreachable", "joint_margin") or turn < 180.0:
        return ""
    return f"; the leg turns the tool {turn:.0f} deg (tool: {{turn: 0}} keeps it still)"


class _Contacts:
    """A copy of the arm's model in which its collision geoms collide with each other too."""

    def __init__(self, path: Path, home_qpos: np.ndarray) -> None:
        m = self.model = load_model(path)
        arm_geoms = m.geom_group == _COLLISION_GROUP
        m.geom_contype[arm_geoms] = 2
        m.geom_conaffinity[arm_geoms] = 3
        m.geom_margin[arm_geoms] = CLEARANCE
        bodies = np.unique(m.geom_bodyid[arm_geoms])  # the broad phase filters body pairs first
        m.body_contype[bodies] |= 2
        m.body_conaffinity[bodies] |= 3
        if hasattr(m, "body_margin"):
            m.body_margin[bodies] = np.maximum(m.body_margin[bodies], CLEARANCE)
        self.data = mujoco.MjData(m)
        self.ignored = {pair for pair, _ in self.contacts(home_qpos)}

    def contacts(self, qpos: np.ndarray) -> list[tuple[tuple[str, str], float]]:
        """``((geom, geom), distance)`` of the contacts within ``CLEARANCE`` at ``qpos``."""
        m, d = self.model, self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        out = []
        for c in d.contact[: d.ncon]:
            pair = tuple(sorted((m.geom(int(c.geom1)).name, m.geom(int(c.geom2)).name)))
            out.append(((pair[0], pair[1]), float(c.dist)))
        return out


def reach_problems(
    exercise: Exercise, model_path: str | Path | None = None
) -> tuple[list[Problem], ReachReport]:
    """The problems of the arm along the path (module docstring), and what it does there.

    Args:
        exercise: The exercise.
        model_path: The arm's MJCF; None: our UR5.

    Returns:
        ``(problems, report)``; at most one problem of each kind per leg (its first point).
    """
    arm = Arm(model_path)
    home_rot = arm.hand_rotation()
    lo, hi = arm.joint_range
    contacts = _Contacts(arm.path, arm.data.qpos.copy())
    out: list[Problem] = []
    seen: set[tuple[str, str]] = set()
    names = exercise.leg_names

    def report(kind: str, k: int, j: int, detail: str) -> None:
        if (kind, names[k]) not in seen:
            seen.add((kind, names[k]))
            out.append(Problem(kind, names[k], j, detail + _turn_hint(exercise, k, kind)))

    try:
        arm.reset(exercise.start)
    except ConfigError as exc:  # start out of reach or in contact: carry on from home
        report("unreachable", 0, 0, str(exc))
    traj = exercise.trajectory
    samples = _samples(exercise)
    qs = np.zeros((len(samples), arm.n_joints))
    margins, sigmas, clear = [], [], [CLEARANCE]
    for i, (k, j, s) in enumerate(samples):
        target = traj.position(s)
        rot = exercise.tool_rotation(s, home_rot)
        res = solve_ik(arm.model, arm.data, arm._handles, arm._arm_jacobian, target, rot)
        rot_err = float(np.linalg.norm(rotation_vector(arm.hand_rotation(), rot)))
        if res > IK_ACCEPT or rot_err > ROT_ACCEPT:
            report(
                "unreachable",
                k,
                j,
                f"{np.round(target, 4).tolist()} m not reached with the tool orientation asked for "
                f"(residual {res:.3g} m, {math.degrees(rot_err):.2g} deg)",
            )
        q = arm.joint_positions()
        qs[i] = q
        margin = np.minimum(q - lo, hi - q)
        margins.append(float(margin.min()))
        if margin.min() < JOINT_MARGIN:
            jn = int(np.argmin(margin))
            report(
                "joint_margin",
                k,
                j,
                f"joint {arm.joint_names[jn]!r} at {q[jn]:.3f} rad, {margin[jn]:.3f} rad from the "
                f"end of its range (at least {JOINT_MARGIN} rad)",
            )
        sigma = float(np.linalg.svd(arm._arm_jacobian(), compute_uv=False)[-1])
        sigmas.append(sigma)
        if sigma < MIN_SIGMA:
            report(
                "singular",
                k,
                j,
                f"near a singularity at {np.round(target, 4).tolist()} m: the handle Jacobian's "
                f"smallest singular value is {sigma:.3f} m/rad (at least {MIN_SIGMA:.3f})",
            )
        for pair, dist in contacts.contacts(arm.data.qpos):
            if pair in contacts.ignored:
                continue
            clear.append(dist)
            what = "the table" if "table" in pair else f"itself ({pair[0]} and {pair[1]})"
            other = pair[1] if pair[0] == "table" else pair[0]
            if "table" in pair:
                what = f"the table ({other})"
            report(
                "collision",
                k,
                j,
                f"the arm comes within {dist:.3f} m of {what} at {np.round(target, 4).tolist()} m "
                f"(at least {CLEARANCE} m)",
            )
    qs.setflags(write=False)
    s_arr = np.array([s for _, _, s in samples])
    s_arr.setflags(write=False)
    rep = ReachReport(s_arr, qs, min(margins), min(sigmas), min(clear))
    return out, rep
