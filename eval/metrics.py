"""The paper's per-session metrics, computed from an :class:`~eval.episode.EpisodeLog`.

Time series are summarised by **time-weighted** means, so a log sampled at 25 Hz and one sampled
at 500 Hz of the same session give the same numbers (up to the sampling resolution): each sample
stands for the interval until the next sample (zero-order hold), the last sample for the interval
before it (see :func:`time_weights`). On a uniform grid this is the plain mean.

Each metric is taken over the part of the session where it means something (a *window*):

=================  ===========  ===========================================================
column             window       definition
=================  ===========  ===========================================================
``am``             --           ``t_speech - t_motion`` (s); positive: motion finished first
``abs_am``         --           ``|am|`` (s)
``em_mean_abs``    ``either``   mean ``|EM|`` (s) while motion or speech is still going on
``a_mean``         ``speech``   mean audio pace while speech is going on
``a_dev``          ``speech``   mean ``|a - 1|`` while speech is going on
``a_within_0_1``   ``speech``   share (0-1) of the speech time with ``|a - 1| <= 0.1``
``voice_natural``  ``speech``   share (0-1) of the speech time in which the voice is heard within
                                0.1 of its natural rate: ``|v - 1| <= 0.1`` with ``v`` the voice's
                                rate (:func:`voice_trace`); equal to ``a_within_0_1`` for a
                                stretched voice
``pause_share``    ``speech``   share (0-1) of the speech time in silence: pauses between clips
                                and pause vertices
``filler_share``   ``speech``   share (0-1) of the speech time spent saying fillers
``p_mean``         ``motion``   mean physical pace while motion is going on
``coop_mean``      ``motion``   mean cooperation while the robot guides the hand
``t_motion``       --           motion completion time (s)
``t_speech``       --           speech completion time (s)
``return``         --           episode return
``content_share``  ``motion``   share (0-1) of the motion's duration in which content is heard:
                                a phrase's words as the voice renders them (:func:`voice_trace`),
                                not a filler, a pause, the silence after a clip or the natural
                                voice's wait (:func:`content_time`); words said after the motion
                                ended do not count
``sm_max_abs``     --           largest ``|SM_k|`` (s): when leg ``k``'s first words start minus
                                when the motion enters leg ``k``, over the legs after the first
                                whose words were said (:mod:`eval.legs`); NaN for an unmarked
                                graph
``legs_in_step``   --           share (0-1) of those legs whose words start within 1 s of the leg
                                (words never said: not in step); NaN for an unmarked graph
``path_error``     ``motion``   mean path error (m): the hand's distance from its closest point
                                on the exercise's path (``info["path_deviation"]``, what the
                                safety monitor watches); NaN when the log lacks the trace
``effort``         ``motion``   the person's effort (N): mean ``|F|`` of the force the person
                                applies to the handle (the log's ``f_user``), Tejwani et al.'s
                                (2026) push force; NaN when the log lacks the force
=================  ===========  ===========================================================

Cooperation is averaged over the motion only because after the motion ends the hand rests and
``c`` drifts back to 1 for as long as the speech lasts, which would favour the controller that talks
longest. A metric whose window is empty (e.g. no speech at all) is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from eval.episode import EpisodeLog
from eval.legs import leg_metrics
from langenv.errors import ConfigError
from langenv.speech.voice import voice_rate, waiting_spans, words_heard

__all__ = [
    "A_TOLERANCE",
    "METRICS",
    "METRIC_COLUMNS",
    "NUMERIC_METRICS",
    "OPTIONAL_METRICS",
    "MetricSpec",
    "Window",
    "content_time",
    "episode_metrics",
    "speech_shares",
    "time_mean",
    "time_samples",
    "time_weights",
    "voice_trace",
    "window_mask",
]

Window = Literal["motion", "speech", "either", "all"]
"""Part of a session a metric is taken over (see the module docstring)."""

A_TOLERANCE = 0.1
"""Audio pace counts as natural when ``|a - 1| <= A_TOLERANCE`` (the study's 0.1)."""

_EPS = 1e-9  # so that |a - 1| == 0.1 up to rounding counts as within


@dataclass(frozen=True)
class MetricSpec:
    """How a metric is named, measured and printed.

    Attributes:
        label: Short label for tables and axes (``"|AM|"``).
        unit: Unit (``"s"``, ``"m/s"``, ``""`` when dimensionless, ``"%"`` for shares).
        decimals: Decimals to print in the unit shown (shares are printed in percent).
        description: One line for a reader.
        lower_is_better: Whether smaller values are better (``None``: neither).
    """

    label: str
    unit: str
    decimals: int
    description: str
    lower_is_better: bool | None = None


METRICS: dict[str, MetricSpec] = {
    "am": MetricSpec("AM", "s", 2, "actual misalignment t_speech - t_motion (+: motion first)"),
    "abs_am": MetricSpec("|AM|", "s", 2, "absolute actual misalignment", True),
    "em_mean_abs": MetricSpec("mean |EM|", "s", 2, "mean |t_a - t_x| while either goes on", True),
    "a_mean": MetricSpec("mean a", "", 3, "mean audio pace while speaking"),
    "a_dev": MetricSpec("mean |a-1|", "", 3, "mean audio pace distortion while speaking", True),
    "a_within_0_1": MetricSpec(
        "|a-1| <= 0.1", "%", 1, "share of speech time at near-natural pace", False
    ),
    "voice_natural": MetricSpec(
        "voice natural", "%", 1, "share of speech time with the voice within 0.1 of natural", False
    ),
    "pause_share": MetricSpec("pauses", "%", 1, "share of speech time in silence (pauses)"),
    "filler_share": MetricSpec("fillers", "%", 1, "share of speech time saying fillers"),
    "p_mean": MetricSpec("mean p", "", 3, "mean physical pace while moving"),
    "coop_mean": MetricSpec("mean c", "", 3, "mean cooperation while moving"),
    "t_motion": MetricSpec("t_motion", "s", 2, "motion completion time"),
    "t_speech": MetricSpec("t_speech", "s", 2, "speech completion time"),
    "return": MetricSpec("return", "", 2, "episode return (sum of rewards)", False),
    # last: the bootstrap of summary.md draws from one generator in this order, so a metric
    # added at the end leaves the intervals of the others as they were
    "content_share": MetricSpec(
        "content", "%", 1, "share of the motion's duration in which words are heard", False
    ),
    "sm_max_abs": MetricSpec(
        "max |SM|", "s", 2, "largest |start of a leg's words - start of the leg|", True
    ),
    "legs_in_step": MetricSpec(
        "legs in step", "%", 1, "share of legs whose words start within 1 s of the leg", False
    ),
    "path_error": MetricSpec(
        "path error", "m", 4, "mean distance of the hand from the path while moving", True
    ),
    "effort": MetricSpec("effort", "N", 2, "mean |force| the person applies while moving", True),
}
"""Specification of every numeric metric, in column order."""

NUMERIC_METRICS: tuple[str, ...] = tuple(METRICS)
"""Numeric columns of a session row, in order."""

METRIC_COLUMNS: tuple[str, ...] = ("policy", "user", *NUMERIC_METRICS)
"""All columns of a session row (``sessions.csv``), in order."""

OPTIONAL_METRICS: frozenset[str] = frozenset(
    {
        "pause_share",
        "filler_share",
        "voice_natural",
        "content_share",
        "sm_max_abs",
        "legs_in_step",
        "path_error",
        "effort",
    }
)
"""Metrics that tables of older runs lack (langctrl 0.4 and before; ``voice_natural`` and
``content_share``: 0.5; ``sm_max_abs`` and ``legs_in_step``: after 0.5.0; ``path_error`` and
``effort``: after 0.6): read as NaN."""


def time_weights(t: np.ndarray) -> np.ndarray:
    """Duration each sample stands for (zero-order hold).

    Args:
        t: Sample times (s), shape ``(n,)``, ``n >= 2``, strictly increasing.

    Returns:
        Weights (s), shape ``(n,)``: ``t[i+1] - t[i]``, and for the last sample ``t[-1] - t[-2]``.
        They sum to ``t[-1] - t[0]`` plus one last interval.

    Raises:
        ConfigError: if ``t`` is not 1-D with at least two strictly increasing samples.
    """
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.shape[0] < 2:
        raise ConfigError(f"t must have shape (n,) with n >= 2, got {t.shape}")
    dt = np.diff(t)
    if not (dt > 0.0).all():
        raise ConfigError("t must be strictly increasing")
    return np.append(dt, dt[-1])


def time_mean(x: np.ndarray, t: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Time-weighted mean of ``x`` over the samples selected by ``mask``.

    Args:
        x: Values, shape ``(n,)``.
        t: Sample times (s), shape ``(n,)``, strictly increasing.
        mask: Boolean selection, shape ``(n,)``; ``None`` selects all.

    Returns:
        ``sum(w x) / sum(w)`` over the selection with :func:`time_weights` ``w``; NaN when the
        selection is empty.

    Raises:
        ConfigError: if the shapes differ.
    """
    x = np.asarray(x, dtype=np.float64)
    w = time_weights(t)
    if x.shape != w.shape:
        raise ConfigError(f"x has shape {x.shape} but t has shape {w.shape}")
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != w.shape:
            raise ConfigError(f"mask has shape {mask.shape} but t has shape {w.shape}")
        w = w * mask
    total = float(w.sum())
    if total <= 0.0:
        return float("nan")
    return float(np.sum(w * x) / total)  # NumPy's pairwise sum, not BLAS: the same on any CPU


def window_mask(log: EpisodeLog, window: Window) -> np.ndarray:
    """Samples of ``log`` inside ``window``.

    Args:
        log: The episode.
        window: ``"motion"`` (motion not over), ``"speech"`` (speech not over), ``"either"`` (one
            of them not over) or ``"all"``.

    Returns:
        Boolean mask, shape ``(n,)``.

    Raises:
        ConfigError: for an unknown window.
    """
    if window == "motion":
        return ~log.motion_done
    if window == "speech":
        return ~log.speech_done
    if window == "either":
        return ~(log.motion_done & log.speech_done)
    if window == "all":
        return np.ones(log.n, dtype=bool)
    raise ConfigError(f"window must be 'motion', 'speech', 'either' or 'all', got {window!r}")


def time_samples(log: EpisodeLog, name: str, window: Window, hz: float = 50.0) -> np.ndarray:
    """Values of a trace inside a window, resampled on a uniform time grid (zero-order hold).

    Pooling these across sessions weights every session by its duration, whatever its log rate.

    Args:
        log: The episode.
        name: A float trace of :class:`EpisodeLog` (``"cooperation"``, ``"a"``, ``"em"``...).
        window: See :func:`window_mask`.
        hz: Grid rate (Hz), > 0.

    Returns:
        The held values at ``t[0] + k / hz`` for the grid points inside the window, shape ``(m,)``.

    Raises:
        ConfigError: for an unknown trace, window or a non-positive rate.
    """
    if not hz > 0.0:
        raise ConfigError(f"hz must be > 0, got {hz!r}")
    if name not in ("cooperation", "hand_speed", "p", "a", "t_x", "t_a", "em"):
        raise ConfigError(f"name must be a float trace of EpisodeLog, got {name!r}")
    mask = window_mask(log, window)
    end = log.t[-1] + (log.t[-1] - log.t[-2])
    grid = log.t[0] + np.arange(int(np.floor((end - log.t[0]) * hz - 1e-9)) + 1) / hz
    idx = np.searchsorted(log.t, grid, side="right") - 1
    values: np.ndarray = getattr(log, name)
    return values[idx][mask[idx]]


def speech_shares(log: EpisodeLog, waiting: np.ndarray | None = None) -> dict[str, float]:
    """Shares of the speech time (from the log's start to the speech's end) in silence and in
    fillers, from the log's utterances.

    Args:
        log: The episode.
        waiting: Samples at which a natural voice waits in silence inside a clip's slot
            (:func:`voice_trace`), shape ``(n,)``; they count as silence.

    Returns:
        ``{"pause_share": ..., "filler_share": ...}``, each in [0, 1]; NaN when the speech took
        no time or no utterance was recorded.
    """
    span = log.t_speech - float(log.t[0])
    clips = [u for u in log.utterances if not u.is_pause]
    if span <= 0.0 or not clips:
        return {"pause_share": float("nan"), "filler_share": float("nan")}
    said = sum(min(u.t_end, log.t_speech) - u.t_start for u in clips)
    filler = sum(min(u.t_end, log.t_speech) - u.t_start for u in clips if u.filler)
    if waiting is not None and waiting.any():
        weights = np.where((log.t < log.t_speech) & waiting, time_weights(log.t), 0.0)
        said -= float(np.sum(weights))
        for u in clips:  # a filler's wait is silence, not the filler said
            if u.filler:
                filler -= float(np.sum(weights[(log.t >= u.t_start) & (log.t < u.t_end)]))
    return {
        "pause_share": min(1.0, max(0.0, 1.0 - said / span)),
        "filler_share": min(1.0, max(0.0, filler / span)),
    }


def content_time(log: EpisodeLog, waiting: np.ndarray, until: float) -> float:
    """Time (s) from the log's start to ``until`` in which a phrase's words are heard.

    A *content* utterance is a clip that is neither a filler nor a pause vertex; its words are
    heard over ``[t_start, t_end)`` (the graph's silence after a clip is not part of it) except
    where the voice waits in silence (``waiting``, the natural voice's wait from
    :func:`voice_trace`); :func:`langenv.speech.voice.words_heard` counts them.

    Args:
        log: The episode.
        waiting: Whether the voice waits at each sample, shape ``(n,)``, bool.
        until: End of the window (s), e.g. ``log.t_motion``.

    Returns:
        Seconds of words heard in ``[t[0], until)``, ``>= 0``.
    """
    spans = [(u.t_start, u.t_end) for u in log.utterances if not u.is_pause and not u.filler]
    return words_heard(log.t, waiting, spans, until)


def voice_trace(log: EpisodeLog) -> tuple[np.ndarray, np.ndarray]:
    """The rate at which the voice is heard at each sample of ``log``, and whether it waits in
    silence there; shape ``(n,)`` each.

    A stretched voice (``log.voice == "stretch"``) is heard at the speech pace ``a``. A natural
    voice (:mod:`langenv.speech.voice`) says every clip but the last at ``max(a, 0.9)`` and then
    waits at rate 1 until the clip's slot ends (:func:`langenv.speech.voice.voice_rate`); a
    clip the speech ends with follows ``a`` (:func:`~langenv.speech.voice.waiting_spans`).
    """
    if log.voice != "natural":
        return log.a, np.zeros(log.n, dtype=bool)
    clips = [(u.t_start, u.t_end) for u in log.utterances if not u.is_pause]
    return voice_rate(log.t, log.a, waiting_spans(log.t, log.speech_done, clips))


def episode_metrics(log: EpisodeLog) -> dict[str, float | str]:
    """The session row of ``log``: ``policy``, ``user`` and the metrics of the module docstring.

    Args:
        log: The episode.

    Returns:
        A dict with exactly the keys :data:`METRIC_COLUMNS`, in that order; ``policy`` and
        ``user`` are str, the rest float (NaN when a window is empty).
    """
    t = log.t
    speech = window_mask(log, "speech")
    motion = window_mask(log, "motion")
    either = window_mask(log, "either")
    dev = np.abs(log.a - 1.0)
    voice, waiting = voice_trace(log)
    am = log.am
    row: dict[str, float | str] = {
        "policy": log.policy,
        "user": log.user,
        "am": am,
        "abs_am": abs(am),
        "em_mean_abs": time_mean(np.abs(log.em), t, either),
        "a_mean": time_mean(log.a, t, speech),
        "a_dev": time_mean(dev, t, speech),
        "a_within_0_1": time_mean((dev <= A_TOLERANCE + _EPS).astype(np.float64), t, speech),
        "voice_natural": time_mean(
            (np.abs(voice - 1.0) <= A_TOLERANCE + _EPS).astype(np.float64), t, speech
        ),
        **speech_shares(log, waiting),
        "p_mean": time_mean(log.p, t, motion),
        "coop_mean": time_mean(log.cooperation, t, motion),
        "t_motion": log.t_motion,
        "t_speech": log.t_speech,
        "return": log.ret,
        "content_share": _content_share(log, waiting),
        **leg_metrics(log),
        "path_error": (
            time_mean(log.path_deviation, t, motion)
            if log.path_deviation is not None
            else float("nan")
        ),
        "effort": (
            time_mean(np.linalg.norm(log.f_user, axis=1), t, motion)
            if log.f_user is not None
            else float("nan")
        ),
    }
    return row


def _content_share(log: EpisodeLog, waiting: np.ndarray) -> float:
    """``content_share``: words heard over the motion's duration (NaN for a motion of no time)."""
    span = log.t_motion - float(log.t[0])
    if not span > 0.0:
        return float("nan")
    return min(1.0, content_time(log, waiting, log.t_motion) / span)
