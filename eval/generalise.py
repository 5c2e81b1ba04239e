"""Does a learned aligner generalise? Every policy on every held-out exercise and person.

Run::

    python -m eval.generalise --model runs/general/best/ppo_general.zip --out out/generalise
    python -m eval.generalise --model MODEL --role test --users 48 --out out/test_look_1

The split (exercises and user seeds of each role, the users' perturbations) is the one recorded
with the model (``worlds`` in ``MODEL_config.yaml``, written by ``python -m train.ppo`` from a
config with a ``worlds`` section), or ``--split CONFIG`` (a config with one). Every policy of
``--policies`` (default ``ac,lc-noap,lc,lc-em-end``) and the learned one (``ppo:MODEL``) runs
on every exercise of the role times its first ``--users`` user seeds, each user a
:class:`~langenv.users.PerturbedUser` of the split's perturbations (``--no-perturb``: the plain
synthetic population), the same episodes for every policy: paired.

``--role`` is ``validation`` by default. The test exercises and users are for the claim: look
at them (``--role test``) only with the model you ship, at most twice per study, and record each
look in ``docs/history.md``; the command says so when it runs on them.

Writes into ``OUT`` (refused when it holds files, unless ``--overwrite``):

* ``sessions.csv``: one row per episode, the session metrics of :mod:`eval.metrics` plus
  ``exercise``, ``perturbation``, ``abs_am_le_1s`` and ``protective_stop``;
* ``generalise.md``: per metric (:data:`COMPARED`) and per exercise (and all together), each
  policy's statistic, the best analytic one, and the paired bootstrap 95 % intervals of the learned
  minus the best analytic and minus ``lc-em-end``;
* ``METRIC.png``: one plot per metric (each policy's statistic per exercise, and the intervals);
* ``config.json``: the arguments, the split and whether this was a look at the test set.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from eval.stats import Stat

__all__ = [
    "COMPARED",
    "Comparison",
    "build_parser",
    "compare_rows",
    "main",
    "markdown",
    "parse_args",
]

#: The metrics compared: column -> (statistic, label). Lower is better for all of them except
#: ``abs_am_le_1s`` (the share of sessions with ``|AM| <= 1 s``), where higher is.
COMPARED: dict[str, tuple[Stat, str]] = {
    "em_mean_abs": ("mean", "mean |EM| (s)"),
    "abs_am": ("median", "median |AM| (s)"),
    "abs_am_le_1s": ("mean", "share |AM| <= 1 s"),
    "a_dev": ("mean", "mean |a - 1|"),
    "protective_stop": ("mean", "protective stops (share)"),
}
_HIGHER_IS_BETTER = frozenset({"abs_am_le_1s"})
REFERENCE = "lc-em-end"


@dataclass(frozen=True)
class Comparison:
    """One metric on one group of episodes (an exercise, or ``"all"``).

    Attributes:
        metric: Column of :data:`COMPARED`.
        group: Exercise name or ``"all"``.
        values: Each policy's statistic.
        best: The best analytic policy on this metric and group.
        vs_best: Learned minus best analytic: ``(estimate, lo, hi)``, paired by episode.
        vs_reference: Learned minus ``lc-em-end`` (NaNs when it did not run).
        n: Episodes per policy.
    """

    metric: str
    group: str
    values: dict[str, float]
    best: str
    vs_best: tuple[float, float, float]
    vs_reference: tuple[float, float, float]
    n: int


def _column(rows: list[dict[str, Any]], policy: str, metric: str) -> np.ndarray:
    mine = sorted((r for r in rows if r["policy"] == policy), key=lambda r: r["key"])
    return np.array([float(r[metric]) for r in mine], dtype=np.float64)


def compare_rows(
    rows: list[dict[str, Any]],
    learned: str,
    analytic: Sequence[str],
    *,
    n_boot: int = 2000,
    seed: int = 0,
) -> list[Comparison]:
    """Per metric and group, the learned policy against the best analytic one (paired).

    Args:
        rows: Episode rows with ``policy``, ``exercise``, ``key`` (the episode, the same for every
            policy) and the columns of :data:`COMPARED`.
        learned: The learned policy's name in ``rows``.
        analytic: The analytic policies' names.
        n_boot: Bootstrap resamples.
        seed: Seed of the bootstrap.

    Raises:
        ConfigError: when the policies did not run the same episodes.
    """
    from langenv.errors import ConfigError

    groups = sorted({str(r["exercise"]) for r in rows})
    out = []
    for metric, (stat, _label) in COMPARED.items():
        for group in [*groups, "all"]:
            sub = [r for r in rows if group == "all" or r["exercise"] == group]
            keys = {
                p: sorted(r["key"] for r in sub if r["policy"] == p) for p in [learned, *analytic]
            }
            if any(k != keys[learned] for k in keys.values()):
                raise ConfigError(f"{group}: the policies did not run the same episodes")
            cols = {p: _column(sub, p, metric) for p in keys}
            fn = np.nanmedian if stat == "median" else np.nanmean
            values = {p: float(fn(c)) for p, c in cols.items()}
            sign = -1.0 if metric in _HIGHER_IS_BETTER else 1.0
            best = min(analytic, key=lambda p: (sign * values[p], p))
            vs_best = _diff(cols[learned], cols[best], stat, n_boot, seed)
            vs_ref = (math.nan, math.nan, math.nan)
            if REFERENCE in cols:
                vs_ref = _diff(cols[learned], cols[REFERENCE], stat, n_boot, seed)
            n = len(keys[learned])
            out.append(Comparison(metric, group, values, best, vs_best, vs_ref, n))
    return out


def _diff(
    x: np.ndarray, y: np.ndarray, stat: Stat, n_boot: int, seed: int
) -> tuple[float, float, float]:
    """Paired bootstrap interval of ``stat(x - y)`` (each comparison from the same seed)."""
    from eval.stats import bootstrap_diff_ci

    ci = bootstrap_diff_ci(
        x, y, paired=True, stat=stat, n_boot=n_boot, rng=np.random.default_rng(seed)
    )
    return (ci.estimate, ci.lo, ci.hi)


def _ci(c: tuple[float, float, float]) -> str:
    est, lo, hi = c
    if math.isnan(est):
        return "n/a"
    return f"{est:+.3f} [{lo:+.3f}, {hi:+.3f}]"


def markdown(comparisons: Sequence[Comparison], learned: str, analytic: Sequence[str]) -> str:
    """The comparisons as Markdown tables, one per metric."""
    lines: list[str] = []
    for metric, (_stat, label) in COMPARED.items():
        mine = [c for c in comparisons if c.metric == metric]
        if not mine:
            continue
        better = "higher" if metric in _HIGHER_IS_BETTER else "lower"
        lines += [f"### {label} ({better} is better)", ""]
        head = ["exercise", "n", *analytic, learned, "best analytic", f"{learned} - best [95 % CI]"]
        head.append(f"{learned} - {REFERENCE} [95 % CI]")
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for c in mine:
            cells = [c.group, str(c.n), *(f"{c.values[p]:.3f}" for p in [*analytic, learned])]
            cells += [c.best, _ci(c.vs_best), _ci(c.vs_reference)]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def plot_metric(
    comparisons: Sequence[Comparison], metric: str, policies: Sequence[str], path: Path
) -> Path:
    """One metric's figure: each policy's statistic per group (top), and the learned minus the
    best analytic with its interval (bottom)."""
    from matplotlib.figure import Figure

    from eval.plots import _save, policy_color

    mine = [c for c in comparisons if c.metric == metric]
    groups = [c.group for c in mine]
    x = np.arange(len(groups))
    fig = Figure(figsize=(1.6 + 1.3 * len(groups), 5.0), facecolor="white")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    width = 0.8 / len(policies)
    for i, p in enumerate(policies):
        top.bar(
            x + (i - (len(policies) - 1) / 2) * width,
            [c.values[p] for c in mine],
            width,
            label=p,
            color=policy_color(p, i),
        )
    top.set_ylabel(COMPARED[metric][1])
    top.legend(
        fontsize=7, ncols=min(5, len(policies)), loc="lower center", bbox_to_anchor=(0.5, 1.0)
    )
    est = np.array([c.vs_best[0] for c in mine])
    lo = np.array([c.vs_best[1] for c in mine])
    hi = np.array([c.vs_best[2] for c in mine])
    bottom.errorbar(x, est, yerr=[est - lo, hi - est], fmt="o", color="black", capsize=4)
    bottom.axhline(0.0, color="grey", lw=0.8)
    bottom.set_ylabel("learned - best\nanalytic (95 % CI)")
    bottom.set_xticks(x, groups, rotation=20)
    fig.tight_layout()
    return _save(fig, path)


def _perturbation(user: Any, seed: int) -> str:
    """The perturbation the env draws for ``seed`` (its first draws are the user's)."""
    from gymnasium.utils import seeding

    rng, _ = seeding.np_random(seed)
    user.reset(rng)
    return str(getattr(user, "kind", "none"))


def _split(ns: argparse.Namespace) -> Any:
    from langenv.worlds import WorldSplit
    from policies.learned import model_files

    return WorldSplit.load(ns.split if ns.split is not None else model_files(ns.model)[2])


def _jobs(ns: argparse.Namespace, split: Any, specs: list[str], names: dict[str, str]) -> list:
    from eval.compare import Job
    from langenv.users import PerturbedUser, SyntheticUser

    jobs = []
    for ex, seed in split.pairs(ns.role, ns.users * len(split.exercises(ns.role))):
        user = SyntheticUser() if ns.no_perturb else PerturbedUser(split.perturbations)
        out_dir = ns.out / "sessions" / Path(ex).stem
        out_dir.mkdir(parents=True, exist_ok=True)
        for spec in specs:
            job = Job(spec, f"s{seed}", seed, None, str(out_dir), False, False, None,
                      split.graphs.get(ex), names[spec], exercise=ex, user_model=user)  # fmt: skip
            jobs.append(job)
    return jobs


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl generalise`` (``python -m eval.generalise``)."""
    p = argparse.ArgumentParser(
        prog="langctrl generalise",
        description=__doc__.split("\n")[0] + " Also run as python -m eval.generalise.",
    )
    p.add_argument(
        "--model",
        type=Path,
        required=True,
        metavar="ZIP",
        help="the learned model (.zip; required)",
    )
    p.add_argument(
        "--policies",
        default="ac,lc-noap,lc,lc-em-end",
        metavar="LIST",
        help="comma-separated analytic policies to compare it with (default: %(default)s)",
    )
    p.add_argument(
        "--split",
        default=None,
        metavar="CONFIG",
        help="a training config with a 'worlds' section (default: the split recorded with the "
        "model)",
    )
    p.add_argument(
        "--role",
        choices=("validation", "test"),
        default="validation",
        help="which held-out exercises and users; test only for the model you ship, at most "
        "twice (default: %(default)s)",
    )
    p.add_argument(
        "--users",
        type=int,
        default=24,
        metavar="N",
        help="users per exercise: the role's first N user seeds (default: %(default)s)",
    )
    p.add_argument(
        "--no-perturb",
        action="store_true",
        help="the plain synthetic population instead of the split's perturbed users",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=2,
        metavar="N",
        help="parallel episode processes (default: %(default)s)",
    )
    p.add_argument(
        "--n-boot",
        type=int,
        default=2000,
        metavar="N",
        help="bootstrap resamples per interval (default: %(default)s)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the bootstrap (default: %(default)s)"
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="output directory, refused when it holds files (required)",
    )
    p.add_argument(
        "--overwrite", action="store_true", help="write into a non-empty --out all the same"
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line (see the module docstring)."""
    p = build_parser()
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (2: bad arguments or split)."""
    from eval.compare import policy_names, run_jobs
    from eval.report import atomic_write, write_sessions_csv
    from langenv.errors import ConfigError, ModelError

    ns = parse_args(argv)
    analytic = [s.strip() for s in ns.policies.split(",") if s.strip()]
    learned_spec = f"ppo:{ns.model}"
    try:
        if ns.users < 1:
            raise ConfigError(f"--users must be >= 1, got {ns.users}")
        if ns.out.is_dir() and any(ns.out.iterdir()) and not ns.overwrite:
            raise ConfigError(f"--out {ns.out} holds files; give --overwrite or another --out")
        from policies import load_policy

        for spec in [*analytic, learned_spec]:
            load_policy(spec)  # every policy loads before any episode runs
        split = _split(ns)
        split.pairs(ns.role, ns.users * len(split.exercises(ns.role)))  # enough users
    except (ConfigError, ModelError, FileNotFoundError, KeyError) as exc:
        print(f"eval.generalise: error: {exc}", file=sys.stderr)
        return 2
    if ns.role == "test":
        print(
            "eval.generalise: this is a look at the TEST exercises and users: record it and its "
            "figures in docs/history.md (at most two looks per study)",
            file=sys.stderr,
        )
    specs = [*analytic, learned_spec]
    names = policy_names(specs)
    jobs = _jobs(ns, split, specs, names)
    rows = run_jobs(jobs, ns.workers)
    for job, row in zip(jobs, rows, strict=True):
        row["exercise"] = job.exercise
        row["key"] = f"{job.exercise}/{job.user}"
        row["perturbation"] = _perturbation(job.user_model, job.seed)
        row["abs_am_le_1s"] = float(float(row["abs_am"]) <= 1.0)
    learned = names[learned_spec]
    comps = compare_rows(rows, learned, analytic, n_boot=ns.n_boot, seed=ns.seed)
    write_sessions_csv(
        [{k: v for k, v in r.items() if k != "key"} for r in rows], ns.out / "sessions.csv"
    )
    text = markdown(comps, learned, analytic)
    atomic_write(
        ns.out / "generalise.md", f"# {ns.role}: {', '.join(split.exercises(ns.role))}\n\n{text}"
    )
    for metric in COMPARED:
        plot_metric(comps, metric, [*analytic, learned], ns.out / f"{metric}.png")
    config = {
        "model": str(ns.model),
        "policies": specs,
        "role": ns.role,
        "test_look": ns.role == "test",
        "users_per_exercise": ns.users,
        "perturbed": not ns.no_perturb,
        "split": split.to_dict(),
        "n_boot": ns.n_boot,
        "seed": ns.seed,
    }
    atomic_write(ns.out / "config.json", json.dumps(config, indent=2) + "\n")
    print(text)
    print(f"wrote {ns.out} ({len(rows)} episodes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
