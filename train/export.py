"""Export a checkpoint of a training run as a model ``PPOPolicy`` loads (``ppo:PATH``).

Run::

    python -m train.export runs/ppo --steps 100000 --out models/ppo_aligner

copies ``RUN/checkpoints/NAME_<steps>_steps.zip`` and its ``NAME_vecnormalize_<steps>_steps.pkl``
to ``OUT.zip`` and ``OUT_vecnormalize.pkl``, writes the run's config (``RUN/run_config.yaml``) as
``OUT_config.yaml`` with the checkpoint's step count and origin (relative to ``RUN``; the run's
paths as :func:`train.ppo.recorded_path` records them), and loads the result once with
:meth:`policies.learned.PPOPolicy.load` so that a broken export fails here, not in an evaluation.
Nothing is written when an input is missing, nor over an existing ``OUT.*`` without
``--overwrite``.

``--choice-only`` exports only the phrase-choice part of the learned correction: the exported
config's residual gets ``pace_scale = audio_scale = 0``, so the paces are the base controller's
and the network only moves the next-phrase target (``choice_only: true`` records it). The models
shipped from attempt 12 to 14 were exported this way (``docs/history.md``).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml

__all__ = ["ExportArgs", "export", "main", "parse_args"]


@dataclass(frozen=True)
class ExportArgs:
    """Arguments of ``python -m train.export``.

    Attributes:
        run: Output directory of a ``python -m train.ppo`` run.
        steps: Step count of the checkpoint to export (``checkpoints/NAME_<steps>_steps.zip``).
        out: Stem of the exported model (``OUT.zip``, ``OUT_vecnormalize.pkl``,
            ``OUT_config.yaml``).
        name: The run's model name; None: ``train.name`` of ``RUN/run_config.yaml``.
        choice_only: Keep only the phrase-choice correction (pace corrections off).
        overwrite: Replace existing ``OUT.*`` files.
    """

    run: Path
    steps: int
    out: Path
    name: str | None = None
    choice_only: bool = False
    overwrite: bool = False


def parse_args(argv: Sequence[str] | None = None) -> ExportArgs:
    """Parse the command line into :class:`ExportArgs`."""
    p = argparse.ArgumentParser(prog="python -m train.export", description=__doc__.split("\n")[0])
    p.add_argument("run", type=Path, help="output directory of a python -m train.ppo run")
    p.add_argument("--steps", type=int, required=True, help="step count of the checkpoint")
    p.add_argument("--out", type=Path, required=True, help="stem of the exported model")
    p.add_argument(
        "--name", default=None, help="the run's model name (default: train.name of its config)"
    )
    p.add_argument(
        "--choice-only",
        action="store_true",
        help="keep only the phrase-choice correction (the paces stay the base controller's)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing OUT.* files")
    ns = p.parse_args(argv)
    return ExportArgs(
        run=ns.run,
        steps=ns.steps,
        out=ns.out,
        name=ns.name,
        choice_only=ns.choice_only,
        overwrite=ns.overwrite,
    )


def export(args: ExportArgs) -> Path:
    """Export the checkpoint; returns the model zip.

    Raises:
        FileNotFoundError: naming the missing checkpoint, normalisation or run config.
        FileExistsError: naming an existing output file (without ``overwrite``).
        ValueError: if the exported model does not load.
    """
    from policies.learned import PPOPolicy, model_files
    from train.ppo import checkpoint_files, recorded_args

    run_config = args.run / "run_config.yaml"
    if not run_config.is_file():
        raise FileNotFoundError(f"train.export: not found: {run_config}")
    config = yaml.safe_load(run_config.read_text())
    if not isinstance(config, dict):
        raise ValueError(f"{run_config}: not a run config")
    name = args.name
    if name is None:
        train = config.get("train")
        name = train.get("name") if isinstance(train, dict) else None
        if not isinstance(name, str) or not name:
            raise ValueError(f"{run_config}: no train.name (pass --name)")
    sources = (*checkpoint_files(args.run / "checkpoints", name, args.steps), run_config)
    for f in sources:
        if not f.is_file():
            raise FileNotFoundError(f"train.export: not found: {f}")
    config["num_timesteps"] = args.steps
    if args.choice_only:
        residual = config.get("residual")
        if not isinstance(residual, dict):
            raise ValueError(f"{run_config}: no residual section, so no correction to restrict")
        residual["pace_scale"] = 0.0
        residual["audio_scale"] = 0.0
        config["choice_only"] = True
    config["exported_from"] = sources[0].relative_to(args.run).as_posix()
    if isinstance(config.get("train"), dict):
        config["train"] = recorded_args(config["train"])
    targets = model_files(args.out)
    taken = [t for t in targets if t.exists()]
    if taken and not args.overwrite:
        raise FileExistsError(f"train.export: {taken[0]} exists; give --overwrite to replace it")
    targets[0].parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(sources[0], targets[0])
    shutil.copyfile(sources[1], targets[1])
    targets[2].write_text(yaml.safe_dump(config, sort_keys=False))
    PPOPolicy.load(targets[0])
    return targets[0]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args = parse_args(argv)
    try:
        path = export(args)
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        print(f"train.export: error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
