"""The learned aligner: a PPO policy that corrects the Language Controller (residual RL).

The network does not act on ``LangCtrl-v0`` directly. Its action ``r`` in ``[-1, 1]^k`` is a bounded
*correction* of the analytic LC action (:class:`policies.analytic.LanguageController`), computed
from the same observation:

* pace commands: ``p_cmd = p*_LC + pace_scale r_0``, ``a_cmd = a_cmd_LC + audio_scale r_1``
  (``audio_scale`` defaults to ``pace_scale``);
* next phrase, ``choice_mode="target"``: target speech duration ``t_x 2^{2 u}`` with
  ``u = choice_scale r_2`` (``u = 0`` is the paper's rule);
* next phrase, ``choice_mode="scores"``: per-child scores ``(prior_k + choice_scale r_{2+k}) / 2``
  with the paper's rule as prior ``prior_k = (5 - d_k) / (5 + d_k)``, ``d_k = |t_x - mid_k|`` (s),
  so the argmax at ``r = 0`` is the paper's choice.

At ``r = 0`` the learned policy *is* LC, so PPO only has to improve on it. The same mapping
(:class:`ResidualLC`) is used by the training wrapper (``train.wrappers.ResidualLCWrapper``) and by
:class:`PPOPolicy`, which loads a model saved by ``langctrl train`` together with its
observation normalisation and the env arguments it was trained with.

The network also sees a few features the raw observation lacks (:data:`FEATURES`): LC's own
action, the misalignments on a 1 s scale (the raw ones are on a 40 s scale) and how fast the motion
actually progresses compared with its estimate ``t_x`` (resistance the person has shown so far);
a phrase chooser may also read what each child asks (``ResidualSpec.child_intents``: its intent,
:func:`~policies.coach.intent_inputs`, from the graph it speaks, :meth:`PPOPolicy.use_graph`).
"""

from __future__ import annotations

import math
import pickle
import warnings
import zipfile
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from langenv.control.pacing import (
    AlignerGains,
    PaceLimits,
    action_from_command,
    command_from_action,
)
from langenv.errors import ConfigError, GraphChoicesError, ModelError, ObservationLayoutError
from langenv.exercise.script import SpokenGraph, graph_label
from langenv.task import observation as ob
from langenv.task.observation import Obs
from policies.analytic import LanguageController
from policies.coach import INTENT_INPUTS, ChildIntents, intent_inputs, load_intents
from policies.mlp import MlpActor

__all__ = [
    "FEATURES",
    "INTENT_INPUTS",
    "MlpActor",
    "PPOPolicy",
    "ResidualLC",
    "ResidualSpec",
    "child_inputs",
    "file_sha256",
    "graph_digest",
    "intent_inputs",
    "model_files",
    "observation_layout",
    "widened_inputs",
]

#: Names of the features :class:`ResidualLC` appends to the env's observation, in order.
FEATURES: tuple[str, ...] = (
    "lc_u_p",  # LC's physical pace action
    "lc_u_a",  # LC's audio pace action
    "mis_fine",  # (t_a/a - t_x/p) / 1 s, clipped
    "em_fine",  # (t_a - t_x) / 1 s, clipped
    "motion_rate",  # -dt_x/dt over the last decision, minus 1, clipped
    "motion_rate_avg",  # the same, averaged over ~1 s
    "time_lost",  # elapsed - (t_x(0) - t_x), / 10 s, clipped
    "residual_p",  # the previous correction (pace), as applied
    "residual_a",
)


def observation_layout(max_children: int, child_intents: bool = False) -> dict[str, Any]:
    """The learned policy's input layout for a phrase graph whose largest out-degree is
    ``max_children``: the env's fields (:mod:`langenv.task.observation`, with its scales), the child
    blocks, then :data:`FEATURES`, then with ``child_intents`` each child block's intent inputs
    (:func:`~policies.coach.intent_inputs`).

    Returns:
        ``{"size": N, "signature": HEX}``: the input size and the first 16 hex digits of the
        SHA-256 of the fields' names and scales in order. A model's config records it
        (``observation_layout``); :meth:`PPOPolicy.load` compares it with the code's.
    """
    import hashlib

    children = [f"child{k}.{c.name}" for k in range(max_children) for c in ob.ChildField]
    names = [f.name for f in Obs] + children + list(FEATURES)
    if child_intents:
        names += [f"child{k}.intent.{i}" for k in range(max_children) for i in INTENT_INPUTS]
    scales = (
        f"T={ob.T_SCALE},PACE={ob.PACE_SCALE},SPEED={ob.SPEED_SCALE},ELAPSED={ob.ELAPSED_SCALE},"
        f"TREND={ob.TREND_WINDOW},FINE={FINE_SCALE},LOST={LOST_SCALE},RATE={RATE_AVG_TAU}"
    )
    text = ",".join(names) + ";" + scales
    return {"size": len(names), "signature": hashlib.sha256(text.encode()).hexdigest()[:16]}


def _layout_text(layout: dict[str, Any]) -> str:
    return f"size={layout.get('size')} signature={layout.get('signature')}"


def child_inputs(old_children: int, new_children: int) -> tuple[int, int]:
    """Where a model's input grows when its graphs' largest number of choices goes from
    ``old_children`` to ``new_children``: ``(at, n)``, the new child blocks' ``n`` inputs
    inserted before input ``at`` (after the old child blocks, before :data:`FEATURES`).

    Widening puts zero weights on them and neutral normalisation (mean 0, variance 1), so the
    widened model acts as the original whatever they hold (:meth:`PPOPolicy.use_graph` in
    memory, ``langctrl widen`` on disk).
    """
    return ob.FIRST_CHILD + ob.CHILD_FIELDS * old_children, ob.CHILD_FIELDS * (
        new_children - old_children
    )


def widened_inputs(
    old_children: int, new_children: int, child_intents: bool = False
) -> tuple[tuple[int, int], ...]:
    """Every ``(at, n)`` where a model's input grows from ``old_children`` to ``new_children``
    choices, the last first (so that inserting them in this order leaves each ``at`` right):
    the child blocks' (:func:`child_inputs`) and, with ``child_intents``, the new children's
    intent inputs after the old ones' (the end of the input)."""
    at, n = child_inputs(old_children, new_children)
    if not child_intents:
        return ((at, n),)
    k = len(INTENT_INPUTS)
    end = ob.FIRST_CHILD + ob.CHILD_FIELDS * old_children + len(FEATURES) + k * old_children
    return ((end, k * (new_children - old_children)), (at, n))


#: Time constant (s) of the motion-rate feature's average (the features' one home; the
#: compiled map :mod:`policies.residual_kernels` reads these too).
RATE_AVG_TAU = 1.0
#: Scale (s) of the time-lost feature.
LOST_SCALE = 10.0
#: Scale (s) of the fine misalignment features.
FINE_SCALE = 1.0
#: Distance scale (s) of the scores prior.
PRIOR_SCALE = 5.0


@dataclass(frozen=True)
class ResidualSpec:
    """How a correction ``r`` in ``[-1, 1]^k`` is added to LC's action.

    Attributes:
        choice_mode: The env's next-phrase action design: ``"target"`` or ``"scores"``.
        max_children: Number of choice scores (the phrase graph's largest out-degree) for
            ``"scores"``; ignored for ``"target"``.
        pace_scale: Largest change of the physical pace command (pace units, >= 0; 0: the base's
            physical pace as it is, the network's output for it is ignored).
        audio_scale: Largest change of the audio pace command (pace units, >= 0; 0 as for
            ``pace_scale``); ``None``: the same as ``pace_scale``. A small value keeps the learned
            corrections on the motion side, where they cost no audio distortion.
        choice_scale: Largest change of the choice action (``"target"``: of ``u``, where ``u = 1``
            is two octaves; ``"scores"``: of the score, whose LC prior spans ``[-1, 1]``), > 0.
        decision_hz: Decision rate the correction was trained at (for the motion-rate feature).
        terminal: Terminal-phase horizon of the base controller (s of ``t_x``; see
            :class:`policies.analytic.LanguageController`); 0: the base is the paper's LC. While
            the base is in its terminal or finishing phase, the pace corrections are off (the
            base ends speech and motion together to the millisecond; the correction acts on the
            alignment before that and on the phrase choice). A phrase chooser
            (``decisions="choices"``) may be given one at evaluation (its choices are the
            network's, the paces its base's); :class:`train.choices.ChoicePoints` trains only
            without one.
        k_em: Extra feedback of the base-pace misalignment on the base's physical pace (1/s;
            see :class:`policies.analytic.LanguageController`); 0: the paper's LC, 1: ``lc-em``.
        gate_em: The correction's gate (s, >= 0; 0: always on). While the misalignment at base
            pace ``|t_a - t_x|`` is below it, the whole correction is off (paces and phrase
            choice: the base as it is), so the network acts only where the base lets the
            alignment slip; a base that keeps it is left alone to the bit.
        deadband: Dead band of the correction (in ``[0, 1)``; 0: none): each component of ``r``
            acts as ``sign(r) max(0, |r| - deadband) / (1 - deadband)``, so that small outputs
            leave the base alone and the network must commit to correct it.
        k_c: The base's cooperation gain of the audio law (1/s; the paper's 10).
        choice: The base's phrase rule: ``"mid"`` (the paper's) or ``"fill"`` (``lc-fill``'s
            content rule, :func:`policies.analytic.fill_choice`); the correction moves the
            base's target duration (``"target"`` mode: ``u = u_base + choice_scale r_2``).
        fill_margin, fill_anticipate, pause_scale: The content rule's settings (see
            :class:`policies.analytic.LanguageController`).
        decisions: When the network decides. ``"steps"``: at every step of the env (its
            ``decision_hz``), on the paces and the phrase; ``"choices"``: only where the next
            phrase is chosen among several (the env at 500 Hz, a tick per step; between those
            ticks the base acts alone), on the phrase: the learned phrase chooser of issue 38,
            whose paces are the base's (``pace_scale = audio_scale = 0``).
        child_intents: Whether the network also reads each child's intent
            (:func:`~policies.coach.intent_inputs`, after :data:`FEATURES`): what each wording
            asks of a person who listens, from the graph spoken
            (:meth:`ResidualLC.use_intents`). Only with ``decisions="choices"``; False in a
            model's config that lacks it.
    """

    choice_mode: Literal["target", "scores"] = "target"
    max_children: int = 1
    pace_scale: float = 0.3
    choice_scale: float = 0.5
    audio_scale: float | None = None
    decision_hz: int = 50
    terminal: float = 0.0
    k_em: float = 0.0
    gate_em: float = 0.0
    deadband: float = 0.0
    k_c: float = 10.0
    choice: Literal["mid", "fill"] = "mid"
    fill_margin: float = 1.0
    fill_anticipate: float = 0.0
    pause_scale: float = 1.0
    decisions: Literal["steps", "choices"] = "steps"
    child_intents: bool = False

    def __post_init__(self) -> None:
        if self.choice_mode not in ("target", "scores"):
            raise ConfigError(
                f"ResidualSpec.choice_mode must be 'target' or 'scores', got {self.choice_mode!r}"
            )
        if not isinstance(self.max_children, int) or self.max_children < 1:
            raise ConfigError(
                f"ResidualSpec.max_children must be an int >= 1, got {self.max_children!r}"
            )
        if not isinstance(self.decision_hz, int) or self.decision_hz <= 0:
            raise ConfigError(
                f"ResidualSpec.decision_hz must be a positive int, got {self.decision_hz!r}"
            )
        for name in ("pace_scale", "audio_scale", "choice_scale", "terminal", "k_em", "gate_em"):
            value = getattr(self, name)
            if name == "audio_scale" and value is None:
                continue
            strict = name == "choice_scale"  # 0 would switch the phrase choice off
            if not (
                isinstance(value, int | float)
                and math.isfinite(value)
                and (value > 0.0 if strict else value >= 0.0)
            ):
                bound = "> 0" if strict else ">= 0"
                raise ConfigError(f"ResidualSpec.{name} must be finite and {bound}, got {value!r}")
        if not (isinstance(self.deadband, int | float) and 0.0 <= self.deadband < 1.0):
            raise ConfigError(f"ResidualSpec.deadband must be in [0, 1), got {self.deadband!r}")
        if self.decisions not in ("steps", "choices"):
            raise ConfigError(
                f"ResidualSpec.decisions must be 'steps' or 'choices', got {self.decisions!r}"
            )
        if not isinstance(self.child_intents, bool):
            raise ConfigError(
                f"ResidualSpec.child_intents must be true or false, got {self.child_intents!r}"
            )
        if self.child_intents and self.decisions != "choices":
            raise ConfigError("ResidualSpec: child_intents needs decisions='choices'")
        if self.decisions == "choices":
            if self.choice_mode != "target" or self.decision_hz != 500:
                raise ConfigError(
                    "ResidualSpec: decisions='choices' needs choice_mode='target' and "
                    f"decision_hz=500, got {self.choice_mode!r} and {self.decision_hz}"
                )
            if self.pace_scale != 0.0 or self.audio_gain != 0.0:
                raise ConfigError(
                    "ResidualSpec: decisions='choices' acts on the phrase only: pace_scale and "
                    "audio_scale must be 0"
                )
        self.base()  # the base's settings are checked where they are used

    def base(self) -> LanguageController:
        """The base controller the correction is added to (a fresh one).

        Raises:
            ConfigError: for a base setting its controller refuses.
        """
        return LanguageController(
            name="base",
            gains=AlignerGains(k_c=float(self.k_c)),
            decision_hz=self.decision_hz,
            action_dim=3,
            terminal=self.terminal,
            k_em=self.k_em,
            choice=self.choice,
            fill_margin=self.fill_margin,
            fill_anticipate=self.fill_anticipate,
            pause_scale=self.pause_scale,
        )

    @property
    def audio_gain(self) -> float:
        """Largest change of the audio pace command (``audio_scale``, or ``pace_scale``)."""
        return self.pace_scale if self.audio_scale is None else float(self.audio_scale)

    @property
    def n_choice(self) -> int:
        """Size of the choice part of the env's action."""
        return 1 if self.choice_mode == "target" else self.max_children

    @property
    def action_dim(self) -> int:
        """Size of the correction ``r`` (and of the env's action)."""
        return 2 + self.n_choice


class ResidualLC:
    """LC (with ``spec.terminal``'s terminal phase and ``spec.k_em``'s feedback) plus a bounded
    correction; augments the observation with :data:`FEATURES`.

    Stateful over an episode (the motion-rate features): call :meth:`start` with the observation
    returned by ``reset`` and :meth:`observe` with each later one, in order; :meth:`action` maps a
    correction to the env's action for the latest observation.

    Args:
        spec: The correction's design.
        limits: The env's pace limits (bounds of the action map).
    """

    def __init__(self, spec: ResidualSpec, limits: PaceLimits | None = None) -> None:
        self.spec = spec
        self.limits = limits if limits is not None else PaceLimits()
        self.lc = replace(spec.base(), limits=self.limits)
        self._obs = np.zeros(0, np.float32)
        self._base = np.zeros(3, np.float32)  # the base's action for _obs
        self._base_final = False  # whether the base is in its terminal or finishing phase
        self._t_x0 = 0.0
        self._rate = 0.0
        self._rate_avg = 0.0
        self._last_r = np.zeros(2)
        self._intents: ChildIntents | None = None

    @property
    def n_features(self) -> int:
        """Number of appended inputs: :data:`FEATURES`, then with ``spec.child_intents`` the
        child intent inputs."""
        extra = self.spec.max_children * len(INTENT_INPUTS) if self.spec.child_intents else 0
        return len(FEATURES) + extra

    def use_intents(self, reader: ChildIntents | None) -> None:
        """Read the children's intents (``spec.child_intents``) with ``reader``: the intents of
        the graph the env speaks (None: unknown, their inputs 0)."""
        self._intents = reader

    @property
    def reads_intents(self) -> bool:
        """Whether :meth:`use_intents` gave it a graph's intents."""
        return self._intents is not None

    def start(self, obs: np.ndarray) -> np.ndarray:
        """Begin an episode at its first observation; returns the augmented observation."""
        self._obs = np.asarray(obs, dtype=np.float32)
        self.lc.reset()
        self._t_x0 = ob.seconds(self._obs, Obs.T_X)
        self._rate = self._rate_avg = 0.0
        self._last_r = np.zeros(2)
        return self._augment()

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """Take the next observation of the episode; returns the augmented observation."""
        new = np.asarray(obs, dtype=np.float32)
        if self._obs.size == 0:
            return self.start(new)
        dt = (float(new[Obs.ELAPSED]) - float(self._obs[Obs.ELAPSED])) * ob.ELAPSED_SCALE
        if dt <= 0.0:
            dt = 1.0 / self.spec.decision_hz
        rate = (float(self._obs[Obs.T_X]) - float(new[Obs.T_X])) * ob.T_SCALE / dt - 1.0
        self._rate = min(1.0, max(-1.0, rate))
        w = 1.0 - math.exp(-dt / RATE_AVG_TAU)
        self._rate_avg += w * (self._rate - self._rate_avg)
        self._obs = new
        return self._augment()

    def _augment(self) -> np.ndarray:
        obs = self._obs
        t_x = max(0.0, ob.seconds(obs, Obs.T_X))
        t_a = max(0.0, ob.seconds(obs, Obs.T_A))
        p = ob.pace(obs, Obs.P)
        a = ob.pace(obs, Obs.A)
        lc = self._base = self.lc.act(obs)  # once per observation: action() reuses it
        self._base_final = self.lc.phase(obs) in ("terminal", "finishing")
        elapsed = ob.elapsed(obs)
        lost = elapsed - (self._t_x0 - t_x)
        feats = np.array(
            [
                lc[0],
                lc[1],
                (t_a / a - t_x / p) / FINE_SCALE,
                (t_a - t_x) / FINE_SCALE,
                self._rate,
                self._rate_avg,
                lost / LOST_SCALE,
                self._last_r[0],
                self._last_r[1],
            ],
            dtype=np.float32,
        )
        np.clip(feats, -1.0, 1.0, out=feats)
        if not self.spec.child_intents:
            return np.concatenate([obs, feats])
        intents = intent_inputs(obs, self._intents, self.spec.max_children)
        return np.concatenate([obs, feats, intents])

    def action(self, residual: np.ndarray) -> np.ndarray:
        """The env's action for the latest observation and a correction.

        Args:
            residual: Correction ``r``, shape ``(spec.action_dim,)``; clipped to ``[-1, 1]``.

        Returns:
            The env's action, float32, shape ``(spec.action_dim,)``, in ``[-1, 1]``.

        Raises:
            ConfigError: if ``residual`` has the wrong shape or is not finite, or no observation
                was given yet.
        """
        spec = self.spec
        r = np.asarray(residual, dtype=np.float64).reshape(-1)
        if r.shape != (spec.action_dim,):
            raise ConfigError(f"residual must have shape ({spec.action_dim},), got {r.shape}")
        if not np.all(np.isfinite(r)):
            raise ConfigError(f"residual must be finite, got {r.tolist()}")
        if self._obs.size == 0:
            raise ConfigError("ResidualLC.action called before start(observation)")
        r = np.clip(r, -1.0, 1.0)
        if spec.deadband > 0.0:
            r = np.sign(r) * np.maximum(0.0, np.abs(r) - spec.deadband) / (1.0 - spec.deadband)
        obs, lim, lc = self._obs, self.limits, self._base
        if self._base_final:
            r[:2] = 0.0  # the base's terminal law has the last word on the paces
        if spec.gate_em > 0.0 and abs(ob.seconds(obs, Obs.T_A) - ob.seconds(obs, Obs.T_X)) < (
            spec.gate_em
        ):
            r[:] = 0.0  # the base holds the alignment: no correction at all
        if spec.pace_scale == 0.0:
            r[0] = 0.0  # no physical pace correction (the ignored output is not fed back)
        if spec.audio_gain == 0.0:
            r[1] = 0.0
        out = np.zeros(spec.action_dim, np.float32)
        p_cmd = command_from_action(float(lc[0]), lim.p_max) + spec.pace_scale * r[0]
        a_cmd = command_from_action(float(lc[1]), lim.a_max) + spec.audio_gain * r[1]
        out[0] = action_from_command(p_cmd, lim.p_max)
        out[1] = action_from_command(a_cmd, lim.a_max)
        self._last_r = r[:2].copy()
        if spec.choice_mode == "target":  # the base's target moved (the paper's base: u = 0)
            out[2] = min(1.0, max(-1.0, float(lc[2]) + spec.choice_scale * r[2]))
        else:
            t_x = max(0.0, ob.seconds(obs, Obs.T_X))
            for k in range(spec.max_children):
                base = ob.child_index(k)
                if base + 2 >= obs.shape[0]:
                    break
                mid = 0.5 * (float(obs[base + 1]) + float(obs[base + 2])) * ob.T_SCALE
                d = abs(t_x - mid)
                prior = (PRIOR_SCALE - d) / (PRIOR_SCALE + d)
                score = 0.5 * (prior + spec.choice_scale * r[2 + k])
                out[2 + k] = min(1.0, max(-1.0, score))
        return out


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def graph_digest(phrase_graph: str | Path) -> str:
    """SHA-256 of a phrase graph's YAML (a shipped key such as ``"lc"`` or a path)."""
    from langenv.speech.graph import graph_path

    return file_sha256(graph_path(phrase_graph))


def _shipped_graph_of(digest: str | None) -> str | None:
    """The shipped graph whose YAML has this digest (a model trained on the shipped graph of its
    day records only the digest: the study's graph before the default graph existed)."""
    if not digest:
        return None
    from langenv.speech.graph import SHIPPED_GRAPHS

    for name in ("lc", *sorted(SHIPPED_GRAPHS)):
        if graph_digest(name) == digest:
            return name
    return None


def model_files(path: str | Path) -> tuple[Path, Path, Path]:
    """The three files of a saved model: ``(STEM.zip, STEM_vecnormalize.pkl, STEM_config.yaml)``.

    Args:
        path: The model zip, with or without its ``.zip`` suffix.
    """
    p = Path(path)
    stem = p.with_suffix("") if p.suffix == ".zip" else p
    return (
        stem.with_name(stem.name + ".zip"),
        stem.with_name(stem.name + "_vecnormalize.pkl"),
        stem.with_name(stem.name + "_config.yaml"),
    )


@dataclass
class PPOPolicy:
    """A trained residual PPO policy, acting through ``LangCtrl-v0``'s observation/action.

    Build it with :meth:`load`. ``act`` is deterministic (the mean action of the Gaussian policy).

    It chooses phrases (``graph_role = "graph"``): it speaks the exercise's phrase graph, or an
    override, never silently the one it was trained on (:mod:`langenv.exercise.script`).
    :meth:`use_graph` fits it to that graph before the env is built.

    Attributes:
        name: ``"ppo"``.
        graph_role: ``"graph"``.
        decision_hz: Decision rate the model was trained at.
        env_kwargs: Further env arguments it was trained with (``choice_mode``...); after
            :meth:`use_graph` also ``max_children``, the observation's child blocks.
        path: The model zip.
        trained_graph: The phrase graph it was trained on, as tables name it (its config's
            ``env_kwargs.phrase_graph`` or single ``phrase_graphs`` entry, or the shipped graph
            whose digest it records), or None (trained on several: across exercises, each
            speaking its own script). For reports and the "changed since" warning only.
        trained_digest: SHA-256 of that graph's YAML when it was trained, or None.
        widened_from: The number of choices the model was trained for, when :meth:`use_graph`
            widened it to a graph with more; else None.
    """

    model: MlpActor
    normalizer: Any
    residual: ResidualLC
    decision_hz: int = 50
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    path: Path = Path()
    name: str = "ppo"
    graph_role: str = "graph"
    trained_graph: str | None = None
    trained_digest: str | None = None
    widened_from: int | None = None
    _started: bool = False

    @classmethod
    def load(cls, path: str | Path) -> PPOPolicy:
        """Load ``STEM.zip``, its ``STEM_vecnormalize.pkl`` and its ``STEM_config.yaml``.

        Args:
            path: The model zip written by ``langctrl train`` (``.zip`` optional).

        Raises:
            FileNotFoundError: naming the file, if one of the three is missing.
            ModelError: (a ValueError) naming the file, if one is corrupt or inconsistent with
                the others; :class:`~langenv.errors.ObservationLayoutError` if the model was
                trained for another observation layout (its recorded signature, or for an older
                model its input size, differs from this code's).
        """
        zip_path, norm_path, cfg_path = model_files(path)
        for f in (zip_path, norm_path, cfg_path):
            if not f.is_file():
                raise FileNotFoundError(f"PPO model file not found: {f}")
        config = _read_config(cfg_path)
        env_kwargs = dict(config.get("env_kwargs") or {})
        spec_kw = dict(config.get("residual") or {})
        try:
            spec = ResidualSpec(**spec_kw)
        except (TypeError, ConfigError) as exc:
            raise ModelError(f"{cfg_path}: invalid 'residual' section: {exc}") from None
        normalizer = _read_normalizer(norm_path)
        model = _read_model(zip_path)
        n_obs, n_act = model.n_inputs, model.n_actions
        if n_act != spec.action_dim:
            raise ModelError(
                f"{zip_path}: model has {n_act} actions but its config's residual needs "
                f"{spec.action_dim} ({cfg_path})"
            )
        mean = getattr(getattr(normalizer, "obs_rms", None), "mean", None)
        if mean is None or int(np.prod(np.shape(mean))) != n_obs:
            raise ModelError(
                f"{norm_path}: observation normaliser does not match the model's {n_obs} inputs"
            )
        _check_layout(config, cfg_path, zip_path, n_obs, spec)
        hz = int(env_kwargs.pop("decision_hz", spec.decision_hz))
        digest = config.get("phrase_graph_sha256") or None
        listed = config.get("phrase_graphs")
        one = listed[0] if isinstance(listed, list) and len(listed) == 1 else None
        trained = env_kwargs.pop("phrase_graph", None) or one or _shipped_graph_of(digest)
        env_kwargs.pop("max_episode_steps", None)
        env_kwargs.pop("max_children", None)  # set by use_graph for the graph spoken
        env_kwargs.pop("exercise", None)  # trained on one or several: the caller chooses
        return cls(
            model=model,
            normalizer=normalizer,
            residual=ResidualLC(spec),
            decision_hz=hz,
            env_kwargs=env_kwargs,
            path=zip_path,
            trained_graph=graph_label(str(trained)) if trained else None,
            trained_digest=str(digest) if digest else None,
        )

    @property
    def max_children(self) -> int:
        """The largest number of choices the model reads (its observation's child blocks)."""
        return self.residual.spec.max_children

    def use_graph(self, spoken: SpokenGraph) -> None:
        """Fit the model to the phrase graph it is to speak (before the env is built).

        * a graph with at most :attr:`max_children` choices: the env's observation keeps the
          model's child blocks (``env_kwargs["max_children"]``), the extra ones empty, as in
          training across exercises;
        * a graph with more, for a ``"target"`` model (one phrase action whatever the number of
          children): the model is widened in memory exactly as ``langctrl widen`` widens
          it on disk (zero weights and neutral normalisation on the new child blocks: it acts as
          trained, blind to the extra children's inputs; the env's choice rule still chooses
          among all of them); :attr:`widened_from` records it;
        * a graph with more for a ``"scores"`` model (one output per child): refused.

        Warns when the graph is the one the model was trained on and its file changed since.

        Raises:
            GraphChoicesError: a ``"scores"`` model and a graph with more choices than it has
                outputs (naming the model, the graph and both numbers).
        """
        spec = self.residual.spec
        if spoken.max_children > spec.max_children:
            if spec.choice_mode != "target":
                raise GraphChoicesError(
                    self.path,
                    spoken.label,
                    spec.max_children,
                    spoken.max_children,
                    "its 'scores' action has one output per choice, which widening cannot add: "
                    "retrain it on this graph (langctrl train) or speak another (--graph)",
                )
            self._widen(spoken.max_children)
        self.env_kwargs["max_children"] = self.residual.spec.max_children
        if spec.child_intents:
            self.residual.use_intents(load_intents(spoken.ref))
        if (
            self.trained_digest is not None
            and spoken.label == self.trained_graph
            and graph_digest(spoken.ref) != self.trained_digest
        ):
            warnings.warn(
                f"{self.path}: the phrase graph {spoken.label} changed since this model was "
                "trained on it; retrain it (langctrl train) for best results",
                stacklevel=2,
            )

    def _widen(self, max_children: int) -> None:
        """Widen the model's input to ``max_children`` child blocks (see :meth:`use_graph`)."""
        old = self.residual.spec.max_children
        weights = list(self.model.weights)
        rms = self.normalizer.obs_rms
        for at, n in widened_inputs(old, max_children, self.residual.spec.child_intents):
            weights[0] = np.insert(weights[0], [at] * n, 0.0, axis=1)
            rms.mean = np.insert(np.asarray(rms.mean, np.float64), at, np.zeros(n))
            rms.var = np.insert(np.asarray(rms.var, np.float64), at, np.ones(n))
        self.model = MlpActor(tuple(weights), self.model.biases, self.model.activation)
        spec = replace(self.residual.spec, max_children=max_children)
        self.residual = ResidualLC(spec, self.residual.limits)
        self.widened_from = old if self.widened_from is None else self.widened_from

    def reset(self) -> None:
        """Start a new episode (the next observation is the one ``reset`` returned)."""
        self._started = False

    def correction(self, observation: np.ndarray) -> np.ndarray:
        """The network's correction ``r`` for the next observation of the episode (deterministic).

        Advances the residual map's episode state (features); follow it with
        ``self.residual.action(r)`` for this observation, as :meth:`act` does.
        """
        if not self._started:
            n_env = int(np.shape(observation)[0]) + self.residual.n_features
            if n_env != self.model.n_inputs:
                raise ObservationLayoutError(
                    self.path,
                    f"size={n_env} (this env's observation and the features)",
                    f"size={self.model.n_inputs}",
                    "the env's observation has another number of child blocks than the model "
                    "reads: build the env after langenv.exercise.speak(policy, exercise), "
                    "with the policy's env_kwargs",
                )
            if self.residual.spec.child_intents and not self.residual.reads_intents:
                raise ModelError(
                    f"{self.path}: the model reads each choice's intent from the graph spoken: "
                    "fit it to the graph first (langenv.exercise.speak(policy, exercise))"
                )
            aug = self.residual.start(observation)
            self._started = True
        else:
            aug = self.residual.observe(observation)
        norm = self.normalizer.normalize_obs(aug[None, :].astype(np.float32))
        return self.model(norm[0])

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The env's action for one observation (deterministic), float32.

        A model that decides at the phrase choices only (``decisions: choices``) is its base
        at every other tick, and the network is consulted (and its features advanced) only
        where the base's :meth:`~policies.analytic.LanguageController.choice_due`, as in its
        training (:class:`train.choices.ChoicePoints`).
        """
        if self.residual.spec.decisions == "choices":
            if not self._started:
                self.correction(observation)  # checks the layout, starts the features
            lc = self.residual.lc
            base = lc.act(observation)
            if not lc.choice_due(observation):
                return base
        return self.residual.action(self.correction(observation))

    def config(self) -> dict[str, Any]:
        """The residual design (for reports)."""
        return asdict(self.residual.spec)


def _check_layout(
    config: dict[str, Any], cfg_path: Path, zip_path: Path, n_obs: int, spec: ResidualSpec
) -> None:
    """Refuse a model trained for another observation layout than this code gives.

    A config that records ``observation_layout`` (every model trained since it was introduced) is
    compared by signature; an older one (the shipped model) by the model's input size.

    Raises:
        ObservationLayoutError: naming the file, the expected and the found layout.
    """
    now = observation_layout(spec.max_children, spec.child_intents)
    recorded = config.get("observation_layout")
    hint = "retrain it with this code (langctrl train)"
    if isinstance(recorded, dict) and recorded.get("signature") != now["signature"]:
        raise ObservationLayoutError(cfg_path, _layout_text(now), _layout_text(recorded), hint)
    if n_obs != now["size"]:
        found = f"size={n_obs} (its network's inputs)"
        raise ObservationLayoutError(zip_path, _layout_text(now), found, hint)


def _read_config(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot read model config: {exc}") from None
    if not isinstance(data, dict):
        raise ModelError(f"{path}: model config must be a YAML mapping")
    return data


def _read_normalizer(path: Path) -> Any:
    try:
        with path.open("rb") as fh:
            normalizer = pickle.load(fh)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise ModelError(f"{path}: cannot read VecNormalize statistics: {exc}") from None
    if not hasattr(normalizer, "normalize_obs"):
        raise ModelError(f"{path}: not a VecNormalize pickle")
    normalizer.training = False
    return normalizer


def _read_model(path: Path) -> MlpActor:
    try:
        return MlpActor.from_sb3_zip(path)
    except (zipfile.BadZipFile, OSError, ValueError, KeyError, RuntimeError, EOFError) as exc:
        raise ModelError(f"{path}: cannot read PPO model: {exc}") from None
