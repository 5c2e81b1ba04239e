"""Does the person's pace follow the speech? The listening person's ``follow``, fitted to AC.

Run::

    langctrl listening --sessions ../shared/sessions --out out/listening

Under AC the study's speech ran at its own pace (``a = 1``), whatever the person did, so in the
AC sessions the speech ran ahead of the motion or behind it as the person happened to move: the
one place in the recordings where the speech varies independently of the controller's reaction
to the person. If people follow the speech, they speed up when it runs ahead and slow down when
it lags. This job measures that, and fits :class:`~langenv.users.ListeningParams`' ``follow``
(the push along the motion per second of the speech's lead, N/s) to it by indirect inference:

1. **The statistic** (:func:`lead_statistic`). The speech's lead ``L(t)`` is its progress minus
   the motion's, in seconds of speech: ``L = T (sigma_speech - sigma_motion)``, with
   ``sigma_speech`` the share of the speech said (from ``t_a`` at ``a = 1``), ``sigma_motion`` the
   share of the path done (the hand's speed integrated, over the session's whole path) and ``T``
   the speech's length. Over the time the speech runs (from 1 s), for each lag ``tau`` in
   :data:`LAGS` and each response ``y`` (the cooperation ``c``, the hand's speed ``v``): the
   partial correlation of ``y(t + tau)`` with ``L(t)`` given ``1, t, t^2`` (the session's trend:
   fatigue, the exercise's course), ``c(t)`` and ``y(t)`` (the person's state now). A lagged
   partial correlation, not the raw one: the raw one is confounded by the trend and by the
   person's own persistence (a resisting person falls behind the speech *and* goes on
   resisting). Each session gives one; the people's mean is taken on Fisher's z.
2. **The null and the fit.** The same statistic on simulated AC sessions (the same controller,
   speech and measurement) of ``N`` synthetic people (seeds ``SEED..``; never the calibration
   or fidelity seeds) who do not listen, then of the same people listening with ``follow`` on a
   grid (:data:`FOLLOW_GRID`; the other parameters at their defaults: AC's words carry no
   intents). ``follow`` is fitted by least squares of the recorded statistics against the
   simulated ones (interpolated linearly in ``follow``), each weighted by the recorded one's
   bootstrap variance; its 95 % interval is that of the fit over bootstrap resamples of the
   recorded people (2000, seeded).
3. **AC's length.** The simulated AC motion time (median over the people) at each ``follow``,
   against the recorded median: the simulation's one lasting miss (``docs/fidelity.md``).

Writes ``OUT/listening.json`` (every figure), ``OUT/listening.md`` (the tables) and
``OUT/listening.png`` (recorded and simulated statistics by lag, the fit's loss, AC's length).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from eval.markdown import markdown_table

__all__ = [
    "FOLLOW_GRID",
    "LAGS",
    "Trace",
    "fit_follow",
    "fit_listening",
    "lead_statistic",
    "simulate_ac",
    "trace_from_session",
    "write_listening",
]

LAGS: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0, 3.0)
"""Lags (s) from the speech's lead to the response."""

RESPONSES: tuple[str, ...] = ("c", "v")
"""The responses: cooperation and hand speed."""

FOLLOW_GRID: tuple[float, ...] = (-3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0)
"""``follow`` values simulated (N per s of lead)."""

GRID_HZ = 50.0
"""Sample rate of the traces (the recordings')."""

START_S = 1.0
"""The statistic starts here (s): the recordings' first samples hold a digitising glitch."""


@dataclass(frozen=True)
class Trace:
    """One AC session, sampled at :data:`GRID_HZ`.

    Attributes:
        name: The session or simulated person.
        t: Time (s), shape (n,).
        c: Cooperation, shape (n,).
        v: Hand speed (m/s), shape (n,).
        lead: The speech's lead over the motion (s of speech), shape (n,).
        speaking: Whether the speech still runs, shape (n,), bool.
        length: The motion's length (s).
    """

    name: str
    t: np.ndarray
    c: np.ndarray
    v: np.ndarray
    lead: np.ndarray
    speaking: np.ndarray
    length: float


def _lead(t: np.ndarray, v: np.ndarray, said: np.ndarray, total: float) -> np.ndarray:
    """``T (sigma_speech - sigma_motion)``: ``said`` is the speech said so far (s)."""
    dist = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    motion = dist / dist[-1] if dist[-1] > 0 else np.zeros_like(dist)
    return np.asarray(said - total * motion, dtype=np.float64)


def trace_from_session(session: Any) -> Trace:
    """A recorded AC session (needs ``ee_speed`` and ``t_a``): the speech's length is ``t_a`` at
    the start (the median of samples 1-5, past the first sample's glitch) less the lab's floor
    of ``t_a`` (its last value)."""
    t, c, v, t_a = session.t, session.cooperation, session.ee_speed, session.t_a
    if v is None or t_a is None:
        raise ValueError(f"{session.name}: needs ee_speed and t_a")
    start, floor = float(np.median(t_a[1:6])), float(t_a[-1])
    total = start - floor
    said = np.clip(start - t_a, 0.0, total)
    speaking = t_a > floor + 0.05
    return Trace(session.name, t, c, v, _lead(t, v, said, total), speaking, float(t[-1]))


def lead_statistic(tr: Trace, tau: float, response: str) -> float:
    """The partial correlation of ``y(t + tau)`` with the lead ``L(t)`` given ``1, t, t^2,
    c(t), y(t)``, over ``t >= START_S`` while the speech runs (module docstring); NaN with fewer
    than 20 samples."""
    y = tr.c if response == "c" else tr.v
    dt = float(np.median(np.diff(tr.t)))
    k = round(tau / dt)
    idx = np.flatnonzero((tr.t >= START_S) & tr.speaking)
    idx = idx[idx + k < tr.t.size]
    if idx.size < 20:
        return float("nan")
    s = tr.t[idx] - tr.t[idx].mean()
    z = np.column_stack([np.ones(idx.size), s, s * s, tr.c[idx], y[idx]])
    x, target = tr.lead[idx], y[idx + k]
    rx = x - z @ np.linalg.lstsq(z, x, rcond=None)[0]
    ry = target - z @ np.linalg.lstsq(z, target, rcond=None)[0]
    den = float(np.sqrt((rx @ rx) * (ry @ ry)))
    return float(rx @ ry / den) if den > 0 else float("nan")


def statistics(traces: Sequence[Trace]) -> np.ndarray:
    """Each trace's statistic, shape ``(people, responses, lags)``."""
    return np.array(
        [[[lead_statistic(tr, tau, r) for tau in LAGS] for r in RESPONSES] for tr in traces]
    )


def pooled(stats: np.ndarray) -> np.ndarray:
    """The people's mean on Fisher's z, back-transformed: shape ``(responses, lags)``."""
    z = np.arctanh(np.clip(stats, -0.999, 0.999))
    return np.asarray(np.tanh(np.nanmean(z, axis=0)))


def bootstrap(stats: np.ndarray, n: int, seed: int) -> np.ndarray:
    """:func:`pooled` over ``n`` resamples of the people, shape ``(n, responses, lags)``."""
    rng = np.random.default_rng(seed)
    m = stats.shape[0]
    return np.array([pooled(stats[rng.integers(0, m, m)]) for _ in range(n)])


# --------------------------------------------------------------------------------- simulation
def _episode(args: tuple[float | None, int, str]) -> Trace:
    """One simulated AC session: ``(follow or None for a synthetic person, seed, policy)``."""
    import gymnasium as gym

    import langenv
    from langenv.exercise import speak
    from langenv.users import ListeningParams, ListeningUser, SyntheticUser
    from policies import load_policy

    follow, seed, name = args
    pol = load_policy(name)
    hz = int(GRID_HZ) if name == "ac" else pol.decision_hz
    key = (name, hz)
    env = _ENVS.get(key)
    if env is None:
        env = _ENVS[key] = gym.make(
            langenv.ENV_ID, phrase_graph=speak(pol).ref, decision_hz=hz, max_episode_steps=120 * hz
        )
    user = SyntheticUser() if follow is None else ListeningUser(ListeningParams(follow=follow))
    obs, info = env.reset(seed=seed, options={"user": user})
    pol.reset()
    rows = [(info["time"], info["cooperation"], info["hand_speed"], info["t_a"])]
    done = False
    while not done and not info["motion_done"]:
        obs, _, terminated, truncated, info = env.step(pol.act(obs))
        rows.append((info["time"], info["cooperation"], info["hand_speed"], info["t_a"]))
        done = terminated or truncated
    a = np.array(rows)
    t, c, v, t_a = a.T
    total = float(t_a[0])
    said = np.clip(total - t_a, 0.0, total)
    length = info["t_motion"] if info["t_motion"] is not None else float(t[-1])
    return Trace(f"s{seed}", t, c, v, _lead(t, v, said, total), t_a > 0.05, float(length))


_ENVS: dict[tuple[str, int], Any] = {}


def simulate_ac(
    follow: float | None, seeds: Sequence[int], workers: int, policy: str = "ac"
) -> list[Trace]:
    """Simulated sessions of ``policy`` (AC: at 50 Hz, as recorded), one per seed: synthetic
    people (``follow=None``) or the same people listening with ``follow``."""
    jobs = [(follow, s, policy) for s in seeds]
    if workers <= 1:
        return [_episode(j) for j in jobs]
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(_episode, jobs))


# ------------------------------------------------------------------------------------ the fit
def fit_follow(
    recorded: np.ndarray, weights: np.ndarray, grid: Sequence[float], simulated: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray]:
    """The ``follow`` whose simulated statistics are nearest the recorded ones.

    Args:
        recorded: The recorded statistics, shape ``(responses, lags)``.
        weights: Their weights (1 / bootstrap variance), same shape.
        grid: The ``follow`` values simulated, increasing.
        simulated: The simulated statistics at each, shape ``(len(grid), responses, lags)``.

    Returns:
        ``(follow, fine, loss)``: the minimiser over a fine grid (201 points over the grid's
        span; the simulated statistics interpolated linearly), the fine grid and the weighted
        squared error on it.
    """
    g = np.asarray(grid, dtype=np.float64)
    fine = np.linspace(g[0], g[-1], 201)
    sims = np.asarray(simulated)
    flat = sims.reshape(len(g), -1)
    interp = np.stack([np.interp(fine, g, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    err = (interp - recorded.reshape(1, -1)) ** 2 * weights.reshape(1, -1)
    loss = np.nansum(err, axis=1)
    return float(fine[int(np.argmin(loss))]), fine, loss


def _figure(out: Path, res: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(16, 3.8))
    lags = np.array(LAGS)
    names = {"c": "cooperation c(t + lag)", "v": "hand speed v(t + lag)"}
    for j, r in enumerate(RESPONSES):
        ax = axes[j]
        rec = np.array(res["recorded"][r])
        lo, hi = np.array(res["recorded_ci"][r]).T
        ax.fill_between(lags, lo, hi, color="C0", alpha=0.2, label="recorded, 95 % CI")
        ax.plot(lags, rec, "o-", color="C0", label="recorded (8 people)")
        ax.plot(lags, res["null"][r], "s--", color="C1", label="synthetic (no listening)")
        ax.plot(
            lags,
            res["at_fit"][r],
            "^-",
            color="C2",
            label=f"listening, follow={res['follow']:+.2f}",
        )
        ax.axhline(0.0, color="0.7", lw=0.8)
        ax.set_xlabel("lag (s)")
        ax.set_ylabel("partial correlation with the speech's lead")
        ax.set_title(names[r], fontsize=10)
    axes[0].legend(fontsize=7)
    ax = axes[2]
    ax.plot(res["fine"], res["loss"], color="C2")
    lo, hi = res["follow_ci"]
    ax.axvspan(lo, hi, color="C2", alpha=0.15, label="95 % CI")
    ax.axvline(res["follow"], color="C2", ls="--")
    ax.set_xlabel("follow (N per s of lead)")
    ax.set_ylabel("weighted squared error")
    ax.set_title("the fit", fontsize=10)
    ax.legend(fontsize=7)
    ax = axes[3]
    grid = np.array(res["grid"])
    ax.plot(grid, res["ac_length"], "o-", color="C2", label="listening, median")
    ax.axhline(res["ac_length_null"], color="C1", ls="--", label="synthetic, median")
    ax.axhline(res["ac_length_recorded"], color="C0", label="recorded, median")
    ax.set_xlabel("follow (N per s of lead)")
    ax.set_ylabel("AC motion time (s)")
    ax.set_title("AC's session length", fontsize=10)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def _markdown(res: dict[str, Any]) -> str:
    header = ["response", "lag (s)", "recorded [95 % CI]", "synthetic", "listening at the fit"]
    body = [
        [
            r,
            f"{tau:g}",
            "{:+.2f} [{:+.2f}, {:+.2f}]".format(res["recorded"][r][i], *res["recorded_ci"][r][i]),
            f"{res['null'][r][i]:+.2f}",
            f"{res['at_fit'][r][i]:+.2f}",
        ]
        for r in RESPONSES
        for i, tau in enumerate(LAGS)
    ]
    lo, hi = res["follow_ci"]
    lines = [
        *markdown_table(header, body),
        "",
        f"follow = {res['follow']:+.2f} N/s [95 % CI {lo:+.2f}, {hi:+.2f}]",
        "",
        *markdown_table(
            ["follow (N/s)", *(f"{g:+g}" for g in res["grid"])],
            [["AC motion time, median (s)", *(f"{x:.2f}" for x in res["ac_length"])]],
        ),
        "",
        f"AC motion time: recorded median {res['ac_length_recorded']:.2f} s, synthetic "
        f"{res['ac_length_null']:.2f} s",
    ]
    return "\n".join(lines) + "\n"


def fit_listening(
    sessions_dir: Path, users: int, seed: int, boot: int, workers: int
) -> dict[str, Any]:
    """Fit ``follow`` to the AC sessions in ``sessions_dir`` with ``users`` simulated people
    (seeds ``seed`` on, the bootstrap's ``seed`` too) and ``boot`` bootstrap resamples: the
    result that ``listening.json`` holds.

    Raises:
        SessionDataError: a bad session file.
    """
    from langenv.users import load_sessions

    sessions = load_sessions(sessions_dir, "*_ac.csv")
    rec_traces = [trace_from_session(s) for s in sessions]
    rec_stats = statistics(rec_traces)
    recorded = pooled(rec_stats)
    boots = bootstrap(rec_stats, boot, seed)
    weights = 1.0 / np.maximum(np.nanvar(boots, axis=0), 1e-4)
    seeds = list(range(seed, seed + users))
    null = simulate_ac(None, seeds, workers)
    runs = [simulate_ac(f, seeds, workers) for f in FOLLOW_GRID]
    sims = np.array([pooled(statistics(r)) for r in runs])
    follow, fine, loss = fit_follow(recorded, weights, FOLLOW_GRID, sims)
    fits = [fit_follow(b, weights, FOLLOW_GRID, sims)[0] for b in boots]
    lo, hi = np.quantile(fits, [0.025, 0.975]).tolist()
    at_fit = simulate_ac(follow, seeds, workers)

    def by_r(x: np.ndarray) -> dict[str, list[float]]:
        return {r: np.asarray(x)[j].tolist() for j, r in enumerate(RESPONSES)}

    ci = np.quantile(boots, [0.025, 0.975], axis=0)  # (2, responses, lags)
    return {
        "recorded": by_r(recorded),
        "recorded_ci": {
            r: np.stack([ci[0, j], ci[1, j]], 1).tolist() for j, r in enumerate(RESPONSES)
        },
        "recorded_people": {t.name: by_r(s) for t, s in zip(rec_traces, rec_stats, strict=True)},
        "null": by_r(pooled(statistics(null))),
        "at_fit": by_r(pooled(statistics(at_fit))),
        "grid": list(FOLLOW_GRID),
        "simulated": [by_r(s) for s in sims],
        "follow": follow,
        "follow_ci": [lo, hi],
        "fine": fine.tolist(),
        "loss": loss.tolist(),
        "ac_length": [float(np.median([t.length for t in r])) for r in runs],
        "ac_length_null": float(np.median([t.length for t in null])),
        "ac_length_fit": float(np.median([t.length for t in at_fit])),
        "ac_length_recorded": float(np.median([t.length for t in rec_traces])),
        "people": users,
        "seed": seed,
    }


def write_listening(out: Path, res: dict[str, Any]) -> str:
    """Write ``listening.json``, ``listening.md`` and ``listening.png`` of ``res``
    (:func:`fit_listening`) into ``out``; the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "listening.json").write_text(json.dumps(res, indent=1) + "\n")
    text = _markdown(res)
    (out / "listening.md").write_text(text)
    _figure(out / "listening.png", res)
    return text
