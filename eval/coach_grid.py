"""Coaches across the listening person's assumptions: every policy at every point of a grid.

Run::

    langctrl coach-grid --out out/coach_grid                       # the test worlds
    langctrl coach-grid --role validation --users 24 --out out/coach_val
    langctrl coach-grid --model models/ppo_coach.zip --out out/coach_grid

What no data gives about a person who listens (the latency from the words to the force, the
probability of complying, the effect of ``relax``, ``faster`` and ``slower``...) stays an
assumption with a range (:data:`langenv.users.listening.SOURCES`); a coach is judged across
those ranges, never at one setting. The grid is a YAML file (``--grid``, default
``configs/coach_grid.yaml``: each assumption at both ends of its documented range, the others at
their defaults)::

    design: one-at-a-time     # the default point, then one point per value of each axis
    fixed: {}                 # ListeningParams fields set at every point
    axes: {latency: [0.4, 2.0], comply: [0.3, 0.9]}   # or design: product (every combination)

At every point each policy of ``--policies`` (default ``lc,lc-fill-end,lc-coach``) and each
``--model`` (``ppo:PATH``) runs on the role's exercises and people (``--role``, default
``test``; ``validation`` for tuning; the split of ``--split``, default ``configs/ppo_coach.yaml``):
the role's first ``--users`` people per exercise, each a :class:`~langenv.users.ListeningUser`
of the point's parameters reset with the person's seed, so every policy and every point meets
the same people (paired). Per point and per policy the differences from ``--base`` (default
``lc-fill-end``, the best analytic policy that ignores intents), paired by session, with
percentile-bootstrap 95 % intervals (:func:`eval.stats.bootstrap_diff_ci`, of the mean) for
the metrics of :data:`COMPARED`.

Writes into ``OUT`` (refused when it holds files, unless ``--overwrite`` or ``--resume``):

* ``points/NNN.csv``: the sessions of point ``NNN`` as it finishes; ``--resume`` keeps the
  points already there (the same arguments: ``config.json`` must match) and runs the rest;
* ``sessions.csv``: every session (the metrics of :mod:`eval.metrics` plus ``point``,
  ``point_label``, ``exercise`` and ``session_s``, the session's length: the later of the
  motion's and the speech's end);
* ``grid.csv``: one row per point, policy and metric: ``estimate``, ``lo``, ``hi`` (policy minus
  base) and ``n`` (sessions paired);
* ``grid.md``: the coaches' bars (:mod:`eval.coach_bars`: each ``--model`` against
  ``lc-coach``, ``lc-coach`` against the base), the differences as tables, and per policy at how
  many points each metric is better (the interval beyond 0 on the metric's good side) and worse;
* ``grid.png``: the gain over the grid (:func:`plot_grid`): per metric, each policy's
  difference from the base with its interval at every point;
* ``config.json``: the arguments, the grid's points, the split.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from langenv.errors import ConfigError

__all__ = [
    "COMPARED",
    "DEFAULT_GRID",
    "DESIGNS",
    "GridPoint",
    "GridSpec",
    "check_coach_grid",
    "differences",
    "grid_jobs",
    "grid_markdown",
    "plot_grid",
    "run_coach_grid",
    "tally",
]

#: The metrics compared: column -> (label, lower is better).
COMPARED: Mapping[str, tuple[str, bool]] = MappingProxyType(
    {
        "session_s": ("session length (s)", True),
        "path_error": ("mean path error (m)", True),
        "effort": ("effort (N)", True),
        "content_share": ("content share", False),
        "legs_in_step": ("legs in step", False),
        "abs_am": ("|AM| (s)", True),
    }
)
DESIGNS = ("one-at-a-time", "product")
"""How a grid's axes make its points."""
DEFAULT_GRID = Path("configs/coach_grid.yaml")
DEFAULT_SPLIT = Path("configs/ppo_coach.yaml")
BASE = "lc-fill-end"
_GRID_KEYS = frozenset({"design", "fixed", "axes"})


@dataclass(frozen=True)
class GridPoint:
    """One point of the grid: a label (``"default"``, ``"latency=2"``) and its parameters."""

    label: str
    params: Any  # ListeningParams


@dataclass(frozen=True)
class GridSpec:
    """A grid of the listening person's parameters (module docstring).

    Attributes:
        design: One of :data:`DESIGNS`.
        fixed: :class:`~langenv.users.ListeningParams` fields set at every point.
        axes: Field -> its values (at least one each).
        where: Where the spec came from, for errors.

    Raises:
        ConfigError: naming ``where`` and the key, for an unknown design or field, a value that
            is not a number, an empty axis, or a point :class:`ListeningParams` refuses.
    """

    design: str = "one-at-a-time"
    fixed: Mapping[str, float] = field(default_factory=dict)
    axes: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    where: str = "grid"

    def __post_init__(self) -> None:
        from langenv.users import ListeningParams

        names = [f.name for f in fields(ListeningParams)]
        if self.design not in DESIGNS:
            raise ConfigError(f"{self.where}: design must be one of {DESIGNS}, got {self.design!r}")
        for key, given in (("fixed", self.fixed), ("axes", self.axes)):
            for name in given:
                if name not in names:
                    raise ConfigError(
                        f"{self.where}: {key}: unknown field {name!r}; known: {', '.join(names)}"
                    )
        fixed = {k: _number(self.where, f"fixed.{k}", v) for k, v in self.fixed.items()}
        axes: dict[str, tuple[float, ...]] = {}
        for name, values in self.axes.items():
            if not isinstance(values, list | tuple) or not values:
                raise ConfigError(f"{self.where}: axes.{name} must be a non-empty list")
            axes[name] = tuple(_number(self.where, f"axes.{name}", v) for v in values)
        object.__setattr__(self, "fixed", MappingProxyType(fixed))
        object.__setattr__(self, "axes", MappingProxyType(axes))
        self.points()  # every point is a valid person

    @classmethod
    def load(cls, path: str | Path) -> GridSpec:
        """The grid of a YAML file (module docstring).

        Raises:
            ConfigError: naming the file: unreadable, not a mapping, an unknown key, or a bad
                grid (see the class).
        """
        import yaml

        try:
            data = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"{path}: cannot read: {exc}") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: must be a mapping with {sorted(_GRID_KEYS)}")
        unknown = sorted(set(data) - _GRID_KEYS)
        if unknown:
            raise ConfigError(f"{path}: unknown key(s) {unknown}; known: {sorted(_GRID_KEYS)}")
        for key in ("fixed", "axes"):
            if not isinstance(data.get(key) or {}, dict):
                raise ConfigError(f"{path}: {key} must be a mapping of field: value")
        return cls(
            str(data.get("design", "one-at-a-time")),
            data.get("fixed") or {},
            data.get("axes") or {},
            str(path),
        )

    def points(self) -> list[GridPoint]:
        """The grid's points, in a fixed order (the default point first for one-at-a-time)."""
        from langenv.users import ListeningParams

        def point(values: Mapping[str, float]) -> GridPoint:
            label = ",".join(f"{k}={v:g}" for k, v in values.items()) or "default"
            try:
                return GridPoint(label, ListeningParams(**{**self.fixed, **values}))
            except (ConfigError, TypeError) as exc:
                raise ConfigError(f"{self.where}: point {label}: {exc}") from None

        if self.design == "product":
            names = list(self.axes)
            combos = itertools.product(*(self.axes[n] for n in names))
            return [point(dict(zip(names, c, strict=True))) for c in combos]
        out = [point({})]
        for name, values in self.axes.items():
            out += [point({name: v}) for v in values]
        return out


def _number(where: str, key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)


def grid_jobs(
    points: Sequence[GridPoint],
    pairs: Sequence[tuple[str, int]],
    specs: Sequence[str],
    names: Mapping[str, str],
    params: Mapping[str, tuple[tuple[str, float], ...]],
    graphs: Mapping[str, str],
    out: Path,
) -> list[tuple[int, Any]]:
    """``(point index, Job)`` for every point, episode (exercise, person's seed) and policy spec:
    the same people at every point, for every policy (``params``: a spec's parameters set)."""
    from eval.compare import Job
    from langenv.users import ListeningUser

    jobs = []
    for i, pt in enumerate(points):
        person = ListeningUser(pt.params)
        for ex, seed in pairs:
            for spec in specs:
                job = Job(spec, f"s{seed}", seed, None, str(out), False, False, None,
                          graphs.get(ex), names[spec], exercise=ex, user_model=person,
                          params=params.get(spec, ()), save_log=False)  # fmt: skip
                jobs.append((i, job))
    return jobs


def differences(
    rows: Sequence[Mapping[str, Any]],
    policies: Sequence[str],
    base: str,
    n_boot: int = 2000,
    seed: int = 0,
) -> list[dict[str, Any]]:
    """Per point, policy (other than ``base``) and metric of :data:`COMPARED`: the mean of the
    paired differences policy minus base (sessions keyed by exercise and person) and its
    bootstrap 95 % interval (one generator seeded with ``seed``, drawn in this order)."""
    from eval.stats import bootstrap_diff_ci

    rng = np.random.default_rng(seed)
    by: dict[tuple[int, str], dict[tuple[str, str], Mapping[str, Any]]] = {}
    labels: dict[int, str] = {}
    for r in rows:
        by.setdefault((int(r["point"]), str(r["policy"])), {})[(r["exercise"], r["user"])] = r
        labels[int(r["point"])] = str(r["point_label"])
    out = []
    for point in sorted(labels):
        theirs = by.get((point, base), {})
        for pol in policies:
            if pol == base:
                continue
            mine = by.get((point, pol), {})
            keys = sorted(set(mine) & set(theirs))
            for metric in COMPARED:
                x = np.array([float(mine[k][metric]) for k in keys])
                y = np.array([float(theirs[k][metric]) for k in keys])
                d = bootstrap_diff_ci(x, y, paired=True, n_boot=n_boot, rng=rng)
                out.append(
                    {"point": point, "point_label": labels[point], "policy": pol,
                     "metric": metric, "estimate": d.estimate, "lo": d.lo, "hi": d.hi,
                     "n": len(keys)}
                )  # fmt: skip
    return out


def tally(diffs: Sequence[Mapping[str, Any]], policy: str, metric: str) -> tuple[int, int, int]:
    """``(better, worse, points)``: at how many points ``policy``'s interval lies beyond 0 on
    the metric's good side, on its bad side, and of how many points with an interval."""
    lower = COMPARED[metric][1]
    better = worse = total = 0
    for d in diffs:
        if d["policy"] != policy or d["metric"] != metric or math.isnan(d["lo"]):
            continue
        total += 1
        below, above = d["hi"] < 0.0, d["lo"] > 0.0
        better += below if lower else above
        worse += above if lower else below
    return better, worse, total


def grid_markdown(diffs: Sequence[Mapping[str, Any]], base: str, bars: str = "") -> str:
    """``grid.md``: the coaches' bars (``bars``, :mod:`eval.coach_bars`), the tally per policy,
    then per policy a table of every point and metric."""
    policies = list(dict.fromkeys(d["policy"] for d in diffs))
    lines = [f"# Policies against {base} across the listening assumptions", ""]
    if bars:
        lines += [bars]
    lines += ["Each cell: at how many points the 95 % interval of the difference lies on the "
              "metric's good side / on its bad side / points.", ""]  # fmt: skip
    lines += ["| policy | " + " | ".join(_label(m) for m in COMPARED) + " |"]
    lines += ["|---" * (len(COMPARED) + 1) + "|"]
    for pol in policies:
        cells = ["{} / {} / {}".format(*tally(diffs, pol, m)) for m in COMPARED]
        lines.append(f"| {pol} | " + " | ".join(cells) + " |")
    for pol in policies:
        lines += ["", f"## {pol} - {base} (mean of the paired differences [95 % CI])", ""]
        lines += ["| point | " + " | ".join(_label(m) for m in COMPARED) + " | n |"]
        lines += ["|---" * (len(COMPARED) + 2) + "|"]
        mine = [d for d in diffs if d["policy"] == pol]
        for point in dict.fromkeys(d["point"] for d in mine):
            here = {d["metric"]: d for d in mine if d["point"] == point}
            cells = [_cell(here[m]) for m in COMPARED]
            first = here[next(iter(COMPARED))]
            lines.append(f"| {first['point_label']} | " + " | ".join(cells) + f" | {first['n']} |")
    return "\n".join(lines) + "\n"


def _label(metric: str) -> str:
    """A metric's label as a Markdown table cell (its ``|`` escaped)."""
    return COMPARED[metric][0].replace("|", "\\|")


def _cell(d: Mapping[str, Any]) -> str:
    if math.isnan(d["estimate"]):
        return "n/a"
    digits = 4 if d["metric"] == "path_error" else 3
    return f"{d['estimate']:+.{digits}f} [{d['lo']:+.{digits}f}, {d['hi']:+.{digits}f}]"


def plot_grid(diffs: Sequence[Mapping[str, Any]], base: str, path: Path) -> Path:
    """``grid.png``: per metric, each policy's difference from ``base`` with its interval at
    every point (the gain over the grid)."""
    from matplotlib.figure import Figure

    from eval.plots import _save, policy_color

    policies = list(dict.fromkeys(d["policy"] for d in diffs))
    labels = list(dict.fromkeys(d["point_label"] for d in diffs))
    fig = Figure(figsize=(max(8.0, 0.45 * len(labels)), 13.0))
    axes = fig.subplots(len(COMPARED), 1)
    x = np.arange(len(labels))
    width = 0.8 / max(1, len(policies))
    for ax, metric in zip(np.atleast_1d(axes), COMPARED, strict=True):
        for j, pol in enumerate(policies):
            mine = {
                d["point_label"]: d for d in diffs if d["policy"] == pol and d["metric"] == metric
            }
            est = np.array([mine[lb]["estimate"] if lb in mine else np.nan for lb in labels])
            lo = np.array([mine[lb]["lo"] if lb in mine else np.nan for lb in labels])
            hi = np.array([mine[lb]["hi"] if lb in mine else np.nan for lb in labels])
            xs = x + (j - (len(policies) - 1) / 2) * width
            ax.errorbar(xs, est, yerr=[est - lo, hi - est], fmt="o", ms=3, capsize=2, label=pol,
                        color=policy_color(pol, j))  # fmt: skip
        ax.axhline(0.0, color="grey", lw=0.8)
        label, lower = COMPARED[metric]
        ax.set_ylabel(f"{label}\n({'lower' if lower else 'higher'} is better)", fontsize=7)
        ax.set_xticks(x, [] if metric != list(COMPARED)[-1] else labels, rotation=60, fontsize=6)
    np.atleast_1d(axes)[0].legend(fontsize=7, ncols=max(1, len(policies)), loc="lower right")
    fig.suptitle(f"difference from {base} (mean, 95 % CI) at each point of the grid", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def _coach_params(
    text: str | None, specs: Sequence[str]
) -> dict[str, tuple[tuple[str, float], ...]]:
    """``--coach`` as resolved parameters of the ``lc-coach`` spec."""
    if text is None:
        return {}
    if "lc-coach" not in specs:
        raise ConfigError("--coach sets lc-coach's parameters: add lc-coach to --policies")
    from eval.overrides import resolve_policy_param
    from policies import load_policy

    coach = load_policy("lc-coach")
    params = []
    for item in (s.strip() for s in text.split(",") if s.strip()):
        key, eq, value = item.partition("=")
        if not eq:
            raise ConfigError(f"--coach: {item!r} is not KEY=VALUE")
        try:
            params.append((resolve_policy_param(coach, key.strip()), float(value)))
        except ValueError:
            raise ConfigError(f"--coach: {item!r}: not a number") from None
    from eval.overrides import apply_policy_params

    apply_policy_params(coach, params)  # the rule checks the values now
    return {"lc-coach": tuple(sorted(params))}


def _prepare(ns: argparse.Namespace) -> tuple[Any, list[GridPoint], list[str], dict[str, Any]]:
    """The split, the points, the policy specs and the config; every check before any episode."""
    from langenv.worlds import WorldSplit
    from policies import load_policy

    if ns.users < 1:
        raise ConfigError(f"--users must be >= 1, got {ns.users}")
    analytic = [s.strip() for s in ns.policies.split(",") if s.strip()]
    specs = [*analytic, *(f"ppo:{m}" for m in ns.model)]
    if ns.base not in analytic:
        raise ConfigError(f"--base {ns.base} is not one of --policies ({ns.policies})")
    if len(set(specs)) != len(specs):
        raise ConfigError("a policy or --model is given twice")
    for spec in specs:
        load_policy(spec)  # every policy loads before any episode runs
    params = _coach_params(ns.coach, specs)
    points = GridSpec.load(ns.grid).points()
    split = WorldSplit.load(ns.split)
    n = ns.users * len(split.exercises(ns.role))
    split.pairs(ns.role, n)  # enough people
    config = {
        "grid": str(ns.grid), "points": [p.label for p in points], "policies": specs,
        "base": ns.base, "coach": {k: dict(v) for k, v in params.items()}, "role": ns.role,
        "test_look": ns.role == "test", "users_per_exercise": ns.users,
        "split": split.to_dict(), "n_boot": ns.n_boot, "seed": ns.seed,
    }  # fmt: skip
    return split, points, specs, config


def _check_out(ns: argparse.Namespace, config: Mapping[str, Any]) -> None:
    if not (ns.out.is_dir() and any(ns.out.iterdir())):
        return
    if ns.resume:
        try:
            before = json.loads((ns.out / "config.json").read_text())
        except (OSError, ValueError):
            raise ConfigError(f"--resume: {ns.out} has no readable config.json") from None
        if before != json.loads(json.dumps(config)):
            raise ConfigError(f"--resume: {ns.out} was run with other arguments (config.json)")
    elif not ns.overwrite:
        raise ConfigError(
            f"--out {ns.out} holds files; give --overwrite, --resume or another --out"
        )


def _run_points(
    ns: argparse.Namespace, jobs: list[tuple[int, Any]], points: list[GridPoint]
) -> list[dict[str, Any]]:
    """Every point's sessions: read back from ``points/NNN.csv`` with ``--resume``, else run
    and written there as the point finishes."""
    from eval.compare import run_jobs
    from eval.report import read_sessions_csv, write_sessions_csv

    (ns.out / "points").mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for i, pt in enumerate(points):
        part = ns.out / "points" / f"{i:03d}.csv"
        if ns.resume and part.is_file():
            rows += read_sessions_csv(part)
            print(f"point {i + 1}/{len(points)} {pt.label}: kept", file=sys.stderr)
            continue
        mine = [job for k, job in jobs if k == i]
        print(f"point {i + 1}/{len(points)} {pt.label}", file=sys.stderr)
        found = run_jobs(mine, ns.workers)
        for job, row in zip(mine, found, strict=True):
            row.update(point=i, point_label=pt.label, exercise=job.exercise)
            row["session_s"] = max(float(row["t_motion"]), float(row["t_speech"]))
        write_sessions_csv(found, part)
        rows += found
    return rows


def check_coach_grid(
    ns: argparse.Namespace,
) -> tuple[Any, list[GridPoint], list[str], dict[str, Any]]:
    """Every check of ``langctrl coach-grid``'s arguments ``ns`` before any episode: the split,
    the points, the policy specs and the run's config.

    Raises:
        ConfigError: a bad argument, grid, split or ``--out``.
        ModelError: a model that does not load.
    """
    split, points, specs, config = _prepare(ns)
    _check_out(ns, config)
    return split, points, specs, config


def run_coach_grid(
    ns: argparse.Namespace, checked: tuple[Any, list[GridPoint], list[str], dict[str, Any]]
) -> tuple[str, int, int]:
    """Run ``langctrl coach-grid`` with its arguments ``ns``, as :func:`check_coach_grid`
    found them; the grid's table, and how many sessions and points ran."""
    from eval.compare import policy_names
    from eval.report import atomic_write, write_sessions_csv

    split, points, specs, config = checked
    ns.out.mkdir(parents=True, exist_ok=True)
    atomic_write(ns.out / "config.json", json.dumps(config, indent=2) + "\n")
    names = policy_names(specs)
    pairs = split.pairs(ns.role, ns.users * len(split.exercises(ns.role)))
    jobs = grid_jobs(points, pairs, specs, names, config_params(config), split.graphs, ns.out)
    rows = _run_points(ns, jobs, points)
    write_sessions_csv(rows, ns.out / "sessions.csv")
    diffs = differences(rows, [names[s] for s in specs], ns.base, ns.n_boot, ns.seed)
    _write_grid_csv(diffs, ns.out / "grid.csv")
    text = grid_markdown(diffs, ns.base, _bars(rows, diffs, specs, names, ns))
    atomic_write(ns.out / "grid.md", text)
    plot_grid(diffs, ns.base, ns.out / "grid.png")
    return text, len(rows), len(points)


def _bars(
    rows: Sequence[Mapping[str, Any]],
    diffs: Sequence[Mapping[str, Any]],
    specs: Sequence[str],
    names: Mapping[str, str],
    ns: argparse.Namespace,
) -> str:
    """The coaches' bars (:mod:`eval.coach_bars`): each model against ``lc-coach`` (its
    differences taken here, the same generator seed), ``lc-coach`` against the base."""
    from eval.coach_bars import bar_pairs, bars_markdown, coach_bars

    models = [names[s] for s in specs if s.startswith("ppo:")]
    policies = [names[s] for s in specs]
    pairs = bar_pairs(policies, models, ns.base)
    by = {ns.base: diffs}
    for against in {a for _, a in pairs} - {ns.base}:
        by[against] = differences(rows, models, against, ns.n_boot, ns.seed)
    return bars_markdown(coach_bars(rows, by, pairs))


def config_params(config: Mapping[str, Any]) -> dict[str, tuple[tuple[str, float], ...]]:
    """The policies' parameters a config records (``--coach``), as :func:`grid_jobs` takes them."""
    return {spec: tuple(sorted(v.items())) for spec, v in config.get("coach", {}).items()}


def _write_grid_csv(diffs: Sequence[Mapping[str, Any]], path: Path) -> None:
    import io

    from eval.report import atomic_write

    buf = io.StringIO()
    cols = ["point", "point_label", "policy", "metric", "estimate", "lo", "hi", "n"]
    writer = csv.DictWriter(buf, cols, lineterminator="\n")
    writer.writeheader()
    for d in diffs:
        writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in d.items()})
    atomic_write(path, buf.getvalue())
