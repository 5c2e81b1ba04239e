"""The learned phrase chooser's env: one step per phrase choice, the speech people hear as reward.

:class:`ChoicePoints` wraps ``LangCtrl-v0`` (at ``decision_hz=500``, a tick per step) or a
:class:`~langenv.worlds.WorldEnv` of such envs, so that the agent acts only where the next
phrase is chosen among several children (a semi-MDP over the phrase boundaries). Between two
choices the base controller (:class:`~policies.analytic.LanguageController`, usually the content
rule ``lc-fill``) drives the env alone: where its action is its pace law, the env applies the law
in compiled code (:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>`), elsewhere (in
a pause it shortens) a Python step per tick. At a choice the agent's correction ``r`` moves the
base's target duration (:class:`~policies.learned.ResidualLC`: ``u = u_base + choice_scale r_2``),
and the observation is the env's plus :data:`policies.learned.FEATURES`, as ``PPOPolicy`` sees it
at evaluation. With ``r = 0`` the episode is the base's, tick for tick.

Reward, once, when the episode ends (weights are keyword arguments; each term in ``info``):

* ``reward_content = w_content * content_share``: the share of the motion's duration in which a
  phrase's words are heard, as the voice renders them (the metric of :mod:`eval.metrics`,
  computed here from the recorded pace and the timeline's utterances with
  :func:`langenv.speech.voice.words_heard`);
* ``reward_voice = w_voice * voice_natural``: the share of the speech time in which the voice is
  heard within 0.1 of its natural rate;
* ``reward_legs = w_legs * legs_in_step``: the share of the leg boundaries whose words start
  within 1 s of the motion entering the leg (:mod:`langenv.speech.in_step`, the metric of
  :mod:`eval.legs`, from the env's ``info["leg"]`` at every tick and the timeline's utterances
  with the graph's legs; 0 for an unmarked graph or an exercise of one leg);
* ``reward_length = -w_length * t_end``: the session's length (s), the later of the motion's
  and the speech's end (0 by default; the learned coach's recipe weighs it);
* the alignment terms: ``reward_am = -w_am |AM| - w_am_fine ln(1 + |AM| / am_scale)``,
  ``reward_am_far = -w_am_far`` when ``|AM| > 1 s``, ``reward_em = -w_em`` mean ``|EM|``;
  a protective stop or a cut-off episode pays ``-w_stop`` instead of the alignment terms.

**People who listen** (``listening``, the learned coach): each episode's person is a
:class:`~langenv.users.ListeningUser` whose :class:`~langenv.users.ListeningParams` are drawn
uniformly within ranges (``"assumptions"``: each swept assumption's documented range,
:data:`langenv.users.listening.SOURCES`, the other fields at their defaults; or a mapping of
field to ``[lo, hi]``), from a generator seeded by the reset's seed (a held-out
:class:`~langenv.worlds.WorldEnv`, reset without one by the periodic evaluation: its next
person's seed), so a run's people are the same for the same seeds. The draw is in the reset's
``info["listening"]`` (field: value).

**What each child asks** (``child_intents``, the learned coach): the observation also holds,
per child block, a one-hot of the intent of the wording it stands for
(:func:`policies.coach.intent_inputs`, after :data:`~policies.learned.FEATURES`), read from the
episode's graph as ``PPOPolicy`` reads it from the graph it speaks, so that the network can
choose by what a wording asks, not by its length only. The model's config records it
(``residual.child_intents``); off, the observation is the one of before, float for float.

The final step's ``info`` also holds the metrics themselves (``content_share``,
``voice_natural``, ``legs_in_step``, ``sm_max_abs``, ``em_mean_abs``, ``am``), which the
periodic evaluation of :mod:`train.ppo` records (:mod:`train.callbacks`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from langenv.control.pacing import PaceLaw
from langenv.errors import ConfigError
from langenv.speech.in_step import boundaries, graph_legs, in_step, said_words
from langenv.speech.voice import voice_rate, waiting_spans, words_heard
from langenv.task import observation as ob
from policies.analytic import FILL_ANTICIPATE, FILL_K_C, FILL_MARGIN, FILL_PAUSE_SCALE
from policies.coach import ChildIntents
from policies.learned import ResidualLC, ResidualSpec
from train.shaping import ChoiceReward

__all__ = ["EPISODE_S", "ChoicePoints", "listening_ranges", "session_legs", "session_speech"]

EPISODE_S = 60.0
"""Longest episode (s of simulated time), as ``langctrl compare`` runs one."""
_NATURAL = 0.1  # the voice counts as natural within this of its natural rate
_EPS = 1e-9


def listening_ranges(
    spec: str | Mapping[str, Sequence[float]] | None,
) -> dict[str, tuple[float, float]] | None:
    """``ChoicePoints``' ``listening`` as field -> ``(lo, hi)`` (module docstring).

    Raises:
        ConfigError: naming the field, for an unknown word or field, a range that is not two
            numbers ``lo <= hi``, or ends :class:`~langenv.users.ListeningParams` refuses.
    """
    if spec is None:
        return None
    from langenv.users import ListeningParams
    from langenv.users.listening import SOURCES

    if spec == "assumptions":
        return {k: s.range for k, s in SOURCES.items() if s.kind == "assumption"}
    if not isinstance(spec, Mapping):
        raise ConfigError(
            f"ChoicePoints: listening must be 'assumptions' or a mapping, got {spec!r}"
        )
    out: dict[str, tuple[float, float]] = {}
    for name, pair in spec.items():
        if name not in SOURCES:
            raise ConfigError(
                f"ChoicePoints: listening: unknown field {name!r}; known: {', '.join(SOURCES)}"
            )
        try:
            lo, hi = (float(v) for v in pair)
        except (TypeError, ValueError):
            raise ConfigError(f"ChoicePoints: listening.{name} must be [lo, hi]") from None
        if not lo <= hi:
            raise ConfigError(f"ChoicePoints: listening.{name} needs lo <= hi, got {lo}, {hi}")
        out[name] = (lo, hi)
    for ends in ({k: v[0] for k, v in out.items()}, {k: v[1] for k, v in out.items()}):
        ListeningParams(**ends)  # both ends are people it accepts
    return out


def session_speech(
    t: np.ndarray,
    a: np.ndarray,
    speech_done: np.ndarray,
    utterances: list[Any],
    graph: Any,
    t_motion: float,
) -> tuple[float, float]:
    """``(content_share, voice_natural)`` of a session, as :func:`eval.metrics.episode_metrics`
    measures them, from its trace and the speech timeline's utterances.

    Args:
        t: Sample times (s), shape ``(n,)``.
        a: Speech pace at those times.
        speech_done: Whether the speech is over at each sample (bool).
        utterances: The timeline's utterances (``SpeechTimeline.utterances()``).
        graph: The phrase graph spoken (its ``voice``, fillers and pauses).
        t_motion: When the motion ended (s).
    """
    clips = [u for u in utterances if u.length is None]  # not a pause vertex
    if graph.voice == "natural":
        spans = waiting_spans(t, speech_done, [(u.t_start, u.t_end) for u in clips])
        v, waiting = voice_rate(t, a, spans)
    else:
        v, waiting = a, np.zeros(t.shape, dtype=bool)
    w = np.append(np.diff(t), t[-1] - t[-2])
    speaking = ~speech_done
    total = float(np.sum(w * speaking))
    natural = (np.abs(v - 1.0) <= _NATURAL + _EPS) & speaking
    voice = float(np.sum(w * natural) / total) if total > 0.0 else math.nan
    span = t_motion - float(t[0])
    spans = [(u.t_start, u.t_end) for u in clips if u.phrase not in graph.fillers]
    content = min(1.0, words_heard(t, waiting, spans, t_motion) / span) if span > 0 else math.nan
    return content, voice


def session_legs(
    t: np.ndarray,
    leg: np.ndarray,
    utterances: list[Any],
    graph: Any,
    leg_names: tuple[str, ...],
) -> dict[str, float]:
    """``{"sm_max_abs": ..., "legs_in_step": ...}`` of a session, as
    :func:`eval.legs.leg_metrics` measures them (:mod:`langenv.speech.in_step`), from its trace
    and the speech timeline's utterances.

    Args:
        t: Sample times (s), shape ``(n,)``.
        leg: The motion's leg index at those times (``info["leg"]``), shape ``(n,)``.
        utterances: The timeline's utterances (``SpeechTimeline.utterances()``).
        graph: The phrase graph spoken (its vertices' legs and kinds).
        leg_names: The motion's legs (``LangCtrlEnv.motion_legs``).
    """
    _, spoken = graph_legs(graph)
    return in_step(boundaries(t, leg, leg_names, spoken, said_words(utterances, graph)))


class ChoicePoints(gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """The env as the learned phrase chooser meets it (module docstring).

    Args:
        env: ``LangCtrl-v0`` built with ``decision_hz=500`` (possibly wrapped), or a
            :class:`~langenv.worlds.WorldEnv` of such envs.
        choice_scale: Largest change of the base's target-duration action (see
            :class:`~policies.learned.ResidualSpec`).
        k_c: The base's cooperation gain of the audio law (``lc-fill``: 0).
        choice: The base's phrase rule (``"fill"``: ``lc-fill``'s; ``"mid"``: the paper's).
        fill_margin: The content rule's margin (s).
        fill_anticipate: How much the content rule trusts the person's pace so far.
        pause_scale: The base's pause target over ``t_x`` in pauses with a choice after them.
        k_em: The base's misalignment feedback on the physical pace (1/s).
        listening: The people who listen (module docstring); None: the env's own people.
        child_intents: Whether the observation holds each child's intent (module docstring).
        **weights: The reward's weights (:class:`~train.shaping.ChoiceReward`: ``w_content``,
            ``w_voice``, ``w_legs``, ``w_am``, ``w_am_fine``, ``am_scale``, ``w_am_far``,
            ``w_em``, ``w_stop``, ``w_length``).

    Raises:
        ConfigError: if the env does not step one tick at a time, or for a bad setting.
    """

    #: Train.ppo puts the Monitor outside this wrapper (its steps are the agent's choices).
    monitor_outside: ClassVar[bool] = True

    def __init__(
        self,
        env: gym.Env[np.ndarray, np.ndarray],
        choice_scale: float = 0.5,
        k_c: float = FILL_K_C,
        choice: str = "fill",
        fill_margin: float = FILL_MARGIN,
        fill_anticipate: float = FILL_ANTICIPATE,
        pause_scale: float = FILL_PAUSE_SCALE,
        k_em: float = 0.0,
        listening: str | Mapping[str, Sequence[float]] | None = None,
        child_intents: bool = False,
        **weights: float,
    ) -> None:
        super().__init__(env)
        inner: Any = env.unwrapped
        if int(inner.decision_hz) != 500:
            raise ConfigError(
                f"ChoicePoints: the env must decide at 500 Hz (a tick per step), got "
                f"decision_hz={inner.decision_hz}"
            )
        self.reward = ChoiceReward.from_kwargs(weights)
        self.residual_spec = ResidualSpec(
            choice_mode=inner.choice_mode,
            max_children=int(inner.max_children),
            pace_scale=0.0,
            audio_scale=0.0,
            choice_scale=float(choice_scale),
            decision_hz=500,
            k_em=float(k_em),
            k_c=float(k_c),
            choice=choice,  # type: ignore[arg-type]
            fill_margin=float(fill_margin),
            fill_anticipate=float(fill_anticipate),
            pause_scale=float(pause_scale),
            decisions="choices",
            child_intents=child_intents,
        )
        self.core = ResidualLC(self.residual_spec, inner.paces.limits)
        base = self.core.lc
        self.law = PaceLaw(base.gains.k_c, base.gains.k_a, base.k_em, base.em_clip, base.limits)
        n_obs = int(np.prod(env.observation_space.shape or (0,))) + self.core.n_features
        self.observation_space = spaces.Box(-1.0, 1.0, (n_obs,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.residual_spec.action_dim,), np.float32)
        self._limit = round(EPISODE_S * 500)
        self.listening = listening_ranges(listening)
        self._people = np.random.default_rng()
        self._read: tuple[Any, ChildIntents] | None = None  # (graph, its intents)
        self._reset_trace()

    # ------------------------------------------------------------------ the episode
    def _plant(self) -> Any:
        """The ``LangCtrlEnv`` of the current episode."""
        inner: Any = self.env.unwrapped
        return getattr(inner, "current", inner)

    def _reset_trace(self) -> None:
        # (t, a, em, motion_done, speech_done, leg) per tick
        self._chunks: list[tuple[np.ndarray, ...]] = []
        self._rows: list[tuple[float, float, float, bool, bool, int]] = []  # not yet in a chunk
        self._ticks = 0
        self._done = False
        self._final: tuple[float, dict[str, Any]] | None = None

    def _record(self, info: dict[str, Any]) -> None:
        self._rows.append(
            (
                float(info["time"]),
                float(info["a"]),
                float(info["em"]),
                bool(info["motion_done"]),
                bool(info["speech_done"]),
                int(info["leg"]),
            )
        )

    def _flush(self) -> None:
        if self._rows:
            cols = list(zip(*self._rows, strict=True))
            self._chunks.append(tuple(np.asarray(c) for c in cols))
            self._rows = []

    def _trace(self) -> tuple[np.ndarray, ...]:
        self._flush()
        return tuple(np.concatenate([c[k] for c in self._chunks]) for k in range(6))

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        drawn = self._listener(seed if seed is not None else self._held_out_seed())
        if drawn is not None:
            inner: Any = self.env.unwrapped
            if hasattr(inner, "current"):  # a WorldEnv resets each episode with its .user
                inner.user = drawn
            else:
                options = {**(options or {}), "user": drawn}
        obs, info = self.env.reset(seed=seed, options=options)
        self._reset_trace()
        if self.residual_spec.child_intents:
            self._read_intents()
        self._record(info)
        aug = self.core.start(obs)
        obs, reward, info = self._advance(obs, info, False)
        if drawn is not None:
            info = {**info, "listening": asdict(drawn.listening)}
        if self._done:  # over before any choice: the next step only returns the reward
            self._final = (reward, info)
            return aug.astype(np.float32), info
        return self.core.observe(obs).astype(np.float32), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._final is not None:
            reward, info = self._final
            self._final = None
            obs = self.core.observe(self._plant().observation()).astype(np.float32)
            return obs, reward, bool(info["terminated"]), not info["terminated"], info
        if self._done:
            raise ConfigError("ChoicePoints.step after the episode ended: call reset()")
        act = self.core.action(np.asarray(action, dtype=np.float64))
        obs, _, terminated, _, info = self._plant().step(act)
        self._ticks += 1
        self._record(info)
        obs, reward, info = self._advance(obs, info, terminated)
        out = self.core.observe(obs).astype(np.float32)
        if not self._done:
            return out, reward, False, False, info
        return out, reward, bool(info["terminated"]), not info["terminated"], info

    def _read_intents(self) -> None:
        """Read the children's intents of the episode's graph (once per graph)."""
        graph = self._plant().graph
        if self._read is None or self._read[0] is not graph:
            self._read = (graph, ChildIntents(graph))
        self.core.use_intents(self._read[1])

    def _held_out_seed(self) -> int | None:
        """The next held-out person's seed when the env is a validation or test
        :class:`~langenv.worlds.WorldEnv` (the periodic evaluation resets it without a seed), so
        that the same person always listens alike; None otherwise."""
        seed = getattr(self.env.unwrapped, "next_user_seed", None)
        return seed if isinstance(seed, int) else None

    def _listener(self, seed: int | None) -> Any:
        """The episode's listening person (None without ``listening``)."""
        if self.listening is None:
            return None
        from langenv.users import ListeningParams, ListeningUser

        if seed is not None:
            self._people = np.random.default_rng([seed, 46])
        values = {k: float(self._people.uniform(lo, hi)) for k, (lo, hi) in self.listening.items()}
        return ListeningUser(ListeningParams(**values))

    def _advance(
        self, obs: np.ndarray, info: dict[str, Any], terminated: bool
    ) -> tuple[np.ndarray, float, dict[str, Any]]:
        """Let the base drive the env to the next choice (reward 0) or to the episode's end
        (the reward of the module docstring; ``info["terminated"]`` says which end)."""
        plant = self._plant()
        base = self.core.lc
        while not terminated and self._ticks < self._limit:
            act = base.act(obs)
            if base.choice_due(obs):
                return obs, 0.0, info
            if act[2] == 0.0 and plant.runs_compiled:  # the base is its law until Python
                run = plant.run_law(self.law, self._limit - self._ticks - 1)
                if run.steps:
                    self._flush()
                    rows = run.info
                    self._follow(base, rows["t_x"], rows["time"])
                    self._chunks.append(
                        (
                            rows["time"],
                            rows["a"],
                            rows["em"],
                            rows["motion_done"].astype(bool),
                            rows["speech_done"].astype(bool),
                            rows["leg"].astype(np.int64),
                        )
                    )
                    self._ticks += run.steps
                if run.last is not None:
                    obs, _, terminated, _, info = run.last
                    self._ticks += 1
                    self._record(info)
                    continue
                if self._ticks >= self._limit:
                    break
                obs = plant.observation()
                act = base.act(obs)
                if base.choice_due(obs):
                    return obs, 0.0, info
            obs, _, terminated, _, info = plant.step(act)
            self._ticks += 1
            self._record(info)
        self._done = True
        info = dict(info, terminated=terminated)
        return obs, self._final_reward(info, terminated), info

    @staticmethod
    def _follow(base: Any, t_x: np.ndarray, time: np.ndarray) -> None:
        """The base's horizon tracking through the ticks the law ran without it, each value as
        its observation would have stored it (:meth:`LanguageController.track
        <policies.analytic.LanguageController.track>`)."""
        if base.choice != "fill":
            return
        seen_t_x = np.clip(t_x / ob.T_SCALE, -1.0, 1.0).astype(np.float32).astype(float)
        seen_now = np.clip(time / ob.ELAPSED_SCALE, -1.0, 1.0).astype(np.float32).astype(float)
        base.track_many(seen_t_x * ob.T_SCALE, seen_now * ob.ELAPSED_SCALE)

    def _final_reward(self, info: dict[str, Any], terminated: bool) -> float:
        """The episode's reward (module docstring); its terms and metrics go into ``info``."""
        plant = self._plant()
        t, a, em, md, sd, leg = self._trace()
        keep = np.append(np.diff(t) > 0.0, True)  # the trace strictly increasing
        t, a, em, md, sd, leg = t[keep], a[keep], em[keep], md[keep], sd[keep], leg[keep]
        t_motion = info.get("t_motion")
        t_motion = float(t_motion) if t_motion is not None else float(t[-1])
        said = plant.speech.utterances()
        content, voice = session_speech(t, a, sd, said, plant.graph, t_motion)
        legs = session_legs(t, leg, said, plant.graph, plant.motion_legs)
        w = np.append(np.diff(t), t[-1] - t[-2]) * ~(md & sd)
        em_mean = float(np.sum(w * np.abs(em)) / np.sum(w)) if np.sum(w) > 0 else 0.0
        length = max(t_motion, float(plant.t_speech or t[-1]))
        am = info.get("am")
        am = float(am) if terminated and am is not None else None
        terms = self.reward.terms((content, voice, legs["legs_in_step"]), em_mean, length, am)
        info.update(terms)
        info.update(content_share=content, voice_natural=voice, em_mean_abs=em_mean, **legs)
        return float(sum(terms.values()))
