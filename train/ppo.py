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
section sets defaults of :class:`~train.config.TrainArgs` (seeds, evaluation, checkpoints),
which the command line overrides. A config may ``inherit: OTHER.yaml`` and set only what differs
(see :func:`~train.config.load_config`; a train.ppo extension that rl-zoo3 does not read).

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

The parts of a run live beside this script, as rl-zoo3's beside its ``train.py``:
:mod:`train.config` (the arguments and the YAML), :mod:`train.factories` (the envs),
:mod:`train.resume` (checkpoints, the resume point, ``--init-from``), :mod:`train.provenance`
(what a run records about itself) and :mod:`train.callbacks` (periodic evaluation, the best model,
the resume point).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
from stable_baselines3.common.vec_env import VecNormalize

from langenv.errors import ConfigError
from train.callbacks import (
    BEST_RETURN,
    MetricsEvalCallback,
    ResumePointCallback,
    SaveBest,
    restore_history,
)
from train.config import VEC_ENVS, Run, TrainArgs, ppo_kwargs, resolve
from train.factories import close_env, make_envs, residual_section
from train.provenance import config_dict, recorded_args
from train.resume import (
    check_fresh_out,
    init_files,
    init_from_model,
    resolve_resume,
    resume_files,
    resume_source,
    save_triple,
)

__all__ = ["build_parser", "main", "parse_args", "train"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl train`` (``python -m train.ppo``).

    Every option but ``--config`` defaults to None, so that :func:`parse_args` can tell which were
    given: the config's ``train`` section sets those not given, :class:`TrainArgs` the rest.
    """
    p = argparse.ArgumentParser(
        prog="langctrl train",
        description="Train the learned aligner (SB3 PPO) from a zoo-style config; the config's "
        "'train' section sets these options, the command line overrides it. Also run as "
        "python -m train.ppo.",
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


def _add_run_options(p: argparse.ArgumentParser) -> None:
    """The config, where the run goes, its budget and its seed."""
    p.add_argument(
        "--config",
        type=Path,
        default=TrainArgs.config,
        metavar="YAML",
        help="zoo-style YAML of hyperparameters, keyed by the env id (default: %(default)s)",
    )
    p.add_argument(
        "--env-id", default=None, metavar="ID", help=f"Gymnasium env id {_default('env_id')}"
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help=f"run directory; a fresh run refuses one that holds files {_default('out')}",
    )
    p.add_argument(
        "--name", default=None, help=f"file stem of the saved model, NAME.zip {_default('name')}"
    )
    p.add_argument(
        "--total-timesteps",
        type=int,
        default=None,
        metavar="STEPS",
        help="training budget, env steps of all envs together, rounded up to whole rollouts "
        f"(n_steps x n_envs) {_default('total_timesteps', 'its n_timesteps')}",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seed of the first training env (env i: SEED + i) and of PPO; >= 1000000 keeps "
        f"training users apart from evaluation users {_default('seed')}",
    )


def _add_evaluation_options(p: argparse.ArgumentParser) -> None:
    """The periodic evaluation and the checkpoints."""
    p.add_argument(
        "--eval-seed",
        type=int,
        default=None,
        metavar="SEED",
        help=f"seed of the first periodic-evaluation user {_default('eval_seed')}",
    )
    p.add_argument(
        "--n-eval-episodes",
        type=int,
        default=None,
        metavar="N",
        help=f"users per periodic evaluation, 0: none {_default('n_eval_episodes')}",
    )
    p.add_argument(
        "--eval-freq",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"env steps (all envs) between periodic evaluations {_default('eval_freq')}",
    )
    p.add_argument(
        "--checkpoint-freq",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"env steps (all envs) between checkpoints {_default('checkpoint_freq')}",
    )


def _add_env_options(p: argparse.ArgumentParser) -> None:
    """How many training envs, and the vector env that steps them."""
    p.add_argument(
        "--n-envs",
        type=int,
        default=None,
        metavar="N",
        help=f"parallel training envs {_default('n_envs', 'its n_envs')}",
    )
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
    p.add_argument(
        "--init-from",
        type=Path,
        default=None,
        metavar="ZIP",
        help="fine-tune: start from this model's weights and normalisation statistics "
        f"{_default('init_from', 'random weights')}",
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
    p.add_argument(
        "--device", default=None, help=f"torch device of the learner {_default('device')}"
    )
    p.add_argument(
        "--torch-threads",
        type=int,
        default=None,
        metavar="N",
        help=f"torch threads of the learner process {_default('torch_threads')}",
    )
    p.add_argument(
        "--verbose",
        type=int,
        default=None,
        metavar="{0,1,2}",
        help=f"SB3 verbosity, 0 (quiet) to 2 {_default('verbose')}",
    )


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
        run, saved = resolve_resume(args, given)
    else:
        run = resolve(args, given)
        check_fresh_out(run.args.out)
    a = run.args
    if (note := run.budget_note()) is not None:
        print(note, file=sys.stderr)
    torch.set_num_threads(a.torch_threads)
    if a.init_from is not None and not a.resume:
        init_files(a.init_from)  # a missing file fails before any env starts
    a.out.mkdir(parents=True, exist_ok=True)
    env, eval_env = make_envs(run)
    try:
        model, config, steps = _setup_model(run, env, saved)
        return _learn(run, model, eval_env, config, steps)
    finally:
        close_env(env)
        if eval_env is not None:
            close_env(eval_env)


def _setup_model(run: Run, env: Any, saved: dict[str, Any] | None) -> tuple[Any, dict, int]:
    """The model (new, fine-tuned or resumed), the run's config and the step count it starts at.

    ``run_config.yaml`` is written once the model is set up, so that a failed start leaves an
    earlier run's file alone.
    """
    a = run.args
    ckpt_dir = a.out / "checkpoints"
    tb = str(a.out / "tb") if a.tensorboard else None
    if saved is not None:
        zip_path, pkl, is_point = resume_source(ckpt_dir, a.name)
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
        config = config_dict(run, residual_section(env), {})
        model = PPO(
            run.hyper.get("policy", "MlpPolicy"),
            env,
            seed=a.seed,
            device=a.device,
            tensorboard_log=tb,
            verbose=a.verbose,
            **ppo_kwargs(run),
        )
        steps = 0
        if a.init_from is not None:
            config["init_from_sha256"] = init_from_model(model, env, a.init_from)
            print(f"starting from the weights of {a.init_from}", file=sys.stderr)
    (a.out / "run_config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return model, config, steps


def _callbacks(
    run: Run, eval_env: Any, config: dict[str, Any], steps: int
) -> tuple[list[Any], ResumePointCallback]:
    """The run's callbacks (checkpoints, the resume point, the periodic evaluation with the best
    model), their schedules going on from ``steps``; and the resume point's callback."""
    a = run.args
    ckpt_dir, eval_dir, best_dir = a.out / "checkpoints", a.out / "eval", a.out / BEST_RETURN
    point = ResumePointCallback(ckpt_dir, a.name)
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
        eval_cb = MetricsEvalCallback(
            eval_env,
            n_eval_episodes=a.n_eval_episodes,
            eval_freq=max(1, a.eval_freq // run.n_envs),
            log_path=str(eval_dir),
            deterministic=True,
            callback_on_new_best=SaveBest(best_dir / a.name, config),
            verbose=0,  # its report is the project's one line on stderr ([eval @ N steps])
        )
        callbacks.append(eval_cb)
        if a.resume:
            best_cfg = best_dir / f"{a.name}_config.yaml"
            if not best_cfg.is_file():  # a run written before the folder had its name
                best_cfg = a.out / "best" / best_cfg.name
            n = restore_history(eval_cb, eval_dir, best_cfg, steps)
            print(f"{n} earlier evaluations carried over", file=sys.stderr)
    for cb in callbacks:  # the schedules go on where the interrupted run was
        cb.n_calls = steps // run.n_envs
    return callbacks, point


def _learn(run: Run, model: Any, eval_env: Any, config: dict[str, Any], steps: int) -> Path:
    """Run PPO to the budget with checkpoints, resume points and periodic evaluations."""
    a = run.args
    callbacks, point = _callbacks(run, eval_env, config, steps)
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
            f"{resume_files(a.out / 'checkpoints', a.name)[0].parent}"
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
    save_triple(model, None, final, config)
    print(f"wrote {final}.zip ({model.num_timesteps} steps, {wall:.0f} s)", file=sys.stderr)
    return final.with_suffix(".zip")


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
