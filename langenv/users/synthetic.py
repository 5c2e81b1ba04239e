"""Synthetic users: seeded, randomised resistance episodes, calibrated against the recordings.

A synthetic person resists in *episodes*. Each episode is a trapezoid of the force measured after
the sensor's deadband ("excess" force ``E``, N): it ramps up from 0 over ``rise`` seconds, holds a
plateau ``magnitude``, and ramps down to 0 over ``fall`` seconds, ``duration`` seconds after its
onset. The plateau is multiplied by log-normal noise, ``exp(noise_std * xi(t) - noise_std^2 / 2)``
with ``xi`` a unit Ornstein–Uhlenbeck process of time constant ``noise_tau``. The person pushes
against the motion with ``|F| = E + deadband`` while an episode is under way and not at all
otherwise, which is the convention :class:`~langenv.users.replay.ReplayUser` uses for recorded
sessions, so synthetic and replayed users are comparable.

How many episodes and when. With ``count_pmf`` the number of episodes is drawn first (the
calibrated users draw it from the recorded sessions' counts) and the person cooperates fully after
the last one. The first episode starts at ``t = 0`` with probability ``p_start_resisting`` (the
person already resists when the session starts), otherwise after a log-normal delay. With
``onset_window`` (the calibrated users) the later onsets are spread uniformly over the first
``onset_window`` seconds, as the recorded ones are, and an episode ends by ``min_gap`` before the
next one starts. Without it, episodes follow each other as a renewal process, each later one
starting a log-normal ``gap`` after the previous one ended, for as many episodes as drawn or, with
no ``count_pmf``, for as long as the session lasts (up to ``horizon``): the longer the session,
the more episodes, which in ``LangCtrl-v0`` feeds on itself (resistance near a stop, where the
propelling force tapers, stalls the hand).
Episode magnitudes are log-normal around a per-session level: ``log magnitude = log median +
session_sigma * z_session + magnitude.sigma * z_episode``, so some people resist harder than others.
Everything is drawn from the generator given to :meth:`SyntheticUser.reset`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import lru_cache
from pathlib import Path
from typing import Self

import numpy as np

from langenv.errors import ConfigError
from langenv.users.base import (
    DEFAULT_DEADBAND,
    against_motion,
    float_view,
    sample_table,
    sample_table_array,
)
from langenv.users.noise_kernels import ar1

__all__ = [
    "CALIBRATED_YAML",
    "Episode",
    "LogNormal",
    "SyntheticUser",
    "SyntheticUserParams",
    "ar1_filter",
]

CALIBRATED_YAML = Path(__file__).resolve().parents[1] / "assets" / "users" / "synthetic.yaml"
"""The calibrated parameters shipped with the package (written by ``python -m eval.calibrate``)."""

_LOGNORMAL_FIELDS = frozenset({"first_onset", "gap", "duration", "rise", "fall", "magnitude"})


def _finite(owner: str, name: str, value: float, *, low: float, strict: bool) -> None:
    ok = math.isfinite(value) and (value > low if strict else value >= low)
    if not ok:
        op = ">" if strict else ">="
        raise ConfigError(f"{owner}.{name} must be finite and {op} {low}, got {value!r}")


@dataclass(frozen=True)
class LogNormal:
    """Log-normal distribution: ``median * exp(sigma * z)``, ``z ~ N(0, 1)``.

    Attributes:
        median: Median (> 0), in the unit of the quantity it describes.
        sigma: Standard deviation of the logarithm (>= 0).
    """

    median: float
    sigma: float

    def __post_init__(self) -> None:
        _finite("LogNormal", "median", self.median, low=0.0, strict=True)
        _finite("LogNormal", "sigma", self.sigma, low=0.0, strict=False)

    def sample(self, rng: np.random.Generator) -> float:
        """One draw (one standard normal from ``rng``)."""
        return self.median * math.exp(self.sigma * float(rng.standard_normal()))

    @property
    def mean(self) -> float:
        """Mean ``median * exp(sigma^2 / 2)``."""
        return self.median * math.exp(0.5 * self.sigma**2)

    @classmethod
    def fit(cls, samples: np.ndarray, censored: np.ndarray | None = None) -> LogNormal:
        """Maximum-likelihood fit to positive samples (n,), n >= 2.

        Args:
            samples: Observations (n,), > 0.
            censored: Optional mask (n,): ``True`` where the observation is only a lower bound
                (right-censored, e.g. an episode cut by the end of a recording). Needs at least
                one uncensored sample.

        Raises:
            ConfigError: if fewer than 2 samples, any is not finite and > 0, or all are censored.
        """
        x = np.asarray(samples, dtype=np.float64)
        if x.ndim != 1 or x.size < 2 or not np.all(np.isfinite(x) & (x > 0.0)):
            raise ConfigError("LogNormal.fit: samples must be 1-D, >= 2 of them, finite and > 0")
        logs = np.log(x)
        if censored is None or not np.any(censored):
            return cls(median=float(np.exp(logs.mean())), sigma=float(logs.std()))
        cens = np.asarray(censored, dtype=bool)
        if cens.shape != x.shape or np.all(cens):
            raise ConfigError("LogNormal.fit: censored must match samples and leave one uncensored")
        from scipy.optimize import minimize
        from scipy.stats import norm

        obs, low = logs[~cens], logs[cens]

        def nll(theta: np.ndarray) -> float:
            mu, log_sigma = float(theta[0]), float(theta[1])
            sigma = math.exp(log_sigma)
            ll = norm.logpdf(obs, mu, sigma).sum() + norm.logsf(low, mu, sigma).sum()
            return -float(ll)

        start = np.array([logs.mean(), math.log(max(float(logs.std()), 1e-3))])
        res = minimize(nll, start, method="Nelder-Mead", options={"xatol": 1e-6, "fatol": 1e-9})
        return cls(median=float(math.exp(res.x[0])), sigma=float(math.exp(res.x[1])))


@dataclass(frozen=True)
class SyntheticUserParams:
    """Distributions of a synthetic user's resistance episodes (see the module docstring).

    :meth:`calibrated` returns the values fitted to the study's sessions
    (:mod:`langenv.users.calibration`).

    Attributes:
        count_pmf: ``None`` (default): episodes recur until ``horizon``. Otherwise the
            probabilities of 0, 1, 2, ... episodes per session (sum to 1 within 1e-3).
        p_start_resisting: Probability that the first episode is under way at ``t = 0``.
        first_onset: Onset (s) of the first episode otherwise.
        gap: Time (s) from the end of an episode to the onset of the next.
        duration: Episode length (s), onset to release, ramps included.
        rise: Ramp-up time (s). Ramps longer than the episode are scaled down to fit.
        fall: Ramp-down time (s).
        magnitude: Plateau force above the deadband (N) of a typical person's episode.
        session_sigma: Spread (log) of a person's resistance level around ``magnitude.median``.
        noise_std: Standard deviation (log) of the multiplicative force noise, >= 0.
        noise_tau: Correlation time (s) of the force noise (Ornstein–Uhlenbeck), > 0.
        max_excess: Cap (N) on the force above the deadband.
        deadband: Force sensor deadband (N): the person pushes with ``E + deadband``.
        horizon: Time (s) up to which the force is tabulated; episodes are cut there.
        onset_window: ``None`` (default): onsets follow the renewal process. Otherwise (needs
            ``count_pmf``) the onsets after the first are spread uniformly over
            ``(first onset, onset_window)`` s, at least ``min_gap`` plus 0.1 s apart, and an
            episode ends at the latest ``min_gap`` before the next one starts (``gap`` unused).
        min_gap: Shortest lull (s) between episodes with ``onset_window`` (> 0).
        resolution: Step (s) on which the force is tabulated at reset.
    """

    p_start_resisting: float
    first_onset: LogNormal
    gap: LogNormal
    duration: LogNormal
    rise: LogNormal
    fall: LogNormal
    magnitude: LogNormal
    session_sigma: float
    noise_std: float
    noise_tau: float
    count_pmf: tuple[float, ...] | None = None
    onset_window: float | None = None
    min_gap: float = 0.3
    max_excess: float = 25.0
    deadband: float = DEFAULT_DEADBAND
    horizon: float = 120.0
    resolution: float = 0.01

    def __post_init__(self) -> None:
        owner = "SyntheticUserParams"
        if self.count_pmf is not None:
            pmf = tuple(float(x) for x in self.count_pmf)
            if (
                not pmf
                or any(not (math.isfinite(x) and x >= 0.0) for x in pmf)
                or not math.isclose(sum(pmf), 1.0, abs_tol=1e-3)
            ):
                raise ConfigError(
                    f"{owner}.count_pmf must be None or non-negative probabilities summing to 1, "
                    f"got {self.count_pmf!r}"
                )
            object.__setattr__(self, "count_pmf", pmf)
        if not (math.isfinite(self.p_start_resisting) and 0.0 <= self.p_start_resisting <= 1.0):
            raise ConfigError(
                f"{owner}.p_start_resisting must lie in [0, 1], got {self.p_start_resisting!r}"
            )
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("first_onset", "gap", "duration", "rise", "fall", "magnitude"):
                if not isinstance(value, LogNormal):
                    raise ConfigError(
                        f"{owner}.{f.name} must be a LogNormal, got {type(value).__name__}"
                    )
        for name in ("session_sigma", "noise_std", "deadband"):
            _finite(owner, name, getattr(self, name), low=0.0, strict=False)
        if self.onset_window is not None:
            _finite(owner, "onset_window", self.onset_window, low=0.0, strict=True)
            if self.count_pmf is None:
                raise ConfigError(f"{owner}.onset_window needs count_pmf (the number of episodes)")
        for name in ("noise_tau", "max_excess", "horizon", "resolution", "min_gap"):
            _finite(owner, name, getattr(self, name), low=0.0, strict=True)
        if self.resolution > self.horizon:
            raise ConfigError(
                f"{owner}.resolution ({self.resolution}) must not exceed horizon ({self.horizon})"
            )

    @classmethod
    def calibrated(cls, **overrides: object) -> SyntheticUserParams:
        """The parameters fitted to the study's sessions (:data:`CALIBRATED_YAML`, written by
        ``python -m eval.calibrate``), with ``overrides`` replaced.

        Raises:
            ConfigError: on an unknown or invalid override (names the field).
        """
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise ConfigError(f"SyntheticUserParams has no field(s) {', '.join(unknown)}")
        if not overrides:  # frozen: every person of the calibrated population shares it
            return _calibrated()
        return dataclasses.replace(_calibrated(), **overrides)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """Plain data (numbers, lists, ``{median, sigma}`` for the log-normals), for YAML."""
        out: dict[str, object] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, LogNormal):
                value = {"median": value.median, "sigma": value.sigma}
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, object], where: str = "SyntheticUserParams") -> Self:
        """Parameters from :meth:`to_dict`'s form.

        Raises:
            ConfigError: naming ``where`` and the field, for an unknown, missing or bad field.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where}: expected a mapping of fields, got {type(data).__name__}")
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"{where}: unknown field(s) {', '.join(unknown)}")
        kwargs: dict[str, object] = {}
        for key, value in data.items():
            if key in _LOGNORMAL_FIELDS:
                if not (isinstance(value, Mapping) and set(value) == {"median", "sigma"}):
                    raise ConfigError(f"{where}: {key} must be {{median: ..., sigma: ...}}")
                try:
                    value = LogNormal(float(value["median"]), float(value["sigma"]))
                except (TypeError, ValueError) as exc:  # ConfigError is a ValueError
                    raise ConfigError(f"{where}: {key}: {exc}") from None
            elif key == "count_pmf" and value is not None:
                if not isinstance(value, list):
                    raise ConfigError(f"{where}: count_pmf must be a list of probabilities")
                value = tuple(value)
            kwargs[key] = value
        try:
            return cls(**kwargs)  # type: ignore[arg-type]
        except TypeError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None

    @classmethod
    def load(cls, path: str | Path) -> Self:
        """Parameters from a YAML file (:meth:`to_dict`'s form under the key ``params``).

        Raises:
            ConfigError: naming the file, when it cannot be read or holds bad parameters.
        """
        import yaml

        try:
            data = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"{path}: cannot read synthetic-user parameters: {exc}") from None
        if not isinstance(data, Mapping) or "params" not in data:
            raise ConfigError(f"{path}: expected a mapping with a 'params' entry")
        return cls.from_dict(data["params"], where=str(path))


@lru_cache(maxsize=1)
def _calibrated() -> SyntheticUserParams:
    return SyntheticUserParams.load(CALIBRATED_YAML)


@dataclass(frozen=True)
class Episode:
    """One resistance episode (drawn at reset).

    Attributes:
        onset: Start time (s).
        duration: Length (s), ramps included.
        rise: Ramp-up time (s).
        fall: Ramp-down time (s); ``rise + fall <= duration``.
        magnitude: Plateau force above the deadband (N).
    """

    onset: float
    duration: float
    rise: float
    fall: float
    magnitude: float

    @property
    def end(self) -> float:
        """Release time (s)."""
        return self.onset + self.duration

    def envelope(self, t: np.ndarray) -> np.ndarray:
        """Noise-free force above the deadband (N) at times ``t`` (...,), s."""
        t = np.asarray(t, dtype=np.float64)
        with np.errstate(over="ignore", divide="ignore"):
            up = (t - self.onset) / self.rise if self.rise > 0.0 else np.inf
            down = (self.end - t) / self.fall if self.fall > 0.0 else np.inf
            shape = np.clip(np.minimum(up, down), 0.0, 1.0)
        inside = (t > self.onset) & (t < self.end)
        return np.where(inside, self.magnitude * shape, 0.0)


class SyntheticUser:
    """A seeded random person who resists in episodes (module docstring).

    Args:
        params: Episode distributions; ``None`` uses :meth:`SyntheticUserParams.calibrated`.

    Attributes:
        episodes: The episodes drawn at the last :meth:`reset` (empty before the first one).
        level: The person's resistance level factor drawn at the last reset.
    """

    def __init__(self, params: SyntheticUserParams | None = None) -> None:
        if params is None:
            params = SyntheticUserParams.calibrated()
        if not isinstance(params, SyntheticUserParams):
            raise ConfigError(
                f"SyntheticUser: params must be SyntheticUserParams, got {type(params).__name__}"
            )
        self.params = params
        self.episodes: tuple[Episode, ...] = ()
        self.level = 1.0
        n = math.floor(params.horizon / params.resolution + 1e-9) + 1
        self.grid, self.f_applied = _grid(n, params.resolution)
        """:attr:`grid`: tabulation times (m,), s; :attr:`f_applied`: force magnitude the person
        applies (m,), N, at :attr:`grid` (zeros until :meth:`reset`). Read-only: the grid and
        the zeros are shared by every person of the same grid."""
        self._table = float_view(self.f_applied)

    def __getstate__(self) -> dict[str, object]:
        """Pickled without :attr:`_table` (a view of :attr:`f_applied`)."""
        state = dict(self.__dict__)
        del state["_table"]
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self.grid.setflags(write=False)  # unpickled arrays are writeable copies
        self.f_applied.setflags(write=False)
        self._table = float_view(self.f_applied)

    def _draw_episodes(self, rng: np.random.Generator) -> tuple[Episode, ...]:
        p = self.params
        self.level = math.exp(p.session_sigma * float(rng.standard_normal()))
        episodes: list[Episode] = []
        count: int | None = None
        if p.count_pmf is not None:
            pmf = np.asarray(p.count_pmf)
            count = int(rng.choice(pmf.size, p=pmf / pmf.sum()))
        if rng.random() < p.p_start_resisting:
            onset = 0.0
        else:
            onset = p.first_onset.sample(rng)
        if p.onset_window is not None and count is not None:
            return self._draw_in_window(rng, onset, count, p.onset_window)
        while onset < p.horizon and (count is None or len(episodes) < count):
            episodes.append(self._draw_episode(rng, onset, math.inf))
            onset = onset + episodes[-1].duration + p.gap.sample(rng)
        return tuple(episodes)

    def _draw_in_window(
        self, rng: np.random.Generator, first: float, count: int, window: float
    ) -> tuple[Episode, ...]:
        """``count`` episodes, the first at ``first``, the others spread over ``(first, window)``.

        Sorted uniform draws with a minimum spacing ``min_gap + 0.1`` s: ``count - 1`` uniforms on
        ``[0, room]``, ``room = window - first - (count - 1) spacing`` (0 if negative), sorted,
        plus ``k * spacing``. Each episode is cut ``min_gap`` before the next onset.
        """
        p = self.params
        if count == 0:
            return ()
        spacing = p.min_gap + 0.1
        room = max(window - first - (count - 1) * spacing, 0.0)
        rest = np.sort(rng.random(count - 1)) * room + spacing * np.arange(1, count)
        onsets = [first, *(first + rest).tolist()]
        episodes = []
        for k, onset in enumerate(onsets):
            latest_end = onsets[k + 1] - p.min_gap if k + 1 < count else math.inf
            episodes.append(self._draw_episode(rng, onset, latest_end))
        return tuple(episodes)

    def _draw_episode(self, rng: np.random.Generator, onset: float, latest_end: float) -> Episode:
        """One episode starting at ``onset`` (s), ending by ``latest_end`` (s) at the latest."""
        p = self.params
        duration = min(p.duration.sample(rng), latest_end - onset)
        rise = p.rise.sample(rng)
        fall = p.fall.sample(rng)
        if rise + fall > duration:
            scale = duration / (rise + fall)
            rise *= scale
            fall *= scale
        magnitude = min(self.level * p.magnitude.sample(rng), p.max_excess)
        return Episode(onset, duration, rise, fall, magnitude)

    def reset(self, rng: np.random.Generator) -> None:
        """Draw a new person and session: level, episodes, then the force noise, all from ``rng``.

        Args:
            rng: The generator to draw from (the env's ``np_random``).
        """
        p = self.params
        self.episodes = self._draw_episodes(rng)
        grid = self.grid
        envelope = np.zeros_like(grid)
        for ep in self.episodes:
            lo = int(np.searchsorted(grid, ep.onset, side="right"))
            hi = int(np.searchsorted(grid, ep.end, side="left"))
            if hi > lo:
                envelope[lo:hi] = ep.envelope(grid[lo:hi])
        noise = self._ou_noise(rng, grid.shape[0])
        bias = 0.5 * p.noise_std**2
        # math.exp per sample (the C library's exp), not np.exp: NumPy's vectorised exp rounds
        # differently with AVX-512 than without, and this table drives every tick. Only where
        # the person pushes: elsewhere the table is 0 whatever the noise.
        on = np.flatnonzero(envelope > 0.0)
        factor = np.array([math.exp(p.noise_std * z - bias) for z in noise[on].tolist()])
        applied = np.zeros_like(envelope)
        applied[on] = np.minimum(envelope[on] * factor, p.max_excess) + p.deadband
        applied.setflags(write=False)
        self.f_applied = applied
        self._table = float_view(applied)

    def _ou_noise(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Unit-variance Ornstein–Uhlenbeck samples (n,) at :attr:`grid` (exact discretisation)."""
        a = math.exp(-self.params.resolution / self.params.noise_tau)
        z = rng.standard_normal(n)
        z[1:] *= math.sqrt(1.0 - a * a)
        return ar1_filter(z, a)

    def magnitude(self, t: float) -> float:
        """Force magnitude (N) the person applies at time ``t`` (s)."""
        return sample_table(self._table, self.params.resolution, t)

    def magnitude_array(self, t: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`magnitude`: ``t`` (...,), s, to magnitudes of the same shape, N."""
        return sample_table_array(self.f_applied, self.params.resolution, t)

    def force_table(self) -> tuple[np.ndarray, float]:
        """The tabulated magnitudes (m,), N, and their step (s): :meth:`force` is
        ``against_motion(sample_table(table, step, t), tangent)`` (the env's compiled ticks)."""
        return self.f_applied, self.params.resolution

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Force (3,), N: :meth:`magnitude` along ``-tangent`` (the hand's velocity is not used)."""
        return against_motion(self.magnitude(t), tangent)

    def __repr__(self) -> str:
        return f"SyntheticUser({len(self.episodes)} episodes)"


@lru_cache(maxsize=8)
def _grid(n: int, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """``n`` tabulation times every ``resolution`` s and ``n`` zeros, read-only: one pair per
    process for every person of that grid."""
    grid = np.arange(n, dtype=np.float64) * resolution
    zeros = np.zeros(n)
    grid.setflags(write=False)
    zeros.setflags(write=False)
    return grid, zeros


def ar1_filter(x: np.ndarray, a: float) -> np.ndarray:
    """``y[0] = x[0]``, ``y[n] = x[n] + a y[n-1]``: ``scipy.signal.lfilter([1], [1, -a], x)``
    to the bit (the same operations in the same order), without importing ``scipy.signal``
    (about a second per process). ``x``: (n,); returns a new float64 array (n,)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    out = np.empty_like(x)
    ar1(x, float(a), out)  # compiled: the same two operations per sample, in order
    return out
