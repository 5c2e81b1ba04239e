"""What a training run is asked to do: :class:`TrainArgs` and the zoo-style YAML config.

The config is keyed like rl-baselines3-zoo's (top-level key ``LangCtrl-v0`` with ``n_envs``,
``n_timesteps``, ``policy``, ``normalize``, ``env_wrapper``, ``env_kwargs``, ``policy_kwargs`` and
PPO's own arguments; rl-zoo3's ``utils.py`` reads the same keys: ``lin_X`` schedules,
``policy_kwargs`` strings, wrappers by dotted name), plus two sections rl-zoo3 does not read: an
optional ``train`` (defaults of :class:`TrainArgs`) and ``worlds`` (:mod:`langenv.worlds`). A
config may ``inherit: OTHER.yaml`` (:func:`load_config`). :func:`resolve` joins the config and the
arguments into a :class:`Run`, what the env factories (:mod:`train.factories`) and the learner
(:mod:`train.ppo`) read.
"""

from __future__ import annotations

import ast
import copy
import importlib
import math
import re
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import yaml

from langenv.errors import ConfigError
from langenv.validation import yaml_text

__all__ = [
    "SB3_N_STEPS",
    "VEC_ENVS",
    "Run",
    "TrainArgs",
    "WrapperChain",
    "load_config",
    "load_worlds",
    "normalize_kwargs",
    "ppo_kwargs",
    "resolve",
    "whole_rollouts",
    "wrapper_chain",
]

#: The vector envs a run may step its envs in (``--vec-env``).
VEC_ENVS = ("auto", "batched", "subproc", "dummy")

#: Keys of a zoo-style section that are not PPO constructor arguments.
_ZOO_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_wrapper", "env_kwargs")
_UNSUPPORTED = ("frame_stack", "callback", "vec_env_wrapper", "normalize_kwargs")

SB3_N_STEPS = 2048
"""PPO's ``n_steps`` when the config gives none (SB3's default)."""


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


def normalize_kwargs(value: Any, path: Path) -> dict[str, Any] | None:
    """Zoo's ``normalize``: bool, dict, or a dict literal string."""
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


def wrapper_chain(spec: Any, path: Path) -> WrapperChain | None:
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
    return WrapperChain(chain)


@dataclass(frozen=True)
class WrapperChain:
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


@dataclass
class Run:
    """Everything a run needs, resolved from the YAML and the arguments."""

    args: TrainArgs
    hyper: dict[str, Any]
    env_kwargs: dict[str, Any]
    wrapper: WrapperChain | None
    normalize: dict[str, Any] | None
    n_envs: int
    total: int  # the budget asked for, rounded up to whole rollouts (what PPO trains)
    worlds: Any = None  # langenv.worlds.WorldSplit, from the config's ``worlds`` section
    asked: int = 0  # the budget asked for (--total-timesteps or the config's n_timesteps)

    @property
    def rollout(self) -> int:
        """Steps of one PPO rollout, all envs together (``n_steps x n_envs``)."""
        return int(self.hyper.get("n_steps", SB3_N_STEPS)) * self.n_envs

    def budget_note(self) -> str | None:
        """A line saying that the budget was rounded up to whole rollouts, or None."""
        if self.asked in (0, self.total):
            return None
        n_steps = self.rollout // self.n_envs
        return (
            f"the budget of {self.asked:,} steps is rounded up to {self.total:,}: PPO trains "
            f"whole rollouts of {n_steps:,} steps x {self.n_envs} envs ({self.rollout:,} steps)"
        )


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


def resolve(args: TrainArgs, given: set[str] | None = None) -> Run:
    """A fresh run's :class:`Run`: the config's hyperparameters, its ``train`` section for the
    arguments not in ``given`` (the names given on the command line), its wrappers and worlds.

    Raises:
        FileNotFoundError: for a missing config.
        ConfigError: naming the config, for anything it may not hold.
    """
    hyper, section = load_config(args.config, args.env_id)
    given = given if given is not None else set()
    defaults = {k: v for k, v in section.items() if k not in given}
    for key in ("out", "init_from"):
        if defaults.get(key) is not None:
            defaults[key] = Path(defaults[key])
    args = replace(args, **defaults) if defaults else args
    n_envs = int(args.n_envs or hyper.get("n_envs", 1))
    asked = int(args.total_timesteps or float(hyper.get("n_timesteps", 100_000)))
    total = whole_rollouts(asked, int(hyper.get("n_steps", SB3_N_STEPS)) * n_envs)
    env_kwargs = dict(hyper.get("env_kwargs") or {})
    wrapper = wrapper_chain(hyper.get("env_wrapper"), args.config)
    normalize = normalize_kwargs(hyper.get("normalize"), args.config)
    worlds = load_worlds(_read_config(args.config, ()), args.config)
    if worlds is not None and "exercise" in env_kwargs:
        raise ConfigError(
            f"{args.config}: with 'worlds' the exercises are the split's; remove "
            "env_kwargs.exercise"
        )
    return Run(args, hyper, env_kwargs, wrapper, normalize, n_envs, total, worlds, asked)


def ppo_kwargs(run: Run) -> dict[str, Any]:
    """The keyword arguments of SB3's ``PPO`` in ``run``'s config (schedules and
    ``policy_kwargs`` evaluated as rl-zoo3 evaluates them)."""
    kw = {k: v for k, v in run.hyper.items() if k not in _ZOO_KEYS}
    kw["policy_kwargs"] = _policy_kwargs(kw.get("policy_kwargs"), run.args.config)
    for key in ("learning_rate", "clip_range"):
        if key in kw:
            kw[key] = _schedule(kw[key])
    return kw
