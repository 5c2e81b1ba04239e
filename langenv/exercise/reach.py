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
from langenv.robot.safety import DEFAULT_MAX_SPEED

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


class _Findings:
    """The problems found along the path: at most one of each kind per leg (its first place),
    and each run of consecutive samples out of reach as one ``unreachable`` problem."""

    def __init__(self, exercise: Exercise) -> None:
        self.exercise = exercise
        self.out: list[Problem] = []
        self._seen: set[tuple[str, str]] = set()
        self._run: list[tuple[int, int, float, np.ndarray, float, float, str]] = []

    def report(self, kind: str, k: int, j: int, detail: str, s: float | None = None) -> None:
        """A problem of ``kind`` at sample ``j`` of leg ``k`` (arc length ``s``, m)."""
        name = self.exercise.leg_names[k]
        if (kind, name) in self._seen:
            return
        self._seen.add((kind, name))
        at = None if s is None else max(0.0, s - self.exercise.leg_span(k)[0])
        detail += _turn_hint(self.exercise, k, kind)
        self.out.append(Problem(kind, name, j, detail, at))

    def unreached(
        self, k: int, j: int, s: float, target: np.ndarray, res: float, rot: float, why: str
    ) -> None:
        """Sample ``j`` of leg ``k`` is out of reach (residuals in m and rad; ``why``: the
        joints held at the ends of their ranges, or "")."""
        self._run.append((k, j, s, target, res, rot, why))

    def reached(self) -> None:
        """A sample in reach: a run out of reach before it ends there."""
        if not self._run:
            return
        (k, j, s, first, res, rot, why), (k1, _, s1, last, *_) = self._run[0], self._run[-1]
        where = f"{np.round(first, 4).tolist()} m"
        if len(self._run) > 1:
            until = s1 - self.exercise.leg_span(k1)[0]
            leg = "it" if k1 == k else f"leg {self.exercise.leg_names[k1]!r}"
            where = (
                f"{s1 - s:.2f} m of the path, from {where} to {np.round(last, 4).tolist()} m "
                f"({until:.2f} m along {leg}),"
            )
        self._run = []
        self.report(
            "unreachable",
            k,
            j,
            f"{where} not reached with the tool orientation asked for (residual {res:.3g} m, "
            f"{math.degrees(rot):.2g} deg at the first point{why})",
            s,
        )


def reach_problems(
    exercise: Exercise, model_path: str | Path | None = None
) -> tuple[list[Problem], ReachReport]:
    """The problems of the arm along the path (module docstring), and what it does there.

    Where a sample is out of reach the arm's pose means nothing: only ``unreachable`` is said
    of it (one problem for a run of such samples, from its first to its last point), and the
    next sample is sought from the last pose in reach.

    Args:
        exercise: The exercise.
        model_path: The arm's MJCF; None: our UR5.

    Returns:
        ``(problems, report)``; at most one problem of each kind per leg (its first point).
    """
    arm = Arm(model_path)
    home_rot = arm.hand_rotation()
    contacts = _Contacts(arm.path, arm.data.qpos.copy())
    found = _Findings(exercise)
    try:
        arm.reset(exercise.start)
    except ConfigError as exc:  # start out of reach or in contact: carry on from home
        found.report("unreachable", 0, 0, str(exc), exercise.leg_span(0)[0])
    traj = exercise.trajectory
    samples = _samples(exercise)
    qs = np.zeros((len(samples), arm.n_joints))
    figures: dict[str, list[float]] = {"margin": [], "sigma": [], "clear": [CLEARANCE]}
    good = arm.data.qpos.copy()
    for i, (k, j, s) in enumerate(samples):
        target, rot = traj.position(s), exercise.tool_rotation(s, home_rot)
        res = solve_ik(arm.model, arm.data, arm._handles, arm._arm_jacobian, target, rot)
        rot_err = float(np.linalg.norm(rotation_vector(arm.hand_rotation(), rot)))
        qs[i] = arm.joint_positions()
        if res > IK_ACCEPT or rot_err > ROT_ACCEPT:
            found.unreached(k, j, s, target, res, rot_err, _held(arm, qs[i]))
            arm.data.qpos[:] = good  # the next sample from the last pose in reach
            continue
        found.reached()
        good = arm.data.qpos.copy()
        _pose_checks(arm, contacts, found, (k, j, s), target, figures)
    found.reached()
    qs.setflags(write=False)
    s_arr = np.array([s for _, _, s in samples])
    s_arr.setflags(write=False)
    lowest = {key: min(v, default=math.nan) for key, v in figures.items()}
    rep = ReachReport(s_arr, qs, lowest["margin"], lowest["sigma"], lowest["clear"])
    return found.out, rep


def _held(arm: Arm, q: np.ndarray) -> str:
    """``"; joint 'elbow' held at the end of its range"`` for the joints the IK left at a range's
    end (what kept it from the point), or ``""``."""
    lo, hi = arm.joint_range
    margin = np.minimum(q - lo, hi - q)
    names = [repr(n) for n, m in zip(arm.joint_names, margin, strict=True) if m < 1e-9]
    return f"; joint {', '.join(names)} held at the end of its range" if names else ""


def _pose_checks(
    arm: Arm,
    contacts: _Contacts,
    found: _Findings,
    sample: tuple[int, int, float],
    target: np.ndarray,
    figures: dict[str, list[float]],
) -> None:
    """Joint margins, manipulability and contacts of the arm's pose at a sample in reach."""
    k, j, s = sample
    lo, hi = arm.joint_range
    q = arm.joint_positions()
    margin = np.minimum(q - lo, hi - q)
    figures["margin"].append(float(margin.min()))
    if margin.min() < JOINT_MARGIN:
        jn = int(np.argmin(margin))
        found.report(
            "joint_margin",
            k,
            j,
            f"joint {arm.joint_names[jn]!r} at {q[jn]:.3f} rad, {margin[jn]:.3f} rad from the "
            f"end of its range (at least {JOINT_MARGIN} rad)",
            s,
        )
    sigma = float(np.linalg.svd(arm._arm_jacobian(), compute_uv=False)[-1])
    figures["sigma"].append(sigma)
    point = np.round(target, 4).tolist()
    if sigma < MIN_SIGMA:
        found.report(
            "singular",
            k,
            j,
            f"near a singularity at {point} m: the handle Jacobian's smallest singular value "
            f"is {sigma:.3f} m/rad (at least {MIN_SIGMA:.3f})",
            s,
        )
    for pair, dist in contacts.contacts(arm.data.qpos):
        if pair in contacts.ignored:
            continue
        figures["clear"].append(dist)
        other = pair[1] if pair[0] == "table" else pair[0]
        what = f"the table ({other})" if "table" in pair else f"itself ({pair[0]} and {pair[1]})"
        found.report(
            "collision",
            k,
            j,
            f"the arm comes within {dist:.3f} m of {what} at {point} m (at least {CLEARANCE} m)",
            s,
        )
