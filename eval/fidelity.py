"""How faithful is the simulation? Replay the study's users and compare with their recordings.

Run::

    langctrl fidelity --sessions ../shared/sessions --out out/fidelity
    langctrl fidelity --sessions ../shared/sessions --users synthetic:48 --seed 0

Every recorded session ``*_ac.csv``, ``*_lcnoap.csv``, ``*_lc.csv`` is replayed in ``LangCtrl-v0``
under the controller named by its suffix (the user is the force that reproduces the recorded
cooperation, :class:`~langenv.users.ReplayUser`), and the simulated session is measured the way the
recording is:

* **session length**: simulated motion end / the recording's last ``t``, per session;
* **hand speed against cooperation** (AC sessions, ``p = 1``): median speed per cooperation bin,
  over the motion (recorded: every sample; simulated: until the motion ends);
* **paces**: medians of ``p`` (over the motion) and ``a`` (over the motion while speech goes on) of
  LC-noAP and LC, all sessions of a controller pooled on a 50 Hz grid;
* **speech length at the start**: ``t_a`` when the session starts (recorded: the median of the
  first five samples, which skips the digitised traces' first-sample glitch);
* **actual misalignment** ``AM = t_speech - t_motion`` of the simulated sessions (the recordings
  end with the motion, so their AM is not in the files; the study's summary figure gives about
  -0.5 / +1.3 / +0.35 s for AC / LC-noAP / LC).

With ``--users synthetic:N`` the same N seeded synthetic users (seeds ``S .. S+N-1``) run under
each controller, and their median motion time per controller and their cooperation quantiles
(10/50/90 %, pooled over the motion) are compared with the recordings'. ``--users listening:N``
runs the same people listening to what the robot says (:class:`~langenv.users.ListeningUser`,
``--listening KEY=VALUE,...`` for its parameters; :mod:`eval.users`); the checks are then named
``listening ...``.

Each figure is checked against :class:`FidelityTargets` and marked PASS or FAIL. Writes
``OUT/fidelity.md`` (tables), ``OUT/fidelity.png`` (figure) and ``OUT/fidelity.json`` (all
figures, for scripts); prints the summary table.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from eval.markdown import markdown_table

__all__ = [
    "CONTROLLERS",
    "COOP_BINS",
    "Check",
    "FidelityTargets",
    "Measures",
    "Trace",
    "measure",
    "run_checks",
    "run_fidelity",
    "trace_from_log",
    "trace_from_session",
]

CONTROLLERS: dict[str, str] = {"ac": "ac", "lcnoap": "lc-noap", "lc": "lc"}

STUDY_GRAPH = "study"
"""The phrase graph LC speaks here: the study's (``langenv.speech.graph.SHIPPED_GRAPHS``), since
fidelity compares the simulation with the study's recordings; the product's default graph (with
pauses and fillers) is measured by ``eval.compare``."""
"""Session-file suffix -> policy that recorded it (``u3_lcnoap.csv`` was run under LC-noAP)."""

COOP_BINS: tuple[float, ...] = (0.0, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0)
"""Edges of the cooperation bins of the speed curve (the last bin includes 1)."""

GRID_HZ = 50.0
"""Rate (Hz) at which traces are pooled (the recordings' rate)."""

MIN_BIN_SECONDS = 2.0
"""A cooperation bin is compared only with this much time (s) in both recorded and simulated."""


@dataclass(frozen=True)
class FidelityTargets:
    """The bars the simulation must meet (issue "Fidelity", measured on the study's users).

    Attributes:
        length_ratio: Per controller, median simulated / recorded session length in this range.
        speed_tol: Per cooperation bin, |simulated - recorded| median hand speed (m/s) at most.
        p_tol: |simulated - recorded| median physical pace (LC-noAP, LC) at most.
        a_tol: |simulated - recorded| median audio pace (LC-noAP, LC) at most.
        speech_tol: |simulated - recorded| speech length at the start (s) at most.
        am_ac: Range (s) of AC's median AM.
        am_lcnoap_min: LC-noAP's median AM above this (s): its speech ends after the motion, as
            in the study.
        motion_ratio: Synthetic users: per controller, median motion time / recorded median.
        coop_tol: Synthetic users: |synthetic - recorded| cooperation quantile at most.
    """

    length_ratio: tuple[float, float] = (0.90, 1.15)
    speed_tol: float = 0.02
    p_tol: float = 0.05
    a_tol: float = 0.08
    speech_tol: float = 0.5
    am_ac: tuple[float, float] = (-2.0, 1.0)
    am_lcnoap_min: float = 0.0
    motion_ratio: tuple[float, float] = (0.90, 1.15)
    coop_tol: float = 0.1


@dataclass(frozen=True, eq=False)
class Trace:
    """One session, recorded or simulated, reduced to what fidelity compares.

    Arrays are sampled on a uniform ``GRID_HZ`` grid from the session's start to its motion end.

    Attributes:
        name: Session name (``"u3_lc"``).
        controller: Policy name (``"ac"``, ``"lc-noap"``, ``"lc"``).
        length: Motion end (s): the recording's last ``t``, or the simulated motion end.
        cooperation: Cooperation over the motion, shape (n,).
        speed: Hand speed over the motion (m/s), shape (n,).
        p: Physical pace over the motion, shape (n,).
        a: Audio pace over the motion while speech goes on, shape (m,).
        em: Estimated misalignment ``t_a - t_x`` over the motion (s), shape (n,).
        speech_at_start: Speech ETC ``t_a`` at the start (s).
        am: Actual misalignment (s), NaN when unknown (recordings).
    """

    name: str
    controller: str
    length: float
    cooperation: np.ndarray = field(repr=False)
    speed: np.ndarray = field(repr=False)
    p: np.ndarray = field(repr=False)
    a: np.ndarray = field(repr=False)
    em: np.ndarray = field(repr=False)
    speech_at_start: float
    am: float = float("nan")


def _held(t: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``x`` (sampled at ``t``) held (zero-order) at the times ``grid``."""
    idx = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)
    return x[idx]


def controller_of(name: str) -> str | None:
    """Policy that recorded the session ``name`` (its file stem), from its suffix; else None."""
    suffix = name.rsplit("_", 1)[-1].lower()
    return CONTROLLERS.get(suffix)


def trace_from_session(session: Any, controller: str) -> Trace:
    """The :class:`Trace` of a recorded :class:`~langenv.users.Session` (needs ``ee_speed``)."""
    t = session.t
    grid = np.arange(t[0], t[-1], 1.0 / GRID_HZ)

    def col(name: str, default: float) -> np.ndarray:
        x = getattr(session, name)
        return _held(t, x, grid) if x is not None else np.full(grid.size, default)

    if session.ee_speed is None:
        raise ValueError(f"{session.path or session.name}: fidelity needs the column 'ee_speed'")
    t_a = session.t_a
    start = float(np.median(t_a[:5])) if t_a is not None else float("nan")
    return Trace(
        name=session.name,
        controller=controller,
        length=float(t[-1]),
        cooperation=col("cooperation", 1.0),
        speed=col("ee_speed", 0.0),
        p=col("physical_pace", 1.0),
        a=col("audio_pace", 1.0),
        em=col("em", float("nan")),
        speech_at_start=start,
    )


def trace_from_log(log: Any, name: str, controller: str) -> Trace:
    """The :class:`Trace` of a simulated :class:`~eval.episode.EpisodeLog`."""
    end = min(log.t_motion, float(log.t[-1]))
    grid = np.arange(0.0, end, 1.0 / GRID_HZ)
    speaking = grid < log.t_speech
    return Trace(
        name=name,
        controller=controller,
        length=float(log.t_motion),
        cooperation=_held(log.t, log.cooperation, grid),
        speed=_held(log.t, log.hand_speed, grid),
        p=_held(log.t, log.p, grid),
        a=_held(log.t, log.a, grid)[speaking],
        em=_held(log.t, log.em, grid),
        speech_at_start=float(log.t_a[0]),
        am=float(log.am),
    )


def speed_by_cooperation(traces: Sequence[Trace]) -> tuple[np.ndarray, np.ndarray]:
    """Median hand speed per cooperation bin (:data:`COOP_BINS`) over ``traces``, pooled.

    Returns:
        ``(median, seconds)``: per bin the median speed (m/s, NaN if empty) and the time (s) the
        pooled traces spend in it; shapes ``(len(COOP_BINS) - 1,)``.
    """
    c = np.concatenate([tr.cooperation for tr in traces]) if traces else np.zeros(0)
    v = np.concatenate([tr.speed for tr in traces]) if traces else np.zeros(0)
    edges = np.asarray(COOP_BINS)
    k = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, edges.size - 2)
    med = np.full(edges.size - 1, np.nan)
    secs = np.zeros(edges.size - 1)
    for b in range(edges.size - 1):
        sel = v[k == b]
        secs[b] = sel.size / GRID_HZ
        if sel.size:
            med[b] = float(np.median(sel))
    return med, secs


def _pooled_median(traces: Sequence[Trace], attr: str) -> float:
    parts = [getattr(tr, attr) for tr in traces]
    x = np.concatenate(parts) if parts else np.zeros(0)
    return float(np.median(x)) if x.size else float("nan")


@dataclass(frozen=True)
class Measures:
    """The figures fidelity compares, of a set of recorded or of simulated sessions.

    Attributes (dicts are keyed by controller, ``"ac"``, ``"lc-noap"``, ``"lc"``):
        length: Per controller, session lengths (s) by session name.
        speed_bins: AC's median hand speed per cooperation bin (m/s).
        speed_seconds: AC's time per cooperation bin (s).
        p_median: Median physical pace (LC-noAP, LC).
        a_median: Median audio pace (LC-noAP, LC).
        speech_at_start: Median speech length at the start (s).
        am_median: Median AM (s), NaN for recordings.
        em_median: Median estimated misalignment over the motion (s; for context: the lab's
            motion ETC was not ours).
    """

    length: dict[str, dict[str, float]]
    speed_bins: list[float]
    speed_seconds: list[float]
    p_median: dict[str, float]
    a_median: dict[str, float]
    speech_at_start: dict[str, float]
    am_median: dict[str, float]
    em_median: dict[str, float]


def measure(traces: Sequence[Trace]) -> Measures:
    """The :class:`Measures` of a set of traces."""
    by: dict[str, list[Trace]] = {}
    for tr in traces:
        by.setdefault(tr.controller, []).append(tr)
    ac = by.get("ac", [])
    med, secs = speed_by_cooperation(ac)
    aligners = [c for c in ("lc-noap", "lc") if c in by]
    return Measures(
        length={c: {tr.name: tr.length for tr in trs} for c, trs in by.items()},
        speed_bins=med.tolist(),
        speed_seconds=secs.tolist(),
        p_median={c: _pooled_median(by[c], "p") for c in aligners},
        a_median={c: _pooled_median(by[c], "a") for c in aligners},
        speech_at_start={
            c: float(np.median([tr.speech_at_start for tr in trs])) for c, trs in by.items()
        },
        am_median={c: float(np.median([tr.am for tr in trs])) for c, trs in by.items()},
        em_median={c: _pooled_median(trs, "em") for c, trs in by.items()},
    )


@dataclass(frozen=True)
class Check:
    """One figure checked against its target."""

    name: str
    measured: str
    target: str
    passed: bool


def _fmt_range(lo: float, hi: float) -> str:
    return f"[{lo:g}, {hi:g}]"


def length_ratios(rec: Measures, sim: Measures, controller: str) -> dict[str, float]:
    """Simulated / recorded length of each session of ``controller`` (sessions in both)."""
    r, s = rec.length.get(controller, {}), sim.length.get(controller, {})
    return {k: s[k] / r[k] for k in sorted(r) if k in s}


def run_checks(rec: Measures, sim: Measures, targets: FidelityTargets) -> list[Check]:
    """Replay checks: ``sim`` (replays) against ``rec`` (recordings)."""
    checks: list[Check] = []
    lo, hi = targets.length_ratio
    for c in sorted(sim.length, key=list(CONTROLLERS.values()).index):
        ratios = list(length_ratios(rec, sim, c).values())
        if not ratios:
            continue
        m = float(np.median(ratios))
        text = f"{m:.3f} ({min(ratios):.2f}-{max(ratios):.2f})"
        checks.append(Check(f"length ratio {c}", text, _fmt_range(lo, hi), lo <= m <= hi))
    edges = COOP_BINS
    for b, (r, s) in enumerate(zip(rec.speed_bins, sim.speed_bins, strict=True)):
        enough = min(rec.speed_seconds[b], sim.speed_seconds[b]) >= MIN_BIN_SECONDS
        if not enough or np.isnan(r) or np.isnan(s):
            continue
        name = f"AC speed, c in [{edges[b]:.2f}, {edges[b + 1]:.2f}{']' if b == 5 else ')'}"
        checks.append(
            Check(
                name,
                f"{s:.3f} vs {r:.3f} m/s",
                f"within {targets.speed_tol:g}",
                abs(s - r) <= targets.speed_tol,
            )
        )
    for label, attr, tol in (("p", "p_median", targets.p_tol), ("a", "a_median", targets.a_tol)):
        for c, s in getattr(sim, attr).items():
            r = getattr(rec, attr).get(c, float("nan"))
            ok = bool(abs(s - r) <= tol)
            checks.append(
                Check(f"median {label} {c}", f"{s:.3f} vs {r:.3f}", f"within {tol:g}", ok)
            )
    for c, s in sim.speech_at_start.items():
        r = rec.speech_at_start.get(c, float("nan"))
        ok = bool(abs(s - r) <= targets.speech_tol)
        checks.append(
            Check(
                f"speech at start {c}",
                f"{s:.2f} vs {r:.2f} s",
                f"within {targets.speech_tol:g}",
                ok,
            )
        )
    if "ac" in sim.am_median:
        m = sim.am_median["ac"]
        lo, hi = targets.am_ac
        checks.append(Check("median AM ac", f"{m:+.2f} s", _fmt_range(lo, hi), lo <= m <= hi))
    if "lc-noap" in sim.am_median:
        m = sim.am_median["lc-noap"]
        floor = targets.am_lcnoap_min
        checks.append(Check("median AM lc-noap", f"{m:+.2f} s", f"> {floor:g}", m > floor))
    return checks


def synthetic_checks(
    rec: Measures,
    rec_traces: Sequence[Trace],
    syn_traces: Sequence[Trace],
    targets: FidelityTargets,
    kind: str = "synthetic",
) -> tuple[list[Check], dict[str, Any]]:
    """Synthetic users against the recordings: motion time per controller, cooperation quantiles.
    ``kind`` names the people in the checks (``synthetic`` or ``listening``, :mod:`eval.users`).

    Returns:
        The checks and the figures behind them (for ``fidelity.json``).
    """
    checks: list[Check] = []
    lo, hi = targets.motion_ratio
    figures: dict[str, Any] = {"motion_time": {}, "coop_quantiles": {}}
    for c in CONTROLLERS.values():
        syn = [tr.length for tr in syn_traces if tr.controller == c]
        recorded = list(rec.length.get(c, {}).values())
        if not syn or not recorded:
            continue
        s, r = float(np.median(syn)), float(np.median(recorded))
        figures["motion_time"][c] = {"synthetic": s, "recorded": r}
        checks.append(
            Check(
                f"{kind} motion time {c}",
                f"{s:.2f} vs {r:.2f} s ({s / r:.3f})",
                _fmt_range(lo, hi),
                lo <= s / r <= hi,
            )
        )
    levels = (0.1, 0.5, 0.9)
    qs = np.quantile(np.concatenate([tr.cooperation for tr in syn_traces]), levels)
    qr = np.quantile(np.concatenate([tr.cooperation for tr in rec_traces]), levels)
    for lev, s, r in zip(levels, qs.tolist(), qr.tolist(), strict=True):
        figures["coop_quantiles"][f"{lev:g}"] = {"synthetic": s, "recorded": r}
        checks.append(
            Check(
                f"{kind} cooperation q{round(lev * 100)}",
                f"{s:.3f} vs {r:.3f}",
                f"within {targets.coop_tol:g}",
                abs(s - r) <= targets.coop_tol,
            )
        )
    return checks, figures


# ------------------------------------------------------------------------------------ running
def _simulate(
    jobs: Sequence[tuple[str, str, int, str | None]],
    workers: int,
    user_params: Any = None,
    user_model: Any = None,
) -> list[tuple[str, str, Any]]:
    """Run ``(policy, user name, seed, session CSV or None)`` episodes; return their logs."""
    from eval.compare import Job, run_jobs
    from eval.episode import EpisodeLog

    with tempfile.TemporaryDirectory(prefix="fidelity-") as tmp:
        specs = [
            Job(
                pol,
                user,
                seed,
                sess,
                tmp,
                False,
                False,
                None,
                phrase_graph=STUDY_GRAPH,
                user_params=user_params,
                user_model=user_model if sess is None else None,
            )
            for pol, user, seed, sess in jobs
        ]
        run_jobs(specs, workers)
        return [
            (user, pol, EpisodeLog.load_npz(Path(tmp) / f"{pol}_{user}.npz"))
            for pol, user, _, _ in jobs
        ]


def replay_traces(sessions: Sequence[Any], workers: int) -> list[Trace]:
    """Replay every session under the controller that recorded it."""
    jobs: list[tuple[str, str, int, str | None]] = []
    for s in sessions:
        c = controller_of(s.name)
        if c is not None:
            jobs.append((c, s.name, 0, str(s.path)))
    return [trace_from_log(log, user, pol) for user, pol, log in _simulate(jobs, workers)]


def synthetic_traces(
    n: int, seed: int, workers: int, params: Any = None, user_model: Any = None
) -> list[Trace]:
    """``n`` synthetic users (seeds ``seed..seed+n-1``) under each of the three controllers.

    Args:
        n: Number of users.
        seed: Seed of the first (``env.reset(seed=...)`` draws the user).
        workers: Worker processes.
        params: :class:`~langenv.users.SyntheticUserParams` (default: the calibrated ones).
        user_model: A :class:`~langenv.users.User` reset with each seed instead (e.g. a
            :class:`~langenv.users.ListeningUser`).
    """
    jobs: list[tuple[str, str, int, str | None]] = [
        (c, f"s{seed + i}", seed + i, None) for c in CONTROLLERS.values() for i in range(n)
    ]
    logs = _simulate(jobs, workers, params, user_model)
    return [trace_from_log(log, user, pol) for user, pol, log in logs]


# ------------------------------------------------------------------------------------ outputs
def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    return [*markdown_table(header, rows), ""]


def render_markdown(
    checks: Sequence[Check],
    rec: Measures,
    sim: Measures,
    rec_traces: Sequence[Trace],
    sim_traces: Sequence[Trace],
    synthetic: dict[str, Any] | None,
) -> str:
    """The text of ``fidelity.md``: checks, sessions, speed bins, paces, synthetic users."""
    n_pass = sum(c.passed for c in checks)
    lines = [
        "# Fidelity: the simulation against the study's recordings",
        "",
        f"{n_pass} of {len(checks)} checks pass. Recorded sessions are replayed under the "
        "controller that recorded them (`langctrl fidelity`; definitions in its docstring).",
        "",
        "## Checks",
        "",
        *_md_table(
            ("figure", "simulated vs recorded", "target", "verdict"),
            [(c.name, c.measured, c.target, "PASS" if c.passed else "FAIL") for c in checks],
        ),
        *_md_sessions(rec_traces, sim_traces),
        *_md_speed_bins(rec, sim),
        *_md_paces(rec, sim),
    ]
    if synthetic is not None:
        lines += _md_synthetic(synthetic)
    return "\n".join(lines)


def _md_sessions(rec_traces: Sequence[Trace], sim_traces: Sequence[Trace]) -> list[str]:
    """Per replayed session: lengths, speech at the start, AM."""
    rec_by = {tr.name: tr for tr in rec_traces}
    rows = [
        (
            tr.name,
            tr.controller,
            f"{r.length:.2f}",
            f"{tr.length:.2f}",
            f"{tr.length / r.length:.2f}",
            f"{r.speech_at_start:.2f}",
            f"{tr.speech_at_start:.2f}",
            f"{tr.am:+.2f}",
        )
        for tr in sim_traces
        if (r := rec_by.get(tr.name)) is not None
    ]
    header = (
        "session",
        "controller",
        "recorded length (s)",
        "simulated (s)",
        "ratio",
        "speech at start, recorded (s)",
        "simulated (s)",
        "simulated AM (s)",
    )
    return ["## Sessions", "", *_md_table(header, rows)]


def _md_speed_bins(rec: Measures, sim: Measures) -> list[str]:
    """Median hand speed per cooperation bin, recorded and simulated."""
    edges = COOP_BINS
    rows = [
        (
            f"[{edges[b]:.2f}, {edges[b + 1]:.2f}{']' if b == len(edges) - 2 else ')'}",
            f"{rec.speed_bins[b]:.3f}",
            f"{sim.speed_bins[b]:.3f}",
            f"{rec.speed_seconds[b]:.1f}",
            f"{sim.speed_seconds[b]:.1f}",
        )
        for b in range(len(edges) - 1)
    ]
    header = ("cooperation", "recorded (m/s)", "simulated (m/s)", "recorded (s)", "simulated (s)")
    return ["## Hand speed by cooperation (AC sessions, p = 1)", "", *_md_table(header, rows)]


def _md_paces(rec: Measures, sim: Measures) -> list[str]:
    """Median paces per controller, recorded and simulated, and the simulated median AM."""
    rows = [
        (
            c,
            f"{rec.p_median.get(c, 1.0):.3f}",
            f"{sim.p_median.get(c, 1.0):.3f}",
            f"{rec.a_median.get(c, 1.0):.3f}",
            f"{sim.a_median.get(c, 1.0):.3f}",
            f"{sim.am_median[c]:+.2f}",
        )
        for c in CONTROLLERS.values()
        if c in sim.length
    ]
    header = ("controller", "p recorded", "p simulated", "a recorded", "a simulated")
    return [
        "## Paces (medians) and misalignment",
        "",
        *_md_table((*header, "AM simulated (s)"), rows),
    ]


def _md_synthetic(synthetic: dict[str, Any]) -> list[str]:
    """Synthetic users' median motion time per controller and cooperation quantiles."""
    times = [
        (c, f"{v['recorded']:.2f}", f"{v['synthetic']:.2f}")
        for c, v in synthetic["motion_time"].items()
    ]
    quantiles = [
        (f"q{float(k) * 100:.0f}", f"{v['recorded']:.3f}", f"{v['synthetic']:.3f}")
        for k, v in synthetic["coop_quantiles"].items()
    ]
    return [
        "## Synthetic users",
        "",
        *_md_table(("controller", "recorded median (s)", "synthetic median (s)"), times),
        *_md_table(("cooperation quantile", "recorded", "synthetic"), quantiles),
    ]


def fidelity_figure(
    rec: Measures,
    sim: Measures,
    rec_traces: Sequence[Trace],
    sim_traces: Sequence[Trace],
    syn_traces: Sequence[Trace] | None,
    path: Path,
) -> None:
    """``fidelity.png``: lengths, speed against cooperation, paces, speech, AM (and synthetic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ctrls = [c for c in CONTROLLERS.values() if c in sim.length]
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    _plot_lengths(axes[0, 0], rec, sim, ctrls)
    _plot_speed(axes[0, 1], rec, sim, rec_traces, sim_traces)
    _plot_pace(axes[0, 2], "p", "physical pace p", rec_traces, sim_traces)
    _plot_pace(axes[1, 0], "a", "audio pace a", rec_traces, sim_traces)
    _plot_speech(axes[1, 1], rec_traces, sim_traces, ctrls)
    _plot_am(axes[1, 2], sim_traces, syn_traces, ctrls)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_lengths(ax: Any, rec: Measures, sim: Measures, ctrls: Sequence[str]) -> None:
    """Per controller, each replay's simulated / recorded length, the median and the target."""
    for i, c in enumerate(ctrls):
        ratios = list(length_ratios(rec, sim, c).values())
        ax.scatter(np.full(len(ratios), i) + np.linspace(-0.15, 0.15, len(ratios)), ratios, s=18)
        ax.hlines(np.median(ratios), i - 0.3, i + 0.3, color="k")
    ax.axhspan(*FidelityTargets().length_ratio, color="g", alpha=0.12, label="target")
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_xticks(range(len(ctrls)), ctrls)
    ax.set_ylabel("simulated / recorded session length")
    ax.set_title("Session length (replays)")
    ax.legend(loc="upper left")


def _plot_speed(
    ax: Any, rec: Measures, sim: Measures, rec_traces: Sequence[Trace], sim_traces: Sequence[Trace]
) -> None:
    """AC sessions: hand speed against cooperation, samples and bin medians."""
    mids = 0.5 * (np.asarray(COOP_BINS[:-1]) + np.asarray(COOP_BINS[1:]))
    ax.plot(mids, rec.speed_bins, "o-", label="recorded")
    ax.plot(mids, sim.speed_bins, "s--", label="simulated")
    for traces, color in ((rec_traces, "C0"), (sim_traces, "C1")):
        for tr in (t for t in traces if t.controller == "ac"):
            ax.scatter(tr.cooperation[::10], tr.speed[::10], s=2, color=color, alpha=0.15)
    ax.set_xlabel("cooperation c")
    ax.set_ylabel("hand speed (m/s)")
    ax.set_title("AC: hand speed against cooperation (bin medians)")
    ax.legend()


def _plot_pace(
    ax: Any, attr: str, label: str, rec_traces: Sequence[Trace], sim_traces: Sequence[Trace]
) -> None:
    """Violins of one pace (``"p"`` or ``"a"``) for LC-noAP and LC, recorded beside simulated."""
    data, pos, colors = [], [], []
    for i, c in enumerate(("lc-noap", "lc")):
        for j, (traces, col) in enumerate(((rec_traces, "C0"), (sim_traces, "C1"))):
            x = [getattr(t, attr) for t in traces if t.controller == c]
            if x:
                data.append(np.concatenate(x))
                pos.append(2 * i + 0.8 * j)
                colors.append(col)
    if data:
        parts = ax.violinplot(data, positions=pos, showmedians=True, widths=0.7)
        for body, col in zip(parts["bodies"], colors, strict=True):
            body.set_facecolor(col)
    ax.set_xticks([0.4, 2.4], ["LC-noAP", "LC"])
    ax.set_title(f"{label}: recorded (blue) vs simulated (orange)")


def _plot_speech(
    ax: Any, rec_traces: Sequence[Trace], sim_traces: Sequence[Trace], ctrls: Sequence[str]
) -> None:
    """Median speech length at the start per controller, recorded and simulated."""
    for i, c in enumerate(ctrls):
        r = [t.speech_at_start for t in rec_traces if t.controller == c]
        s = [t.speech_at_start for t in sim_traces if t.controller == c]
        ax.bar(i - 0.2, np.median(r), 0.4, color="C0", label="recorded" if i == 0 else None)
        ax.bar(i + 0.2, np.median(s), 0.4, color="C1", label="simulated" if i == 0 else None)
    ax.set_xticks(range(len(ctrls)), ctrls)
    ax.set_ylabel("speech at a = 1 at the start (s)")
    ax.set_title("Speech length at the start")
    ax.legend()


STUDY_AM: dict[str, float] = {"ac": -0.5, "lc-noap": 1.3, "lc": 0.35}
"""The study's median AM per controller (s), read off its summary figure (approximate)."""


def _plot_am(
    ax: Any, sim_traces: Sequence[Trace], syn_traces: Sequence[Trace] | None, ctrls: Sequence[str]
) -> None:
    """AM of the replays (and of the synthetic users) per controller, with the study's figure."""
    for i, c in enumerate(ctrls):
        am = [t.am for t in sim_traces if t.controller == c]
        ax.scatter(np.full(len(am), i) + np.linspace(-0.15, 0.15, len(am)), am, s=18, color="C1")
        study_label = "study's figure (approx.)" if i == 0 else None
        ax.scatter([i], [STUDY_AM[c]], marker="*", s=160, color="C0", zorder=3, label=study_label)
        if syn_traces:
            syn = [t.am for t in syn_traces if t.controller == c]
            syn_label = "synthetic users" if i == 0 else None
            ax.scatter(np.full(len(syn), i + 0.3), syn, s=6, color="C2", alpha=0.5, label=syn_label)
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_xticks(range(len(ctrls)), ctrls)
    ax.set_ylabel("AM = speech end - motion end (s)")
    ax.set_title("Actual misalignment (replays)")
    ax.legend()


def run_fidelity(sessions_dir: Path, out: Path, spec: Any, seed: int, workers: int) -> list[Check]:
    """Replay the recorded sessions in ``sessions_dir`` (and, with ``spec``, an
    :class:`eval.users.UserSpec`, run its simulated users from ``seed``) and write
    ``fidelity.md``, ``fidelity.png`` and ``fidelity.json`` into ``out``; the checks.

    Raises:
        SessionDataError: no session CSV named ``*_ac.csv``, ``*_lcnoap.csv`` or ``*_lc.csv``,
            or a bad one (nothing written).
    """
    from langenv.errors import SessionDataError
    from langenv.users import load_sessions

    sessions = [
        s for s in load_sessions(sessions_dir, "*.csv") if controller_of(s.name) is not None
    ]
    if not sessions:
        raise SessionDataError(
            f"{sessions_dir}: no session CSVs named *_ac.csv, *_lcnoap.csv or *_lc.csv"
        )
    rec_traces = [trace_from_session(s, str(controller_of(s.name))) for s in sessions]
    sim_traces = replay_traces(sessions, workers)
    rec, sim = measure(rec_traces), measure(sim_traces)
    targets = FidelityTargets()
    checks = run_checks(rec, sim, targets)
    syn_traces = None
    syn_figs = None
    if spec is not None:
        syn_traces = synthetic_traces(spec.count, seed, workers, user_model=spec.model())
        syn_checks, syn_figs = synthetic_checks(rec, rec_traces, syn_traces, targets, spec.kind)
        checks += syn_checks
    out.mkdir(parents=True, exist_ok=True)
    md = render_markdown(checks, rec, sim, rec_traces, sim_traces, syn_figs)
    (out / "fidelity.md").write_text(md + "\n")
    fidelity_figure(rec, sim, rec_traces, sim_traces, syn_traces, out / "fidelity.png")
    report = {
        "checks": [asdict(c) for c in checks],
        "recorded": asdict(rec),
        "simulated": asdict(sim),
        "synthetic": syn_figs,
    }
    (out / "fidelity.json").write_text(json.dumps(report, indent=1) + "\n")
    return checks
