"""Train the learned aligner: Stable-Baselines3 PPO on ``LangCtrl-v0``.

Run::

    python -m train.ppo --config configs/ppo.yaml                       # the shipped model
    python -m train.ppo --config configs/ppo.yaml --total-timesteps 4000 --out runs/ppo_smoke
    python -m train.ppo --config configs/ppo.yaml --out runs/ppo --resume  # after an interruption
    python -m train.ppo --config CONFIG --init-from runs/ppo/NAME.zip  # fine-tune a model

The YAML is keyed like rl-baselines3-zoo's (top-level key ``LangCtrl-v0`` with ``n_envs``,
``n_timesteps``, ``policy``, ``normalize``, ``env_wrapper``, ``env_kwargs``, ``policy_kwargs`` and
PPO's own arguments), so ``python -m rl_zoo3.train --algo ppo --gym-packages langenv --env
LangCtrl-v0 --conf-file configs/ppo.yaml`` trains the same model; an optional top-level ``train``
section sets defaults of :class:`TrainArgs` (seeds, evaluation, checkpoints), which the command
line overrides. A config may ``inherit: OTHER.yaml`` and set only what differs (see
:func:`load_config`; a train.ppo extension that rl-zoo3 does not read).

What a run writes into ``--out``:

* ``NAME.zip``, ``NAME_vecnormalize.pkl``, ``NAME_config.yaml``: the final model, its
  observation/reward normalisation and the run's full config (what ``PPOPolicy.load`` reads);
* ``best_return/NAME.*``: the same three files at the periodic evaluation with the highest mean
  return (SB3's rule; its config records it, ``eval_mean_reward``). The model a run is meant
  to give is chosen by ``train.export --best`` (its own rule), not this one;
* ``checkpoints/NAME_<steps>_steps.zip`` and ``NAME_vecnormalize_<steps>_steps.pkl``: snapshots
  every ``checkpoint_freq`` steps (what ``train.export`` reads), taken at that step, i.e. with the
  weights of the last update before it;
* ``checkpoints/resume/NAME.zip`` and ``NAME_vecnormalize.pkl``: the *resume point*, the state
  right after the latest update (saved, atomically, at the start of every rollout and at the end);
* ``run_config.yaml``: the run's full settings; ``eval/evaluations.npz``: periodic evaluation
  results; ``tb/``: TensorBoard logs.

A fresh run refuses an ``--out`` that already holds files. ``--resume`` continues the run in
``--out`` from its resume point with the settings and budget of its ``run_config.yaml`` (only
``--total-timesteps`` and settings that do not change what is learned, such as
``--checkpoint-freq`` or ``--no-progress-bar``, may be given anew; ``--n-eval-episodes 0`` turns
evaluation off): no update is lost, the step counters of the checkpoints and evaluations go on
where they were, the evaluation history and the best model carry over, and the random generators
are reseeded from ``seed`` and the step count, so a resumed run is reproducible. Ctrl-C stops a
run with one line (the resume point is already on disk) and exit status 130.

Exercises: ``env_kwargs.exercise`` is one exercise (a shipped name or a YAML path; default the
study's) or a list of them: training env ``i`` then guides exercise ``i mod k`` (give ``n_envs`` a
multiple of ``k``), and the periodic evaluation runs one env per exercise, the held-out users
spread over them. Every exercise is checked (``langctrl exercise check``) before
training starts; they must share the phrase graph (the observation's size depends on it).

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
import os
import re
import shutil
import signal
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
from stable_baselines3.common.vec_env import SubprocVecEnv, VecNormalize

from langenv.errors import ConfigError
from langenv.files import temp_dir
from langenv.validation import yaml_text

__all__ = [
    "TrainArgs",
    "build_parser",
    "checkpoint_files",
    "code_version",
    "init_files",
    "load_config",
    "main",
    "parse_args",
    "recorded_args",
    "recorded_path",
    "resume_files",
    "train",
]

#: The vector envs a run may step its envs in (``--vec-env``).
VEC_ENVS = ("auto", "batched", "subproc", "dummy")

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
            ``n_timesteps``. Rounded up to whole rollouts (``n_steps x n_envs``), which is what
            PPO trains; a line on stderr says so.
        seed: Seed of the first training env (env ``i`` gets ``seed + i``) and of PPO; >= 1e6 so
            that no training user is an evaluation user.
        eval_seed: Seed of the first held-out periodic-evaluation user.
        n_eval_episodes: Held-out users per periodic evaluation (0 disables it).
        eval_freq: Env steps (all envs together) between periodic evaluations.
        checkpoint_freq: Env steps between checkpoints.
        n_envs: Parallel training envs; ``None``: the YAML's ``n_envs``.
        vec_env: ``"batched"`` (every env a session of one batched env, stepped in one
            compiled call over the cores: :mod:`train.vec_env`), ``"subproc"`` (one process
            per env), ``"dummy"`` (in this process) or ``"auto"``: batched where it applies
            (no ``worlds``, only the wrappers it has a batched form of), else subprocesses only
            when there are more CPU cores than envs (the learner needs one too; on fewer, the
            processes' hand-offs cost more than the parallel env steps gain). Any of them: the
            same envs with the same seeds, the same run.
        resume: Continue the run in ``out`` from its resume point, with its saved settings.
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
    vec_env: str = "auto"
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
        if self.vec_env not in VEC_ENVS:
            raise ConfigError(
                f"TrainArgs.vec_env must be one of {', '.join(VEC_ENVS)}, got {self.vec_env!r}"
            )
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", self.name):
            raise ConfigError(f"TrainArgs.name must be a plain file stem, got {self.name!r}")


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl train`` (``python -m train.ppo``).

    Every option but ``--config`` defaults to None, so that :func:`parse_args` can tell which were
    given: the config's ``train`` section sets those not given, :class:`TrainArgs` the rest.
    """

    def default(name: str, shown: object = None) -> str:
        value = getattr(TrainArgs, name) if shown is None else shown
        return f"(default: the config's train.{name}, else {value})"

    p = argparse.ArgumentParser(
        prog="langctrl train",
        description="Train the learned aligner (SB3 PPO) from a zoo-style config; the config's "
        "'train' section sets these options, the command line overrides it. Also run as "
        "python -m train.ppo.",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=TrainArgs.config,
        metavar="YAML",
        help="zoo-style YAML of hyperparameters, keyed by the env id (default: %(default)s)",
    )
    p.add_argument(
        "--env-id", default=None, metavar="ID", help=f"Gymnasium env id {default('env_id')}"
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help=f"run directory; a fresh run refuses one that holds files {default('out')}",
    )
    p.add_argument(
        "--name", default=None, help=f"file stem of the saved model, NAME.zip {default('name')}"
    )
    p.add_argument(
        "--total-timesteps",
        type=int,
        default=None,
        metavar="STEPS",
        help="training budget, env steps of all envs together, rounded up to whole rollouts "
        f"(n_steps x n_envs) {default('total_timesteps', 'its n_timesteps')}",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seed of the first training env (env i: SEED + i) and of PPO; >= 1000000 keeps "
        f"training users apart from evaluation users {default('seed')}",
    )
    p.add_argument(
        "--eval-seed",
        type=int,
        default=None,
        metavar="SEED",
        help=f"seed of the first periodic-evaluation user {default('eval_seed')}",
    )
    p.add_argument(
        "--n-eval-episodes",
        type=int,
        default=None,
        metavar="N",
        help=f"users per periodic evaluation, 0: none {default('n_eval_episodes')}",
    )
    p.add_argument(
        "--eval-freq",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"env steps (all envs) between periodic evaluations {default('eval_freq')}",
    )
    p.add_argument(
        "--checkpoint-freq",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"env steps (all envs) between checkpoints {default('checkpoint_freq')}",
    )
    p.add_argument(
        "--n-envs",
        type=int,
        default=None,
        metavar="N",
        help=f"parallel training envs {default('n_envs', 'its n_envs')}",
    )
    p.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default=None,
        help="batched: every env a session of one batched env (one compiled call per step over "
        "the cores); subproc: one process per env; dummy: in this process; auto: batched where "
        "it applies (no worlds, batched wrappers), else subprocesses only with more CPU cores "
        f"than envs; the same run either way {default('vec_env')}",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        default=None,
        help="continue the run in --out from its resume point, with its saved settings",
    )
    p.add_argument(
        "--init-from",
        type=Path,
        default=None,
        metavar="ZIP",
        help="fine-tune: start from this model's weights and normalisation statistics "
        f"{default('init_from', 'random weights')}",
    )
    p.add_argument(
        "--no-progress-bar",
        dest="progress_bar",
        action="store_false",
        default=None,
        help="hide SB3's progress bar (shown unless the config's train.progress_bar is false)",
    )
    p.add_argument(
        "--no-tensorboard",
        dest="tensorboard",
        action="store_false",
        default=None,
        help="write no TensorBoard logs to OUT/tb (written unless the config's "
        "train.tensorboard is false)",
    )
    p.add_argument(
        "--device", default=None, help=f"torch device of the learner {default('device')}"
    )
    p.add_argument(
        "--torch-threads",
        type=int,
        default=None,
        metavar="N",
        help=f"torch threads of the learner process {default('torch_threads')}",
    )
    p.add_argument(
        "--verbose",
        type=int,
        default=None,
        metavar="{0,1,2}",
        help=f"SB3 verbosity, 0 (quiet) to 2 {default('verbose')}",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> tuple[TrainArgs, set[str]]:
    """Parse the command line; returns the arguments and the names given explicitly."""
    p = build_parser()
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

    A config may start from another one: a top-level ``inherit: OTHER.yaml`` (relative to the
    config's folder) reads ``OTHER.yaml`` first, and this file's mappings are merged into it key
    by key (a list or a value replaces the inherited one whole). rl-zoo3 does not read
    ``inherit``; a stage that only ``train.ppo`` runs (such as a fine-tune) may use it.

    Raises:
        FileNotFoundError: if the file (or one it inherits from) does not exist.
        ConfigError: naming the file, if it is not valid YAML, inherits in a cycle, lacks
            ``env_id`` or uses a zoo key this script does not support.
    """
    data = _read_config(path, ())
    if not isinstance(data.get(env_id), dict):
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


def _read_config(path: Path, seen: tuple[Path, ...]) -> dict[str, Any]:
    """One config file as a mapping, with what it inherits merged in (``inherit`` removed)."""
    if not path.is_file():
        raise FileNotFoundError(f"config file not found: {path}")
    if path.resolve() in seen:
        chain = " -> ".join(str(p) for p in (*seen, path.resolve()))
        raise ConfigError(f"{path}: 'inherit' forms a cycle: {chain}")
    try:
        data = yaml.safe_load(yaml_text(path.read_text(), path))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: must be a mapping (top-level keys: the env id, 'train')")
    parent = data.pop("inherit", None)
    if parent is None:
        return data
    if not isinstance(parent, str) or not parent:
        raise ConfigError(f"{path}: 'inherit' must name a config file, got {parent!r}")
    base = _read_config(path.parent / parent, (*seen, path.resolve()))
    return _merge(base, data)


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``over`` merged into a copy of ``base``: mappings key by key, anything else replaced."""
    out = copy.deepcopy(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


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

    @property
    def monitor_outside(self) -> bool:
        """Whether the Monitor goes outside these wrappers: a wrapper whose steps are not the
        env's (``train.choices.ChoicePoints``: one step per phrase choice) says so."""
        return any(getattr(klass, "monitor_outside", False) for klass, _ in self.chain)


def _monitored(env: Any, wrapper: Any) -> Any:
    """``env`` with a Monitor and ``wrapper``, the Monitor inside it unless it must be outside
    (:attr:`_WrapperChain.monitor_outside`), so that it counts the agent's steps."""
    from stable_baselines3.common.monitor import Monitor

    if wrapper is None:
        return Monitor(env)
    if getattr(wrapper, "monitor_outside", False):
        return Monitor(wrapper(env))
    return wrapper(Monitor(env))


@dataclass
class _Run:
    """Everything a run needs, resolved from the YAML and the arguments."""

    args: TrainArgs
    hyper: dict[str, Any]
    env_kwargs: dict[str, Any]
    wrapper: _WrapperChain | None
    normalize: dict[str, Any] | None
    n_envs: int
    total: int  # the budget asked for, rounded up to whole rollouts (what PPO trains)
    worlds: Any = None  # langenv.worlds.WorldSplit, from the config's ``worlds`` section
    asked: int = 0  # the budget asked for (--total-timesteps or the config's n_timesteps)

    @property
    def rollout(self) -> int:
        """Steps of one PPO rollout, all envs together (``n_steps x n_envs``)."""
        return int(self.hyper.get("n_steps", _SB3_N_STEPS)) * self.n_envs

    def budget_note(self) -> str | None:
        """A line saying that the budget was rounded up to whole rollouts, or None."""
        if self.asked in (0, self.total):
            return None
        n_steps = self.rollout // self.n_envs
        return (
            f"the budget of {self.asked:,} steps is rounded up to {self.total:,}: PPO trains "
            f"whole rollouts of {n_steps:,} steps x {self.n_envs} envs ({self.rollout:,} steps)"
        )


_SB3_N_STEPS = 2048  # PPO's n_steps when the config gives none
BEST_RETURN = "best_return"
"""The run's folder of the model at its highest mean evaluation return (SB3's best model)."""


def whole_rollouts(steps: int, rollout: int) -> int:
    """``steps`` rounded up to a whole number of rollouts of ``rollout`` steps (at least one)."""
    return max(1, math.ceil(steps / rollout)) * rollout


def load_worlds(data: dict[str, Any], path: Path) -> Any:
    """The :class:`~langenv.worlds.WorldSplit` of a config's (or a run config's) top-level
    ``worlds`` mapping, or None without one.

    Raises:
        ConfigError: naming the file, for a bad split.
    """
    section = data.get("worlds")
    if section is None:
        return None
    from langenv.worlds import WorldSplit

    try:
        return WorldSplit.from_dict(section)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def _resolve(args: TrainArgs, given: set[str] | None = None) -> _Run:
    hyper, section = load_config(args.config, args.env_id)
    given = given if given is not None else set()
    defaults = {k: v for k, v in section.items() if k not in given}
    for key in ("out", "init_from"):
        if defaults.get(key) is not None:
            defaults[key] = Path(defaults[key])
    args = replace(args, **defaults) if defaults else args
    n_envs = int(args.n_envs or hyper.get("n_envs", 1))
    asked = int(args.total_timesteps or float(hyper.get("n_timesteps", 100_000)))
    total = whole_rollouts(asked, int(hyper.get("n_steps", _SB3_N_STEPS)) * n_envs)
    env_kwargs = dict(hyper.get("env_kwargs") or {})
    wrapper = _wrapper_class(hyper.get("env_wrapper"), args.config)
    normalize = _normalize_kwargs(hyper.get("normalize"), args.config)
    worlds = load_worlds(_read_config(args.config, ()), args.config)
    if worlds is not None and "exercise" in env_kwargs:
        raise ConfigError(
            f"{args.config}: with 'worlds' the exercises are the split's; remove "
            "env_kwargs.exercise"
        )
    return _Run(args, hyper, env_kwargs, wrapper, normalize, n_envs, total, worlds, asked)


def _ppo_kwargs(run: _Run) -> dict[str, Any]:
    kw = {k: v for k, v in run.hyper.items() if k not in _ZOO_KEYS}
    kw["policy_kwargs"] = _policy_kwargs(kw.get("policy_kwargs"), run.args.config)
    for key in ("learning_rate", "clip_range"):
        if key in kw:
            kw[key] = _schedule(kw[key])
    return kw


def use_batched(vec_env: str, run: _Run) -> bool:
    """Whether ``vec_env`` (see :class:`TrainArgs`) steps ``run``'s envs as one batched env.

    Raises:
        ConfigError: ``"batched"`` for a run it cannot step (worlds, another wrapper).
    """
    from train.vec_env import BATCHED_WRAPPERS

    if vec_env not in ("batched", "auto"):
        return False
    names = [_dotted(k) for k, _ in (run.wrapper.chain if run.wrapper is not None else [])]
    why = ""
    if run.args.env_id != "LangCtrl-v0":
        why = f"env {run.args.env_id!r} (batched: LangCtrl-v0)"
    elif run.worlds is not None:
        why = "a run across worlds (its envs change scripts per episode)"
    elif any(name not in BATCHED_WRAPPERS for name in names):
        why = f"env_wrapper {names} (batched: {', '.join(BATCHED_WRAPPERS)})"
    if why and vec_env == "batched":
        raise ConfigError(f"--vec-env batched cannot step {why}; use subproc or dummy")
    return not why


def _dotted(klass: Any) -> str:
    return f"{klass.__module__}.{klass.__qualname__}"


def use_subprocesses(vec_env: str, n_envs: int) -> bool:
    """Whether ``vec_env`` (see :class:`TrainArgs`) runs ``n_envs`` envs in subprocesses."""
    if n_envs < 2 or vec_env == "dummy":
        return False
    return vec_env == "subproc" or _cpu_cores() > n_envs


def _cpu_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _make_envs(run: _Run) -> tuple[Any, Any]:
    """Training VecEnv (normalised) and evaluation VecEnv (normalisation in eval mode)."""
    import gymnasium as gym
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    import langenv  # noqa: F401  (registers the env)
    from train.wrappers import SeedCycle

    a = run.args
    cls = _SubprocVecEnv if use_subprocesses(a.vec_env, run.n_envs) else DummyVecEnv
    if run.worlds is not None and not use_batched(a.vec_env, run):
        return _make_world_envs(run, cls)
    per_env = _exercise_kwargs(run.env_kwargs)
    env: Any
    if use_batched(a.vec_env, run):
        from train.vec_env import make_batched_vec_env

        chain = run.wrapper.chain if run.wrapper is not None else []
        sessions = [
            {k: v for k, v in per_env[i % len(per_env)].items() if k != "max_episode_steps"}
            for i in range(run.n_envs)
        ]
        env = make_batched_vec_env(
            run.n_envs,
            {"max_episode_steps": run.env_kwargs.get("max_episode_steps")},
            a.seed,
            [(_dotted(k), kw) for k, kw in chain],
            session_kwargs=sessions,
        )
    elif len(per_env) == 1 and not getattr(run.wrapper, "monitor_outside", False):
        env = make_vec_env(
            a.env_id,
            n_envs=run.n_envs,
            seed=a.seed,
            vec_env_cls=cls,
            env_kwargs=run.env_kwargs,
            wrapper_class=run.wrapper,
        )
    else:  # make_vec_env gives every env the same kwargs: its loop, exercise i mod k
        fns: list[Any] = [
            _EnvFn(a.env_id, per_env[i % len(per_env)], run.wrapper, a.seed, i)
            for i in range(run.n_envs)
        ]
        env = cls(fns)
        env.seed(a.seed)
    if run.normalize is not None:
        env = VecNormalize(env, **run.normalize)
    eval_env: Any = None
    if a.n_eval_episodes > 0:
        seeds = [a.eval_seed + i for i in range(a.n_eval_episodes)]
        chain = run.wrapper.chain if run.wrapper is not None else []
        k = len(per_env)

        def make_eval_env(j: int) -> Any:
            wrap = _WrapperChain(chain, ((SeedCycle, {"seeds": seeds[j::k] or seeds[:1]}),))
            return lambda: _monitored(gym.make(a.env_id, **per_env[j]), wrap)

        # Not make_vec_env: it seeds the first reset at random even with seed=None, which would
        # override SeedCycle and make the first evaluation episode a random user. A bare
        # DummyVecEnv passes seed=None, so SeedCycle picks eval_seed, eval_seed + 1, ...
        eval_env = DummyVecEnv([make_eval_env(j) for j in range(k)])
        if run.normalize is not None:
            kw = {k: v for k, v in run.normalize.items() if k != "norm_reward"}
            eval_env = VecNormalize(eval_env, training=False, norm_reward=False, **kw)
    return env, eval_env


def _make_world_envs(run: _Run, cls: Any) -> tuple[Any, Any]:
    """Training and validation VecEnvs across the worlds of ``run.worlds``
    (:mod:`langenv.worlds`): training env ``i`` draws its worlds from seed ``seed + i``; the
    periodic evaluation cycles through ``n_eval_episodes`` validation (exercise, user) pairs."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    a, split = run.args, run.worlds
    split.check()
    fns: list[Any] = [
        _WorldFn(split, "train", run.env_kwargs, run.wrapper, a.seed, i) for i in range(run.n_envs)
    ]
    env = cls(fns)
    env.seed(a.seed)
    if run.normalize is not None:
        env = VecNormalize(env, **run.normalize)
    eval_env: Any = None
    if a.n_eval_episodes > 0:
        split.pairs("validation", a.n_eval_episodes)  # enough validation users, before training
        from langenv.worlds import WorldEnv

        n = a.n_eval_episodes
        eval_env = DummyVecEnv(
            [lambda: _monitored(WorldEnv(split, "validation", run.env_kwargs, n), run.wrapper)]
        )
        if run.normalize is not None:
            kw = {k: v for k, v in run.normalize.items() if k != "norm_reward"}
            eval_env = VecNormalize(eval_env, training=False, norm_reward=False, **kw)
    return env, eval_env


@dataclass(frozen=True)
class _WorldFn:
    """One training env across worlds (picklable for subprocesses): a
    :class:`~langenv.worlds.WorldEnv` with its TimeLimit's steps, a Monitor and the wrappers."""

    split: Any
    role: str
    env_kwargs: dict[str, Any]
    wrapper: Any
    seed: int | None
    rank: int

    def __call__(self) -> Any:
        from langenv.worlds import WorldEnv

        env = WorldEnv(self.split, self.role, self.env_kwargs)
        return _seeded_monitored(env, self.wrapper, self.seed, self.rank)


def _seeded_monitored(env: Any, wrapper: Any, seed: int | None, rank: int) -> Any:
    """``env`` as ``make_vec_env`` finishes each of its envs: the action space seeded
    ``seed + rank``, a Monitor, then ``wrapper`` (:func:`_monitored`)."""
    if seed is not None:
        env.action_space.seed(seed + rank)
    return _monitored(env, wrapper)


def _exercise_kwargs(env_kwargs: dict[str, Any]) -> list[dict[str, Any]]:
    """The env kwargs of each exercise of ``env_kwargs["exercise"]`` (one or a list), checked.

    Raises:
        ConfigError: an empty list, or an exercise that does not load or fails its checks.
    """
    from langenv.exercise import resolve_exercise
    from langenv.exercise.check import check_exercise
    from langenv.speech.graph import PhraseGraph, graph_path

    given = env_kwargs.get("exercise")
    if not isinstance(given, list | tuple):
        if given is not None:
            check_exercise(resolve_exercise(given))
        return [env_kwargs]
    if not given:
        raise ConfigError("env_kwargs.exercise: an empty list; give one exercise or several")
    widest = 1
    for ex in given:
        exercise = resolve_exercise(ex)
        check_exercise(exercise)
        graph = env_kwargs.get("phrase_graph") or exercise.graph
        widest = max(widest, PhraseGraph.load(graph_path(graph)).max_children)
    # one observation layout for all: the child blocks of the widest graph (unless given)
    common = {"max_children": widest, **env_kwargs}
    return [{**common, "exercise": ex} for ex in given]


@dataclass(frozen=True)
class _EnvFn:
    """One training env of a list of exercises, made as ``make_vec_env`` makes each of its own
    (the action space seeded ``seed + rank``, a Monitor, the wrappers); picklable for
    subprocesses."""

    env_id: str
    kwargs: dict[str, Any]
    wrapper: Any
    seed: int | None
    rank: int

    def __call__(self) -> Any:
        import gymnasium as gym

        env = gym.make(self.env_id, **{"render_mode": "rgb_array", **self.kwargs})
        return _seeded_monitored(env, self.wrapper, self.seed, self.rank)


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
    from policies.learned import graph_digest, observation_layout

    graphs = _trained_graphs(run)
    if run.worlds is not None:
        extra = {"worlds": run.worlds.to_dict(), **extra}
    if residual:
        extra = {"observation_layout": observation_layout(int(residual["max_children"])), **extra}
    return {
        run.args.env_id: _plain(run.hyper),
        "train": recorded_args(run.args),
        "env_kwargs": _plain(run.env_kwargs),
        "residual": residual,
        # every graph trained on, as tables name them (langenv.exercise.script.graph_label);
        # the digest of the one graph a single-graph run trained on (None: several, varied)
        "phrase_graphs": [label for label, _ in graphs],
        "phrase_graph_sha256": (
            graph_digest(graphs[0][1]) if run.worlds is None and len(graphs) == 1 else None
        ),
        "n_envs": run.n_envs,
        "total_timesteps": run.total,
        "versions": {
            **code_version(langenv.__version__),
            "stable_baselines3": stable_baselines3.__version__,
            "python": sys.version.split()[0],
        },
        **extra,
    }


def _trained_graphs(run: _Run) -> list[tuple[str, str]]:
    """``(label, ref)`` of each phrase graph the run's envs speak, in first-use order: the
    config's ``env_kwargs.phrase_graph``, else each training exercise's script (across worlds:
    the train role's, before their variants)."""
    from langenv.exercise import resolve_exercise
    from langenv.exercise.script import graph_label

    given = run.env_kwargs.get("phrase_graph")
    if run.worlds is not None:
        names = run.worlds.exercises("train")
        refs = [run.worlds.graphs.get(n, resolve_exercise(n).graph) for n in names]
    elif given is not None:
        refs = [str(given)]
    else:
        exercise = run.env_kwargs.get("exercise")
        listed = exercise if isinstance(exercise, list | tuple) else [exercise]
        refs = [resolve_exercise(ex).graph for ex in listed]
    found = {graph_label(ref): str(ref) for ref in refs}
    return list(found.items())


def code_version(installed: str) -> dict[str, str]:
    """The version of the code that trains: ``{"langctrl": VERSION}`` plus ``git_commit`` (with
    ``+dirty`` for uncommitted changes) when the code runs from a git checkout.

    ``installed`` is ``langenv.__version__`` (the installed package metadata). An editable
    install keeps the metadata of the day it was installed, so when the source tree beside the
    imported ``langenv`` has a ``pyproject.toml`` whose version differs, that version is the
    one recorded (it is the code that runs) and a line on stderr says to reinstall.

    Args:
        installed: The installed metadata's version.
    """
    import subprocess
    import tomllib

    import langenv

    root = Path(langenv.__file__).resolve().parents[1]
    version = installed
    try:
        source = tomllib.loads((root / "pyproject.toml").read_text())["project"]["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        source = None
    if isinstance(source, str) and source != installed:
        print(
            f"langctrl train: the installed metadata says langctrl {installed} but the code that "
            f"runs is {source} ({root / 'pyproject.toml'}); recording {source} (reinstall: pip "
            "install -e .)",
            file=sys.stderr,
        )
        version = source
    out = {"langctrl": version}
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return out
    out["git_commit"] = commit + ("+dirty" if dirty else "")
    return out


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


def recorded_path(path: Path | str) -> str:
    """A path as a run's config records it: describing no machine.

    A relative path is kept; an absolute path inside the working directory becomes relative to
    it; any other absolute path (a temporary folder, another disk) is recorded by its name only.

    Args:
        path: The path given to the run.

    Returns:
        A POSIX path string.
    """
    p = Path(path)
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.relative_to(Path.cwd()).as_posix()
    except ValueError:
        return p.name


def recorded_args(args: TrainArgs | dict[str, Any]) -> dict[str, Any]:
    """:class:`TrainArgs` (or their recorded mapping) as a config records them: plain values,
    paths through :func:`recorded_path`."""
    items = asdict(args) if isinstance(args, TrainArgs) else dict(args)
    path_keys = {"config", "out", "init_from"}
    return {
        k: (recorded_path(v) if (isinstance(v, Path) or k in path_keys) and v is not None else v)
        for k, v in items.items()
    }


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


def resume_files(ckpt_dir: Path, name: str) -> tuple[Path, Path]:
    """The resume point's model zip and VecNormalize pickle (``checkpoints/resume/NAME.zip``,
    ``NAME_vecnormalize.pkl``)."""
    return ckpt_dir / "resume" / f"{name}.zip", ckpt_dir / "resume" / f"{name}_vecnormalize.pkl"


def _save_resume_point(model: Any, ckpt_dir: Path, name: str) -> None:
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


def _resume_source(ckpt_dir: Path, name: str) -> tuple[Path, Path, bool]:
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


def _resolve_resume(args: TrainArgs, given: set[str]) -> tuple[_Run, dict[str, Any]]:
    """The interrupted run's settings (from its ``run_config.yaml``), with the overrides allowed.

    Returns:
        The run and its saved config.

    Raises:
        FileNotFoundError: no checkpoint, or no ``run_config.yaml`` in the run's directory.
        ConfigError: an explicit argument that differs from the run's saved setting (naming it).
    """
    out = args.out if "out" in given else _resolve(args, given).args.out
    ckpt_dir = out / "checkpoints"
    _resume_source(ckpt_dir, args.name if "name" in given else _saved_name(out, args))
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
        total = whole_rollouts(asked, int(hyper.get("n_steps", _SB3_N_STEPS)) * n_envs)
    merged = replace(merged, total_timesteps=total)
    run = _Run(
        merged,
        hyper,
        dict(hyper.get("env_kwargs") or {}),
        _wrapper_class(hyper.get("env_wrapper"), path),
        _normalize_kwargs(hyper.get("normalize"), path),
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


def _restore_history(eval_cb: EvalCallback, eval_dir: Path, best_cfg: Path, steps: int) -> int:
    """Give a resumed run's evaluation callback the evaluations made up to ``steps`` and the best
    mean return so far; returns how many evaluations carried over."""
    path = eval_dir / "evaluations.npz"
    if path.is_file():
        with np.load(path) as data:
            keep = np.asarray(data["timesteps"]) <= steps
            eval_cb.evaluations_timesteps = [int(t) for t in np.asarray(data["timesteps"])[keep]]
            eval_cb.evaluations_results = [list(r) for r in np.asarray(data["results"])[keep]]
            eval_cb.evaluations_length = [list(r) for r in np.asarray(data["ep_lengths"])[keep]]
            if isinstance(eval_cb, _MetricsEvalCallback):
                width = np.asarray(data["results"]).reshape(keep.size, -1).shape[1]
                for key in EVAL_METRICS:  # NaN (one per user) for a run recorded before they were
                    missing = np.full((keep.size, width), np.nan)
                    rows = np.asarray(data[key]) if key in data else missing
                    kept = rows[keep]
                    eval_cb.evaluations_metrics[key] = [np.atleast_1d(r).tolist() for r in kept]
    means = [float(np.mean(r)) for r in eval_cb.evaluations_results]
    best = max(means, default=-np.inf)
    if best_cfg.is_file():
        recorded = (yaml.safe_load(best_cfg.read_text()) or {}).get("eval_mean_reward")
        if isinstance(recorded, int | float):
            best = max(best, float(recorded))
    eval_cb.best_mean_reward = best
    if means:
        eval_cb.last_mean_reward = means[-1]
    return len(means)


class _ResumePoint(BaseCallback):
    """Saves the resume point at the start of every rollout, i.e. right after PPO has learned
    from the previous one, and once more at the end of training."""

    def __init__(self, ckpt_dir: Path, name: str) -> None:
        super().__init__()
        self.ckpt_dir, self.name = ckpt_dir, name
        self.saved_at: int | None = None

    def _save(self) -> None:
        _save_resume_point(self.model, self.ckpt_dir, self.name)
        self.saved_at = int(self.model.num_timesteps)

    def _on_rollout_start(self) -> None:
        self._save()

    def _on_training_end(self) -> None:
        self._save()

    def _on_step(self) -> bool:
        return True


class _IgnoreSigint:
    """Env factory for a worker process that leaves Ctrl-C to the learner process, which then
    closes the workers cleanly (instead of each worker dying with its own traceback)."""

    def __init__(self, make: Any) -> None:
        self.make = make

    def __call__(self) -> Any:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        return self.make()


class _SubprocVecEnv(SubprocVecEnv):
    """SubprocVecEnv whose workers ignore SIGINT (see :class:`_IgnoreSigint`) and whose rewards
    are float32, as a DummyVecEnv stores them (SB3's SubprocVecEnv passes Python floats on as
    float64), so that the two give the same run."""

    def __init__(self, env_fns: list[Any], start_method: str | None = None) -> None:
        from langenv.batch.warm import warm_up

        warm_up()  # compiled here once, before the workers start (they would compile together)
        super().__init__([_IgnoreSigint(fn) for fn in env_fns], start_method)

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = super().step_wait()
        return obs, np.asarray(rewards, dtype=np.float32), dones, infos


def _close(env: Any) -> None:
    """Close a VecEnv; a worker already gone is not an error worth a traceback."""
    try:
        env.close()
    except (EOFError, BrokenPipeError, ConnectionResetError):
        for proc in getattr(getattr(env, "venv", env), "processes", []):
            proc.terminate()


def _check_fresh_out(out: Path) -> None:
    if out.is_dir() and any(out.iterdir()):
        raise ConfigError(
            f"--out {out} already holds files (an earlier run?); continue that run with "
            "--resume, or start this one in another --out"
        )
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")


def train(args: TrainArgs, given: set[str] | None = None) -> Path:
    """Train (or resume) a run; returns the final model zip.

    Raises:
        FileNotFoundError: for a missing config, or ``resume`` without a checkpoint.
        ConfigError: for an invalid config, a fresh run in a non-empty ``out``, or a resume
            with a setting that differs from the run's.
        KeyboardInterrupt: on Ctrl-C, after one line on stderr (the resume point is on disk).
    """
    import torch

    given = given if given is not None else set()
    saved: dict[str, Any] | None = None
    if args.resume:
        run, saved = _resolve_resume(args, given)
    else:
        run = _resolve(args, given)
        _check_fresh_out(run.args.out)
    a = run.args
    if (note := run.budget_note()) is not None:
        print(note, file=sys.stderr)
    torch.set_num_threads(a.torch_threads)
    if a.init_from is not None and not a.resume:
        init_files(a.init_from)  # a missing file fails before any env starts
    a.out.mkdir(parents=True, exist_ok=True)
    env, eval_env = _make_envs(run)
    try:
        model, config, steps = _setup_model(run, env, saved)
        return _learn(run, model, env, eval_env, config, steps)
    finally:
        _close(env)
        if eval_env is not None:
            _close(eval_env)


def _setup_model(run: _Run, env: Any, saved: dict[str, Any] | None) -> tuple[Any, dict, int]:
    """The model (new, fine-tuned or resumed), the run's config and the step count it starts at.

    ``run_config.yaml`` is written once the model is set up, so that a failed start leaves an
    earlier run's file alone.
    """
    a = run.args
    ckpt_dir = a.out / "checkpoints"
    tb = str(a.out / "tb") if a.tensorboard else None
    if saved is not None:
        zip_path, pkl, is_point = _resume_source(ckpt_dir, a.name)
        if isinstance(env, VecNormalize):
            env = VecNormalize.load(str(pkl), env.venv)
        model = PPO.load(zip_path, env=env, device=a.device, tensorboard_log=tb)
        steps = int(model.num_timesteps)
        model.set_random_seed(a.seed + steps)  # a resumed run is reproducible too
        what = "the state after the update at" if is_point else "snapshot (no resume point) at"
        print(
            f"resuming from {zip_path}: {what} {steps} steps, budget {run.total}", file=sys.stderr
        )
        config = dict(saved, train=recorded_args(a), total_timesteps=run.total)
    else:
        config = _config_dict(run, _residual_section(env), {})
        model = PPO(
            run.hyper.get("policy", "MlpPolicy"),
            env,
            seed=a.seed,
            device=a.device,
            tensorboard_log=tb,
            verbose=a.verbose,
            **_ppo_kwargs(run),
        )
        steps = 0
        if a.init_from is not None:
            config["init_from_sha256"] = _init_from(model, env, a.init_from)
            print(f"starting from the weights of {a.init_from}", file=sys.stderr)
    (a.out / "run_config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return model, config, steps


def _learn(
    run: _Run, model: Any, env: Any, eval_env: Any, config: dict[str, Any], steps: int
) -> Path:
    """Run PPO to the budget with checkpoints, resume points and periodic evaluations."""
    a = run.args
    ckpt_dir, eval_dir, best_dir = a.out / "checkpoints", a.out / "eval", a.out / BEST_RETURN
    eval_cb: _MetricsEvalCallback | None = None

    class _SaveBest(BaseCallback):
        def _on_step(self) -> bool:
            assert eval_cb is not None
            cfg = dict(config, eval_mean_reward=float(eval_cb.best_mean_reward))
            _save_triple(self.model, None, best_dir / a.name, cfg)
            return True

    point = _ResumePoint(ckpt_dir, a.name)
    callbacks: list[Any] = [
        CheckpointCallback(
            save_freq=max(1, a.checkpoint_freq // run.n_envs),
            save_path=str(ckpt_dir),
            name_prefix=a.name,
            save_vecnormalize=True,
        ),
        point,
    ]
    if eval_env is not None:
        eval_cb = _MetricsEvalCallback(
            eval_env,
            n_eval_episodes=a.n_eval_episodes,
            eval_freq=max(1, a.eval_freq // run.n_envs),
            log_path=str(eval_dir),
            deterministic=True,
            callback_on_new_best=_SaveBest(),
            verbose=0,  # its report is the project's one line on stderr ([eval @ N steps])
        )
        callbacks.append(eval_cb)
        if a.resume:
            best_cfg = best_dir / f"{a.name}_config.yaml"
            if not best_cfg.is_file():  # a run written before the folder had its name
                best_cfg = a.out / "best" / best_cfg.name
            n = _restore_history(eval_cb, eval_dir, best_cfg, steps)
            print(f"{n} earlier evaluations carried over", file=sys.stderr)
    for cb in callbacks:  # the schedules go on where the interrupted run was
        cb.n_calls = steps // run.n_envs
    remaining = max(0, run.total - steps)
    final = a.out / a.name
    if a.resume and remaining == 0 and final.with_suffix(".zip").is_file():
        print(
            f"the run has reached its budget of {run.total} steps; nothing to do (give "
            "--total-timesteps to train further)",
            file=sys.stderr,
        )
        return final.with_suffix(".zip")
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
        where = (
            f"the state after the update at {point.saved_at} steps is in "
            f"{resume_files(ckpt_dir, a.name)[0].parent}"
            if point.saved_at is not None
            else "nothing to resume from yet"
        )
        print(
            f"langctrl train: interrupted at {model.num_timesteps} steps; {where}; continue with "
            "--resume",
            file=sys.stderr,
        )
        raise
    wall = time.perf_counter() - t0
    config["wall_time_s"] = round(wall, 3)
    _save_triple(model, None, final, config)
    print(f"wrote {final}.zip ({model.num_timesteps} steps, {wall:.0f} s)", file=sys.stderr)
    return final.with_suffix(".zip")


#: Per-episode metrics the periodic evaluation records in ``eval/evaluations.npz`` beside SB3's
#: ``timesteps``, ``results`` and ``ep_lengths`` (one row per evaluation, one column per user):
#: ``|AM|`` at the end (s; NaN when a session did not end by itself), mean ``|EM|`` over its
#: decisions (s) and mean ``|a - 1|`` over its decisions while speech goes on; and where the
#: env reports them at the end (``train.choices.ChoicePoints``: the session's own metrics, its
#: mean ``|EM|`` over time) ``content_share``, ``voice_natural`` and ``legs_in_step`` (NaN
#: otherwise, and for a session without leg boundaries).
EVAL_METRICS: tuple[str, ...] = (
    "abs_am", "em_mean_abs", "a_dev", "content_share", "voice_natural", "legs_in_step"
)  # fmt: skip


#: The base's figures on the held-out users (``eval/`` of a run; :data:`EVAL_METRICS`, one per
#: user): a phrase chooser's run evaluates its base once, before training.
BASE_FILE = "base.npz"


def _is_chooser(env: Any) -> bool:
    """Whether ``env`` (a VecEnv) is a phrase chooser's (``decisions: choices``)."""
    if not _has_attr(env, "residual_spec"):
        return False
    spec = env.get_attr("residual_spec", indices=[0])[0]
    return getattr(spec, "decisions", "steps") == "choices"


def _nanmean(values: Sequence[float]) -> float:
    """The mean of the finite values (NaN when there are none)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if x.size else math.nan


class _ZeroCorrection:
    """A "model" whose action is always 0: the residual's base (for ``evaluate_policy``)."""

    def __init__(self, shape: tuple[int, ...] | None) -> None:
        self.shape = tuple(shape or ())

    def predict(self, observation: Any, *args: Any, **kwargs: Any) -> tuple[np.ndarray, None]:
        n = int(np.shape(observation)[0])
        return np.zeros((n, *self.shape), np.float32), None


class _MetricsEvalCallback(EvalCallback):
    """EvalCallback that also logs and records the held-out users' ``|AM|``, ``|EM|`` and
    ``|a - 1|`` (:data:`EVAL_METRICS`), so that a checkpoint can be chosen by them
    (``python -m train.export RUN --best``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._episode: dict[str, list[float]] = {k: [] for k in EVAL_METRICS}
        self._em_steps: list[float] = []
        self._a_steps: list[float] = []
        self.evaluations_metrics: dict[str, list[list[float]]] = {k: [] for k in EVAL_METRICS}

    def _on_training_start(self) -> None:
        """Evaluate the base (a zero correction) once on the held-out users, where the env
        reports the speech people hear: ``eval/base.npz``, what ``train.export --best`` holds
        the checkpoints against (:data:`BASE_FILE`)."""
        super()._on_training_start()
        if self.log_path is None:
            return
        path = Path(self.log_path).parent / BASE_FILE
        if path.is_file() or not _is_chooser(self.eval_env):
            return
        self._episode = {k: [] for k in EVAL_METRICS}
        self._em_steps, self._a_steps = [], []
        from stable_baselines3.common.evaluation import evaluate_policy

        evaluate_policy(
            _ZeroCorrection(self.eval_env.action_space.shape),
            self.eval_env,
            n_eval_episodes=self.n_eval_episodes,
            deterministic=True,
            callback=self._log_success_callback,
        )
        if np.isfinite(self._episode["content_share"]).all():
            arrays: dict[str, Any] = {k: np.asarray(v, float) for k, v in self._episode.items()}
            np.savez(path, **arrays)
            print(
                f"[eval of the base] held-out users: content "
                f"{np.mean(self._episode['content_share']):.4f}, voice natural "
                f"{np.mean(self._episode['voice_natural']):.4f}, |AM| <= 1 s "
                f"{np.mean(np.asarray(self._episode['abs_am']) <= 1.0):.3f}, legs in step "
                f"{_nanmean(self._episode['legs_in_step']):.3f}",
                file=sys.stderr,
            )

    def _on_step(self) -> bool:
        self._episode = {k: [] for k in EVAL_METRICS}
        self._em_steps, self._a_steps = [], []
        ok = bool(super()._on_step())
        if self._episode["abs_am"]:
            for key in EVAL_METRICS:
                self.evaluations_metrics[key].append(list(self._episode[key]))
            self._save_metrics()
            am = float(np.nanmean(self._episode["abs_am"]))
            em = float(np.mean(self._episode["em_mean_abs"]))
            a_dev = float(np.nanmean(self._episode["a_dev"]))
            self.logger.record("eval/abs_am", am)
            self.logger.record("eval/abs_am_median", float(np.nanmedian(self._episode["abs_am"])))
            self.logger.record("eval/em_mean_abs", em)
            self.logger.record("eval/a_dev", a_dev)
            speech = ""
            if np.isfinite(self._episode["content_share"]).any():
                content = float(np.nanmean(self._episode["content_share"]))
                voice = float(np.nanmean(self._episode["voice_natural"]))
                within = float(np.mean(np.asarray(self._episode["abs_am"]) <= 1.0))
                self.logger.record("eval/content_share", content)
                self.logger.record("eval/voice_natural", voice)
                legs = _nanmean(self._episode["legs_in_step"])
                self.logger.record("eval/legs_in_step", legs)
                speech = (
                    f", content {content:.4f}, voice natural {voice:.4f}, |AM| <= 1 s {within:.3f}"
                    f", legs in step {legs:.3f}"
                )
            print(
                f"[eval @ {self.num_timesteps} steps] held-out users: mean |AM| {am:.3f} s, "
                f"median |AM| {np.nanmedian(self._episode['abs_am']):.3f} s, mean |EM| "
                f"{em:.3f} s, mean |a-1| {a_dev:.3f}{speech}, return {self.last_mean_reward:.2f}",
                file=sys.stderr,
            )
        return ok

    def _save_metrics(self) -> None:
        """Rewrite ``evaluations.npz`` with SB3's arrays and :data:`EVAL_METRICS`."""
        if self.log_path is None or len(self.evaluations_timesteps) != len(
            self.evaluations_metrics["abs_am"]
        ):
            return
        arrays: dict[str, Any] = {
            "timesteps": self.evaluations_timesteps,
            "results": self.evaluations_results,
            "ep_lengths": self.evaluations_length,
        }
        arrays.update({k: np.asarray(v, dtype=float) for k, v in self.evaluations_metrics.items()})
        np.savez(self.log_path, **arrays)

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        info = locals_["info"]
        self._em_steps.append(abs(float(info.get("em", 0.0))))
        if not info.get("speech_done", False):
            self._a_steps.append(abs(float(info.get("a", 1.0)) - 1.0))
        if locals_["done"]:
            am = info.get("am")
            self._episode["abs_am"].append(abs(float(am)) if am is not None else math.nan)
            em = info.get("em_mean_abs")  # the session's own, where the env reports it
            em = float(em) if em is not None else float(np.mean(self._em_steps))
            self._episode["em_mean_abs"].append(em)
            a_dev = float(np.mean(self._a_steps)) if self._a_steps else math.nan
            self._episode["a_dev"].append(a_dev)
            for key in ("content_share", "voice_natural", "legs_in_step"):
                value = info.get(key)
                self._episode[key].append(float(value) if value is not None else math.nan)
            self._em_steps, self._a_steps = [], []


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args, given = parse_args(argv)
    try:
        path = train(args, given)
    except (FileNotFoundError, ConfigError) as exc:
        print(f"langctrl train: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    print(path)
    return 0


if __name__ == "__main__":
    shutil.get_terminal_size()  # rich's progress bar reads it; fail early on odd terminals
    raise SystemExit(main())
