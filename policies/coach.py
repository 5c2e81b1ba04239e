"""``lc-coach``: the best analytic policy (``lc-fill-end``) plus a therapist's rule for which
intent to say when (:class:`~policies.analytic.LanguageController` with ``intents=True``; this
module holds the rule and how it chooses).

A person who listens (:class:`~langenv.users.listening.ListeningUser`) responds to what a wording
asks (its intent, :data:`~langenv.speech.intents.INTENTS`). ``lc-fill-end`` chooses its wordings
by length only (the content rule, :func:`~policies.analytic.fill_choice`); the coach chooses among
the same children by what they ask, with the rule a therapist would write
(:class:`CoachRule`, :meth:`CoachRule.intent`), in this order:

1. ``relax`` when the person pushes against the path: cooperation below ``relax_c`` and falling
   faster than ``relax_trend`` (1/s);
2. ``encourage`` as cooperation falls: below ``encourage_c``;
3. ``faster`` when the person's pace lags (their own pace, the motion's rate over the commanded
   physical pace, averaged over ``pace_tau``, below ``1 - pace_band``), ``slower`` when it leads
   (above ``1 + pace_band``);
4. ``guide`` otherwise.

**It never breaks the per-leg law.** It chooses only where the content rule chooses (the slot's
end, among at least two children), only among the children the content rule lets end with the
motion (``t_min <= plan - margin``, the gates included: a gate is a child like any other, and a
leg's words still wait for their leg), and only a child whose shortest speech is at most
``slack`` s shorter than the content rule's own choice; when none of them asks for the wanted
intent it says what ``lc-fill-end`` says. Paces, pauses and the terminal phase are
``lc-fill-end``'s, unchanged.

**How it knows what a child asks.** The observation gives each child's ``t_min`` and ``t_max``,
not its intent. The coach reads the graph it speaks (``use_graph``, called by
:func:`langenv.exercise.script.speak` before the env is built, or ``use_phrase_graph``)
and finds the current vertex's children by their blocks in the observation
(:class:`ChildIntents`): the blocks the env encodes from the same graph, float for float. Without
a graph, or where two vertices' children share their blocks but not their intents, it says what
``lc-fill-end`` says.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from langenv.errors import ConfigError
from langenv.speech.choice import choice_action, duration_factor, nearest
from langenv.speech.intents import INTENTS
from langenv.task import observation as ob
from langenv.task.observation import Obs

__all__ = [
    "COACH_RULE",
    "INTENT_INPUTS",
    "ChildIntents",
    "CoachRule",
    "PersonPace",
    "coach_choice",
    "intent_inputs",
    "load_intents",
]


@dataclass(frozen=True)
class CoachRule:
    """The therapist's rule: which intent to say given the person's state (module docstring).

    Attributes:
        relax_c: Cooperation below which a falling one asks the person to relax, in [0, 1].
        relax_trend: Cooperation trend (1/s, <= 0) at or below which the person counts as
            pushing against the path now.
        encourage_c: Cooperation below which the coach encourages, in [0, 1].
        pace_band: How far (>= 0) the person's own pace may lie from 1 before the coach asks for
            more speed (below) or less (above); ``inf``: never.
        pace_tau: Time constant (s, > 0) of the average of the person's pace.
        slack: How much shorter (s, >= 0) than the content rule's choice a child's shortest
            speech may be for the coach to say it instead; ``inf``: any child that fits.
    """

    relax_c: float = 0.7
    relax_trend: float = -0.2
    encourage_c: float = 0.85
    pace_band: float = 0.15
    pace_tau: float = 1.0
    slack: float = math.inf

    def __post_init__(self) -> None:
        owner = "CoachRule"
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or math.isnan(v):
                raise ConfigError(f"{owner}.{f.name} must be a number, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        for name in ("relax_c", "encourage_c"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"{owner}.{name} must lie in [0, 1], got {getattr(self, name)}")
        if not -math.inf < self.relax_trend <= 0.0:
            raise ConfigError(
                f"{owner}.relax_trend must be finite and <= 0, got {self.relax_trend}"
            )
        for name in ("pace_band", "slack"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f"{owner}.{name} must be >= 0, got {getattr(self, name)}")
        if not (math.isfinite(self.pace_tau) and self.pace_tau > 0.0):
            raise ConfigError(f"{owner}.pace_tau must be finite and > 0, got {self.pace_tau}")

    def intent(self, cooperation: float, trend: float, pace: float) -> str:
        """The intent to say now: ``relax``, ``encourage``, ``faster``, ``slower`` or ``guide``.

        Args:
            cooperation: The cooperation ``c`` in [0, 1].
            trend: Its trend ``dc/dt`` (1/s).
            pace: The person's own pace (1: as the robot plans).
        """
        if cooperation < self.relax_c and trend <= self.relax_trend:
            return "relax"
        if cooperation < self.encourage_c:
            return "encourage"
        if pace < 1.0 - self.pace_band:
            return "faster"
        if pace > 1.0 + self.pace_band:
            return "slower"
        return "guide"


COACH_RULE = CoachRule(encourage_c=0.0, pace_band=0.05, slack=0.5)
"""``lc-coach``'s rule, tuned on the validation worlds (shoulder_extension, 16 validation people
listening, the 19 points of ``configs/coach_grid.yaml``; HISTORY.md, "Coaches (issue 46, parts
3 and 4)"): never ``encourage`` (its effect, 5-12 %, does not pay for the shorter wording),
``faster``/``slower`` beyond 5 % of the planned pace, and no wording more than 0.5 s shorter
than the content rule's."""


class ChildIntents:
    """The intents of the current vertex's children, read off an observation with the graph.

    Args:
        graph: The phrase graph the env speaks (:class:`~langenv.speech.graph.PhraseGraph`, as
            the env loads it: the same clips, so the same ``t_min`` and ``t_max``).

    Each vertex with at least two children is keyed by its children's blocks as the env encodes
    them (float32 ``t_min / 40``, ``t_max / 40``, clipped to [-1, 1]); a key that two vertices
    share with different intents is dropped (:meth:`of` answers None there).
    """

    def __init__(self, graph: Any) -> None:
        table: dict[tuple[float, ...], tuple[str | None, ...] | None] = {}
        for u in graph.phrases:
            kids = graph.children(u)
            if len(kids) < 2:
                continue
            key = tuple(v for c in kids for v in _block(graph.t_min(c), graph.t_max(c)))
            intents = tuple(graph.intent(c) for c in kids)
            if key in table and table[key] != intents:
                table[key] = None  # ambiguous: the blocks do not tell
            else:
                table.setdefault(key, intents)
        self._table: Mapping[tuple[float, ...], tuple[str | None, ...] | None] = MappingProxyType(
            table
        )

    def of(self, values: ob.ObsValues) -> tuple[str | None, ...] | None:
        """Each valid child's intent (None: a child that asks nothing), in the observation's
        order; None when the blocks match no vertex of the graph (or an ambiguous one)."""
        key: list[float] = []
        k = 0
        while (i := ob.child_index(k)) + ob.CHILD_FIELDS <= len(values):
            if values[i] <= 0.0:
                break
            key += (float(values[i + 1]), float(values[i + 2]))
            k += 1
        return self._table.get(tuple(key))


def _block(t_min: float, t_max: float) -> tuple[float, float]:
    """A child's ``(t_min, t_max)`` as the observation holds them (float32 of the clipped
    encoding, read back as a float)."""
    clip = ob.encode_seconds
    return (
        float(np.float32(min(1.0, max(-1.0, clip(t_min))))),
        float(np.float32(min(1.0, max(-1.0, clip(t_max))))),
    )


#: What each child's intent inputs say (a learned chooser's ``child_intents``,
#: :class:`~policies.learned.ResidualSpec`), in order: the intents of
#: :data:`~langenv.speech.intents.INTENTS`, then ``"none"`` (a wording without one, a filler, a
#: pause or a gate).
INTENT_INPUTS: tuple[str, ...] = (*INTENTS, "none")


def intent_inputs(
    values: ob.ObsValues, reader: ChildIntents | None, max_children: int
) -> np.ndarray:
    """The child intent inputs of an env observation (a learned chooser's ``child_intents``,
    :class:`~policies.learned.ResidualSpec`; training and ``PPOPolicy`` call this): per child
    block, a one-hot over :data:`INTENT_INPUTS` of the intent of the wording it stands for, read
    from the graph spoken with :class:`ChildIntents`, as ``lc-coach`` reads it.

    Zeros for a block without a child, and for every block where the graph does not tell (no
    graph read, or blocks that match no vertex of it, or two with other intents).

    Args:
        values: The env's observation (its child blocks).
        reader: The intents of the graph spoken, or None.
        max_children: Number of child blocks the model reads.

    Returns:
        float32, shape ``(max_children * len(INTENT_INPUTS),)``.
    """
    n = len(INTENT_INPUTS)
    out = np.zeros(max_children * n, np.float32)
    intents = reader.of(values) if reader is not None else None
    for k, intent in enumerate((intents or ())[:max_children]):
        out[k * n + INTENT_INPUTS.index(intent if intent is not None else "none")] = 1.0
    return out


_GRAPHS: dict[tuple[str, int], ChildIntents] = {}  # a graph file's intents, per path and mtime


def load_intents(ref: str | Path) -> ChildIntents:
    """The intents of a graph file (a shipped key or a YAML path), loaded as the env loads it
    (the default clips); cached per file and modification time."""
    from langenv.speech.audio import ClipLibrary
    from langenv.speech.graph import PhraseGraph, graph_path

    path = Path(graph_path(ref))
    key = (str(path.resolve()), path.stat().st_mtime_ns)
    intents = _GRAPHS.get(key)
    if intents is None:
        intents = _GRAPHS[key] = ChildIntents(PhraseGraph.load(path, clips=ClipLibrary()))
    return intents


class PersonPace:
    """The person's own pace: the motion's rate ``-dt_x/dt`` over the physical pace ``p``,
    averaged over ``tau`` s (1 at the start); a new leg's horizon (``t_x`` rising by more than
    ``jump`` s) and a finished motion are not a pace.

    Args:
        tau: Time constant of the average (s), > 0.
        jump: A rise of ``t_x`` (s) that starts a new horizon.
    """

    def __init__(self, tau: float, jump: float) -> None:
        self.tau, self.jump = tau, jump
        self.value = 1.0
        self._at: tuple[float, float] | None = None

    def reset(self) -> None:
        """Back to 1, no observation seen."""
        self.value, self._at = 1.0, None

    def update(self, values: ob.ObsValues) -> None:
        """One more observation (idempotent for a repeated one)."""
        t_x = ob.seconds(values, Obs.T_X)
        now = ob.elapsed(values)
        last = self._at
        if ob.flag(values, Obs.MOTION_DONE):
            self._at = None
            return
        self._at = (t_x, now)
        if last is None or t_x > last[0] + self.jump:
            return
        dt = now - last[1]
        if dt <= 0.0:
            self._at = last
            return
        rate = (last[0] - t_x) / dt / max(ob.pace(values, Obs.P), 1e-3)
        self.value += dt / (self.tau + dt) * (rate - self.value)


@dataclass(frozen=True)
class CoachChoice:
    """What :func:`coach_choice` decided: the action, the intent wanted and the one said."""

    u: float
    want: str
    said: str | None


def coach_choice(
    values: ob.ObsValues,
    u_base: float,
    intents: tuple[str | None, ...],
    rule: CoachRule,
    pace: float,
    plan: float,
    margin: float,
) -> CoachChoice:
    """The choice action at a slot's end: the content rule's ``u_base`` unless a child that
    fits asks for the intent the rule wants (module docstring).

    Args:
        values: The observation (its child blocks are the candidates).
        u_base: The content rule's action (:func:`~policies.analytic.fill_choice`).
        intents: Each valid child's intent (:meth:`ChildIntents.of`).
        rule: The therapist's rule.
        pace: The person's own pace (:class:`PersonPace`).
        plan: The motion's time to go the content rule plans with (s).
        margin: The content rule's margin (s).
    """
    t_x = ob.seconds(values, Obs.T_X)
    blocks = [ob.child(values, k) for k in range(len(intents))]
    t_mins = [b[1] for b in blocks if b is not None]
    mids = [0.5 * (b[1] + b[2]) for b in blocks if b is not None]
    c, trend = ob.fraction(values, Obs.COOPERATION), ob.value(values, Obs.COOPERATION_TREND)
    want = rule.intent(c, trend, pace)
    if len(mids) < 2 or len(mids) != len(intents) or t_x <= 1e-3:
        return CoachChoice(u_base, want, None)
    base = _chosen(mids, t_x * duration_factor(u_base))
    fits = [
        k
        for k, t_min in enumerate(t_mins)
        if t_min <= plan - margin and t_min >= t_mins[base] - rule.slack
    ]
    asked = [k for k in fits if intents[k] == want]
    if not asked or intents[base] == want:
        return CoachChoice(u_base, want, intents[base])
    best = max(asked, key=lambda k: (t_mins[k], -k))
    u = choice_action(max(mids[best], 1e-3) / t_x)
    if _chosen(mids, t_x * duration_factor(u)) != best:  # another child of the same middle
        return CoachChoice(u_base, want, intents[base])  # comes first, or u cannot reach it
    return CoachChoice(u, want, want)


def _chosen(mids: list[float], target: float) -> int:
    """The child the env says for a target duration (:func:`langenv.speech.choice.nearest`:
    the nearest middle, the first on a tie), by its index."""
    keys = [str(k) for k in range(len(mids))]
    return int(nearest(keys, dict(zip(keys, mids, strict=True)), target))
