"""Calibrate the synthetic users against recorded sessions, and write the shipped parameters.

Run::

    langctrl calibrate --sessions ../shared/sessions            # fit and show
    langctrl calibrate --sessions ../shared/sessions --write    # ... and store them

The procedure (its result is ``langenv/assets/users/synthetic.yaml``, which
:meth:`~langenv.users.SyntheticUserParams.calibrated` loads):

1. **Episodes.** Every recorded cooperation trace is inverted to the force the person applied
   above the deadband (:func:`~langenv.users.invert_cooperation`, SPEC §3) and cut into
   resistance episodes (:func:`extract_episodes`): runs above a threshold, merged across short
   lulls; for each, its onset, duration, ramps (to and from 80 % of its peak, as full linear
   ramps), plateau force and the plateau's log-deviations (the noise).
2. **Direct fit** (:func:`fit_params`): the recorded distribution of the number of episodes per
   session; log-normal distributions (maximum likelihood, episodes cut by the start or end of a
   recording counted as censored) for the first onset, the gaps, durations and ramps; the
   magnitudes as a random-effects model on the log scale (within- and between-session spread);
   the noise's spread and correlation time.
3. **Session structure** (:data:`STRUCTURE`): the users resist from the start, spread their
   episodes over the first 13 s of the session as recorded, push at most as hard as the
   propelling force above the deadband (10 N, so the hand creeps on rather than being driven
   back), and are consistent within a session (log spreads 0.5 of the episode durations and
   0.25 of the magnitudes, against 1.05 and 0.58 fitted over all episodes of all sessions).
4. **Closed loop** (:func:`closed_loop_fit`): the medians of the episode durations and
   magnitudes are chosen on a grid so that synthetic users, run in ``LangCtrl-v0`` under AC,
   LC-noAP and LC on calibration seeds (1000 and up: never the evaluation seeds), give motion
   times and pooled cooperation quantiles (10/50/90 %) like the recordings'. Score
   (:class:`ClosedLoopScore`): the largest ``|log(synthetic / recorded median motion time) -
   log(1.017)|`` over the controllers (1.017 is the centre, in log, of the accepted range
   0.90-1.15), plus the squared quantile differences in units of 0.05.

The same users run under every controller, while the study's users resisted longer under AC than
under LC (recorded medians 15.3 / 14.2 / 12.5 s), so the fit balances the controllers rather than
matching each (``langctrl fidelity --users synthetic:N`` checks the result).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from langenv.errors import ConfigError
from langenv.users import LogNormal, Session, SyntheticUserParams, invert_cooperation
from langenv.users.base import DEFAULT_ALPHA, DEFAULT_F_MAX

__all__ = [
    "STRUCTURE",
    "ClosedLoopScore",
    "EpisodeStats",
    "closed_loop_fit",
    "extract_episodes",
    "fit_params",
    "round_params",
    "score",
    "structured",
    "write_params",
]

STRUCTURE: dict[str, object] = {
    "p_start_resisting": 1.0,
    "onset_window": 13.0,
    "max_excess": 10.0,
}
DURATION_SIGMA = 0.5
"""Log spread of a user's episode durations (session structure)."""
MAGNITUDE_SIGMA = 0.25
"""Log spread of a user's episode magnitudes around their level (session structure)."""
RATIO_CENTRE = math.sqrt(0.90 * 1.15)
"""Centre (geometric) of the accepted range of synthetic / recorded median motion time."""
"""Fields set by the session structure (step 3 of the module docstring), not the direct fit."""

QUANTILE_LEVELS: tuple[float, ...] = (0.1, 0.5, 0.9)
"""Cooperation quantile levels compared with the recordings."""


# --------------------------------------------------------------------------------------------
# Episodes and the direct fit
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EpisodeStats:
    """One resistance episode found in a recorded force profile.

    Attributes:
        session: Name of the session.
        onset: Start (s) where the force rises above the threshold (0 if under way before the
            recording starts, i.e. its first cooperation sample is below 0.99).
        duration: Length (s).
        rise: Ramp-up time (s) of the equivalent linear ramp.
        fall: Ramp-down time (s).
        magnitude: Plateau force above the deadband (N).
        left_censored: Under way when the recording starts.
        right_censored: Still under way when the recording ends.
        log_residual: Log-deviations of the plateau force from ``magnitude``, sampled every
            ``step`` seconds (for the noise fit).
    """

    session: str
    onset: float
    duration: float
    rise: float
    fall: float
    magnitude: float
    left_censored: bool
    right_censored: bool
    log_residual: np.ndarray = field(repr=False)

    @property
    def end(self) -> float:
        """Release time (s)."""
        return self.onset + self.duration


def extract_episodes(
    session: Session,
    *,
    step: float = 0.01,
    on_threshold: float = 0.3,
    merge_gap: float = 0.3,
    min_duration: float = 0.2,
    min_peak: float = 1.0,
    ramp_level: float = 0.8,
    alpha: float = DEFAULT_ALPHA,
    f_max: float = DEFAULT_F_MAX,
) -> list[EpisodeStats]:
    """Invert a session's cooperation and cut the force profile into resistance episodes.

    Args:
        session: The recorded session.
        step: Grid step (s) of the inverted force.
        on_threshold: Post-deadband force (N) above which the person is resisting.
        merge_gap: Lulls shorter than this (s) do not split an episode.
        min_duration: Shorter runs (s) are dropped.
        min_peak: Runs whose peak force (N) is lower are dropped.
        ramp_level: Fraction of the peak that ends the ramp-up and starts the ramp-down.
        alpha: Cooperation filter decay factor (per second).
        f_max: Cooperation filter force scale (N).

    Returns:
        The episodes, in time order.
    """
    grid, f = invert_cooperation(session.t, session.cooperation, alpha=alpha, f_max=f_max, dt=step)
    active = f > on_threshold
    edges = np.flatnonzero(np.diff(np.concatenate([[0], active.astype(np.int8), [0]])))
    runs = [[int(a), int(b)] for a, b in zip(edges[::2], edges[1::2], strict=True)]
    merged: list[list[int]] = []
    for run in runs:
        if merged and (run[0] - merged[-1][1]) * step < merge_gap:
            merged[-1][1] = run[1]
        else:
            merged.append(run)
    t_start = session.t[0]
    episodes: list[EpisodeStats] = []
    for lo, hi in merged:
        seg = f[lo:hi]
        peak = float(np.quantile(seg, 0.95))
        duration = (hi - lo) * step
        if duration < min_duration or peak < min_peak:
            continue
        above = np.flatnonzero(seg >= ramp_level * peak)
        first, last = int(above[0]), int(above[-1])
        rise = (first + 1) * step / ramp_level
        fall = (hi - lo - last) * step / ramp_level
        plateau = seg[first : last + 1]
        plateau = plateau[plateau > 0.0]
        magnitude = float(plateau.mean())
        episodes.append(
            EpisodeStats(
                session=session.name,
                onset=float(grid[lo]),
                duration=duration,
                rise=min(rise, duration),
                fall=min(fall, duration),
                magnitude=magnitude,
                left_censored=bool(
                    grid[lo] < t_start
                    or (grid[lo] <= t_start + step and session.cooperation[0] < 0.99)
                ),
                right_censored=hi >= len(f) - 1,
                log_residual=np.log(plateau / magnitude),
            )
        )
    return episodes


def _correlation_time(series: Sequence[np.ndarray], step: float, max_lag: float = 5.0) -> float:
    """Lag (s) where the pooled autocorrelation of ``series`` (centred) first drops below 1/e."""
    max_k = int(max_lag / step)
    num = np.zeros(max_k + 1)
    den = np.zeros(max_k + 1)
    for x in series:
        x = x - x.mean()
        var = float(np.sum(x * x)) / max(len(x), 1)  # sums, not BLAS: the same on any CPU
        for k in range(min(max_k + 1, len(x))):
            num[k] += float(np.sum(x[: len(x) - k] * x[k:]))
            den[k] += (len(x) - k) * var
    acf = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    below = np.flatnonzero(acf < math.exp(-1.0))
    k = int(below[0]) if below.size else max_k
    return max(k * step, step)


def fit_params(
    sessions: Sequence[Session], *, step: float = 0.01, **extract_kwargs: float
) -> tuple[SyntheticUserParams, list[EpisodeStats]]:
    """Fit :class:`SyntheticUserParams` to recorded sessions (procedure in the module docstring).

    Args:
        sessions: The recorded sessions.
        step: Grid step (s) of the inverted force profiles.
        **extract_kwargs: Passed to :func:`extract_episodes`.

    Returns:
        The fitted parameters and all the episodes found.

    Raises:
        ConfigError: if the sessions hold too few episodes to fit (fewer than 2 of a kind).
    """
    per_session = [extract_episodes(s, step=step, **extract_kwargs) for s in sessions]
    episodes = [e for eps in per_session for e in eps]
    if len(episodes) < 2:
        raise ConfigError(f"fit_params: found {len(episodes)} resistance episodes, need >= 2")
    at_start = [
        bool(eps) and eps[0].onset <= s.t[0] + step
        for eps, s in zip(per_session, sessions, strict=True)
    ]
    first = [eps[0].onset for eps, st in zip(per_session, at_start, strict=True) if eps and not st]
    gaps = [b.onset - a.end for eps in per_session for a, b in itertools.pairwise(eps)]
    cut = np.array([e.left_censored or e.right_censored for e in episodes])
    logs = [np.log([e.magnitude for e in eps]) for eps in per_session if eps]
    grand = float(np.concatenate(logs).mean())
    n_eps = np.array([len(x) for x in logs], dtype=np.float64)
    within = np.concatenate([x - x.mean() for x in logs])
    dof = max(len(within) - len(logs), 1)
    var_w = float(np.sum(within * within)) / dof
    means = np.array([x.mean() for x in logs])
    var_b = float(means.var(ddof=1)) - var_w * float(np.mean(1.0 / n_eps)) if len(logs) > 1 else 0.0
    residuals = [e.log_residual for e in episodes if e.log_residual.size >= 10]
    noise_std = float(np.concatenate(residuals).std()) if residuals else 0.0
    counts = np.bincount([len(eps) for eps in per_session])
    params = SyntheticUserParams(
        count_pmf=tuple(float(x) for x in counts / counts.sum()),
        p_start_resisting=float(np.mean(at_start)),
        first_onset=LogNormal.fit(np.asarray(first)),
        gap=LogNormal.fit(np.asarray(gaps)),
        duration=LogNormal.fit(np.array([e.duration for e in episodes]), censored=cut),
        rise=LogNormal.fit(
            np.array([e.rise for e in episodes]),
            censored=np.array([e.left_censored for e in episodes]),
        ),
        fall=LogNormal.fit(
            np.array([e.fall for e in episodes]),
            censored=np.array([e.right_censored for e in episodes]),
        ),
        magnitude=LogNormal(median=math.exp(grand), sigma=math.sqrt(var_w)),
        session_sigma=math.sqrt(max(var_b, 0.0)),
        noise_std=noise_std,
        noise_tau=_correlation_time(residuals, step) if residuals else 0.1,
    )
    return params, episodes


def round_params(params: SyntheticUserParams, digits: int = 3) -> SyntheticUserParams:
    """``params`` with every float rounded to ``digits`` significant digits."""

    def r(x: float) -> float:
        return float(f"{x:.{digits}g}")

    def rl(d: LogNormal) -> LogNormal:
        return LogNormal(median=r(d.median), sigma=r(d.sigma))

    return SyntheticUserParams(
        count_pmf=None
        if params.count_pmf is None
        else tuple(round(x, digits + 1) for x in params.count_pmf),
        p_start_resisting=r(params.p_start_resisting),
        first_onset=rl(params.first_onset),
        gap=rl(params.gap),
        duration=rl(params.duration),
        rise=rl(params.rise),
        fall=rl(params.fall),
        magnitude=rl(params.magnitude),
        session_sigma=r(params.session_sigma),
        noise_std=r(params.noise_std),
        noise_tau=r(params.noise_tau),
        onset_window=None if params.onset_window is None else r(params.onset_window),
        min_gap=r(params.min_gap),
        max_excess=r(params.max_excess),
        deadband=params.deadband,
        horizon=params.horizon,
        resolution=params.resolution,
    )


def structured(direct: SyntheticUserParams, duration: float, magnitude: float) -> Any:
    """The direct fit with :data:`STRUCTURE` and the given duration (s) and magnitude (N)
    medians."""
    return dataclasses.replace(
        direct,
        duration=LogNormal(duration, DURATION_SIGMA),
        magnitude=LogNormal(magnitude, MAGNITUDE_SIGMA),
        **STRUCTURE,  # type: ignore[arg-type]
    )


# --------------------------------------------------------------------------------------------
# Closed loop in LangCtrl-v0
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ClosedLoopScore:
    """Synthetic users in ``LangCtrl-v0`` against the recordings.

    Attributes:
        motion_ratio: Per controller, synthetic / recorded median motion time.
        quantiles: Synthetic pooled cooperation quantiles at :data:`QUANTILE_LEVELS`.
        recorded_quantiles: The recordings' quantiles at the same levels.
        loss: Largest ``|log(ratio / RATIO_CENTRE)|`` plus squared quantile differences / 0.05.
    """

    motion_ratio: dict[str, float]
    quantiles: tuple[float, ...]
    recorded_quantiles: tuple[float, ...]
    loss: float = field(init=False)

    def __post_init__(self) -> None:
        loss = max(abs(math.log(r / RATIO_CENTRE)) for r in self.motion_ratio.values())
        loss += sum(
            ((a - b) / 0.05) ** 2
            for a, b in zip(self.quantiles, self.recorded_quantiles, strict=True)
        )
        object.__setattr__(self, "loss", float(loss))

    def line(self) -> str:
        """One report line."""
        ratios = " ".join(f"{c} {r:.3f}" for c, r in self.motion_ratio.items())
        qs = " ".join(f"{q:.3f}" for q in self.quantiles)
        return f"motion time ratio {ratios} | cooperation q10/50/90 {qs} | loss {self.loss:.4f}"


def score(
    sessions: Sequence[Session], params: SyntheticUserParams, n_users: int, seed: int, workers: int
) -> ClosedLoopScore:
    """Run ``n_users`` synthetic users with ``params`` under AC, LC-noAP and LC; score them."""
    from eval.fidelity import CONTROLLERS, controller_of, synthetic_traces

    traces = synthetic_traces(n_users, seed, workers, params)
    ratio: dict[str, float] = {}
    for c in CONTROLLERS.values():
        rec = [s.t[-1] for s in sessions if controller_of(s.name) == c]
        syn = [tr.length for tr in traces if tr.controller == c]
        if rec and syn:
            ratio[c] = float(np.median(syn) / np.median(rec))
    pooled = np.concatenate([tr.cooperation for tr in traces])
    recorded = np.concatenate([s.cooperation for s in sessions])
    return ClosedLoopScore(
        motion_ratio=ratio,
        quantiles=tuple(float(x) for x in np.quantile(pooled, QUANTILE_LEVELS)),
        recorded_quantiles=tuple(float(x) for x in np.quantile(recorded, QUANTILE_LEVELS)),
    )


def closed_loop_fit(
    sessions: Sequence[Session],
    direct: SyntheticUserParams,
    *,
    durations: Sequence[float],
    magnitudes: Sequence[float],
    n_users: int = 48,
    seed: int = 1000,
    workers: int = 2,
) -> tuple[SyntheticUserParams, list[tuple[float, float, ClosedLoopScore]]]:
    """Grid search of the duration and magnitude medians (step 4 of the module docstring).

    Returns:
        The best parameters (rounded) and every ``(duration, magnitude, score)`` tried.
    """
    if seed < 1000:
        raise ConfigError(f"closed_loop_fit: seed must be >= 1000 (calibration seeds), got {seed}")
    tried = []
    for dur, mag in itertools.product(durations, magnitudes):
        sc = score(sessions, round_params(structured(direct, dur, mag)), n_users, seed, workers)
        print(f"  duration {dur:g} s, magnitude {mag:g} N: {sc.line()}", flush=True)
        tried.append((dur, mag, sc))
    dur, mag, _ = min(tried, key=lambda row: row[2].loss)
    return round_params(structured(direct, dur, mag)), tried


def write_params(params: SyntheticUserParams, path: Path, provenance: str) -> None:
    """Store ``params`` as YAML (``params:`` plus a comment saying how they were made)."""
    import yaml

    text = yaml.safe_dump({"params": params.to_dict()}, sort_keys=False)
    header = "".join(f"# {line}\n" for line in provenance.splitlines())
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(header + text)
    tmp.replace(path)
