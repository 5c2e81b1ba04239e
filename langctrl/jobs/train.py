"""``langctrl train``: train the learned aligner, Stable-Baselines3 PPO on ``LangCtrl-v0``
(what a run does and writes: :mod:`train.ppo`).

    langctrl train --config configs/ppo.yaml                       # the shipped model
    langctrl train --config configs/ppo.yaml --total-timesteps 4000 --out runs/ppo_smoke
    langctrl train --config configs/ppo.yaml --out runs/ppo --resume  # after an interruption
    langctrl train --config CONFIG --init-from runs/ppo/NAME.zip  # fine-tune a model

Exit status 0 (the final model's path printed), 2 on bad usage or a bad config, 130 on Ctrl-C
(the resume point is on disk).
"""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from langctrl import options
from langenv.errors import ConfigError
from train.config import VEC_ENVS, TrainArgs
from train.ppo import train

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl train`` (``python -m langctrl.jobs.train``).

    Every option but ``--config`` defaults to None, so that :func:`parse_args` can tell which were
    given: the config's ``train`` section sets those not given, :class:`TrainArgs` the rest.
    """
    p = options.job_parser(
        "train",
        "Train the learned aligner (SB3 PPO) from a zoo-style config; the config's 'train' "
        "section sets these options, the command line overrides it.",
        options.out_dir(
            "the run; a fresh run refuses one that holds files",
            otherwise=f"the config's train.out, else {TrainArgs.out}",
        ),
        options.seed(
            None,
            of="the first training env (env i: SEED + i) and of PPO; >= 1000000 keeps "
            "training users apart from evaluation users",
            otherwise=f"the config's train.seed, else {TrainArgs.seed}",
        ),
    )
    _add_run_options(p)
    _add_evaluation_options(p)
    _add_env_options(p)
    _add_start_options(p)
    _add_learner_options(p)
    return p


def _default(name: str, shown: object = None) -> str:
    """The help's note on the default of option ``name`` (``shown``: how to show it)."""
    value = getattr(TrainArgs, name) if shown is None else shown
    return f"(default: the config's train.{name}, else {value})"


def _setting(
    p: argparse.ArgumentParser,
    flag: str,
    what: str,
    *,
    type: Callable[[str], object] = str,
    metavar: str | None = None,
    shown: object = None,
) -> None:
    """Add ``flag``, a setting of the config's ``train`` section of the same name: None unless
    given; its help says ``what`` it is, then :func:`_default` (``shown``) where it defaults."""
    name = flag.removeprefix("--").replace("-", "_")
    p.add_argument(
        flag, type=type, default=None, metavar=metavar, help=f"{what} {_default(name, shown)}"
    )


def _add_run_options(p: argparse.ArgumentParser) -> None:
    """The config and the run's budget (where it goes and its seed: the shared options)."""
    p.add_argument(
        "--config",
        type=Path,
        default=TrainArgs.config,
        metavar="YAML",
        help="zoo-style YAML of hyperparameters, keyed by the env id (default: %(default)s)",
    )
    _setting(p, "--env-id", "Gymnasium env id", metavar="ID")
    _setting(p, "--name", "file stem of the saved model, NAME.zip")
    _setting(
        p,
        "--total-timesteps",
        "training budget, env steps of all envs together, rounded up to whole rollouts "
        "(n_steps x n_envs)",
        type=int,
        metavar="STEPS",
        shown="its n_timesteps",
    )


def _add_evaluation_options(p: argparse.ArgumentParser) -> None:
    """The periodic evaluation and the checkpoints."""
    _setting(
        p, "--eval-seed", "seed of the first periodic-evaluation user", type=int, metavar="SEED"
    )
    _setting(
        p, "--n-eval-episodes", "users per periodic evaluation, 0: none", type=int, metavar="N"
    )
    _setting(
        p,
        "--eval-freq",
        "env steps (all envs) between periodic evaluations",
        type=int,
        metavar="STEPS",
    )
    _setting(
        p,
        "--checkpoint-freq",
        "env steps (all envs) between checkpoints",
        type=int,
        metavar="STEPS",
    )


def _add_env_options(p: argparse.ArgumentParser) -> None:
    """How many training envs, and the vector env that steps them."""
    _setting(p, "--n-envs", "parallel training envs", type=int, metavar="N", shown="its n_envs")
    p.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default=None,
        help="batched: every env a session of one batched env (one compiled call per step over "
        "the cores); subproc: one process per env; dummy: in this process; auto: batched where "
        "it applies (no worlds, batched wrappers), else subprocesses only with more CPU cores "
        f"than envs; the same run either way {_default('vec_env')}",
    )


def _add_start_options(p: argparse.ArgumentParser) -> None:
    """Where the weights start: a resumed run's resume point, or a saved model's."""
    p.add_argument(
        "--resume",
        action="store_true",
        default=None,
        help="continue the run in --out from its resume point, with its saved settings",
    )
    _setting(
        p,
        "--init-from",
        "fine-tune: start from this model's weights and normalisation statistics",
        type=Path,
        metavar="ZIP",
        shown="random weights",
    )


def _add_learner_options(p: argparse.ArgumentParser) -> None:
    """What the learner shows and writes, and where it computes."""
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
    _setting(p, "--device", "torch device of the learner")
    _setting(p, "--torch-threads", "torch threads of the learner process", type=int, metavar="N")
    _setting(p, "--verbose", "SB3 verbosity, 0 (quiet) to 2", type=int, metavar="{0,1,2}")


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


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl train``; returns the exit status."""
    args, given = parse_args(argv)
    try:
        path = train(args, given)
    except (FileNotFoundError, ConfigError) as exc:
        return options.fail("train", exc)
    except KeyboardInterrupt:
        return 130
    print(path)
    return 0


if __name__ == "__main__":
    shutil.get_terminal_size()  # rich's progress bar reads it; fail early on odd terminals
    raise SystemExit(main())
