"""A person who listens: the synthetic person plus a response to what the robot says.

:class:`ListeningUser` is the calibrated :class:`~langenv.users.SyntheticUser` (its resistance
episodes, drawn first and unchanged) plus two responses to the speech:

* **to each heard wording's intent** (:data:`~langenv.speech.intents.INTENTS`). The env tells the
  person when a wording's last word is heard (:meth:`ListeningUser.hear`: the clip up to its last
  word, as the voice says it). The person complies with probability ``p_i`` (their own, drawn at
  reset: Beta with mean ``comply`` and concentration ``comply_spread``; 0 for the share
  ``nonresponders`` who respond to no words). A complied wording of intent ``k`` switches the
  response ``L_k`` on after the person's dead time ``d_i`` (drawn around ``latency``) for ``hold``
  seconds (a later complied wording of the same intent extends it); ``L_k`` follows its switch
  through a first-order lag of time constant ``rise``: ``dL/dt = (on - L) / rise``, from 0 to 1
  and back.
* **to the speech running ahead or behind** (``follow``). The env tells the person the speech's
  lead over the motion at every tick (:meth:`ListeningUser.perceive`: the speech's progress minus
  the motion's, in seconds of speech); the person pushes along the motion by ``follow`` N per
  second of lead, seen through the same dead time and rise.

The force is a magnitude against the motion (negative: along it), composed in the force above
the sensor's deadband ("excess", the convention of :mod:`langenv.users.synthetic`)::

    E = E_syn (1 - guide L_guide) (1 - encourage L_encourage) (1 - relax L_relax)
        + slower L_slower - faster L_faster - follow y

with ``E_syn`` the synthetic person's excess and ``y`` the lagged lead; the person pushes with
``|E| + deadband`` in the sign of ``E`` (nothing while ``E = 0``), capped at the synthetic
population's ``max_excess``. Without a response under way the force is the synthetic person's,
bit for bit. Every draw comes from a generator seeded at reset from the env's, after the
synthetic person's draws.

The person is not tabulated: the env computes its force at each 2 ms tick in Python
(``langenv.compiled_steps.TABULATED_USERS`` leaves it out), since what it does depends on what
the speech says during the session.

Where each parameter comes from (published figures, the fit to the study's recordings, or an
assumption with the range to sweep) is :data:`SOURCES`; ``docs/listening.md`` cites them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from types import MappingProxyType

import numpy as np

from langenv.errors import ConfigError
from langenv.speech.intents import INTENTS
from langenv.users.base import against_motion
from langenv.users.synthetic import SyntheticUser, SyntheticUserParams

__all__ = ["SOURCES", "ListeningParams", "ListeningUser", "Source"]

REACTION_S = 0.16
"""A simple reaction to a sound (s): no response starts sooner after the last word."""


@dataclass(frozen=True)
class Source:
    """Where a listening parameter comes from.

    Attributes:
        kind: ``"published"`` (bounded by published figures), ``"fitted"`` (to the study's
            recordings) or ``"assumption"`` (no data gives it: the range is swept).
        range: The plausible range ``(lo, hi)`` in the parameter's unit (what a sweep spans).
        note: The figures and their references, or why it is an assumption.
    """

    kind: str
    range: tuple[float, float]
    note: str


SOURCES: Mapping[str, Source] = MappingProxyType(
    {
        "latency": Source(
            "assumption",
            (0.4, 2.0),
            "no study measures the delay from a spoken instruction to a change of force in "
            "guided arm motion; it is at least a simple reaction to a sound (0.16 s) and a "
            "recognition (about 0.38 s), so the range starts above them",
        ),
        "latency_sigma": Source(
            "assumption", (0.1, 0.5), "spread (log) of the dead time between people"
        ),
        "rise": Source(
            "assumption",
            (0.2, 1.5),
            "time constant of the force's first-order rise once it starts; no data",
        ),
        "hold": Source(
            "assumption",
            (3.0, 30.0),
            "how long a complied wording acts; encouragement keeps its effect when given at "
            "least every ~60 s (Andreacci 2002), the other intents have no data",
        ),
        "comply": Source(
            "assumption",
            (0.3, 0.9),
            "the probability of complying with one utterance: no data; Tejwani 2026's people "
            "split into compliant and non-compliant ones",
        ),
        "comply_spread": Source(
            "assumption",
            (2.0, 20.0),
            "Beta concentration of the per-person probability (small: people differ a lot)",
        ),
        "nonresponders": Source(
            "published",
            (0.2, 0.4),
            "about a third of people take encouragement as neutral or negative (McNair 1996; "
            "Midgley 2018); that they respond to no words at all is an assumption",
        ),
        "guide": Source(
            "published",
            (0.0, 0.7),
            "share of the resistance a complying person lets go: a compliant person pushes "
            "about 3 N where a non-compliant one pushes 10 N (Tejwani 2026's released "
            "notebook), so at most 0.7",
        ),
        "encourage": Source(
            "published",
            (0.05, 0.12),
            "encouragement raises peak force by 5-12 % and time to exhaustion by 8-18 % "
            "(McNair 1996; Belkhiria 2018; Midgley 2018; Andreacci 2002): taken as the share "
            "of the resistance let go",
        ),
        "relax": Source(
            "assumption",
            (0.0, 0.7),
            "the stiffness change after 'relax' has no data; bounded by the compliant "
            "person's 3 N against 10 N (Tejwani 2026)",
        ),
        "faster": Source(
            "assumption",
            (0.0, 6.0),
            "push along the motion (N above the deadband) after 'faster': no data on speed "
            "changes after a spoken instruction in guided arm motion; 3 N is about +30 % of "
            "the study's plateau speed (D0 = 80 N s/m)",
        ),
        "slower": Source(
            "assumption",
            (0.0, 6.0),
            "push against the motion (N above the deadband) after 'slower'; as 'faster'",
        ),
        "follow": Source(
            "fitted",
            (-1.0, 0.0),
            "push along the motion per second of the speech's lead (N/s), fitted to the "
            "study's AC sessions, whose speech runs at its own pace (python -m "
            "eval.listening): 0 [95 % CI -0.99, 0.00]; the range is the interval",
        ),
    }
)
"""Each :class:`ListeningParams` field's source and range (the docs' table reads it)."""


@dataclass(frozen=True)
class ListeningParams:
    """How a :class:`ListeningUser` responds to speech (module docstring).

    Each field's source is in :data:`SOURCES`: ``published`` (bounded by published figures),
    ``fitted`` (to the study's recordings) or ``assumption`` (its range is swept).

    Attributes:
        latency: Mean dead time (s) from a wording's last word to the start of the response
            (assumption, 0.4-2 s; no less than a simple reaction to a sound, 0.16 s, and a
            recognition, about 0.38 s).
        latency_sigma: Spread (log) of a person's dead time around ``latency`` (assumption,
            0.1-0.5); each person's is at least :data:`REACTION_S`.
        rise: Time constant (s) of the response's first-order rise and fall (assumption,
            0.2-1.5 s).
        hold: How long (s) a complied wording acts before the response falls back (assumption,
            3-30 s; encouragement keeps its effect given at least every ~60 s, Andreacci 2002).
        comply: Mean probability of complying with one heard wording (assumption, 0.3-0.9).
        comply_spread: Beta concentration of a person's probability of complying (assumption,
            2-20; ``a = comply * spread``, ``b = (1 - comply) * spread``).
        nonresponders: Share of people who respond to no words (published, 0.2-0.4: about a
            third take encouragement as neutral or negative, McNair 1996, Midgley 2018).
        guide: Share of the resistance let go after a ``guide`` wording (published bound
            0-0.7: compliant 3 N against non-compliant 10 N, Tejwani 2026).
        encourage: Share let go after ``encourage`` (published, 0.05-0.12: peak force +5-12 %,
            time to exhaustion +8-18 %, McNair 1996, Belkhiria 2018, Midgley 2018, Andreacci
            2002).
        relax: Share let go after ``relax`` (assumption, 0-0.7, bounded as ``guide``).
        faster: Push along the motion (N above the deadband) after ``faster`` (assumption,
            0-6 N).
        slower: Push against the motion (N above the deadband) after ``slower`` (assumption,
            0-6 N).
        follow: Push along the motion per second of the speech's lead over the motion, while
            the speech runs (N/s; negative: the person waits for the speech). Fitted to the
            study's AC sessions by ``langctrl listening``: 0, 95 % interval -0.99-0.00
            (the range).
    """

    latency: float = 0.8
    latency_sigma: float = 0.3
    rise: float = 0.5
    hold: float = 8.0
    comply: float = 0.6
    comply_spread: float = 4.0
    nonresponders: float = 0.33
    guide: float = 0.3
    encourage: float = 0.085
    relax: float = 0.4
    faster: float = 3.0
    slower: float = 3.0
    follow: float = 0.0

    def __post_init__(self) -> None:
        owner = "ListeningParams"
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"{owner}.{f.name} must be a finite number, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        checks = {
            "latency": (REACTION_S, 10.0),
            "latency_sigma": (0.0, 2.0),
            "rise": (0.01, 10.0),
            "hold": (0.01, 600.0),
            "comply": (0.0, 1.0),
            "comply_spread": (0.1, 1000.0),
            "nonresponders": (0.0, 1.0),
            "guide": (0.0, 1.0),
            "encourage": (0.0, 1.0),
            "relax": (0.0, 1.0),
            "faster": (0.0, 25.0),
            "slower": (0.0, 25.0),
            "follow": (-20.0, 20.0),
        }
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise ConfigError(f"{owner}.{name} must lie in [{lo:g}, {hi:g}], got {v:g}")

    @classmethod
    def parse(cls, text: str, base: ListeningParams | None = None) -> ListeningParams:
        """Parameters from ``KEY=VALUE,...`` (the jobs' ``--listening``), over ``base``.

        Raises:
            ConfigError: naming the item, for a malformed item, an unknown key (listing the
                known ones), a value that is not a number, or one the field refuses.
        """
        out = base if base is not None else cls()
        names = [f.name for f in fields(cls)]
        items = [s.strip() for s in str(text).split(",") if s.strip()]
        values: dict[str, float] = {}
        for item in items:
            key, eq, value = item.partition("=")
            key = key.strip()
            if not eq or not key:
                raise ConfigError(f"--listening: {item!r} is not KEY=VALUE")
            if key not in names:
                raise ConfigError(f"--listening: unknown key {key!r}; known: {', '.join(names)}")
            try:
                values[key] = float(value)
            except ValueError:
                raise ConfigError(f"--listening: {key}={value.strip()!r} is not a number") from None
        try:
            return replace(out, **values)
        except ConfigError as exc:
            raise ConfigError(f"--listening: {exc}") from None

    def to_text(self) -> str:
        """``KEY=VALUE,...`` of every field (what :meth:`parse` reads back)."""
        return ",".join(f"{f.name}={getattr(self, f.name):g}" for f in fields(self))


_SHARES = ("guide", "encourage", "relax")
_PUSHES = ("faster", "slower")


class ListeningUser(SyntheticUser):
    """A synthetic person who responds to what the robot says (module docstring).

    Args:
        listening: How the person responds; None: :class:`ListeningParams`' defaults.
        params: The synthetic population; None: the calibrated one.

    Attributes:
        responder: Whether the person drawn at the last reset responds to words at all.
        p_comply: Their probability of complying with one heard wording.
        dead_time: Their dead time (s) from the last word to the response.
        heard: ``(time, intent, complied)`` of each wording heard since the reset.
    """

    kind = "listening"
    """What a world's table calls this person (:class:`~langenv.worlds.WorldEnv`'s
    ``perturbation``: none is drawn)."""

    perceives: bool
    """Whether the person needs the speech's lead (``follow != 0``): the env computes it then."""

    def __init__(
        self, listening: ListeningParams | None = None, params: SyntheticUserParams | None = None
    ) -> None:
        super().__init__(params)
        self.listening = listening if listening is not None else ListeningParams()
        if not isinstance(self.listening, ListeningParams):
            raise ConfigError("ListeningUser: listening must be a ListeningParams")
        self.perceives = self.listening.follow != 0.0
        self.responder = False
        self.p_comply = 0.0
        self.dead_time = self.listening.latency
        self.heard: list[tuple[float, str | None, bool]] = []
        self._rng = np.random.default_rng(0)
        self._windows: dict[str, list[tuple[float, float]]] = {k: [] for k in INTENTS}
        self._level = dict.fromkeys(INTENTS, 0.0)
        self._lead: list[tuple[float, float]] = []  # (time, lead) perceived, in order
        self._y = 0.0  # the lagged lead
        self._t = 0.0  # time the state was advanced to

    def reset(self, rng: np.random.Generator) -> None:
        """Draw the synthetic person (as :class:`SyntheticUser` would), then how they listen."""
        super().reset(rng)
        lp = self.listening
        self._rng = np.random.default_rng(int(rng.integers(2**63)))
        r = self._rng
        self.responder = bool(r.random() >= lp.nonresponders)
        a, b = lp.comply * lp.comply_spread, (1.0 - lp.comply) * lp.comply_spread
        p = float(r.beta(a, b)) if 0.0 < lp.comply < 1.0 else lp.comply
        self.p_comply = p if self.responder else 0.0
        s = lp.latency_sigma
        z = float(r.standard_normal())
        self.dead_time = max(REACTION_S, lp.latency * math.exp(s * z - 0.5 * s * s))
        self.heard = []
        self._windows = {k: [] for k in INTENTS}
        self._level = dict.fromkeys(INTENTS, 0.0)
        self._lead = []
        self._y = 0.0
        self._t = 0.0

    # ------------------------------------------------------------------ what the env tells
    def hear(self, t: float, intent: str | None) -> None:
        """A wording's last word is heard at ``t`` (s); ``intent`` is its intent or None.

        The person complies with probability :attr:`p_comply` (one draw per wording with an
        intent); a complied wording switches its intent's response on from ``t + dead_time``
        for ``hold`` s.
        """
        if intent is None:
            self.heard.append((t, None, False))
            return
        complied = bool(self._rng.random() < self.p_comply)
        self.heard.append((t, intent, complied))
        if complied and intent in self._windows:
            start = t + self.dead_time
            wins = self._windows[intent]
            end = start + self.listening.hold
            if wins and start <= wins[-1][1]:
                wins[-1] = (wins[-1][0], max(wins[-1][1], end))
            else:
                wins.append((start, end))

    def perceive(self, t: float, lead: float) -> None:
        """The speech's lead over the motion at ``t`` (s of speech; positive: ahead)."""
        if self.responder:
            self._lead.append((t, lead))

    # ------------------------------------------------------------------ the force
    def _advance(self, t: float) -> None:
        """The responses' levels from the last time advanced to ``t`` (exact first order over
        each stretch where the switches hold still)."""
        t0 = self._t
        if t <= t0:
            return
        rise = self.listening.rise
        for k, wins in self._windows.items():
            level = self._level[k]
            if not wins and level == 0.0:
                continue
            level = _first_order(level, wins, t0, t, rise)
            self._level[k] = level if level > 1e-12 else 0.0
            while wins and wins[0][1] + 40.0 * rise < t0:  # long over: forget it
                wins.pop(0)
        if self.perceives and self._lead:
            seen = _held(self._lead, t - self.dead_time)
            w = math.exp(-(t - t0) / rise)
            self._y = seen + (self._y - seen) * w
        self._t = t

    def magnitude(self, t: float) -> float:
        """Force (N) against the motion at ``t`` (s); negative: along it."""
        m = super().magnitude(t)
        self._advance(t)
        lv = self._level
        if self._y == 0.0 and not any(lv.values()):
            return m  # nothing under way: the synthetic person, bit for bit
        lp = self.listening
        dead = self.params.deadband
        e = max(m - dead, 0.0) if m > 0.0 else 0.0
        for k in _SHARES:
            e *= 1.0 - getattr(lp, k) * lv[k]
        e += lp.slower * lv["slower"] - lp.faster * lv["faster"] - lp.follow * self._y
        cap = self.params.max_excess
        e = min(max(e, -cap), cap)
        if e == 0.0:
            return 0.0
        return math.copysign(abs(e) + dead, e)

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Force (3,), N: :meth:`magnitude` along ``-tangent``."""
        return against_motion(self.magnitude(t), tangent)

    def levels(self) -> dict[str, float]:
        """Each intent's response level now, in [0, 1]."""
        return dict(self._level)

    def __reduce__(self) -> tuple[type[ListeningUser], tuple[ListeningParams, SyntheticUserParams]]:
        """Pickled as a fresh person of the same parameters (what a job hands a worker: the
        env resets it; its tables and draws are not worth carrying)."""
        return (type(self), (self.listening, self.params))

    def __repr__(self) -> str:
        who = f"p_comply={self.p_comply:.2f}" if self.responder else "does not respond"
        return f"ListeningUser({who}, {len(self.episodes)} episodes)"


def _first_order(
    level: float, windows: list[tuple[float, float]], t0: float, t1: float, tau: float
) -> float:
    """``level`` at ``t1`` from ``t0`` under ``dL/dt = (on(t) - L) / tau``, ``on`` 1 inside the
    windows and 0 outside (exact at the windows' edges)."""
    edges = sorted({t0, t1, *(x for w in windows for x in w if t0 < x < t1)})
    for a, b in itertools.pairwise(edges):
        mid = 0.5 * (a + b)
        on = 1.0 if any(s <= mid < e for s, e in windows) else 0.0
        level = on + (level - on) * math.exp(-(b - a) / tau)
    return level


def _held(samples: list[tuple[float, float]], t: float) -> float:
    """The last sample at or before ``t`` (0 before the first)."""
    if t < samples[0][0]:
        return 0.0
    lo, hi = 0, len(samples)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if samples[mid][0] <= t:
            lo = mid
        else:
            hi = mid
    return samples[lo][1]
