"""Where a training run starts from and what it leaves to continue from.

rl-zoo3's ``--trained-agent`` and checkpoints, as this project's runs keep them: the model files
of a run (:func:`save_triple`), SB3's periodic checkpoints (:func:`checkpoint_files`), the
*resume point* written atomically after every update (:func:`save_resume_point`,
:func:`resume_files`) and what ``--resume`` continues with (:func:`resume_source`,
:func:`resolve_resume`: the run's saved settings, with the overrides allowed), and the weights a
fine-tune starts from (``--init-from``: :func:`init_files`, :func:`init_from_model`).
"""

from __future__ import annotations

import re
import shutil
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecNormalize

from langenv.errors import ConfigError
from langenv.files import temp_dir
from train.config import (
    SB3_N_STEPS,
    Run,
    TrainArgs,
    load_worlds,
    normalize_kwargs,
    resolve,
    whole_rollouts,
    wrapper_chain,
)

__all__ = [
    "check_fresh_out",
    "checkpoint_files",
    "init_files",
    "init_from_model",
    "resolve_resume",
    "resume_files",
    "resume_source",
    "save_resume_point",
    "save_triple",
]


def save_triple(model: Any, env: Any, stem: Path, config: dict[str, Any]) -> None:
    """``STEM.zip``, ``STEM_vecnormalize.pkl``, ``STEM_config.yaml``."""
    from policies.learned import model_files

    zip_path, norm_path, cfg_path = model_files(stem)
    zip_path.parent.mkdir(parents=True, exist_ok=True)
    model.save(zip_path)
    vn = model.get_vec_normalize_env() if env is None else env
    if vn is not None and hasattr(vn, "obs_rms"):
        vn.save(norm_path)
    cfg = dict(config, num_timesteps=int(model.num_timesteps))
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))


def checkpoint_files(ckpt_dir: Path, name: str, steps: int) -> tuple[Path, Path]:
    """A checkpoint's model zip and VecNormalize pickle, as SB3's ``CheckpointCallback`` names
    them (``NAME_<steps>_steps.zip``, ``NAME_vecnormalize_<steps>_steps.pkl``)."""
    return (
        ckpt_dir / f"{name}_{steps}_steps.zip",
        ckpt_dir / f"{name}_vecnormalize_{steps}_steps.pkl",
    )


def init_files(path: Path) -> tuple[Path, Path]:
    """The model zip and normalisation pickle that ``--init-from PATH`` reads.

    ``PATH`` is a model (``NAME.zip`` or its stem; pickle ``NAME_vecnormalize.pkl``) or a
    checkpoint ``NAME_<steps>_steps.zip`` (pickle ``NAME_vecnormalize_<steps>_steps.pkl``). The
    pickle need not exist (a run without normalisation).

    Raises:
        FileNotFoundError: naming the model zip, if it does not exist.
    """
    from policies.learned import model_files

    zip_path, pkl, _cfg = model_files(path)
    m = re.fullmatch(r"(.+)_(\d+)_steps\.zip", zip_path.name)
    if m and not pkl.is_file():
        pkl = checkpoint_files(zip_path.parent, m.group(1), int(m.group(2)))[1]
    if not zip_path.is_file():
        raise FileNotFoundError(f"--init-from: model not found: {zip_path}")
    return zip_path, pkl


def init_from_model(model: Any, env: Any, path: Path) -> str:
    """Copy a saved model's network weights (and normalisation statistics) into ``model``;
    returns the source zip's SHA-256.

    Raises:
        FileNotFoundError: for a missing model zip, or a missing pickle when ``env`` normalises.
        ConfigError: naming the file, if it is unreadable, or its spaces, network or
            normalisation do not fit.
    """
    import pickle

    from policies.learned import file_sha256

    zip_path, pkl = init_files(path)
    try:
        src = PPO.load(zip_path, device="cpu")
    except Exception as exc:  # a corrupt zip fails in zipfile, json, torch or pickle
        raise ConfigError(f"--init-from {zip_path}: not a readable SB3 PPO model: {exc}") from None
    for what in ("observation_space", "action_space"):
        old, new = getattr(src, what).shape, getattr(model, what).shape
        if old != new:
            raise ConfigError(
                f"--init-from {zip_path}: its {what} has shape {old}, the config's env {new}"
            )
    try:
        model.policy.load_state_dict(src.policy.state_dict())
    except RuntimeError as exc:
        first = str(exc).splitlines()[0]
        raise ConfigError(
            f"--init-from {zip_path}: its network does not fit the config's policy: {first}"
        ) from None
    if isinstance(env, VecNormalize):
        if not pkl.is_file():
            raise FileNotFoundError(
                f"--init-from: {pkl} not found (the config normalises observations, so the "
                f"weights need the statistics they were trained with)"
            )
        try:
            with pkl.open("rb") as fh:
                stats = pickle.load(fh)
        except Exception as exc:
            raise ConfigError(f"--init-from {pkl}: not a readable VecNormalize: {exc}") from None
        if not isinstance(stats, VecNormalize):
            raise ConfigError(f"--init-from {pkl}: not a VecNormalize ({type(stats).__name__})")
        old_rms: Any = stats.obs_rms
        new_rms: Any = env.obs_rms
        if np.shape(old_rms.mean) != np.shape(new_rms.mean):
            raise ConfigError(f"--init-from {pkl}: statistics for another observation shape")
        env.obs_rms, env.ret_rms = stats.obs_rms, stats.ret_rms
    elif pkl.is_file():
        raise ConfigError(
            f"--init-from {zip_path}: it was trained with normalisation ({pkl.name}) but the "
            f"config has none (set 'normalize')"
        )
    return file_sha256(zip_path)


def resume_files(ckpt_dir: Path, name: str) -> tuple[Path, Path]:
    """The resume point's model zip and VecNormalize pickle (``checkpoints/resume/NAME.zip``,
    ``NAME_vecnormalize.pkl``)."""
    return ckpt_dir / "resume" / f"{name}.zip", ckpt_dir / "resume" / f"{name}_vecnormalize.pkl"


def save_resume_point(model: Any, ckpt_dir: Path, name: str) -> None:
    """Write the resume point: into a fresh directory, then swapped in by renames, so that an
    interruption leaves either the previous resume point or the new one, never a mix."""
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    final = ckpt_dir / "resume"
    old = ckpt_dir / ".resume.old"
    tmp = temp_dir(ckpt_dir, prefix=".resume.tmp-")
    try:
        model.save(tmp / f"{name}.zip")
        vn = model.get_vec_normalize_env()
        if vn is not None:
            vn.save(str(tmp / f"{name}_vecnormalize.pkl"))
        if old.exists():
            shutil.rmtree(old)
        if final.exists():
            final.rename(old)
        tmp.rename(final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(old, ignore_errors=True)


def _latest_checkpoint(ckpt_dir: Path, name: str) -> tuple[Path, Path, int] | None:
    best: tuple[Path, Path, int] | None = None
    for zip_path in ckpt_dir.glob(f"{name}_*_steps.zip"):
        m = re.fullmatch(rf"{re.escape(name)}_(\d+)_steps\.zip", zip_path.name)
        if not m:
            continue
        steps = int(m.group(1))
        pkl = checkpoint_files(ckpt_dir, name, steps)[1]
        if pkl.is_file() and (best is None or steps > best[2]):
            best = (zip_path, pkl, steps)
    return best


def resume_source(ckpt_dir: Path, name: str) -> tuple[Path, Path, bool]:
    """``(model zip, VecNormalize pickle, is a resume point)`` to continue from.

    The resume point (after the latest update) when there is one, also the one a crash left
    renamed aside; else, for runs made before resume points existed, the latest snapshot.

    Raises:
        FileNotFoundError: if there is neither.
    """
    for directory in (ckpt_dir / "resume", ckpt_dir / ".resume.old"):
        zip_path = directory / f"{name}.zip"
        if zip_path.is_file():
            return zip_path, directory / f"{name}_vecnormalize.pkl", True
    found = _latest_checkpoint(ckpt_dir, name)
    if found is None:
        raise FileNotFoundError(
            f"--resume: no checkpoint (resume/{name}.zip or {name}_*_steps.zip) in {ckpt_dir}"
        )
    return found[0], found[1], False


#: Arguments ``--resume`` takes anew: they change neither what is learned nor how it is evaluated.
_RESUME_OVERRIDES = frozenset(
    {
        "total_timesteps",
        "checkpoint_freq",
        "eval_freq",
        "vec_env",
        "progress_bar",
        "tensorboard",
        "device",
        "torch_threads",
        "verbose",
        "config",
        "out",
        "resume",
        "init_from",
    }
)


def resolve_resume(args: TrainArgs, given: set[str]) -> tuple[Run, dict[str, Any]]:
    """The interrupted run's settings (from its ``run_config.yaml``), with the overrides allowed.

    Returns:
        The run and its saved config.

    Raises:
        FileNotFoundError: no checkpoint, or no ``run_config.yaml`` in the run's directory.
        ConfigError: an explicit argument that differs from the run's saved setting (naming it).
    """
    out = args.out if "out" in given else resolve(args, given).args.out
    ckpt_dir = out / "checkpoints"
    resume_source(ckpt_dir, args.name if "name" in given else _saved_name(out, args))
    path = out / "run_config.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"--resume: {path} not found, so the run's settings are unknown")
    try:
        config = yaml.safe_load(path.read_text())
        saved = dict(config["train"])
        env_id = saved["env_id"]
        hyper = dict(config[env_id])
        n_envs, total = int(config["n_envs"]), int(config["total_timesteps"])
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"{path}: not a run config written by train.ppo ({exc!r})") from None
    known = {f.name for f in fields(TrainArgs)}
    kwargs = {k: v for k, v in saved.items() if k in known}
    for key in ("config", "out", "init_from"):
        if kwargs.get(key) is not None:
            kwargs[key] = Path(kwargs[key])
    for key in sorted(given - _RESUME_OVERRIDES):
        mine = getattr(args, key)
        if key == "n_eval_episodes" and mine == 0:
            continue
        if mine != kwargs.get(key):
            raise ConfigError(
                f"--resume continues the run in {out} with its saved settings, but --"
                f"{key.replace('_', '-')} {mine} differs from its {kwargs.get(key)!r} (start a "
                "new run in another --out to change it)"
            )
    kwargs.update({k: getattr(args, k) for k in given if k in known and k != "config"})
    kwargs.update(out=out, resume=True)
    merged = TrainArgs(**kwargs)
    asked = total
    if merged.total_timesteps is not None and "total_timesteps" in given:
        asked = merged.total_timesteps
        total = whole_rollouts(asked, int(hyper.get("n_steps", SB3_N_STEPS)) * n_envs)
    merged = replace(merged, total_timesteps=total)
    run = Run(
        merged,
        hyper,
        dict(hyper.get("env_kwargs") or {}),
        wrapper_chain(hyper.get("env_wrapper"), path),
        normalize_kwargs(hyper.get("normalize"), path),
        n_envs,
        total,
        load_worlds(config, path),
        asked,
    )
    return run, config


def _saved_name(out: Path, args: TrainArgs) -> str:
    """The run's model name from its ``run_config.yaml`` (``args.name`` when unreadable)."""
    try:
        name = yaml.safe_load((out / "run_config.yaml").read_text())["train"]["name"]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return args.name
    return str(name)


def check_fresh_out(out: Path) -> None:
    """Refuse a fresh run's ``--out`` that holds files or is not a directory.

    Raises:
        ConfigError: naming ``out``.
    """
    if out.is_dir() and any(out.iterdir()):
        raise ConfigError(
            f"--out {out} already holds files (an earlier run?); continue that run with "
            "--resume, or start this one in another --out"
        )
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")
