"""Does a learned policy generalise? Every policy on every held-out exercise and person.

Run::

    langctrl generalise --model runs/speech/best.zip --out out/generalise
    langctrl generalise --model M1.zip --model M2.zip --role test --users 48 \
        --population both --out out/test_look_1

The split (exercises and user seeds of each role, the users' perturbations) is the one recorded with
the (first) model (``worlds`` in ``MODEL_config.yaml``, written by ``langctrl train`` from a
config with a ``worlds`` section), or ``--split CONFIG`` (a config with one). Every policy of
``--policies`` (default ``ac,lc-noap,lc,lc-em-end,lc-fill,lc-fill-end``) and each learned one
(``ppo:MODEL``; several ``--model``: ``ppo-STEM``) runs on every exercise of the role times its
first ``--users`` user seeds, the same episodes for every policy: paired. The people are
:class:`~langenv.users.PerturbedUser` of the split's perturbations (``--population perturbed``, the
default), the plain synthetic population (``plain``, or ``--no-perturb``), or both (``both``: each
exercise and user twice, the groups of the tables are then ``EXERCISE (population)``).

**The bars** (:func:`bars`): each learned policy against ``--base`` (default ``lc-fill-end``,
the best analytic policy, chosen on the validation worlds: the most sessions within 1 s, then the
most content; ``HISTORY.md``, issue 38), on the same
episodes, paired, per group and all together: the share of sessions with ``|AM| <= 1 s`` no
lower, the content share higher with the 95 % bootstrap interval of the difference above 0, the
voice heard natural no lower than the base's - 0.02, no more protective stops, and the mean share
of legs whose words start within 1 s of the leg (``legs_in_step``, :mod:`eval.legs`) no lower
(where the graph has ``@leg`` marks).

``--role`` is ``validation`` by default. The test exercises and users are for the claim: look
at them (``--role test``) only with the model you ship, at most twice per study, and record each
look in ``HISTORY.md``; the command says so when it runs on them.

Writes into ``OUT`` (refused when it holds files, unless ``--overwrite``):

* ``sessions.csv``: one row per episode, the session metrics of :mod:`eval.metrics` plus
  ``exercise``, ``population``, ``perturbation``, ``abs_am_le_1s`` and ``protective_stop``;
* ``generalise.md``: every policy's figures on all the episodes; the bars; then per learned
  policy, per metric (:data:`COMPARED`) and per group (and all together), each policy's
  statistic, the best analytic one, and the paired bootstrap 95 % intervals of the learned
  minus the best analytic and minus ``lc-em-end``;
* ``speech.png``: content share against voice natural, one point per policy, and each policy's
  share of sessions with ``|AM| <= 1 s`` beside it (:func:`plot_speech`);
* ``METRIC.png``: one plot per metric (each policy's statistic per group, and the intervals of
  the first learned policy);
* ``config.json``: the arguments, the split and whether this was a look at the test set.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from eval.markdown import markdown_table
from eval.stats import Stat

__all__ = [
    "BASE",
    "COMPARED",
    "Bar",
    "Comparison",
    "bars",
    "bars_markdown",
    "check_generalise",
    "compare_rows",
    "markdown",
    "overview_markdown",
    "plot_speech",
    "run_generalise",
]

#: The metrics compared: column -> (statistic, label). Higher is better for the shares of
#: :data:`_HIGHER_IS_BETTER` (content, voice natural, sessions with ``|AM| <= 1 s``, legs whose
#: words start within 1 s of the leg), lower for the rest.
COMPARED: dict[str, tuple[Stat, str]] = {
    "content_share": ("mean", "content share"),
    "voice_natural": ("mean", "voice natural"),
    "abs_am_le_1s": ("mean", "share |AM| <= 1 s"),
    "protective_stop": ("mean", "protective stops (share)"),
    "abs_am": ("median", "median |AM| (s)"),
    "em_mean_abs": ("mean", "mean |EM| (s)"),
    "a_dev": ("mean", "mean |a - 1|"),
    "legs_in_step": ("mean", "legs in step"),
}
_HIGHER_IS_BETTER = frozenset({"abs_am_le_1s", "content_share", "voice_natural", "legs_in_step"})
REFERENCE = "lc-em-end"
#: The analytic policy the bars compare with by default: the best on the validation worlds (the
#: most sessions with |AM| <= 1 s, then the most content).
BASE = "lc-fill-end"
#: How much lower than the base's the learned policy's voice natural may be (the issue's bar).
VOICE_SLACK = 0.02


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


def _group(row: dict[str, Any]) -> str:
    """A row's group: its ``group`` (exercise and population), else its exercise."""
    return str(row.get("group", row["exercise"]))


def _paired_groups(
    rows: list[dict[str, Any]], policies: Sequence[str]
) -> list[tuple[str, list[dict[str, Any]], int]]:
    """Each group (and ``"all"``) with its rows and episode count, checked paired.

    Raises:
        ConfigError: when ``policies`` did not run the same episodes in a group.
    """
    from langenv.errors import ConfigError

    out = []
    for group in [*sorted({_group(r) for r in rows}), "all"]:
        sub = [r for r in rows if group == "all" or _group(r) == group]
        keys = [sorted(r["key"] for r in sub if r["policy"] == p) for p in policies]
        if any(k != keys[0] for k in keys):
            raise ConfigError(f"{group}: {', '.join(policies)} did not run the same episodes")
        out.append((group, sub, len(keys[0])))
    return out


def _column(rows: list[dict[str, Any]], policy: str, metric: str) -> np.ndarray:
    """``metric`` of ``policy``'s episodes in key order (NaN where a row lacks it: a table of
    an older run)."""
    mine = sorted((r for r in rows if r["policy"] == policy), key=lambda r: r["key"])
    return np.array([float(r.get(metric, math.nan)) for r in mine], dtype=np.float64)


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
    policies = [learned, *analytic]
    groups = _paired_groups(rows, policies)
    out = []
    for metric, (stat, _label) in COMPARED.items():
        for group, sub, n in groups:
            cols = {p: _column(sub, p, metric) for p in policies}
            fn = np.nanmedian if stat == "median" else np.nanmean
            values = {
                p: float(fn(c)) if np.isfinite(c).any() else math.nan for p, c in cols.items()
            }
            sign = -1.0 if metric in _HIGHER_IS_BETTER else 1.0
            best = min(analytic, key=lambda p: (_rank(sign * values[p]), p))
            vs_best = _diff(cols[learned], cols[best], stat, n_boot, seed)
            vs_ref = (math.nan, math.nan, math.nan)
            if REFERENCE in cols:
                vs_ref = _diff(cols[learned], cols[REFERENCE], stat, n_boot, seed)
            out.append(Comparison(metric, group, values, best, vs_best, vs_ref, n))
    return out


def _rank(x: float) -> float:
    return x if math.isfinite(x) else math.inf  # a policy without the metric is never the best


@dataclass(frozen=True)
class Bar:
    """The bars of one learned policy against the base on one group of episodes (paired).

    Attributes:
        learned: The learned policy.
        base: The analytic policy it is held against.
        group: The group (``"all"``, an exercise, or ``EXERCISE (population)``).
        n: Episodes.
        within: Shares of sessions with ``|AM| <= 1 s``: ``(learned, base)``.
        content: Learned minus base mean content share: ``(estimate, lo, hi)``.
        voice: Learned minus base mean voice natural: ``(estimate, lo, hi)``.
        stops: Protective stops: ``(learned, base)``.
        legs: Mean share of legs in step (:mod:`eval.legs`): ``(learned, base)``; NaN where
            the graph has no ``@leg`` marks.
    """

    learned: str
    base: str
    group: str
    n: int
    within: tuple[float, float]
    content: tuple[float, float, float]
    voice: tuple[float, float, float]
    stops: tuple[int, int]
    legs: tuple[float, float] = (math.nan, math.nan)

    @property
    def checks(self) -> dict[str, bool]:
        """Each bar: whether it holds (legs in step: no lower than the base's; the bar holds
        where the base's graph has no legs)."""
        mine, base = self.legs
        return {
            "|AM| <= 1 s": self.within[0] >= self.within[1] - 1e-12,
            "content": self.content[1] > 0.0,
            "voice": self.voice[0] >= -VOICE_SLACK,
            "stops": self.stops[0] <= self.stops[1],
            "legs in step": math.isnan(base) or mine >= base - 1e-12,
        }

    @property
    def holds(self) -> bool:
        """Whether every bar holds."""
        return all(self.checks.values())


def bars(
    rows: list[dict[str, Any]],
    learned: str,
    base: str,
    *,
    n_boot: int = 2000,
    seed: int = 0,
) -> list[Bar]:
    """The bars of ``learned`` against ``base`` per group and all together (module docstring).

    Raises:
        ConfigError: when the two did not run the same episodes.
    """
    out = []
    for group, sub, n in _paired_groups(rows, (learned, base)):
        col = {p: {m: _column(sub, p, m) for m in COMPARED} for p in (learned, base)}
        mine, theirs = col[learned], col[base]
        out.append(
            Bar(
                learned,
                base,
                group,
                n,
                (float(np.mean(mine["abs_am_le_1s"])), float(np.mean(theirs["abs_am_le_1s"]))),
                _diff(mine["content_share"], theirs["content_share"], "mean", n_boot, seed),
                _diff(mine["voice_natural"], theirs["voice_natural"], "mean", n_boot, seed),
                (int(mine["protective_stop"].sum()), int(theirs["protective_stop"].sum())),
                (_mean(mine["legs_in_step"]), _mean(theirs["legs_in_step"])),
            )
        )
    return out


def _mean(x: np.ndarray) -> float:
    """The mean of the finite values (NaN when there are none)."""
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if x.size else math.nan


def overview_markdown(rows: list[dict[str, Any]], policies: Sequence[str]) -> str:
    """Every policy on all the episodes: the speech people hear and the bars' other figures."""
    head = [
        "policy",
        "sessions",
        "content %",
        "voice natural %",
        "pauses %",
        "fillers %",
        "\\|AM\\| <= 1 s",
        "median \\|AM\\| (s)",
        "protective stops",
    ]
    body = []
    for p in policies:
        mine = [r for r in rows if r["policy"] == p]

        def col(m: str, mine: list[dict[str, Any]] = mine) -> np.ndarray:
            return np.array([float(r[m]) for r in mine])

        cells = [
            p,
            str(len(mine)),
            f"{100.0 * np.nanmean(col('content_share')):.1f}",
            f"{100.0 * np.nanmean(col('voice_natural')):.1f}",
            f"{100.0 * np.nanmean(col('pause_share')):.1f}",
            f"{100.0 * np.nanmean(col('filler_share')):.1f}",
            f"{int(col('abs_am_le_1s').sum())}/{len(mine)}",
            f"{np.nanmedian(col('abs_am')):.2f}",
            str(int(col("protective_stop").sum())),
        ]
        body.append(cells)
    return "\n".join(markdown_table(head, body)) + "\n"


def bars_markdown(found: Sequence[Bar]) -> str:
    """The bars as a Markdown table."""
    head = [
        "learned",
        "group",
        "n",
        "\\|AM\\| <= 1 s (learned / base)",
        "content - base [95 % CI]",
        "voice natural - base [95 % CI]",
        "stops (learned / base)",
        "legs in step (learned / base)",
        "verdict",
    ]
    body = []
    for b in found:
        failed = [k for k, ok in b.checks.items() if not ok]
        cells = [
            b.learned,
            b.group,
            str(b.n),
            f"{b.within[0]:.3f} / {b.within[1]:.3f}",
            _ci(b.content, 4),
            _ci(b.voice, 4),
            f"{b.stops[0]} / {b.stops[1]}",
            " / ".join("n/a" if math.isnan(x) else f"{x:.3f}" for x in b.legs),
            "PASS" if not failed else "FAIL: " + ", ".join(k.replace("|", "\\|") for k in failed),
        ]
        body.append(cells)
    return "\n".join(markdown_table(head, body)) + "\n"


def _diff(
    x: np.ndarray, y: np.ndarray, stat: Stat, n_boot: int, seed: int
) -> tuple[float, float, float]:
    """Paired bootstrap interval of ``stat(x - y)`` (each comparison from the same seed)."""
    from eval.stats import bootstrap_diff_ci

    ci = bootstrap_diff_ci(
        x, y, paired=True, stat=stat, n_boot=n_boot, rng=np.random.default_rng(seed)
    )
    return (ci.estimate, ci.lo, ci.hi)


def _ci(c: tuple[float, float, float], digits: int = 3) -> str:
    est, lo, hi = c
    if math.isnan(est):
        return "n/a"
    return f"{est:+.{digits}f} [{lo:+.{digits}f}, {hi:+.{digits}f}]"


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
        body = [
            [
                c.group,
                str(c.n),
                *(_value(c.values[p]) for p in [*analytic, learned]),
                c.best,
                _ci(c.vs_best),
                _ci(c.vs_reference),
            ]
            for c in mine
        ]
        lines += [*markdown_table(head, body), ""]
    return "\n".join(lines)


def _value(x: float) -> str:
    return "n/a" if math.isnan(x) else f"{x:.3f}"


def plot_speech(rows: list[dict[str, Any]], policies: Sequence[str], path: Path) -> Path:
    """The speech people hear, all episodes together: each policy's mean content share against
    its mean voice natural (one point per policy; left: all, middle: around the best), and its
    sessions with ``|AM| <= 1 s`` (right)."""
    from matplotlib.figure import Figure

    from eval.plots import _save, policy_color

    def mean(p: str, m: str) -> float:
        x = np.array([float(r[m]) for r in rows if r["policy"] == p])
        return float(np.nanmean(x)) if np.isfinite(x).any() else math.nan

    markers = "osD^v<>Pp*hX"
    points = {
        p: (100.0 * mean(p, "content_share"), 100.0 * mean(p, "voice_natural")) for p in policies
    }
    fig = Figure(figsize=(13.0, 4.4), facecolor="white")
    left, mid, right = fig.subplots(1, 3, width_ratios=[3, 3, 2.4])
    for i, p in enumerate(policies):
        x, y = points[p]
        style = {"color": policy_color(p, i), "marker": markers[i % len(markers)], "s": 60}
        left.scatter([x], [y], label=p, zorder=3, **style)
        mid.scatter([x], [y], zorder=3, **style)
    left.set_xlabel("content share: words heard over the motion (%)")
    left.set_ylabel("voice heard natural (% of the speech)")
    left.legend(fontsize=7, loc="lower right")
    left.grid(alpha=0.3)
    best = max(points.values(), key=lambda v: v[0])
    near = [p for p, v in points.items() if v[0] >= best[0] - 6.0]
    for k, p in enumerate(near):
        x, y = points[p]
        mid.annotate(p, (x, y), textcoords="offset points", xytext=(6, 10 - 9 * k), fontsize=7)
    xs = [points[p][0] for p in near]
    ys = [points[p][1] for p in near]
    mid.set_xlim(min(xs) - 0.5, max(xs) + 1.5)
    mid.set_ylim(min(ys) - 1.0, max(ys) + 1.0)
    mid.set_title("around the most content", fontsize=9)
    mid.set_xlabel("content share (%)")
    mid.grid(alpha=0.3)
    counts = []
    for p in policies:
        within = [float(r["abs_am_le_1s"]) for r in rows if r["policy"] == p]
        counts.append((int(sum(within)), len(within)))
    shares = [100.0 * k / n if n else 0.0 for k, n in counts]
    rows_y = np.arange(len(policies))
    right.barh(rows_y, shares, color=[policy_color(p, i) for i, p in enumerate(policies)])
    for k, (n_in, n) in enumerate(counts):
        right.text(
            2.0,
            k,
            f"{n_in}/{n}",
            va="center",
            ha="left",
            fontsize=8,
            bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.0},
        )
    right.set_yticks(rows_y, list(policies), fontsize=8)
    right.invert_yaxis()
    right.set_xlim(0.0, 100.0)
    right.set_xlabel("sessions with |AM| <= 1 s (%)")
    fig.tight_layout()
    return _save(fig, path)


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

    return WorldSplit.load(ns.split if ns.split is not None else model_files(ns.model[0])[2])


#: ``--population``'s choices, and the populations each runs.
POPULATIONS: dict[str, tuple[str, ...]] = {
    "perturbed": ("perturbed",),
    "plain": ("plain",),
    "both": ("perturbed", "plain"),
}


def _jobs(ns: argparse.Namespace, split: Any, specs: list[str], names: dict[str, str]) -> list:
    from eval.compare import Job
    from langenv.users import PerturbedUser, SyntheticUser

    jobs = []
    for population in POPULATIONS[ns.population]:
        for ex, seed in split.pairs(ns.role, ns.users * len(split.exercises(ns.role))):
            plain = population == "plain"
            user = SyntheticUser() if plain else PerturbedUser(split.perturbations)
            out_dir = ns.out / "sessions" / population / Path(ex).stem
            out_dir.mkdir(parents=True, exist_ok=True)
            for spec in specs:
                job = Job(spec, f"s{seed}", seed, None, str(out_dir), False, False, None,
                          split.graphs.get(ex), names[spec], exercise=ex, user_model=user,
                          save_log=False)  # fmt: skip
                jobs.append((population, job))
    return jobs


def check_generalise(ns: argparse.Namespace) -> Any:
    """Check the job's arguments (``langctrl generalise``'s namespace) before any episode runs:
    every policy loads, the split gives enough users; the split.

    Raises:
        ConfigError, ModelError, FileNotFoundError, KeyError: saying what is wrong.
    """
    from langenv.errors import ConfigError
    from policies import load_policy

    analytic = [s.strip() for s in ns.policies.split(",") if s.strip()]
    learned_specs = [f"ppo:{m}" for m in ns.model]
    if ns.base not in analytic:
        raise ConfigError(f"--base {ns.base} is not one of --policies ({ns.policies})")
    if len(set(learned_specs)) != len(learned_specs):
        raise ConfigError("a --model is given twice")
    if ns.out.is_dir() and any(ns.out.iterdir()) and not ns.overwrite:
        raise ConfigError(f"--out {ns.out} holds files; give --overwrite or another --out")
    for spec in [*analytic, *learned_specs]:
        load_policy(spec)  # every policy loads before any episode runs
    split = _split(ns)
    split.pairs(ns.role, ns.users * len(split.exercises(ns.role)))  # enough users
    return split


def run_generalise(ns: argparse.Namespace, split: Any) -> tuple[str, int]:
    """Run every policy on ``split``'s held-out exercises and people (:func:`check_generalise`
    first) and write the outputs into ``ns.out``; ``generalise.md``'s text and the number of
    episodes."""
    from eval.compare import policy_names, run_jobs
    from eval.report import atomic_write, write_sessions_csv

    analytic = [s.strip() for s in ns.policies.split(",") if s.strip()]
    learned_specs = [f"ppo:{m}" for m in ns.model]
    specs = [*analytic, *learned_specs]
    names = policy_names(specs)
    pairs = _jobs(ns, split, specs, names)
    rows = run_jobs([job for _, job in pairs], ns.workers)
    both = len(POPULATIONS[ns.population]) > 1
    for (population, job), row in zip(pairs, rows, strict=True):
        row["exercise"] = job.exercise
        row["population"] = population
        row["group"] = f"{job.exercise} ({population})" if both else str(job.exercise)
        row["key"] = f"{population}/{job.exercise}/{job.user}"
        row["perturbation"] = (
            _perturbation(job.user_model, job.seed) if population == "perturbed" else "none"
        )
        row["abs_am_le_1s"] = float(float(row["abs_am"]) <= 1.0)
    learned = [names[s] for s in learned_specs]
    found = [
        b for name in learned for b in bars(rows, name, ns.base, n_boot=ns.n_boot, seed=ns.seed)
    ]
    title = f"# {ns.role}: {', '.join(split.exercises(ns.role))} ({ns.population} people)"
    parts = [
        title,
        "",
        "## Every policy, all episodes",
        "",
        overview_markdown(rows, [*analytic, *learned]),
        f"## The bars: each learned policy against {ns.base}, paired, all sessions",
        "",
        bars_markdown([b for b in found if b.group == "all"]),
        f"## The bars per group: each learned policy against {ns.base}",
        "",
        bars_markdown([b for b in found if b.group != "all"]),
    ]
    comps = {}
    for name in learned:
        comps[name] = compare_rows(rows, name, analytic, n_boot=ns.n_boot, seed=ns.seed)
        parts += [f"## {name}: every metric", "", markdown(comps[name], name, analytic)]
    text = "\n".join(parts)
    write_sessions_csv(
        [{k: v for k, v in r.items() if k not in ("key", "group")} for r in rows],
        ns.out / "sessions.csv",
    )
    atomic_write(ns.out / "generalise.md", text)
    plot_speech(rows, [*analytic, *learned], ns.out / "speech.png")
    shown = [  # the first model's comparisons, with every model's statistic
        replace(c, values={**c.values, **{n: comps[n][i].values[n] for n in learned}})
        for i, c in enumerate(comps[learned[0]])
    ]
    for metric in COMPARED:
        plot_metric(shown, metric, [*analytic, *learned], ns.out / f"{metric}.png")
    config = {
        "models": [str(m) for m in ns.model],
        "policies": specs,
        "base": ns.base,
        "role": ns.role,
        "test_look": ns.role == "test",
        "users_per_exercise": ns.users,
        "population": ns.population,
        "split": split.to_dict(),
        "n_boot": ns.n_boot,
        "seed": ns.seed,
        "bars_hold": {
            b.learned: all(x.holds for x in found if x.learned == b.learned) for b in found
        },
    }
    atomic_write(ns.out / "config.json", json.dumps(config, indent=2) + "\n")
    return text, len(rows)
