"""Train the learned aligner: Stable-Baselines3 PPO on ``LangCtrl-v0``.

Run::

    python -m train.ppo --config configs/ppo.yaml                       # the shipped model
    python -m train.ppo --config configs/ppo.yaml --total-timesteps 4000 --out /tmp/ppo_smoke
    python -m train.ppo --config configs/ppo.yaml --out runs/ppo --resume  # after an interruption
    python -m train.ppo --config CONFIG --init-from runs/ppo/NAME.zip  # fine-tune a model

The YAML is keyed like rl-baselines3-zoo's (top-level key ``LangCtrl-v0`` with ``n_envs``,
``n_timesteps``, ``policy``, ``normalize``, ``env_wrapper``, ``env_kwargs``, ``policy_kwargs`` and
PPO's own arguments), so ``python -m rl_zoo3.train --algo ppo --gym-packages langenv --env
LangCtrl-v0 --conf-file configs/ppo.yaml`` trains the same model; an optional top-level ``train``
section sets defaults of :class:`TrainArgs` (seeds, evaluation, checkpoints), which the command
line overrides.

What a run writes into ``--out``:

* ``NAME.zip``, ``NAME_vecnormalize.pkl``, ``NAME_config.yaml``: the final model, its
  observation/reward normalisation and the run's full config (what ``PPOPolicy.load`` reads);
* ``best/NAME.*``: the same three files for the best periodic evaluation;
* ``checkpoints/NAME_<steps>_steps.zip`` and ``NAME_vecnormalize_<steps>_steps.pkl``: what
  ``--resume`` continues from (also written when the run is interrupted with Ctrl-C);
* ``eval/evaluations.npz``: periodic evaluation results; ``tb/``: TensorBoard logs.

Seeds: training envs are seeded ``seed + i`` (``seed >= 1_000_000`` by default, far from the
evaluation users of ``python -m eval.compare --seed 0``, which are 0..N-1); periodic evaluation
meets the same held-out users ``eval_seed .. eval_seed + n_eval_episodes - 1`` every time
(``900_000`` onwards by default). No replayed session is ever used for training.
"""

from __future__ import annotations

import argparse
import copy
import importlib
import math
import re
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    CheckpointCallback,
    EvalCallback,
)
from stable_baselines3.common.vec_env import VecNormalize

from langenv.errors import ConfigError

__all__ = [
    "TrainArgs",
    "checkpoint_files",
    "init_files",
    "load_config",
    "main",
    "parse_args",
    "train",
]

#: Keys of a zoo-style section that are not PPO constructor arguments.
_ZOO_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_wrapper", "env_kwargs")
_UNSUPPORTED = ("frame_stack", "callback", "vec_env_wrapper", "normalize_kwargs")


@dataclass(frozen=True)
class TrainArgs:
    """Arguments of ``python -m train.ppo`` (defaults; the YAML's ``train`` section overrides them,
    the command line overrides both).

    Attributes:
        config: Zoo-style YAML with the hyperparameters (top-level key ``env_id``).
        env_id: Gymnasium id of the env (and the YAML's key).
        out: Output directory.
        name: File stem of the saved model (``NAME.zip``, ...).
        total_timesteps: Training budget (env steps, all envs together); ``None``: the YAML's
            ``n_timesteps``.
        seed: Seed of the first training env (env ``i`` gets ``seed + i``) and of PPO; >= 1e6 so
            that no training user is an evaluation user.
        eval_seed: Seed of the first held-out periodic-evaluation user.
        n_eval_episodes: Held-out users per periodic evaluation (0 disables it).
        eval_freq: Env steps (all envs together) between periodic evaluations.
        checkpoint_freq: Env steps between checkpoints.
        n_envs: Parallel training envs; ``None``: the YAML's ``n_envs``.
        vec_env: ``"subproc"`` (one process per env) or ``"dummy"`` (in this process).
        resume: Continue from the latest checkpoint in ``out/checkpoints``.
        init_from: Fine-tune: start from this saved model's network weights and normalisation
            statistics instead of random weights (a model zip written by this script or by
            ``train.export``, with its ``_vecnormalize.pkl``; or a checkpoint
            ``NAME_<steps>_steps.zip`` with its ``NAME_vecnormalize_<steps>_steps.pkl``). The
            config's hyperparameters, wrappers and seeds apply; the optimiser starts afresh. Its
            observation and action spaces must equal the new env's. Ignored by ``resume``, which
            continues the fine-tuning run itself.
        progress_bar: Show SB3's progress bar (tqdm + rich).
        tensorboard: Write TensorBoard logs to ``out/tb``.
        device: Torch device for PPO (``"cpu"`` suits this small MLP).
        torch_threads: Torch threads of the learner process.
        verbose: SB3 verbosity (0, 1, 2).
    """

    config: Path = Path("configs/ppo.yaml")
    env_id: str = "LangCtrl-v0"
    out: Path = Path("runs/ppo")
    name: str = "ppo_langctrl"
    total_timesteps: int | None = None
    seed: int = 1_000_000
    eval_seed: int = 900_000
    n_eval_episodes: int = 8
    eval_freq: int = 50_000
    checkpoint_freq: int = 50_000
    n_envs: int | None = None
    vec_env: str = "subproc"
    resume: bool = False
    init_from: Path | None = None
    progress_bar: bool = True
    tensorboard: bool = True
    device: str = "cpu"
    torch_threads: int = 1
    verbose: int = 0

    def __post_init__(self) -> None:
        for name in ("eval_freq", "checkpoint_freq", "torch_threads"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"TrainArgs.{name} must be >= 1, got {getattr(self, name)!r}")
        for name in ("total_timesteps", "n_envs"):
            value = getattr(self, name)
            if value is not None and int(value) < 1:
                raise ConfigError(f"TrainArgs.{name} must be >= 1, got {value!r}")
        if self.n_eval_episodes < 0:
            raise ConfigError(f"TrainArgs.n_eval_episodes must be >= 0, got {self.n_eval_episodes}")
        if self.seed < 0 or self.eval_seed < 0:
            raise ConfigError("TrainArgs.seed and eval_seed must be >= 0")
        if self.vec_env not in ("subproc", "dummy"):
            raise ConfigError(
                f"TrainArgs.vec_env must be 'subproc' or 'dummy', got {self.vec_env!r}"
            )
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", self.name):
            raise ConfigError(f"TrainArgs.name must be a plain file stem, got {self.name!r}")


def parse_args(argv: Sequence[str] | None = None) -> tuple[TrainArgs, set[str]]:
    """Parse the command line; returns the arguments and the names given explicitly."""
    p = argparse.ArgumentParser(
        prog="python -m train.ppo", description="Train the learned aligner (SB3 PPO)."
    )
    p.add_argument("--config", type=Path, default=TrainArgs.config)
    p.add_argument("--env-id", default=None)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--name", default=None)
    p.add_argument("--total-timesteps", type=int, default=None)
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--eval-seed", type=int, default=None)
    p.add_argument("--n-eval-episodes", type=int, default=None)
    p.add_argument("--eval-freq", type=int, default=None)
    p.add_argument("--checkpoint-freq", type=int, default=None)
    p.add_argument("--n-envs", type=int, default=None)
    p.add_argument("--vec-env", choices=("subproc", "dummy"), default=None)
    p.add_argument("--resume", action="store_true", default=None)
    p.add_argument("--init-from", type=Path, default=None)
    p.add_argument("--no-progress-bar", dest="progress_bar", action="store_false", default=None)
    p.add_argument("--no-tensorboard", dest="tensorboard", action="store_false", default=None)
    p.add_argument("--device", default=None)
    p.add_argument("--torch-threads", type=int, default=None)
    p.add_argument("--verbose", type=int, default=None)
    ns = vars(p.parse_args(argv))
    given = {k for k, v in ns.items() if v is not None and k != "config"}
    kwargs = {k: v for k, v in ns.items() if v is not None}
    try:
        return TrainArgs(**kwargs), given
    except ConfigError as exc:
        p.error(str(exc))
        raise  # unreachable


def load_config(path: Path, env_id: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read a zoo-style YAML: ``(hyperparams of env_id, train section)``.

    Raises:
        FileNotFoundError: if the file does not exist.
        ConfigError: naming the file, if it is not valid YAML, lacks ``env_id`` or uses a zoo
            key this script does not support.
    """
    if not path.is_file():
        raise FileNotFoundError(f"config file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get(env_id), dict):
        raise ConfigError(f"{path}: needs a top-level mapping {env_id!r} of hyperparameters")
    hyper = copy.deepcopy(data[env_id])
    bad = [k for k in _UNSUPPORTED if k in hyper]
    if bad:
        raise ConfigError(f"{path}: {env_id}: unsupported key(s) {', '.join(bad)}")
    section = data.get("train") or {}
    if not isinstance(section, dict):
        raise ConfigError(f"{path}: 'train' must be a mapping")
    known = {f.name for f in fields(TrainArgs)}
    unknown = sorted(set(section) - known)
    if unknown:
        raise ConfigError(f"{path}: train: unknown key(s) {', '.join(unknown)}")
    return hyper, section


def _normalize_kwargs(value: Any, path: Path) -> dict[str, Any] | None:
    """Zoo's ``normalize``: bool, dict, or a dict literal string."""
    import ast

    if value is None or value is False:
        return None
    if value is True:
        return {}
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            raise ConfigError(
                f"{path}: normalize must be a bool or a dict, got {value!r}"
            ) from None
    if not isinstance(value, dict):
        raise ConfigError(f"{path}: normalize must be a bool or a dict, got {value!r}")
    return dict(value)


def _policy_kwargs(value: Any, path: Path) -> dict[str, Any]:
    """Zoo's ``policy_kwargs``: a dict, or a string such as ``dict(net_arch=[64], ...)``.

    Strings are evaluated with nothing but ``dict`` and ``torch.nn`` in scope (as zoo does).
    """
    if value is None:
        return {}
    if isinstance(value, dict):
        return dict(value)
    if isinstance(value, str):
        from torch import nn

        try:
            out = eval(value, {"__builtins__": {}}, {"dict": dict, "nn": nn})
        except Exception as exc:
            raise ConfigError(f"{path}: policy_kwargs {value!r}: {exc}") from None
        if isinstance(out, dict):
            return out
    raise ConfigError(f"{path}: policy_kwargs must be a dict, got {value!r}")


def _schedule(value: Any) -> Any:
    """Zoo's ``lin_X`` schedules -> a linear schedule from X to 0; numbers unchanged."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])
        return lambda progress_remaining: progress_remaining * start
    if isinstance(value, str):
        return float(value)
    return value


def _wrapper_class(spec: Any, path: Path) -> _WrapperChain | None:
    """Zoo's ``env_wrapper``: a dotted class name, a ``{name: kwargs}`` mapping, or a list."""
    if spec is None:
        return None
    items = spec if isinstance(spec, list) else [spec]
    chain: list[tuple[Any, dict[str, Any]]] = []
    for item in items:
        kwargs: dict[str, Any] = {}
        if isinstance(item, str):
            name = item
        elif isinstance(item, dict) and len(item) == 1:
            name, kwargs = next(iter(item.items()))
            kwargs = dict(kwargs or {})
        else:
            raise ConfigError(
                f"{path}: env_wrapper entry {item!r} must be a name or {{name: kwargs}}"
            )
        module, _, cls = str(name).rpartition(".")
        try:
            klass = getattr(importlib.import_module(module), cls)
        except (ImportError, AttributeError, ValueError):
            raise ConfigError(f"{path}: env_wrapper {name!r} cannot be imported") from None
        chain.append((klass, kwargs))
    return _WrapperChain(chain)


@dataclass(frozen=True)
class _WrapperChain:
    """Picklable callable applying wrappers innermost first (for SubprocVecEnv)."""

    chain: list[tuple[Any, dict[str, Any]]]
    extra: tuple[tuple[Any, dict[str, Any]], ...] = ()

    def __call__(self, env: Any) -> Any:
        for klass, kwargs in (*self.chain, *self.extra):
            env = klass(env, **kwargs)
        return env


@dataclass
class _Run:
    """Everything a run needs, resolved from the YAML and the arguments."""

    args: TrainArgs
    hyper: dict[str, Any]
    env_kwargs: dict[str, Any]
    wrapper: _WrapperChain | None
    normalize: dict[str, Any] | None
    n_envs: int
    total: int


def _resolve(args: TrainArgs, given: set[str] | None = None) -> _Run:
    hyper, section = load_config(args.config, args.env_id)
    given = given if given is not None else set()
    defaults = {k: v for k, v in section.items() if k not in given}
    for key in ("out", "init_from"):
        if defaults.get(key) is not None:
            defaults[key] = Path(defaults[key])
    args = replace(args, **defaults) if defaults else args
    n_envs = int(args.n_envs or hyper.get("n_envs", 1))
    total = int(args.total_timesteps or float(hyper.get("n_timesteps", 100_000)))
    env_kwargs = dict(hyper.get("env_kwargs") or {})
    wrapper = _wrapper_class(hyper.get("env_wrapper"), args.config)
    normalize = _normalize_kwargs(hyper.get("normalize"), args.config)
    return _Run(args, hyper, env_kwargs, wrapper, normalize, n_envs, total)


def _ppo_kwargs(run: _Run) -> dict[str, Any]:
    kw = {k: v for k, v in run.hyper.items() if k not in _ZOO_KEYS}
    kw["policy_kwargs"] = _policy_kwargs(kw.get("policy_kwargs"), run.args.config)
    for key in ("learning_rate", "clip_range"):
        if key in kw:
            kw[key] = _schedule(kw[key])
    return kw


def _make_envs(run: _Run) -> tuple[Any, Any]:
    """Training VecEnv (normalised) and evaluation VecEnv (normalisation in eval mode)."""
    import gymnasium as gym
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    import langenv  # noqa: F401  (registers the env)
    from train.wrappers import SeedCycle

    a = run.args
    cls = SubprocVecEnv if (a.vec_env == "subproc" and run.n_envs > 1) else DummyVecEnv
    env = make_vec_env(
        a.env_id,
        n_envs=run.n_envs,
        seed=a.seed,
        vec_env_cls=cls,
        env_kwargs=run.env_kwargs,
        wrapper_class=run.wrapper,
    )
    if run.normalize is not None:
        env = VecNormalize(env, **run.normalize)
    eval_env: Any = None
    if a.n_eval_episodes > 0:
        seeds = [a.eval_seed + i for i in range(a.n_eval_episodes)]
        chain = run.wrapper.chain if run.wrapper is not None else []
        eval_wrapper = _WrapperChain(chain, ((SeedCycle, {"seeds": seeds}),))

        def make_eval_env() -> gym.Env[Any, Any]:
            return eval_wrapper(Monitor(gym.make(a.env_id, **run.env_kwargs)))

        # Not make_vec_env: it seeds the first reset at random even with seed=None, which would
        # override SeedCycle and make the first evaluation episode a random user. A bare
        # DummyVecEnv passes seed=None, so SeedCycle picks eval_seed, eval_seed + 1, ...
        eval_env = DummyVecEnv([make_eval_env])
        if run.normalize is not None:
            kw = {k: v for k, v in run.normalize.items() if k != "norm_reward"}
            eval_env = VecNormalize(eval_env, training=False, norm_reward=False, **kw)
    return env, eval_env


def _residual_section(env: Any) -> dict[str, Any]:
    """The ResidualSpec of the training env's wrapper, if any (for ``PPOPolicy``)."""
    spec = env.get_attr("residual_spec")[0] if _has_attr(env, "residual_spec") else None
    return asdict(spec) if spec is not None else {}


def _has_attr(env: Any, name: str) -> bool:
    try:
        env.get_attr(name, indices=[0])
    except AttributeError:
        return False
    return True


def _config_dict(run: _Run, residual: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    import stable_baselines3

    import langenv
    from policies.learned import graph_digest

    args = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(run.args).items()}
    graph = str(run.env_kwargs.get("phrase_graph", "lc"))
    return {
        run.args.env_id: _plain(run.hyper),
        "train": args,
        "env_kwargs": _plain(run.env_kwargs),
        "residual": residual,
        "phrase_graph_sha256": graph_digest(graph),
        "n_envs": run.n_envs,
        "total_timesteps": run.total,
        "versions": {
            "langctrl": langenv.__version__,
            "stable_baselines3": stable_baselines3.__version__,
            "python": sys.version.split()[0],
        },
        **extra,
    }


def _plain(obj: Any) -> Any:
    """A YAML-safe copy (tuples -> lists, paths -> str)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _save_triple(model: Any, env: Any, stem: Path, config: dict[str, Any]) -> None:
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


def _init_from(model: Any, env: Any, path: Path) -> str:
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


def train(args: TrainArgs, given: set[str] | None = None) -> Path:
    """Train (or resume) a run; returns the final model zip.

    Raises:
        FileNotFoundError: for a missing config, or ``resume`` without a checkpoint.
        ConfigError: for an invalid config.
    """
    import torch

    run = _resolve(args, given)
    a = run.args
    torch.set_num_threads(a.torch_threads)
    out = a.out
    out.mkdir(parents=True, exist_ok=True)
    ckpt_dir, eval_dir, best_dir = out / "checkpoints", out / "eval", out / "best"
    if a.init_from is not None and not a.resume:
        init_files(a.init_from)  # a missing file fails before any env starts
    env, eval_env = _make_envs(run)
    config = _config_dict(run, _residual_section(env), {})
    tb = str(out / "tb") if a.tensorboard else None

    if a.resume:
        found = _latest_checkpoint(ckpt_dir, a.name)
        if found is None:
            raise FileNotFoundError(f"--resume: no checkpoint {a.name}_*_steps.zip in {ckpt_dir}")
        zip_path, pkl, _steps = found
        if isinstance(env, VecNormalize):
            env = VecNormalize.load(str(pkl), env.venv)
        model = PPO.load(zip_path, env=env, device=a.device, tensorboard_log=tb)
        print(f"resuming from {zip_path} at {model.num_timesteps} steps", file=sys.stderr)
    else:
        model = PPO(
            run.hyper.get("policy", "MlpPolicy"),
            env,
            seed=a.seed,
            device=a.device,
            tensorboard_log=tb,
            verbose=a.verbose,
            **_ppo_kwargs(run),
        )
        if a.init_from is not None:
            config["init_from_sha256"] = _init_from(model, env, a.init_from)
            print(f"starting from the weights of {a.init_from}", file=sys.stderr)
    # written once the model is set up, so that a failed start leaves an earlier run's file alone
    (out / "run_config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))

    class _SaveBest(BaseCallback):
        def _on_step(self) -> bool:
            _save_triple(self.model, None, best_dir / a.name, config)
            return True

    callbacks: list[Any] = [
        CheckpointCallback(
            save_freq=max(1, a.checkpoint_freq // run.n_envs),
            save_path=str(ckpt_dir),
            name_prefix=a.name,
            save_vecnormalize=True,
        )
    ]
    if eval_env is not None:
        callbacks.append(
            _MetricsEvalCallback(
                eval_env,
                n_eval_episodes=a.n_eval_episodes,
                eval_freq=max(1, a.eval_freq // run.n_envs),
                log_path=str(eval_dir),
                deterministic=True,
                callback_on_new_best=_SaveBest(),
            )
        )
    remaining = max(0, run.total - int(model.num_timesteps))
    t0 = time.perf_counter()
    try:
        model.learn(
            total_timesteps=remaining,
            callback=CallbackList(callbacks),
            progress_bar=a.progress_bar,
            reset_num_timesteps=not a.resume,
            tb_log_name="ppo",
        )
    except KeyboardInterrupt:
        zip_path, pkl = checkpoint_files(ckpt_dir, a.name, int(model.num_timesteps))
        model.save(zip_path)
        vn = model.get_vec_normalize_env()
        if vn is not None:
            vn.save(str(pkl))
        print(
            f"interrupted at {model.num_timesteps} steps; continue with --resume", file=sys.stderr
        )
        raise
    finally:
        env.close()
        if eval_env is not None:
            eval_env.close()
    wall = time.perf_counter() - t0
    config["wall_time_s"] = round(wall, 1)
    final = out / a.name
    _save_triple(model, None, final, config)
    print(f"wrote {final}.zip ({model.num_timesteps} steps, {wall:.0f} s)", file=sys.stderr)
    return final.with_suffix(".zip")


class _MetricsEvalCallback(EvalCallback):
    """EvalCallback that also logs the held-out users' mean ``|AM|`` and mean ``|EM|``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._am: list[float] = []
        self._em: list[float] = []
        self._em_steps: list[float] = []

    def _on_step(self) -> bool:
        self._am, self._em, self._em_steps = [], [], []
        ok = bool(super()._on_step())
        if self._am:
            am, em = float(np.nanmean(self._am)), float(np.mean(self._em))
            self.logger.record("eval/abs_am", am)
            self.logger.record("eval/abs_am_median", float(np.nanmedian(self._am)))
            self.logger.record("eval/em_mean_abs", em)
            print(
                f"[eval @ {self.num_timesteps} steps] held-out users: mean |AM| {am:.3f} s, "
                f"median |AM| {np.nanmedian(self._am):.3f} s, mean |EM| {em:.3f} s, "
                f"return {self.last_mean_reward:.2f}",
                file=sys.stderr,
            )
        return ok

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        info = locals_["info"]
        self._em_steps.append(abs(float(info.get("em", 0.0))))
        if locals_["done"]:
            am = info.get("am")
            self._am.append(abs(float(am)) if am is not None else math.nan)
            self._em.append(float(np.mean(self._em_steps)))
            self._em_steps = []


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args, given = parse_args(argv)
    try:
        path = train(args, given)
    except (FileNotFoundError, ConfigError) as exc:
        print(f"train.ppo: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    print(path)
    return 0


if __name__ == "__main__":
    shutil.get_terminal_size()  # rich's progress bar reads it; fail early on odd terminals
    raise SystemExit(main())
