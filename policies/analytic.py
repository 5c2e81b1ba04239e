"""The paper's controllers as policies of ``LangCtrl-v0``: AC, LC-noAP and LC; and LC's variants.

They read only the env's observation and act only through its action (no access to env
internals). At ``decision_hz=500`` the LC policy is exactly the paper's controller: the env applies
``dp/dt = k_p (p_cmd - p)``, ``da/dt = k_a (a_cmd - a)`` with ``p_cmd = p*`` and
``a_cmd = a* - (k_c/k_a)(1 - c)``, and its "target" phrase choice at ``u = 0`` is the paper's rule
``argmin |t_x - (t_min + t_max)/2|``.

Variants (not in the paper): ``lc-em`` (misalignment feedback on ``p``), ``lc-end`` (a terminal
phase), ``lc-em-end`` (both: the base of the learned aligner up to issue 27) and ``lc-fill``,
whose phrase choice aims at *content*: the longest wording that still lets the speech end with
the motion (:func:`fill_choice`), instead of the paper's middle of the range; ``lc-fill-end`` is
``lc-fill`` with ``lc-end``'s terminal phase; ``lc-coach`` (:mod:`policies.coach`) is
``lc-fill-end`` choosing among the wordings that fit by what they ask of a person who listens.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

import numpy as np

from langenv.control.pacing import (
    AlignerGains,
    PaceLaw,
    PaceLimits,
    action_from_command,
    aligner_commands,
    command_from_action,
)
from langenv.errors import ConfigError
from langenv.exercise.spec import GRAPH_ROLES
from langenv.speech.choice import choice_action
from langenv.task import observation as ob
from langenv.task.observation import Obs
from policies.coach import (
    COACH_RULE,
    ChildIntents,
    CoachRule,
    PersonPace,
    coach_choice,
    load_intents,
)

__all__ = [
    "ANALYTIC",
    "AdmittanceController",
    "LanguageController",
    "fill_choice",
    "make_analytic",
]

#: Time constant (s) of the terminal phase's estimate of the motion's actual rate ``-dt_x/dt``.
RATE_TAU = 0.04
#: Lowest motion rate the terminal phase plans with (a stalled hand must not ask for a = 0).
RATE_FLOOR = 0.3
#: A rise of the observed ``t_x`` by more than this in one observation (s) is a new horizon: the
#: speech of a script marked with legs (:mod:`langenv.speech.legs`) is aligned with the motion's
#: time to the end of the current leg, which starts again at each leg.
NEW_HORIZON = 1.0


def fill_choice(observation: ob.ObsValues, margin: float, horizon: float | None = None) -> float:
    """The content rule's next-phrase action: the child with the longest shortest speech
    ``t_min`` that still fits in the motion's time to go less ``margin``.

    Among the valid children of the current phrase (the observation's child blocks), those with
    ``t_min <= t_x - margin`` can still end with the motion (their shortest continuation fits,
    with ``margin`` s to spare); the one of them with the largest ``t_min`` is chosen (among the
    alternatives of one step, the longest wording; between another saying of a repeat and the
    end, another saying), and when none fits, the one with the smallest ``t_min``. The env
    chooses the child whose middle length ``(t_min + t_max)/2`` is nearest the target duration
    ``t_x 2^{2u}``, so the action is the ``u`` whose target is that child's middle: 0 when it is
    the paper's own choice or there is nothing to choose.

    Args:
        observation: The env's observation (its child blocks are the candidates).
        margin: Time (s) the shortest continuation must leave to spare.
        horizon: The motion's time to go the choice plans with (s); default its ETC ``t_x``.

    Returns:
        The choice action ``u`` in ``[-1, 1]``.
    """
    t_x = ob.seconds(observation, Obs.T_X)
    plan = t_x if horizon is None else horizon
    kids: list[tuple[float, float]] = []  # (t_min, mid) of the valid children, in order
    k = 0
    while (block := ob.child(observation, k)) is not None:
        valid, t_min, t_max = block
        if valid:
            kids.append((t_min, 0.5 * (t_min + t_max)))
        k += 1
    if len(kids) < 2 or t_x <= 1e-3:
        return 0.0
    fits = [i for i, (t_min, _) in enumerate(kids) if t_min <= plan - margin]
    if fits:
        best = max(fits, key=lambda i: (kids[i][0], -i))
    else:
        best = min(range(len(kids)), key=lambda i: (kids[i][0], i))
    paper = min(range(len(kids)), key=lambda i: (abs(t_x - kids[i][1]), i))
    if kids[best][1] == kids[paper][1]:
        return 0.0  # the paper's rule says it (or a child of the same middle length)
    return choice_action(max(kids[best][1], 1e-3) / t_x)


def _valid_children(observation: ob.ObsValues) -> int:
    """How many of the observation's child blocks are valid next phrases."""
    n, k = 0, 0
    while (block := ob.child(observation, k)) is not None:
        n += block[0]
        k += 1
    return n


Phase = Literal["aligning", "terminal", "finishing", "over"]


@dataclass
class AdmittanceController:
    """AC: fixed admittance (``p = a = 1``), one long utterance started with the motion."""

    name: str = "ac"
    graph_role: str = "single"  # the exercise's one wording, said as one utterance
    decision_hz: int = 25
    action_dim: int = 3
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    def reset(self) -> None:
        """Stateless."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Natural paces, paper's phrase rule (irrelevant: a single utterance)."""
        return np.zeros(self.action_dim, np.float32)


@dataclass
class LanguageController:
    """LC (with a phrase graph) or LC-noAP (a single wording): the paper's aligner.

    Args:
        name: ``"lc"`` or ``"lc-noap"``.
        graph_role: ``"graph"`` (LC: the exercise's phrase graph) or ``"single"`` (LC-noAP: its
            one wording); see :mod:`langenv.exercise.script`.
        gains: ``k_c`` of the audio law; ``k_a`` must equal the env's (``PaceLimits.k_a``).
        limits: The env's pace limits (for the action map).
        decision_hz: Decision rate; 500 reproduces the paper's 500 Hz loop exactly.
        action_dim: The env's action size (3 for ``choice_mode="target"``).
        k_em: Extra feedback of the base-pace misalignment ``EM = t_a - t_x`` on the physical
            pace command (1/s): ``p_cmd = p* - clip(k_em EM, ±em_clip)`` while the motion goes
            on. 0 (the paper's LC) by default; ``"lc-em"`` uses 1. Not in the paper: an analytic
            reference for the learned aligner, which finds a correction of this kind
            (``docs/learned.md``).
        em_clip: Bound of that correction (pace units).
        terminal: Horizon (s of ``t_x``) of the *terminal phase*; 0 (the paper's LC) turns it
            off; ``"lc-end"`` uses 1. Not in the paper. Once ``t_x < terminal`` the physical pace
            is commanded back to 1 (near the end the braking guide, not ``p``, sets how fast the
            hand arrives, so LC's ``p*`` there mostly misleads its own plan) and the audio pace is
            set so that the speech left ends when the motion is observed to end:
            ``a_cmd = t_a / (t_x / r)``, with ``r`` the motion's actual rate ``-dt_x/dt``
            (averaged over ``RATE_TAU``, at least ``RATE_FLOOR``). After one of the two has
            ended, the other is finished as fast as allowed (``a_max`` or ``p_max``). See
            :meth:`phase`. This makes the policy stateful: call :meth:`reset` at each episode.
        choice: The phrase rule: ``"mid"`` (the paper's) or ``"fill"`` (the content rule): at
            each choice the next phrase is :func:`fill_choice`'s, the longest wording whose
            shortest continuation still ends ``fill_margin`` s before the motion. The action
            says it only on the tick (at 500 Hz) or the step (slower) in which the slot ends, so
            that the target-duration action does not also move the pause rule's target
            elsewhere; between choices the policy is its pace law (``pace_law()``).
        fill_margin: The content rule's margin (s; any finite number, used with ``"fill"``).
        fill_anticipate: How much the content rule trusts the person's pace so far (>= 0; 0:
            not at all): it plans with the time to go ``t_x (1 + fill_anticipate (r - 1))``,
            ``r`` the seconds the motion has taken per second of ETC it used up (in [1, 3], 1
            until the ETC has fallen by 1 s).
        pause_scale: The pause rule's target duration over ``t_x`` while the speech is in a
            pause vertex with a choice after it (> 0; 1: the rule's own). Below 1 the pauses
            are shortened towards their minimum so that words fill the time instead; the wait
            before the last phrase (one child) is left to the rule. Not 1: no ``pace_law()``.
        intents: Whether the content rule's choice moves to the child that asks what ``rule``
            wants (``lc-coach``, :mod:`policies.coach`; with ``"fill"`` only). The policy then
            reads the graph it speaks (:meth:`use_graph`) and keeps the person's pace.
        rule: The therapist's rule (used with ``intents``).

    Attributes:
        said: With ``intents``: ``(time, intent wanted, intent said)`` of each choice since the
            reset (said None: the child asks nothing).
    """

    name: str = "lc"
    graph_role: str = "graph"
    gains: AlignerGains = field(default_factory=AlignerGains)
    limits: PaceLimits = field(default_factory=PaceLimits)
    decision_hz: int = 500
    action_dim: int = 3
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    k_em: float = 0.0
    em_clip: float = 0.5
    terminal: float = 0.0
    choice: Literal["mid", "fill"] = "mid"
    fill_margin: float = 1.0
    fill_anticipate: float = 0.0
    pause_scale: float = 1.0
    intents: bool = False
    rule: CoachRule = field(default_factory=CoachRule)
    said: list[tuple[float, str, str | None]] = field(default_factory=list, init=False)
    _reader: ChildIntents | None = field(default=None, init=False, repr=False)
    _person: PersonPace | None = field(default=None, init=False, repr=False)
    _last: tuple[float, float] | None = field(default=None, init=False, repr=False)
    _rate: float = field(default=1.0, init=False, repr=False)
    _t_x0: float | None = field(default=None, init=False, repr=False)
    _used: float = field(default=0.0, init=False, repr=False)
    _leg_t0: float = field(default=0.0, init=False, repr=False)
    _prev_t_x: float | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.graph_role not in GRAPH_ROLES:
            raise ConfigError(
                f"LanguageController.graph_role must be one of {sorted(GRAPH_ROLES)}, "
                f"got {self.graph_role!r}"
            )
        for name in ("k_em", "em_clip", "terminal"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(
                    f"LanguageController.{name} must be finite and >= 0, got {value!r}"
                )
        if self.choice not in ("mid", "fill"):
            raise ConfigError(
                f"LanguageController.choice must be 'mid' or 'fill', got {self.choice!r}"
            )
        if not (math.isfinite(self.fill_anticipate) and self.fill_anticipate >= 0.0):
            raise ConfigError(
                "LanguageController.fill_anticipate must be finite and >= 0, "
                f"got {self.fill_anticipate!r}"
            )
        if not (math.isfinite(self.pause_scale) and self.pause_scale > 0.0):
            raise ConfigError(
                f"LanguageController.pause_scale must be finite and > 0, got {self.pause_scale!r}"
            )
        if not math.isfinite(self.fill_margin):
            raise ConfigError(
                f"LanguageController.fill_margin must be finite, got {self.fill_margin!r}"
            )
        if self.intents and self.choice != "fill":
            raise ConfigError("LanguageController.intents needs choice='fill' (the content rule)")
        if not isinstance(self.rule, CoachRule):
            raise ConfigError(f"LanguageController.rule must be a CoachRule, got {self.rule!r}")
        if self.intents:
            self._person = PersonPace(self.rule.pace_tau, NEW_HORIZON)

    def reset(self) -> None:
        """Forget the motion-rate estimate (used only by the terminal phase)."""
        self._last = None
        self._rate = 1.0
        self._t_x0 = None
        self._used = 0.0
        self._leg_t0 = 0.0
        self._prev_t_x = None
        if self._person is not None:
            self._person.reset()
        self.said = []

    def use_graph(self, spoken: Any) -> None:
        """With ``intents``: read the intents of the graph the env will speak (``spoken.ref``,
        :class:`~langenv.exercise.script.SpokenGraph`; :func:`langenv.exercise.script.speak`
        calls it). Without: nothing."""
        if self.intents:
            self._reader = load_intents(spoken.ref)

    def use_phrase_graph(self, graph: Any) -> None:
        """With ``intents``: read the intents of ``graph`` (a
        :class:`~langenv.speech.graph.PhraseGraph`, the env's own)."""
        if self.intents:
            self._reader = ChildIntents(graph)

    @property
    def person_pace(self) -> float:
        """With ``intents``: the person's own pace (:class:`~policies.coach.PersonPace`); 1
        without."""
        return self._person.value if self._person is not None else 1.0

    @property
    def motion_rate(self) -> float:
        """The terminal phase's estimate of the motion's actual rate ``-dt_x/dt`` (1 at rest)."""
        return self._rate

    def phase(self, observation: ob.ObsValues) -> Phase:
        """Which law acts on this observation.

        Returns:
            ``"aligning"``: the paper's aligner; ``"terminal"``: the terminal phase (see
            ``terminal``); ``"finishing"``: one of motion and speech is over and the other is
            finished as fast as allowed; ``"over"``: both are over. Without a terminal phase
            (``terminal == 0``) only ``"aligning"`` and ``"over"`` occur.
        """
        motion_done = ob.flag(observation, Obs.MOTION_DONE)
        speech_done = ob.flag(observation, Obs.SPEECH_DONE)
        if motion_done and speech_done:
            return "over"
        if self.terminal <= 0.0:
            return "aligning"
        if motion_done or speech_done:
            return "finishing"
        t_x = ob.seconds(observation, Obs.T_X)
        return "terminal" if t_x < self.terminal else "aligning"

    def _update_rate(self, observation: ob.ObsValues) -> None:
        """Average ``-dt_x/dt`` over ``RATE_TAU``; idempotent for a repeated observation."""
        t_x = ob.seconds(observation, Obs.T_X)
        now = ob.elapsed(observation)
        if ob.flag(observation, Obs.MOTION_DONE):
            self._last = None
            return
        if self._last is not None:
            dt = now - self._last[1]
            if dt <= 0.0:
                return  # the same observation again (or time did not advance)
            if t_x > self._last[0] + NEW_HORIZON:  # the next leg's horizon: not a rate
                self._last = (t_x, now)
                return
            w = dt / (RATE_TAU + dt)
            self._rate += w * ((self._last[0] - t_x) / dt - self._rate)
        self._last = (t_x, now)

    def pace_law(self) -> PaceLaw | None:
        """This policy as a law the env can apply at every tick itself
        (:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>`: the same episodes, far
        faster at 500 Hz); None with a terminal phase or ``fill_anticipate`` (they keep a
        state the law does not) or a ``pause_scale`` other than 1 (the law's pauses are the
        rule's)."""
        if self.terminal > 0.0 or self.pause_scale != 1.0:
            return None
        if self.choice == "fill" and self.fill_anticipate > 0.0:
            return None
        return PaceLaw(self.gains.k_c, self.gains.k_a, self.k_em, self.em_clip, self.limits)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Pace commands from the ETCs and cooperation; the paper's phrase rule (or the content
        rule, ``choice="fill"``)."""
        values = np.asarray(observation).tolist()  # the same values as floats: cheaper to read
        if self._person is not None:
            self._person.update(values)
        p_star, a_cmd = self._commands(values)
        action = np.zeros(self.action_dim, np.float32)
        action[0] = action_from_command(p_star, self.limits.p_max)
        action[1] = action_from_command(a_cmd, self.limits.a_max)
        if self.choice == "fill":
            action[2] = self._fill_action(values, a_cmd)
        return action  # action[2] = 0: target speech duration = t_x (the paper's rule)

    def choice_due(self, observation: np.ndarray) -> bool:
        """Whether the next phrase is chosen in the coming decision step, among at least two
        valid children: the step whose action's phrase value the env uses (see ``choice``).

        Call it after :meth:`act` on the same observation (it reads the terminal phase's rate
        estimate as :meth:`act` left it).
        """
        values = np.asarray(observation).tolist()
        if _valid_children(values) < 2:
            return False
        return self._slot_ends(values, self._commands(values, update=False)[1])

    def _commands(self, values: ob.ObsValues, update: bool = True) -> tuple[float, float]:
        """The physical and audio pace commands for an observation (``update``: advance the
        terminal phase's rate estimate, idempotent for a repeated observation)."""
        if self.terminal > 0.0 and update:
            self._update_rate(values)
        t_x = max(0.0, ob.seconds(values, Obs.T_X))
        t_a = max(0.0, ob.seconds(values, Obs.T_A))
        c = ob.fraction(values, Obs.COOPERATION)
        motion_done = ob.flag(values, Obs.MOTION_DONE)
        p_star, a_cmd = aligner_commands(
            t_x, t_a, c, self.gains, self.k_em, self.em_clip, not motion_done
        )
        phase = self.phase(values)
        if phase == "terminal":
            p_star = 1.0
            a_cmd = t_a * max(self._rate, RATE_FLOOR) / max(t_x, 1e-6)
        elif phase == "finishing":
            if motion_done:
                a_cmd = self.limits.a_max
            else:
                p_star = self.limits.p_max
        return p_star, a_cmd

    def _fill_action(self, values: ob.ObsValues, a_cmd: float) -> float:
        """The content rule's phrase action (see ``choice``, ``pause_scale``)."""
        t_x = ob.seconds(values, Obs.T_X)
        now = ob.elapsed(values)
        self.track(t_x, now)
        if self._slot_ends(values, a_cmd):
            plan = self._fill_horizon(t_x, now)
            u = fill_choice(values, self.fill_margin, plan)
            return self._coach(values, u, t_x if plan is None else plan) if self.intents else u
        if self.pause_scale != 1.0 and ob.flag(values, Obs.IN_PAUSE):
            if _valid_children(values) >= 2:
                return choice_action(self.pause_scale)
        return 0.0

    def _coach(self, values: ob.ObsValues, u: float, plan: float) -> float:
        """The content rule's ``u`` moved by the therapist's rule (:func:`coach_choice`)."""
        kids = self._reader.of(values) if self._reader is not None else None
        if kids is None:
            return u
        got = coach_choice(values, u, kids, self.rule, self.person_pace, plan, self.fill_margin)
        self.said.append((ob.elapsed(values), got.want, got.said))
        return got.u

    def track(self, t_x: float, now: float) -> None:
        """Follow the motion's horizon through one observation (its ``T_X`` and ``ELAPSED``, as
        the observation stores them): :meth:`act` does it for the content rule; a caller that
        lets the env run the law without the policy (:class:`train.choices.ChoicePoints`) hands
        it the ticks it skipped, so that the state is the same. A rise of more than
        :data:`NEW_HORIZON` is the start of a leg's horizon. Idempotent for a repeated one."""
        if self._t_x0 is None:
            self._t_x0 = t_x
        elif self._prev_t_x is not None and t_x > self._prev_t_x + NEW_HORIZON:
            self._used += self._t_x0 - self._prev_t_x  # a leg's horizon used up
            self._t_x0, self._leg_t0 = t_x, now
        self._prev_t_x = t_x

    def track_many(self, t_x: np.ndarray, now: np.ndarray) -> None:
        """:meth:`track` through many observations at once (the same state)."""
        values, times = t_x.tolist(), now.tolist()
        if not values:
            return
        if self._t_x0 is None or self._prev_t_x is None:
            self.track(values[0], times[0])
        prev = np.array([self._prev_t_x, *values[:-1]])
        for j in np.flatnonzero(t_x > prev + NEW_HORIZON).tolist():
            self._used += self._t_x0 - prev[j]
            self._t_x0, self._leg_t0 = values[j], times[j]
        self._prev_t_x = values[-1]

    def _fill_horizon(self, t_x: float, now: float) -> float | None:
        """The time to go the content rule plans with (None: ``t_x``): ``t_x`` stretched by the
        person's pace ``r`` (seconds of motion per second of ETC used): over the current leg's
        horizon once it has used 1 s, else over the whole session so far."""
        if self.fill_anticipate <= 0.0 or self._t_x0 is None:
            return None
        used = self._t_x0 - t_x
        elapsed = now - self._leg_t0
        if used < 1.0:
            used = self._used + used
            elapsed = now
        if used < 1.0:
            return None
        r = min(3.0, max(1.0, elapsed / used))
        return t_x * (1.0 + self.fill_anticipate * (r - 1.0))

    def _slot_ends(self, values: ob.ObsValues, a_cmd: float) -> bool:
        """Whether the current slot ends (a choice is made) in the coming decision step: at
        500 Hz the tick in which the speech, moving at the pace this command gives, reaches the
        slot's end (the tick :meth:`~langenv.env.LangCtrlEnv.run_law` hands to the policy), else
        the env's ``BOUNDARY_DUE``."""
        if not ob.flag(values, Obs.IN_PAUSE) or ob.flag(values, Obs.SPEECH_DONE):
            return False
        if self.decision_hz < 500:
            return ob.flag(values, Obs.BOUNDARY_DUE)
        dt = 1.0 / self.decision_hz
        lim = self.limits
        a = ob.pace(values, Obs.A)
        cmd = command_from_action(
            float(np.float32(action_from_command(a_cmd, lim.a_max))), lim.a_max
        )
        a_new = min(lim.a_max, max(lim.a_min, a + dt * lim.k_a * (cmd - a)))
        return ob.seconds(values, Obs.PHRASE_LEFT) <= a_new * dt


def _lc(name: str, **kw: Any) -> Callable[[int | None], LanguageController]:
    def build(decision_hz: int | None) -> LanguageController:
        return LanguageController(name=name, decision_hz=decision_hz or 500, **kw)

    return build


# ``lc-fill``'s settings, tuned on the validation worlds of ``configs/ppo_general.yaml``
# (shoulder_extension x the 48 validation users, perturbed; HISTORY.md, issue 38).
#: The content rule's margin (s).
FILL_MARGIN = 0.25
#: How much it trusts the person's pace so far.
FILL_ANTICIPATE = 1.0
#: Its pauses' target over ``t_x`` (0.25: pauses with a choice after them at their minimum).
FILL_PAUSE_SCALE = 0.25
#: The cooperation gain of its audio law (the paper's ``k_c`` is 10): 0, the speech pace follows
#: the alignment alone; a resisting person hears words, not a slowed or waiting voice.
FILL_K_C = 0.0
#: ``lc-fill-end``'s terminal-phase horizon (s of ``t_x``): ``lc-end``'s, so that a person who
#: speeds up at the end does not leave the words committed for a slower motion behind.
FILL_TERMINAL = 1.0


def _fill(
    name: str, terminal: float = 0.0, **kw: Any
) -> Callable[[int | None], LanguageController]:
    """``lc-fill``'s settings (with ``terminal`` and any other ``kw``)."""
    return _lc(
        name,
        choice="fill",
        fill_margin=FILL_MARGIN,
        fill_anticipate=FILL_ANTICIPATE,
        pause_scale=FILL_PAUSE_SCALE,
        gains=AlignerGains(k_c=FILL_K_C),
        terminal=terminal,
        **kw,
    )


Analytic = AdmittanceController | LanguageController

ANALYTIC: Mapping[str, tuple[str, Callable[[int | None], Analytic]]] = MappingProxyType(
    {
        "ac": (
            "fixed admittance, one utterance (p = a = 1)",
            lambda hz: AdmittanceController(decision_hz=hz or 25),
        ),
        "lc-noap": ("the aligner with a single wording", _lc("lc-noap", graph_role="single")),
        "lc": ("the paper's Language Controller", _lc("lc")),
        "lc-em": ("LC with misalignment feedback on p (k_em = 1)", _lc("lc-em", k_em=1.0)),
        "lc-end": ("LC with a 1 s terminal phase", _lc("lc-end", terminal=1.0)),
        "lc-em-end": (
            "LC with both (the learned aligner's base up to issue 27)",
            _lc("lc-em-end", k_em=1.0, terminal=1.0),
        ),
        "lc-fill": (
            "LC whose phrase choice aims at content: the longest wording that still ends with "
            "the motion",
            _fill("lc-fill"),
        ),
        "lc-fill-end": (
            "lc-fill with lc-end's 1 s terminal phase",
            _fill("lc-fill-end", terminal=FILL_TERMINAL),
        ),
        "lc-coach": (
            "lc-fill-end choosing among the fitting wordings by what they ask of the person "
            "(a therapist's rule: relax, encourage, faster, slower, guide)",
            _fill("lc-coach", terminal=FILL_TERMINAL, intents=True, rule=COACH_RULE),
        ),
    }
)
"""The analytic policies by name: ``(what it is, factory(decision_hz))``; the one place their
names live (``langctrl compare --policies``, :func:`make_analytic`, the
``langctrl.policies`` entry points)."""


def make_analytic(name: str, decision_hz: int | None = None) -> Analytic:
    """Build an analytic policy of :data:`ANALYTIC` by name.

    Args:
        name: The controller: a key of :data:`ANALYTIC`.
        decision_hz: Decision rate; default 500 for the aligners (exactly the paper's loop) and 25
            for AC (its commands are constant, so the rate does not change what it does).

    Raises:
        KeyError: for an unknown name (the message lists the known ones).
    """
    entry = ANALYTIC.get(name)
    if entry is None:
        raise KeyError(f"unknown analytic policy {name!r}; known: {', '.join(ANALYTIC)}")
    return entry[1](decision_hz)
