"""An arm's MJCF loaded and its names resolved: handle site, joints, velocity actuators, keyframe.

:func:`load_model` reads the MJCF; :meth:`ArmHandles.resolve` finds, by name, everything the
controller C of :class:`langenv.robot.Arm` acts on and checks it (a hinge or slide joint, a
``<velocity>`` actuator with gear 1 driving that joint), naming the missing or wrong element and
the file in a :class:`~langenv.errors.ConfigError`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from langenv.errors import ConfigError

__all__ = ["ArmHandles", "load_model", "shared_model"]

_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def load_model(path: Path) -> mujoco.MjModel:
    """Load an MJCF file.

    Args:
        path: the MJCF file.

    Returns:
        The compiled ``mujoco.MjModel``.

    Raises:
        ConfigError: ``path`` is not a file or not a valid MJCF (naming it).
    """
    if not path.is_file():
        raise ConfigError(f"model_path {str(path)!r} is not a file")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ConfigError(f"model_path {str(path)!r} is not a valid MJCF: {exc}") from exc


_MODELS: dict[tuple[str, int, int], mujoco.MjModel] = {}
_MODELS_LOCK = threading.Lock()


def shared_model(path: Path) -> mujoco.MjModel:
    """:func:`load_model`, once per file (its resolved path, time and size) in the process.

    MuJoCo reads a model while it steps and never writes to it, each arm stepping its own
    ``MjData``: every arm of a batch of sessions shares one model (its meshes are most of an
    arm's memory). Write to a copy (``copy.copy(model)``), never to the shared one.

    Raises:
        ConfigError: as :func:`load_model`.
    """
    try:
        st = path.stat()
    except OSError:
        return load_model(path)  # its error names the file
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is None:
            model = _MODELS[key] = load_model(path)
    return model


@dataclass(frozen=True, eq=False)
class ArmHandles:
    """Ids and addresses of the elements of a model that the arm's controller acts on.

    Attributes:
        path: the MJCF file (named in error messages).
        handle_site: name of the handle site.
        site_id: its id.
        joint_ids: (n,) ids of the controlled joints, base first.
        joint_names: their names.
        dofs: (n,) their dof addresses (columns of the Jacobian, entries of ``qvel``).
        qadr: (n,) their ``qpos`` addresses.
        act_ids: (n,) ids of the velocity actuators driving them (same order).
        actuator_names: their names.
        home_key: id of the home keyframe, or ``None`` (reset to ``qpos0``).
        lower: (n,) lower joint limits (rad or m; ``-inf`` where unlimited).
        upper: (n,) upper joint limits (``inf`` where unlimited).
        has_limits: whether any controlled joint is limited.
    """

    path: Path
    handle_site: str
    site_id: int
    joint_ids: tuple[int, ...]
    joint_names: tuple[str, ...]
    dofs: NDArray[np.intp]
    qadr: NDArray[np.intp]
    act_ids: NDArray[np.intp]
    actuator_names: tuple[str, ...]
    home_key: int | None
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    has_limits: bool

    @property
    def n_joints(self) -> int:
        """Number of controlled joints."""
        return len(self.joint_ids)

    @classmethod
    def resolve(
        cls,
        model: mujoco.MjModel,
        path: Path,
        handle_site: str,
        joints: Sequence[str] | None,
        actuators: Sequence[str] | None,
        home_keyframe: str | None,
    ) -> ArmHandles:
        """Resolve the names of :class:`~langenv.robot.Arm`'s arguments in ``model``.

        Args:
            model: the loaded model.
            path: its MJCF file (named in error messages).
            handle_site: name of the handle site.
            joints: names of the controlled joints, or ``None`` for every 1-dof joint on the
                chain from the world to the handle site, base first.
            actuators: names of their velocity actuators (same order), or ``None`` to find the
                actuator whose transmission is each joint.
            home_keyframe: name of the home keyframe, or ``None``.

        Returns:
            The resolved handles.

        Raises:
            ConfigError: a missing site, joint, actuator or keyframe, a joint that is not a hinge
                or slide, duplicate joints, or an actuator that is not a velocity servo.
        """
        site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, handle_site)
        if site_id < 0:
            raise ConfigError(f"handle_site {handle_site!r} not found in {path}")
        joint_ids = (
            _chain_joints(model, path, site_id, handle_site)
            if joints is None
            else _named_joints(model, path, joints)
        )
        act_ids = _find_actuators(model, path, joint_ids, actuators)
        _check_velocity_servos(model, path, act_ids)
        home_key: int | None = None
        if home_keyframe is not None:
            home_key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, home_keyframe)
            if home_key < 0:
                raise ConfigError(f"home_keyframe {home_keyframe!r} not found in {path}")
        limited = model.jnt_limited[joint_ids].astype(bool)
        return cls(
            path=path,
            handle_site=handle_site,
            site_id=site_id,
            joint_ids=tuple(joint_ids),
            joint_names=tuple(model.joint(j).name for j in joint_ids),
            dofs=model.jnt_dofadr[joint_ids].astype(np.intp),
            qadr=model.jnt_qposadr[joint_ids].astype(np.intp),
            act_ids=np.asarray(act_ids, dtype=np.intp),
            actuator_names=tuple(model.actuator(a).name for a in act_ids),
            home_key=home_key,
            lower=np.where(limited, model.jnt_range[joint_ids, 0], -np.inf),
            upper=np.where(limited, model.jnt_range[joint_ids, 1], np.inf),
            has_limits=bool(np.any(limited)),
        )


def _chain_joints(m: mujoco.MjModel, path: Path, site_id: int, handle_site: str) -> list[int]:
    """Every hinge/slide joint on the kinematic chain from the world to the site, base first."""
    chain: list[int] = []
    body = int(m.site_bodyid[site_id])
    while body > 0:
        adr, num = int(m.body_jntadr[body]), int(m.body_jntnum[body])
        body_joints = [j for j in range(adr, adr + num) if m.jnt_type[j] in _ONE_DOF]
        chain = body_joints + chain
        body = int(m.body_parentid[body])
    if not chain:
        raise ConfigError(
            f"no hinge/slide joint on the chain to handle_site {handle_site!r} in {path}"
        )
    return chain


def _named_joints(m: mujoco.MjModel, path: Path, joints: Sequence[str]) -> list[int]:
    """Ids of the named hinge/slide joints, in the given order."""
    if isinstance(joints, str) or len(joints) == 0:
        raise ConfigError(f"joints must be a non-empty sequence of names, got {joints!r}")
    ids: list[int] = []
    for name in joints:
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0:
            raise ConfigError(f"joint {name!r} not found in {path}")
        if m.jnt_type[j] not in _ONE_DOF:
            raise ConfigError(f"joint {name!r} in {path} must be a hinge or slide joint")
        ids.append(j)
    if len(set(ids)) != len(ids):
        raise ConfigError(f"joints has duplicates: {list(joints)!r}")
    return ids


def _find_actuators(
    m: mujoco.MjModel, path: Path, joint_ids: list[int], actuators: Sequence[str] | None
) -> list[int]:
    """Actuator ids driving ``joint_ids`` (same order), by name or by transmission."""
    is_joint_trn = m.actuator_trntype == int(mujoco.mjtTrn.mjTRN_JOINT)
    ids: list[int] = []
    if actuators is None:
        for j in joint_ids:
            found = np.flatnonzero(is_joint_trn & (m.actuator_trnid[:, 0] == j))
            if found.size == 0:
                raise ConfigError(f"no actuator drives joint {m.joint(j).name!r} in {path}")
            ids.append(int(found[0]))
        return ids
    if isinstance(actuators, str) or len(actuators) != len(joint_ids):
        raise ConfigError(
            f"actuators must name one actuator per joint ({len(joint_ids)}), got {actuators!r}"
        )
    for name, j in zip(actuators, joint_ids, strict=True):
        a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if a < 0:
            raise ConfigError(f"actuator {name!r} not found in {path}")
        if not is_joint_trn[a] or m.actuator_trnid[a, 0] != j:
            raise ConfigError(
                f"actuator {name!r} in {path} does not drive joint {m.joint(j).name!r}"
            )
        ids.append(a)
    return ids


def _check_velocity_servos(m: mujoco.MjModel, path: Path, act_ids: list[int]) -> None:
    """Raise unless every actuator is a ``<velocity>`` servo (``force = kv (ctrl - qdot)``)."""
    for a in act_ids:
        kv = float(m.actuator_gainprm[a, 0])
        is_velocity = (
            m.actuator_gaintype[a] == int(mujoco.mjtGain.mjGAIN_FIXED)
            and m.actuator_biastype[a] == int(mujoco.mjtBias.mjBIAS_AFFINE)
            and kv > 0.0
            and m.actuator_biasprm[a, 0] == 0.0
            and m.actuator_biasprm[a, 1] == 0.0
            and math.isclose(float(m.actuator_biasprm[a, 2]), -kv)
            and m.actuator_gear[a, 0] == 1.0
        )
        if not is_velocity:
            raise ConfigError(
                f"actuator {m.actuator(a).name!r} in {path} must be a velocity actuator "
                "(<velocity joint=... kv=...>, gear 1)"
            )
