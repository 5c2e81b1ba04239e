"""Export a checkpoint of a training run as a model ``PPOPolicy`` loads (``ppo:PATH``).

Run::

    python -m train.export runs/ppo --steps 100000 --out models/ppo_aligner
    python -m train.export runs/ppo --best --out models/ppo_aligner   # chosen on validation

copies ``RUN/checkpoints/NAME_<steps>_steps.zip`` and its ``NAME_vecnormalize_<steps>_steps.pkl``
to ``OUT.zip`` and ``OUT_vecnormalize.pkl``, writes the run's config (``RUN/run_config.yaml``) as
``OUT_config.yaml`` with the checkpoint's step count and origin (relative to ``RUN``; the run's
paths as :func:`train.provenance.recorded_path` records them), and loads the result once with
:meth:`policies.learned.PPOPolicy.load` so that a broken export fails here, not in an evaluation.
Nothing is written when an input is missing, nor over an existing ``OUT.*`` without
``--overwrite``.

``--best`` exports the checkpoint the periodic evaluations on the held-out users favour instead:
for a phrase chooser's run (content recorded) the most content among the checkpoints that keep
the base's alignment and natural voice (:data:`CONTENT_RULE`); for any other run the lowest
mean ``|AM|`` + mean ``|EM|`` of the held-out users (``train.ppo``'s ``eval_seed`` onwards,
recorded in ``RUN/eval/evaluations.npz``) among the evaluations made at a checkpoint's step count
(``eval_freq`` a multiple of ``checkpoint_freq``), the earliest on a tie; so the choice is
deterministic and uses no test user. A session that did not end by itself (``|AM|`` NaN) makes
its evaluation ineligible. The exported config records the choice (``selected_by``) and
``--best`` prints every eligible evaluation's figures on stderr (see :func:`eval_scores`).

``--choice-only`` exports only the phrase-choice part of the learned correction: the exported
config's residual gets ``pace_scale = audio_scale = 0``, so the paces are the base controller's
and the network only moves the next-phrase target (``choice_only: true`` records it). The models
shipped from attempt 12 to 14 were exported this way (``HISTORY.md``).

``--terminal S`` gives the exported model's base controller a terminal phase of ``S`` s
(:class:`policies.analytic.LanguageController`'s ``terminal``; ``terminal_at_export`` records
it): the shipped phrase chooser, trained on ``lc-fill``, is deployed on ``lc-fill-end``'s base
with ``--terminal 1`` (``docs/learned.md``).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "EvalScore",
    "ExportArgs",
    "best_steps",
    "build_parser",
    "eval_scores",
    "export",
    "main",
    "parse_args",
]


@dataclass(frozen=True)
class ExportArgs:
    """Arguments of ``python -m train.export``.

    Attributes:
        run: Output directory of a ``python -m train.ppo`` run.
        steps: Step count of the checkpoint to export (``checkpoints/NAME_<steps>_steps.zip``);
            None: the one :func:`best_steps` picks (``--best``).
        out: Stem of the exported model (``OUT.zip``, ``OUT_vecnormalize.pkl``,
            ``OUT_config.yaml``).
        name: The run's model name; None: ``train.name`` of ``RUN/run_config.yaml``.
        choice_only: Keep only the phrase-choice correction (pace corrections off).
        overwrite: Replace existing ``OUT.*`` files.
        terminal: The base's terminal-phase horizon in the exported config (s, >= 0); None:
            the run's.
    """

    run: Path
    steps: int | None
    out: Path
    name: str | None = None
    choice_only: bool = False
    overwrite: bool = False
    terminal: float | None = None


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl export`` (``python -m train.export``)."""
    p = argparse.ArgumentParser(
        prog="langctrl export",
        description=__doc__.split("\n")[0] + " Also run as python -m train.export.",
    )
    p.add_argument("run", type=Path, metavar="RUN", help="the run directory of a langctrl train")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument(
        "--steps", type=int, help="step count of the checkpoint (this or --best is required)"
    )
    which.add_argument(
        "--best",
        action="store_true",
        help="the checkpoint the periodic evaluations on the held-out users favour: for a phrase "
        f"chooser's run the {CONTENT_RULE}; for any other run the lowest mean |AM| + mean |EM| "
        "(not the run's best_return/, SB3's highest return)",
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="STEM",
        help="stem of the exported model: STEM.zip, STEM_vecnormalize.pkl, STEM_config.yaml "
        "(required)",
    )
    p.add_argument(
        "--name", default=None, help="the run's model name (default: train.name of its config)"
    )
    p.add_argument(
        "--choice-only",
        action="store_true",
        help="keep only the phrase-choice correction (the paces stay the base controller's)",
    )
    p.add_argument(
        "--terminal",
        type=float,
        default=None,
        metavar="S",
        help="give the exported model's base a terminal phase of S s (the shipped phrase "
        "chooser: 1, lc-fill-end's base; default: the run's)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing OUT.* files")
    return p


def parse_args(argv: Sequence[str] | None = None) -> ExportArgs:
    """Parse the command line into :class:`ExportArgs`."""
    p = build_parser()
    ns = p.parse_args(argv)
    return ExportArgs(
        run=ns.run,
        steps=ns.steps,
        out=ns.out,
        name=ns.name,
        choice_only=ns.choice_only,
        overwrite=ns.overwrite,
        terminal=ns.terminal,
    )


def export(args: ExportArgs) -> Path:
    """Export the checkpoint; returns the model zip.

    Raises:
        FileNotFoundError: naming the missing checkpoint, normalisation or run config.
        FileExistsError: naming an existing output file (without ``overwrite``).
        ValueError: if the exported model does not load.
    """
    from policies.learned import PPOPolicy, model_files
    from train.provenance import recorded_args
    from train.resume import checkpoint_files

    run_config = args.run / "run_config.yaml"
    if not run_config.is_file():
        raise FileNotFoundError(f"langctrl export: not found: {run_config}")
    config = yaml.safe_load(run_config.read_text())
    if not isinstance(config, dict):
        raise ValueError(f"{run_config}: not a run config")
    name = args.name
    if name is None:
        train = config.get("train")
        name = train.get("name") if isinstance(train, dict) else None
        if not isinstance(name, str) or not name:
            raise ValueError(f"{run_config}: no train.name (pass --name)")
    steps, chosen = args.steps, None
    if steps is None:
        chosen = best_steps(args.run, name)
        steps = chosen.steps
    sources = (*checkpoint_files(args.run / "checkpoints", name, steps), run_config)
    for f in sources:
        if not f.is_file():
            raise FileNotFoundError(f"langctrl export: not found: {f}")
    config["num_timesteps"] = steps
    if chosen is not None:
        config["selected_by"] = chosen.record(config)
    if args.choice_only:
        residual = _residual(config, run_config, "no correction to restrict")
        residual["pace_scale"] = 0.0
        residual["audio_scale"] = 0.0
        config["choice_only"] = True
    if args.terminal is not None:
        _set_terminal(config, run_config, args.terminal)
    config["exported_from"] = sources[0].relative_to(args.run).as_posix()
    if isinstance(config.get("train"), dict):
        config["train"] = recorded_args(config["train"])
    targets = model_files(args.out)
    taken = [t for t in targets if t.exists()]
    if taken and not args.overwrite:
        raise FileExistsError(f"langctrl export: {taken[0]} exists; give --overwrite to replace it")
    targets[0].parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(sources[0], targets[0])
    shutil.copyfile(sources[1], targets[1])
    targets[2].write_text(yaml.safe_dump(config, sort_keys=False))
    PPOPolicy.load(targets[0])
    return targets[0]


def _set_terminal(config: dict[str, Any], run_config: Path, terminal: float) -> None:
    """Give the exported config's base a terminal phase (``--terminal``)."""
    import math

    if not (math.isfinite(terminal) and terminal >= 0.0):
        raise ValueError(f"langctrl export: --terminal must be finite and >= 0, got {terminal!r}")
    residual = _residual(config, run_config, "no base to give a terminal phase")
    residual["terminal"] = float(terminal)
    config["terminal_at_export"] = float(terminal)


def _residual(config: dict[str, Any], run_config: Path, why: str) -> dict[str, Any]:
    """The run config's ``residual`` section, or a ValueError naming the file and ``why``."""
    residual = config.get("residual")
    if not isinstance(residual, dict):
        raise ValueError(f"{run_config}: no residual section, so {why}")
    return residual


@dataclass(frozen=True)
class EvalScore:
    """One periodic evaluation of a run, summarised: means over its held-out users.

    Attributes:
        steps: Step count of the evaluation (the checkpoint of that step has its weights).
        abs_am: Mean ``|AM|`` (s).
        em_mean_abs: Mean over users of the mean ``|EM|`` (s).
        a_dev: Mean over users of the mean ``|a - 1|`` while speaking.
        n_users: Held-out users evaluated.
        content_share: Mean share of the motion in which words are heard (NaN: not recorded,
            a run of the alignment recipes).
        voice_natural: Mean share of the speech heard at a natural voice (NaN likewise).
        within: Share of the sessions with ``|AM| <= 1 s``.
        legs_in_step: Mean share of the leg boundaries whose words start within 1 s of the
            leg, over the sessions that have boundaries (NaN: none, or not recorded).
    """

    steps: int
    abs_am: float
    em_mean_abs: float
    a_dev: float
    n_users: int
    content_share: float = float("nan")
    voice_natural: float = float("nan")
    within: float = float("nan")
    legs_in_step: float = float("nan")

    @property
    def speech(self) -> bool:
        """Whether the evaluation recorded the speech people hear (a phrase chooser's run)."""
        import math

        return math.isfinite(self.content_share)

    @property
    def score(self) -> float:
        """Mean ``|AM|`` + mean ``|EM|`` (s): the selection score (lower is better)."""
        return self.abs_am + self.em_mean_abs

    def record(self, run_config: dict[str, Any]) -> dict[str, Any]:
        """What an exported config records of the choice."""
        train = run_config.get("train")
        train = train if isinstance(train, dict) else {}
        if self.speech:
            return {
                "rule": CONTENT_RULE,
                "eval_seed": train.get("eval_seed"),
                "n_users": self.n_users,
                "steps": self.steps,
                "content_share": round(self.content_share, 6),
                "voice_natural": round(self.voice_natural, 6),
                "abs_am_le_1s": round(self.within, 6),
                "legs_in_step": round(self.legs_in_step, 6),
                "abs_am": round(self.abs_am, 6),
                "em_mean_abs": round(self.em_mean_abs, 6),
            }
        return {
            "rule": "lowest periodic-evaluation mean |AM| + mean |EM| among checkpoints",
            "eval_seed": train.get("eval_seed"),
            "n_users": self.n_users,
            "steps": self.steps,
            "score": round(self.score, 6),
            "abs_am": round(self.abs_am, 6),
            "em_mean_abs": round(self.em_mean_abs, 6),
            "a_dev": round(self.a_dev, 6),
        }


CONTENT_RULE = (
    "highest periodic-evaluation mean content share among checkpoints with a share of "
    "|AM| <= 1 s no lower than the base's, a mean voice natural no lower than the base's - 0.02 "
    "and a mean share of legs in step no lower than the base's (where recorded)"
)
"""How ``--best`` chooses among the evaluations of a phrase chooser's run (content recorded),
against its base's figures on the same people (``RUN/eval/base.npz``, written by ``train.ppo``
before training; without it, the best figures any checkpoint reached stand for the base's)."""


def eval_scores(run: Path) -> list[EvalScore]:
    """The periodic evaluations recorded in ``RUN/eval/evaluations.npz``, in step order.

    An evaluation in which a session did not end by itself (``|AM|`` NaN) is left out.

    Raises:
        FileNotFoundError: naming the file, if the run has no evaluations.
        ValueError: naming the file, if it lacks the metrics (a run made before ``train.ppo``
            recorded them, or without periodic evaluation).
    """
    import numpy as np

    from train.callbacks import EVAL_METRICS

    path = run / "eval" / "evaluations.npz"
    if not path.is_file():
        raise FileNotFoundError(
            f"langctrl export: not found: {path} (a run with periodic evaluation)"
        )
    with np.load(path) as data:
        missing = [k for k in ("timesteps", *EVAL_METRICS[:3]) if k not in data]
        if missing:
            raise ValueError(
                f"{path}: no {', '.join(missing)} (recorded by train.ppo's periodic evaluation "
                "since v0.3.1; retrain, or export with --steps)"
            )
        steps = np.asarray(data["timesteps"], dtype=int)
        am, em, a_dev = (np.asarray(data[k], dtype=float) for k in EVAL_METRICS[:3])
        nan = np.full(am.shape, np.nan)
        content, voice, legs = (
            np.asarray(data[k], dtype=float) if k in data else nan for k in EVAL_METRICS[3:6]
        )
    out = []
    for i, n in enumerate(steps):
        if am[i].size == 0 or not np.isfinite(am[i]).all():
            continue
        speech = bool(np.isfinite(content[i]).all())
        out.append(
            EvalScore(
                int(n),
                float(am[i].mean()),
                float(em[i].mean()),
                float(np.nanmean(a_dev[i])),
                int(am[i].size),
                float(content[i].mean()) if speech else float("nan"),
                float(voice[i].mean()) if speech else float("nan"),
                float(np.mean(am[i] <= 1.0)),
                _finite_mean(legs[i]),
            )
        )
    return sorted(out, key=lambda e: e.steps)


def _finite_mean(x: Any) -> float:
    """The mean of the finite values (NaN when there are none)."""
    import numpy as np

    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if x.size else float("nan")


def base_score(run: Path) -> EvalScore | None:
    """The base's figures on the held-out users (``RUN/eval/base.npz``), or None."""
    import numpy as np

    from train.callbacks import BASE_FILE

    path = run / "eval" / BASE_FILE
    if not path.is_file():
        return None
    with np.load(path) as data:
        am = np.asarray(data["abs_am"], dtype=float)
        return EvalScore(
            0,
            float(np.mean(am)),
            float(np.mean(data["em_mean_abs"])),
            float(np.mean(data["a_dev"])),  # NaN where it was not recorded
            int(am.size),
            float(np.mean(data["content_share"])),
            float(np.mean(data["voice_natural"])),
            float(np.mean(am <= 1.0)),
            _finite_mean(data["legs_in_step"]) if "legs_in_step" in data else float("nan"),
        )


def best_steps(run: Path, name: str) -> EvalScore:
    """The evaluation with the lowest score (:attr:`EvalScore.score`; the earliest on a tie)
    among those made at a step count that has a checkpoint in ``RUN/checkpoints``.

    Raises:
        FileNotFoundError: no evaluations (see :func:`eval_scores`).
        ValueError: naming the run, if no evaluation has a checkpoint of its step count.
    """
    from train.resume import checkpoint_files

    eligible = [
        e
        for e in eval_scores(run)
        if all(f.is_file() for f in checkpoint_files(run / "checkpoints", name, e.steps))
    ]
    if not eligible:
        raise ValueError(
            f"{run}: no periodic evaluation at the step count of a checkpoint {name}_<steps>_steps"
            ".zip (make eval_freq a multiple of checkpoint_freq)"
        )
    if all(e.speech for e in eligible):  # a phrase chooser's run: CONTENT_RULE
        for e in eligible:
            print(
                f"{e.steps:>9} steps: content {e.content_share:.4f}, voice natural "
                f"{e.voice_natural:.4f}, |AM| <= 1 s {e.within:.3f}, legs in step "
                f"{e.legs_in_step:.3f}, mean |AM| {e.abs_am:.3f} s ({e.n_users} users)",
                file=sys.stderr,
            )
        base = base_score(run)
        if base is not None:
            top, loud, legs = base.within, base.voice_natural, base.legs_in_step
            print(
                f"    base: content {base.content_share:.4f}, voice natural "
                f"{base.voice_natural:.4f}, |AM| <= 1 s {base.within:.3f}, legs in step "
                f"{base.legs_in_step:.3f}",
                file=sys.stderr,
            )
        else:
            top = max(e.within for e in eligible)
            loud = max(e.voice_natural for e in eligible)
            recorded = [e.legs_in_step for e in eligible if e.legs_in_step == e.legs_in_step]
            legs = max(recorded, default=float("nan"))
        ok = [
            e
            for e in eligible
            if e.within >= top
            and e.voice_natural >= loud - 0.02
            and not e.legs_in_step < legs - 1e-12  # NaN on either side: not recorded
        ]
        if not ok:
            raise ValueError(
                f"{run}: no checkpoint holds the base's share of |AM| <= 1 s ({top:.3f}), "
                f"its voice natural - 0.02 ({loud - 0.02:.4f}) and its legs in step "
                f"({legs:.3f}) on the held-out users"
            )
        best = max(ok, key=lambda e: (e.content_share, -e.steps))
        print(f"chosen: {best.steps} steps (content {best.content_share:.4f})", file=sys.stderr)
        return best
    for e in eligible:
        print(
            f"{e.steps:>9} steps: mean |AM| {e.abs_am:.3f} s + mean |EM| {e.em_mean_abs:.3f} s "
            f"= {e.score:.3f} s (|a-1| {e.a_dev:.3f}, {e.n_users} users)",
            file=sys.stderr,
        )
    best = min(eligible, key=lambda e: (e.score, e.steps))
    print(f"chosen: {best.steps} steps (score {best.score:.3f} s)", file=sys.stderr)
    return best


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args = parse_args(argv)
    try:
        path = export(args)
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        print(f"langctrl export: error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
