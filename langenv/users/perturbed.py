"""Synthetic users who behave in ways the analytic aligners do not model.

The calibrated :class:`~langenv.users.SyntheticUser` resists in trapezoid episodes against the
motion. The analytic controllers' estimate of the motion's time to completion (ETC) assumes that
whatever the person did so far goes on. :class:`PerturbedUser` draws such a person first, then
(from the same generator) one *perturbation* of that person's force, chosen by weight:

* ``none``: the synthetic person as drawn (the population itself);
* ``speeds_up_late``: from a time in ``late_onset`` s on, the person pushes *along* the motion
  with ``push`` N (ramp 0.5 s), resistance dropped: breaks an ETC that assumes the pace so far;
* ``stop_restart``: at a time in ``stop_onset`` s, holds the handle against the motion with
  ``hold`` N above the deadband (the calibrated population's largest resistance is 10 N) for
  ``stop_duration`` s (ramps 0.2 s), then goes on as drawn: a
  stall the ETC reads as the new normal;
* ``tremor``: a sinusoid of ``tremor_hz`` Hz and ``tremor_amplitude`` N along the path on top
  of the resistance (the sensor's 5 N deadband hides the part below it, as it would a real
  tremor): a force with fast oscillations;
* ``lagged``: the resistance passes through a first-order lag of ``lag_tau`` s, slow to give in
  and slow to let go: cooperation that recovers late.

Each range is uniform; every draw comes from the generator given to :meth:`PerturbedUser.reset`
*after* the synthetic person's own draws, so kind ``none`` is the :class:`SyntheticUser` of the
same seed, force for force. The force stays a magnitude along the path tabulated at reset, which
the env's compiled ticks read as they read a synthetic user's, and it is capped at
``SyntheticUserParams.max_excess + deadband`` either way: no perturbation pushes harder than the
calibrated population may. The arm's safety monitor watches these users as any other.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from langenv.errors import ConfigError
from langenv.users.base import against_motion, float_view, sample_table, sample_table_array
from langenv.users.synthetic import SyntheticUser, SyntheticUserParams
from langenv.validation import dataclass_from_dict

__all__ = ["PERTURBATIONS", "Perturbations", "PerturbedUser"]

#: The perturbation kinds, in the order their weights are listed.
PERTURBATIONS: tuple[str, ...] = ("none", "speeds_up_late", "stop_restart", "tremor", "lagged")


def _range(owner: str, name: str, value: object, low: float) -> tuple[float, float]:
    """A ``(lo, hi)`` pair of finite numbers with ``low <= lo <= hi`` (ConfigError naming it)."""
    try:
        lo, hi = (float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ConfigError(f"{owner}.{name} must be a pair [lo, hi], got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and low <= lo <= hi):
        raise ConfigError(f"{owner}.{name} must be finite with {low} <= lo <= hi, got {value!r}")
    return lo, hi


@dataclass(frozen=True)
class Perturbations:
    """Which perturbation a :class:`PerturbedUser` draws, and the ranges of its parameters.

    Attributes:
        weights: Relative weight of each kind of :data:`PERTURBATIONS` (>= 0, not all 0);
            kinds left out weigh 0.
        late_onset: ``speeds_up_late``: when the push along the motion starts (s).
        push: ``speeds_up_late``: its size (N, before the sensor's deadband).
        stop_onset: ``stop_restart``: when the hold starts (s).
        stop_duration: ``stop_restart``: how long it lasts (s).
        hold: ``stop_restart``: its force above the deadband (N).
        tremor_hz: ``tremor``: frequency (Hz; the force is tabulated at 100 Hz, so <= 20).
        tremor_amplitude: ``tremor``: amplitude (N).
        lag_tau: ``lagged``: time constant of the lag (s).
    """

    weights: Mapping[str, float] = field(
        default_factory=lambda: {
            "none": 0.5,
            "speeds_up_late": 0.125,
            "stop_restart": 0.125,
            "tremor": 0.125,
            "lagged": 0.125,
        }
    )
    late_onset: tuple[float, float] = (4.0, 9.0)
    push: tuple[float, float] = (6.0, 12.0)
    stop_onset: tuple[float, float] = (2.0, 8.0)
    stop_duration: tuple[float, float] = (1.5, 4.0)
    hold: tuple[float, float] = (8.0, 10.0)
    tremor_hz: tuple[float, float] = (4.0, 8.0)
    tremor_amplitude: tuple[float, float] = (3.0, 8.0)
    lag_tau: tuple[float, float] = (0.8, 3.0)

    def __post_init__(self) -> None:
        owner = "Perturbations"
        if not isinstance(self.weights, Mapping):
            raise ConfigError(f"{owner}.weights must be a mapping kind -> weight")
        unknown = sorted(set(self.weights) - set(PERTURBATIONS))
        if unknown:
            raise ConfigError(
                f"{owner}.weights: unknown kind(s) {', '.join(unknown)}; known: "
                f"{', '.join(PERTURBATIONS)}"
            )
        w = {k: float(self.weights.get(k, 0.0)) for k in PERTURBATIONS}
        if any(not (math.isfinite(v) and v >= 0.0) for v in w.values()) or sum(w.values()) <= 0:
            raise ConfigError(f"{owner}.weights must be >= 0 and not all 0, got {self.weights!r}")
        object.__setattr__(self, "weights", w)  # a plain dict: picklable for subprocesses
        for f in fields(self):
            if f.name != "weights":
                object.__setattr__(self, f.name, _range(owner, f.name, getattr(self, f.name), 0.0))
        if self.tremor_hz[1] > 20.0:
            raise ConfigError(f"{owner}.tremor_hz must be <= 20 Hz, got {self.tremor_hz!r}")

    @classmethod
    def from_dict(cls, data: Mapping[str, object], where: str = "Perturbations") -> Perturbations:
        """From plain data (a config's mapping); ConfigError naming ``where`` and the field."""
        return dataclass_from_dict(cls, data, where)

    def probabilities(self) -> np.ndarray:
        """The weights of :data:`PERTURBATIONS` normalised, shape ``(5,)``."""
        w = np.array([self.weights[k] for k in PERTURBATIONS], dtype=np.float64)
        return w / w.sum()


class PerturbedUser(SyntheticUser):
    """A synthetic person with one drawn perturbation (module docstring).

    Args:
        perturbations: Kinds and ranges; ``None``: :class:`Perturbations`' defaults.
        params: The synthetic population; ``None``: the calibrated one.

    Attributes:
        kind: The perturbation drawn at the last reset (``"none"`` before the first).
        detail: Its drawn parameters (s, N, Hz).
    """

    def __init__(
        self, perturbations: Perturbations | None = None, params: SyntheticUserParams | None = None
    ) -> None:
        super().__init__(params)
        self.perturbations = perturbations if perturbations is not None else Perturbations()
        if not isinstance(self.perturbations, Perturbations):
            raise ConfigError("PerturbedUser: perturbations must be a Perturbations")
        self.kind = "none"
        self.detail: dict[str, float] = {}

    def reset(self, rng: np.random.Generator) -> None:
        """Draw the synthetic person (as :class:`SyntheticUser` would), then the perturbation."""
        super().reset(rng)
        pert = self.perturbations
        self.kind = PERTURBATIONS[int(rng.choice(len(PERTURBATIONS), p=pert.probabilities()))]
        applied = np.array(self.f_applied, dtype=np.float64)
        p = self.params
        cap = p.max_excess + p.deadband
        t = self.grid
        if self.kind == "speeds_up_late":
            onset, push = rng.uniform(*pert.late_onset), rng.uniform(*pert.push)
            ramp = np.clip((t - onset) / 0.5, 0.0, 1.0)
            applied = np.where(t >= onset, -push * ramp, applied)
            applied[(t >= onset) & (ramp == 0.0)] = 0.0
            self.detail = {"onset": onset, "push": push}
        elif self.kind == "stop_restart":
            onset = rng.uniform(*pert.stop_onset)
            duration, hold = rng.uniform(*pert.stop_duration), rng.uniform(*pert.hold)
            shape = np.clip(np.minimum(t - onset, onset + duration - t) / 0.2, 0.0, 1.0)
            held = np.where(shape > 0.0, hold * shape + p.deadband, 0.0)
            applied = np.maximum(applied, held)
            self.detail = {"onset": onset, "duration": duration, "hold": hold}
        elif self.kind == "tremor":
            hz, amp = rng.uniform(*pert.tremor_hz), rng.uniform(*pert.tremor_amplitude)
            phase = rng.uniform(0.0, 2.0 * math.pi)
            wave = amp * np.array([math.sin(2.0 * math.pi * hz * x + phase) for x in t.tolist()])
            applied = applied + wave
            self.detail = {"hz": hz, "amplitude": amp}
        elif self.kind == "lagged":
            tau = rng.uniform(*pert.lag_tau)
            excess = np.where(applied > 0.0, applied - p.deadband, 0.0)
            w = 1.0 - math.exp(-p.resolution / tau)
            y, out = 0.0, []
            for x in excess.tolist():
                y += w * (x - y)
                out.append(y)
            lagged = np.array(out)
            applied = np.where(lagged > 0.05, lagged + p.deadband, 0.0)
            self.detail = {"tau": tau}
        else:
            self.detail = {}
        applied = np.clip(applied, -cap, cap)
        applied.setflags(write=False)
        self.f_applied = applied
        self._table = float_view(applied)

    def magnitude(self, t: float) -> float:
        """Force (N) against the motion at ``t`` (s); negative: along it."""
        return sample_table(self._table, self.params.resolution, t)

    def magnitude_array(self, t: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`magnitude`."""
        return sample_table_array(self.f_applied, self.params.resolution, t)

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Force (3,), N: :meth:`magnitude` along ``-tangent``."""
        return against_motion(self.magnitude(t), tangent)

    def __repr__(self) -> str:
        return f"PerturbedUser({self.kind}, {len(self.episodes)} episodes)"
