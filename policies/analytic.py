"""The paper's controllers as policies of ``LangCtrl-v0``: AC, LC-noAP and LC.

They read only the env's observation and act only through its action (no access to env
internals). At ``decision_hz=500`` the LC policy is exactly the paper's controller: the env applies
``dp/dt = k_p (p_cmd - p)``, ``da/dt = k_a (a_cmd - a)`` with ``p_cmd = p*`` and
``a_cmd = a* - (k_c/k_a)(1 - c)``, and its "target" phrase choice at ``u = 0`` is the paper's rule
``argmin |t_x - (t_min + t_max)/2|``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from langenv import observation as ob
from langenv.errors import ConfigError
from langenv.exercise.spec import GRAPH_ROLES
from langenv.observation import Obs
from langenv.pacing import PaceLaw, PaceLimits, action_from_command
from policies.aligner import AlignerGains, audio_command, optimal_paces

__all__ = ["AdmittanceController", "LanguageController", "make_analytic"]

#: Time constant (s) of the terminal phase's estimate of the motion's actual rate ``-dt_x/dt``.
RATE_TAU = 0.04
#: Lowest motion rate the terminal phase plans with (a stalled hand must not ask for a = 0).
RATE_FLOOR = 0.3

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
    _last: tuple[float, float] | None = field(default=None, init=False, repr=False)
    _rate: float = field(default=1.0, init=False, repr=False)

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

    def reset(self) -> None:
        """Forget the motion-rate estimate (used only by the terminal phase)."""
        self._last = None
        self._rate = 1.0

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
            w = dt / (RATE_TAU + dt)
            self._rate += w * ((self._last[0] - t_x) / dt - self._rate)
        self._last = (t_x, now)

    def pace_law(self) -> PaceLaw | None:
        """This policy as a law the env can apply at every tick itself
        (:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>`: the same episodes, far
        faster at 500 Hz); None with a terminal phase (it keeps a state the law does not)."""
        if self.terminal > 0.0:
            return None
        return PaceLaw(self.gains.k_c, self.gains.k_a, self.k_em, self.em_clip, self.limits)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Pace commands from the ETCs and cooperation; the paper's phrase rule."""
        values = np.asarray(observation).tolist()  # the same values as floats: cheaper to read
        if self.terminal > 0.0:
            self._update_rate(values)
        t_x = max(0.0, ob.seconds(values, Obs.T_X))
        t_a = max(0.0, ob.seconds(values, Obs.T_A))
        c = ob.fraction(values, Obs.COOPERATION)
        p_star, a_star = optimal_paces(t_x, t_a)
        a_cmd = audio_command(a_star, c, self.gains)
        motion_done = ob.flag(values, Obs.MOTION_DONE)
        if self.k_em > 0.0 and not motion_done:
            p_star -= min(self.em_clip, max(-self.em_clip, self.k_em * (t_a - t_x)))
        phase = self.phase(values)
        if phase == "terminal":
            p_star = 1.0
            a_cmd = t_a * max(self._rate, RATE_FLOOR) / max(t_x, 1e-6)
        elif phase == "finishing":
            if motion_done:
                a_cmd = self.limits.a_max
            else:
                p_star = self.limits.p_max
        action = np.zeros(self.action_dim, np.float32)
        action[0] = action_from_command(p_star, self.limits.p_max)
        action[1] = action_from_command(a_cmd, self.limits.a_max)
        return action  # action[2] = 0: target speech duration = t_x (the paper's rule)


def make_analytic(
    name: str, decision_hz: int | None = None
) -> AdmittanceController | LanguageController:
    """Build ``"ac"``, ``"lc-noap"``, ``"lc"``, ``"lc-em"`` (LC with ``k_em = 1``), ``"lc-end"``
    (LC with a 1 s terminal phase) or ``"lc-em-end"`` (both: the learned aligner's analytic base).

    Args:
        name: The controller.
        decision_hz: Decision rate; default 500 for the aligners (exactly the paper's loop) and 25
            for AC (its commands are constant, so the rate does not change what it does).

    Raises:
        KeyError: for an unknown name (the message lists the known ones).
    """
    if name == "ac":
        return AdmittanceController(decision_hz=decision_hz or 25)
    if name == "lc-noap":
        return LanguageController(
            name="lc-noap", graph_role="single", decision_hz=decision_hz or 500
        )
    if name == "lc":
        return LanguageController(decision_hz=decision_hz or 500)
    if name == "lc-em":
        return LanguageController(name="lc-em", decision_hz=decision_hz or 500, k_em=1.0)
    if name == "lc-end":
        return LanguageController(name="lc-end", decision_hz=decision_hz or 500, terminal=1.0)
    if name == "lc-em-end":
        return LanguageController(
            name="lc-em-end", decision_hz=decision_hz or 500, k_em=1.0, terminal=1.0
        )
    raise KeyError(
        f"unknown analytic policy {name!r}; known: ac, lc-noap, lc, lc-em, lc-end, lc-em-end"
    )
