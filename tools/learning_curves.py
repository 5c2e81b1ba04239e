"""Validation score against training steps for two or more recipes, the same seeds each: the
figure of ``docs/batched.md``.

    python tools/learning_curves.py --recipe "2 envs (subproc)" runs/old_s* \\
        --recipe "32 batched envs" runs/new_s* --out docs/batched_learning.png

Each run directory holds ``eval/evaluations.npz`` (written by ``train.ppo``'s periodic
evaluation on the 48 validation users); each panel draws every run thin and the recipe's mean
over its runs thick: the selection score (mean |AM| + mean |EM|, s; lower is better: what
``langctrl export --best`` minimises) and the mean return.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _curves(run: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    data = np.load(run / "eval" / "evaluations.npz")
    steps = np.asarray(data["timesteps"], dtype=float)
    score = np.nanmean(data["abs_am"], axis=1) + np.mean(data["em_mean_abs"], axis=1)
    ret = np.mean(data["results"], axis=1)
    return steps, score, ret


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--recipe", nargs="+", action="append", required=True, metavar=("NAME", "RUN"),
        help="a recipe's name and its run directories",
    )  # fmt: skip
    p.add_argument("--out", type=Path, required=True, help="the figure (PNG)")
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_s, ax_r) = plt.subplots(1, 2, figsize=(10, 3.6))
    for k, (name, *runs) in enumerate(args.recipe):
        color = f"C{k}"
        curves = [_curves(Path(r)) for r in runs]
        for steps, score, ret in curves:
            ax_s.plot(steps, score, color=color, lw=0.7, alpha=0.45)
            ax_r.plot(steps, ret, color=color, lw=0.7, alpha=0.45)
        n = min(len(c[0]) for c in curves)
        steps = curves[0][0][:n]
        ax_s.plot(steps, np.mean([c[1][:n] for c in curves], axis=0), color=color, lw=2.2,
                  label=f"{name} ({len(curves)} seeds)")  # fmt: skip
        ax_r.plot(steps, np.mean([c[2][:n] for c in curves], axis=0), color=color, lw=2.2)
        print(
            f"{name}: mean over seeds of the score at each evaluation "
            f"{np.round(np.mean([c[1][:n] for c in curves], axis=0), 4).tolist()}"
        )
    ax_s.set_xlabel("training steps")
    ax_s.set_ylabel("mean |AM| + mean |EM| (s)")
    ax_s.set_title("validation score (48 users; lower is better)")
    ax_r.set_xlabel("training steps")
    ax_r.set_ylabel("mean return")
    ax_r.set_title("validation return")
    ax_s.legend(fontsize=8)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
