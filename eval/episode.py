"""The log of one evaluated episode: per-step traces, what was said, and the completion times.

An :class:`EpisodeLog` is what the evaluation keeps of one policy guiding one user: the time series
of the paper's close-up figure (cooperation, hand speed, paces, ETCs, estimated misalignment), the
phrases said with their time spans, and the motion/speech completion times that define the actual
misalignment. It is a read-only value object, saved to and loaded from ``.npz`` without pickling.

:class:`EpisodeRecorder` builds one from the ``info`` dicts of ``LangCtrl-v0`` (or from any mapping
with the same keys), step by step.
"""

from __future__ import annotations

import math
import os
import zipfile
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from langenv.errors import ConfigError, SessionDataError
from langenv.files import temp_file
from langenv.speech.voice import check_voice

__all__ = [
    "FLAG_TRACES",
    "FLOAT_TRACES",
    "SCENE_TRACES",
    "EpisodeLog",
    "EpisodeRecorder",
    "Utterance",
]

FLOAT_TRACES: tuple[str, ...] = ("t", "cooperation", "hand_speed", "p", "a", "t_x", "t_a", "em")
"""Names of the per-step float traces of :class:`EpisodeLog`, in field order."""

FLAG_TRACES: tuple[str, ...] = ("motion_done", "speech_done")
"""Names of the per-step boolean traces of :class:`EpisodeLog`."""

SCENE_TRACES: tuple[str, ...] = ("qpos", "f_user")
"""Names of the optional per-step arrays that replay the scene (:mod:`eval.video`)."""

_TRACES = (*FLOAT_TRACES, *FLAG_TRACES)  # what EpisodeRecorder.append reads from info, in order
_TRACE_KEYS_TIME = tuple("time" if name == "t" else name for name in _TRACES)  # info has no "t"

_NPZ_FORMAT = 3
_NPZ_FORMATS = (1, 2, 3)  # format 1: no scene traces, no phrase graph; 2: no legs


@dataclass(frozen=True)
class Utterance:
    """One phrase (or filler) said during an episode, or one pause vertex's silence.

    Attributes:
        phrase: Id of the phrase-graph vertex (non-empty).
        text: What the phrase says (may be empty when only audio is known; empty for a pause).
        t_start: Episode time at which the phrase started playing (s).
        t_end: Episode time at which it stopped playing, before any pause (s), ``>= t_start``.
        length: For a pause vertex, the length chosen for it (s at a = 1, ``>= 0``); None for
            a clip.
        filler: True for a filler clip ("okay", "so").
        leg: The leg of the exercise the vertex speaks about (its graph's ``leg``); empty in an
            unmarked graph.
    """

    phrase: str
    text: str
    t_start: float
    t_end: float
    length: float | None = None
    filler: bool = False
    leg: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.phrase, str) or not self.phrase:
            raise ConfigError(f"Utterance.phrase must be a non-empty str, got {self.phrase!r}")
        if not isinstance(self.text, str):
            raise ConfigError(f"Utterance.text must be a str, got {type(self.text).__name__}")
        for name in ("t_start", "t_end"):
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if isinstance(value, str) or not math.isfinite(number):
                raise ConfigError(f"Utterance.{name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, number)
        if self.t_end < self.t_start:
            raise ConfigError(
                f"Utterance.t_end ({self.t_end}) must be >= t_start ({self.t_start}) "
                f"for phrase {self.phrase!r}"
            )
        if self.length is not None:
            length = float(self.length)
            if not (math.isfinite(length) and length >= 0.0):
                raise ConfigError(f"Utterance.length must be finite and >= 0, got {self.length!r}")
            object.__setattr__(self, "length", length)
        object.__setattr__(self, "filler", bool(self.filler))
        if not isinstance(self.leg, str):
            raise ConfigError(f"Utterance.leg must be a str, got {type(self.leg).__name__}")

    @property
    def is_pause(self) -> bool:
        """True for a pause vertex's silence."""
        return self.length is not None

    @property
    def duration(self) -> float:
        """Time the phrase played (s)."""
        return self.t_end - self.t_start


@dataclass(frozen=True, eq=False)
class EpisodeLog:
    """Everything the evaluation keeps of one episode (one policy, one user).

    Per-step traces are read-only numpy arrays of shape ``(n,)`` with ``n >= 2``, sampled at the
    instants ``t`` (any rate: the env's decision rate, 25 Hz, or the 500 Hz tick). Float traces are
    float64 and finite; flags are bool and, once set, stay set.

    Attributes:
        policy: Policy name (``"ac"``, ``"lc-noap"``, ``"lc"``, ...).
        user: User name (``"synthetic-3"``, ``"u4_lc"``, ...).
        t: Episode time (s), strictly increasing.
        cooperation: Cooperation ``c`` in [0, 1].
        hand_speed: Hand speed (m/s), ``>= 0``.
        p: Physical pace.
        a: Audio pace.
        t_x: Motion ETC at base pace (s).
        t_a: Speech ETC at base pace (s).
        em: Estimated misalignment ``t_a - t_x`` (s).
        motion_done: True once the motion is over.
        speech_done: True while the speech is over (False again where it goes on after its
            end because the motion went back: :mod:`langenv.speech.repeat`).
        utterances: Phrases said, ordered by start time.
        t_motion: Time at which the motion ended (s).
        t_speech: Time at which the speech ended (s; its last end where it went on).
        ret: Episode return (sum of rewards).
        qpos: Joint positions of the arm model, shape ``(n, nq)`` (rad), float32; None when not
            recorded. With ``f_user`` it replays the scene (:mod:`eval.video`).
        f_user: The person's force on the handle (before the sensor), shape ``(n, 3)`` (N),
            float32; None when not recorded.
        path: The exercise path, shape ``(m, 3)`` (m), float32, drawn in the video; None when
            not recorded.
        phrase_graph: The phrase graph spoken: a shipped graph's key (``"lc"``...) or the YAML's
            absolute path; empty when unknown. With the utterances it re-renders the speech.
        voice: How the graph voices the speech pace (:data:`langenv.speech.voice.VOICES`):
            ``"stretch"`` (the paper's; recorded sessions) or ``"natural"``.
        leg: The leg the motion is in at each sample (``info["leg"]``: its index in
            ``leg_names``, their number once the last is done), shape ``(n,)``, int64, never
            decreasing; None when not recorded.
        leg_names: The names of the motion's legs, in order (the exercise's); empty when unknown.
        spoken_legs: The legs the phrase graph has words for (a phrase vertex marked with the
            leg), in script order; empty for an unmarked graph.
        path_deviation: The hand's distance from its closest point on the exercise's path at
            each sample (``info["path_deviation"]``, m), shape ``(n,)``, float64, ``>= 0``; None
            when not recorded (logs of langctrl 0.6 and before).

    Raises:
        ConfigError: (a ``ValueError``) naming the field, if a trace has the wrong shape, differing
            length, non-finite values, decreasing time or flags that unset; or if a scalar is not
            finite, or utterances are not ordered.
    """

    policy: str
    user: str
    t: np.ndarray
    cooperation: np.ndarray
    hand_speed: np.ndarray
    p: np.ndarray
    a: np.ndarray
    t_x: np.ndarray
    t_a: np.ndarray
    em: np.ndarray
    motion_done: np.ndarray
    speech_done: np.ndarray
    utterances: tuple[Utterance, ...]
    t_motion: float
    t_speech: float
    ret: float
    qpos: np.ndarray | None = None
    f_user: np.ndarray | None = None
    path: np.ndarray | None = None
    phrase_graph: str = ""
    voice: str = "stretch"
    leg: np.ndarray | None = None
    leg_names: tuple[str, ...] = ()
    spoken_legs: tuple[str, ...] = ()
    path_deviation: np.ndarray | None = None

    _scalars: ClassVar[tuple[str, ...]] = ("t_motion", "t_speech", "ret")

    def __post_init__(self) -> None:
        for name in ("policy", "user"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                raise ConfigError(f"EpisodeLog.{name} must be a non-empty str, got {value!r}")
        n = self._check_float_traces()
        self._check_flag_traces(n)
        self._check_scene_traces(n)
        self._check_legs(n)
        self._check_deviation(n)
        if not isinstance(self.phrase_graph, str):
            raise ConfigError(
                f"EpisodeLog.phrase_graph must be a str, got {type(self.phrase_graph).__name__}"
            )
        check_voice(self.voice, "EpisodeLog")
        for name in self._scalars:
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"EpisodeLog.{name} must be a number, got {value!r}") from None
            if not math.isfinite(number):
                raise ConfigError(f"EpisodeLog.{name} must be finite, got {value!r}")
            object.__setattr__(self, name, number)
        for name in ("t_motion", "t_speech"):
            if getattr(self, name) < 0.0:
                raise ConfigError(f"EpisodeLog.{name} must be >= 0 s, got {getattr(self, name)}")
        utterances = tuple(self.utterances)
        for k, u in enumerate(utterances):
            if not isinstance(u, Utterance):
                raise ConfigError(
                    f"EpisodeLog.utterances[{k}] must be an Utterance, got {type(u).__name__}"
                )
            if k and u.t_start < utterances[k - 1].t_start:
                raise ConfigError(
                    f"EpisodeLog.utterances must be ordered by t_start: utterances[{k}] "
                    f"({u.phrase!r}) starts at {u.t_start} s, before utterances[{k - 1}]"
                )
        object.__setattr__(self, "utterances", utterances)

    def _check_float_traces(self) -> int:
        n = -1
        for name in FLOAT_TRACES:
            try:
                arr = np.array(getattr(self, name), dtype=np.float64)
            except (TypeError, ValueError):
                raise ConfigError(f"EpisodeLog.{name} must be numeric") from None
            if arr.ndim != 1:
                raise ConfigError(f"EpisodeLog.{name} must have shape (n,), got {arr.shape}")
            if n < 0:
                n = arr.shape[0]
                if n < 2:
                    raise ConfigError(f"EpisodeLog.{name} needs at least 2 samples, got {n}")
            elif arr.shape[0] != n:
                raise ConfigError(
                    f"EpisodeLog.{name} has {arr.shape[0]} samples but t has {n} (equal lengths)"
                )
            bad = ~np.isfinite(arr)
            if bad.any():
                i = int(np.argmax(bad))
                raise ConfigError(f"EpisodeLog.{name} must be finite, got {arr[i]} at index {i}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        dt = np.diff(self.t)
        if (dt <= 0.0).any():
            i = int(np.argmax(dt <= 0.0))
            raise ConfigError(
                f"EpisodeLog.t must be strictly increasing, got t[{i}]={self.t[i]} "
                f"and t[{i + 1}]={self.t[i + 1]}"
            )
        if (self.hand_speed < 0.0).any():
            raise ConfigError("EpisodeLog.hand_speed must be >= 0 m/s")
        return n

    def _check_flag_traces(self, n: int) -> None:
        for name in FLAG_TRACES:
            raw = np.asarray(getattr(self, name))
            if raw.ndim != 1 or raw.shape[0] != n:
                raise ConfigError(
                    f"EpisodeLog.{name} must have shape ({n},) like t, got {raw.shape}"
                )
            if raw.dtype != np.bool_ and not np.isin(raw, (0, 1)).all():
                raise ConfigError(f"EpisodeLog.{name} must be boolean (or 0/1)")
            arr = raw.astype(np.bool_)
            unset = arr[:-1] & ~arr[1:]
            if name == "motion_done" and unset.any():
                i = int(np.argmax(unset))
                raise ConfigError(
                    f"EpisodeLog.motion_done must stay True once set, but goes back to False at "
                    f"index {i + 1} (t={self.t[i + 1]} s)"
                )
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def _check_scene_traces(self, n: int) -> None:
        for name, rows, width in (("qpos", n, None), ("f_user", n, 3), ("path", None, 3)):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                arr = np.array(value, dtype=np.float32)
            except (TypeError, ValueError):
                raise ConfigError(f"EpisodeLog.{name} must be numeric") from None
            if (
                arr.ndim != 2
                or (rows is not None and arr.shape[0] != rows)
                or (rows is None and arr.shape[0] < 2)
                or (width is not None and arr.shape[1] != width)
            ):
                want = f"({n if rows is not None else 'm >= 2'}, {width or 'k'})"
                raise ConfigError(f"EpisodeLog.{name} must have shape {want}, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ConfigError(f"EpisodeLog.{name} must be finite")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def _check_legs(self, n: int) -> None:
        for name in ("leg_names", "spoken_legs"):
            names = tuple(getattr(self, name))
            if not all(isinstance(x, str) and x for x in names):
                raise ConfigError(f"EpisodeLog.{name} must be leg names, got {names!r}")
            object.__setattr__(self, name, names)
        if self.leg is None:
            return
        raw = np.asarray(self.leg)
        if raw.shape != (n,) or not np.all(np.isfinite(raw)) or not np.all(raw == np.round(raw)):
            raise ConfigError(f"EpisodeLog.leg must be ({n},) leg indices like t, got {raw.shape}")
        arr = raw.astype(np.int64)
        if (arr < 0).any() or (np.diff(arr) < 0).any():
            raise ConfigError("EpisodeLog.leg must be >= 0 and never decrease (the guide's leg)")
        arr.setflags(write=False)
        object.__setattr__(self, "leg", arr)

    def _check_deviation(self, n: int) -> None:
        if self.path_deviation is None:
            return
        try:
            arr = np.array(self.path_deviation, dtype=np.float64)
        except (TypeError, ValueError):
            raise ConfigError("EpisodeLog.path_deviation must be numeric") from None
        if arr.shape != (n,):
            raise ConfigError(f"EpisodeLog.path_deviation must have shape ({n},), got {arr.shape}")
        if not (np.all(np.isfinite(arr)) and np.all(arr >= 0.0)):
            raise ConfigError("EpisodeLog.path_deviation must be finite and >= 0 m")
        arr.setflags(write=False)
        object.__setattr__(self, "path_deviation", arr)

    @property
    def has_scene(self) -> bool:
        """Whether the log holds the joint positions and forces that replay the scene."""
        return self.qpos is not None and self.f_user is not None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    @property
    def am(self) -> float:
        """Actual misalignment ``t_speech - t_motion`` (s); positive: motion finished first."""
        return self.t_speech - self.t_motion

    def save_npz(self, path: str | Path) -> Path:
        """Write the log to an ``.npz`` file atomically (temp file, then rename).

        Args:
            path: Destination file; its directory must exist.

        Returns:
            The path written.
        """
        path = Path(path)
        utt = self.utterances
        payload: dict[str, Any] = {
            "format": np.array(_NPZ_FORMAT),
            "policy": np.array(self.policy),
            "user": np.array(self.user),
            "scalars": np.array([self.t_motion, self.t_speech, self.ret]),
            "utt_phrase": np.array([u.phrase for u in utt], dtype=np.str_),
            "utt_text": np.array([u.text for u in utt], dtype=np.str_),
            "utt_span": np.array([(u.t_start, u.t_end) for u in utt], dtype=np.float64).reshape(
                -1, 2
            ),
            "utt_length": np.array(
                [np.nan if u.length is None else u.length for u in utt], dtype=np.float64
            ),
            "utt_filler": np.array([u.filler for u in utt], dtype=bool),
            "utt_leg": np.array([u.leg for u in utt], dtype=np.str_),
            "leg_names": np.array(self.leg_names, dtype=np.str_),
            "spoken_legs": np.array(self.spoken_legs, dtype=np.str_),
        }
        for name in (*FLOAT_TRACES, *FLAG_TRACES):
            payload[name] = getattr(self, name)
        payload["phrase_graph"] = np.array(self.phrase_graph)
        payload["voice"] = np.array(self.voice)
        for name in (*SCENE_TRACES, "path", "leg", "path_deviation"):
            if getattr(self, name) is not None:
                payload[name] = getattr(self, name)
        fd, tmp = temp_file(path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as fh:
                _savez_fast(fh, payload)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load_npz(cls, path: str | Path) -> EpisodeLog:
        """Read a log written by :meth:`save_npz`.

        Raises:
            SessionDataError: naming the file, if it is unreadable, lacks a field or holds
                invalid data.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                fmt = int(data["format"])
                if fmt not in _NPZ_FORMATS:
                    raise SessionDataError(f"{path}: unsupported episode log format {fmt}")
                spans = data["utt_span"]
                n_utt = len(spans)
                lengths = (
                    data["utt_length"] if "utt_length" in data.files else np.full(n_utt, np.nan)
                )
                fillers = (
                    data["utt_filler"] if "utt_filler" in data.files else np.zeros(n_utt, bool)
                )
                legs = data["utt_leg"] if "utt_leg" in data.files else [""] * n_utt
                utterances = tuple(
                    Utterance(
                        str(ph),
                        str(tx),
                        float(s0),
                        float(s1),
                        None if np.isnan(ln) else float(ln),
                        bool(fl),
                        str(lg),
                    )
                    for ph, tx, (s0, s1), ln, fl, lg in zip(
                        data["utt_phrase"],
                        data["utt_text"],
                        spans,
                        lengths,
                        fillers,
                        legs,
                        strict=True,
                    )
                )
                traces = {name: data[name] for name in (*FLOAT_TRACES, *FLAG_TRACES)}
                t_motion, t_speech, ret = (float(v) for v in data["scalars"])
                scene = {n: data[n] for n in (*SCENE_TRACES, "path") if n in data.files}
                graph = str(data["phrase_graph"]) if "phrase_graph" in data.files else ""
                voice = str(data["voice"]) if "voice" in data.files else "stretch"
                leg_names, spoken = (
                    tuple(str(x) for x in data[key]) if key in data.files else ()
                    for key in ("leg_names", "spoken_legs")
                )
                return cls(
                    policy=str(data["policy"]),
                    user=str(data["user"]),
                    utterances=utterances,
                    t_motion=t_motion,
                    t_speech=t_speech,
                    ret=ret,
                    **traces,
                    **scene,
                    phrase_graph=graph,
                    voice=voice,
                    leg=data["leg"] if "leg" in data.files else None,
                    path_deviation=(
                        data["path_deviation"] if "path_deviation" in data.files else None
                    ),
                    leg_names=leg_names,
                    spoken_legs=spoken,
                )
        except SessionDataError:
            raise
        except KeyError as exc:
            raise SessionDataError(f"{path}: not an episode log, missing field {exc}") from None
        except ConfigError as exc:
            raise SessionDataError(f"{path}: invalid episode log: {exc}") from None
        except (OSError, ValueError) as exc:
            raise SessionDataError(f"{path}: cannot read episode log: {exc}") from None


def _savez_fast(fh: Any, arrays: Mapping[str, Any]) -> None:
    """``np.savez_compressed(fh, **arrays)`` at zlib level 1 instead of 6: the same ``.npz``
    format, read by ``np.load``; for episode logs about as small and 1.5x faster to write."""
    with zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


@dataclass
class EpisodeRecorder:
    """Collects per-step values and builds an :class:`EpisodeLog` at the end of an episode.

    Feed it the env's ``info`` dict after ``reset`` and after every ``step`` (keys ``time`` or
    ``t``, ``cooperation``, ``hand_speed``, ``p``, ``a``, ``t_x``, ``t_a``, ``em``,
    ``motion_done``, ``speech_done``, optionally ``phrase``, ``in_pause``, ``t_motion``,
    ``t_speech``, and the motion's ``leg``, the hand's ``path_deviation`` and the scene keys
    ``qpos`` and ``f_user``, in every sample or in none).
    Unless :meth:`build` is given the exact utterances (preferred: the speech
    timeline's ``utterances()``), they are read off the ``phrase`` key: each run of consecutive
    samples with the same non-empty phrase id, not ``in_pause``, is one utterance, from the time of
    its first sample to the time of the first sample after it (resolution: the sampling interval;
    without ``in_pause`` the pause after a phrase counts as part of it).

    Attributes:
        policy: Policy name written into the log.
        user: User name written into the log.
    """

    policy: str
    user: str
    _rows: list[list[float]] = field(default_factory=list, init=False, repr=False)
    _phrases: list[str | None] = field(default_factory=list, init=False, repr=False)
    _scene: dict[str, list[np.ndarray]] = field(default_factory=dict, init=False, repr=False)
    _legs: list[int] = field(default_factory=list, init=False, repr=False)
    _deviation: list[float] = field(default_factory=list, init=False, repr=False)
    _last: dict[str, Any] = field(default_factory=dict, init=False, repr=False)

    def append(self, info: Mapping[str, Any]) -> None:
        """Record one sample (the scene keys' arrays are copied: they may be live views).

        Raises:
            ConfigError: naming the key, if a required key is missing.
        """
        keys = _TRACES if "t" in info else _TRACE_KEYS_TIME
        try:
            self._rows.append([float(info[key]) for key in keys])
        except KeyError:
            missing = next(key for key in keys if key not in info)
            raise ConfigError(f"EpisodeRecorder.append: info lacks key {missing!r}") from None
        for name in SCENE_TRACES:
            if name in info:
                self._scene.setdefault(name, []).append(np.array(info[name], np.float32))
        if "leg" in info:
            self._legs.append(int(info["leg"]))
        if "path_deviation" in info:
            self._deviation.append(float(info["path_deviation"]))
        phrase = None if info.get("in_pause") else info.get("phrase")
        self._phrases.append(str(phrase) if phrase else None)
        self._last = dict(info)

    def extend(
        self, info: Mapping[str, np.ndarray], phrase: str | None, in_pause: bool = False
    ) -> None:
        """Record several samples at once: ``info`` maps each key :meth:`append` reads (and
        optionally the scene keys) to one value per sample (a column, or rows for the scene
        keys), all with the same phrase (e.g. :attr:`langenv.compiled_steps.LawSteps.info`).

        Raises:
            ConfigError: naming the key, if a required key is missing or the lengths differ.
        """
        keys = _TRACES if "t" in info else _TRACE_KEYS_TIME
        missing = [key for key in keys if key not in info]
        if missing:
            raise ConfigError(f"EpisodeRecorder.extend: info lacks key {missing[0]!r}")
        columns = [np.asarray(info[key], dtype=np.float64) for key in keys]
        n = len(columns[0])
        if any(c.shape != (n,) for c in columns):
            raise ConfigError("EpisodeRecorder.extend: every column must have shape (n,)")
        scene = {name: np.array(info[name], np.float32) for name in SCENE_TRACES if name in info}
        for name, rows in scene.items():
            if rows.ndim != 2 or rows.shape[0] != n:
                raise ConfigError(
                    f"EpisodeRecorder.extend: {name} must have {n} rows, got shape {rows.shape}"
                )
        if n == 0:
            return
        self._rows.extend(np.stack(columns, axis=1).tolist())
        for name, rows in scene.items():
            self._scene.setdefault(name, []).extend(rows)
        if "leg" in info:
            self._legs.extend(np.asarray(info["leg"]).astype(np.int64).tolist())
        if "path_deviation" in info:
            self._deviation.extend(np.asarray(info["path_deviation"], np.float64).tolist())
        said = None if in_pause else phrase
        self._phrases.extend([str(said) if said else None] * n)
        self._last.update((key, float(c[-1])) for key, c in zip(keys, columns, strict=True))
        self._last.update(phrase=phrase, in_pause=in_pause)

    def __len__(self) -> int:
        return len(self._phrases)

    def build(
        self,
        ret: float,
        *,
        texts: Mapping[str, str] | None = None,
        fillers: Collection[str] = (),
        t_motion: float | None = None,
        t_speech: float | None = None,
        utterances: Sequence[Any] | None = None,
        phrase_graph: str = "",
        path: np.ndarray | None = None,
        voice: str = "stretch",
        leg_of: Mapping[str, str | None] | None = None,
        leg_names: Sequence[str] = (),
        spoken_legs: Sequence[str] = (),
    ) -> EpisodeLog:
        """The log of the recorded samples.

        Args:
            ret: Episode return.
            texts: Phrase id -> text, for the utterance labels (empty text when absent).
            fillers: Ids of the graph's filler vertices (their utterances are marked).
            t_motion: Motion end (s); default: the last sample's ``t_motion`` key, else the time
                of the first sample with ``motion_done``.
            t_speech: Speech end (s); same defaults with ``t_speech`` / ``speech_done``.
            utterances: The phrases said with exact times, as objects with ``phrase``,
                ``t_start``, ``t_end`` and optionally ``length`` (a pause vertex's; e.g.
                ``SpeechTimeline.utterances()``); default: read off the recorded ``phrase`` key.
            phrase_graph: The phrase graph spoken (see :attr:`EpisodeLog.phrase_graph`).
            path: The exercise path drawn in videos, shape ``(m, 3)`` (m).
            voice: How the graph voices the speech pace (see :attr:`EpisodeLog.voice`).
            leg_of: Vertex id -> the leg it speaks about (:meth:`PhraseGraph.leg
                <langenv.speech.graph.PhraseGraph.leg>`), for the utterances' ``leg``.
            leg_names: The motion's legs (:attr:`EpisodeLog.leg_names`).
            spoken_legs: The legs the graph has words for (:attr:`EpisodeLog.spoken_legs`).

        Raises:
            ConfigError: if fewer than two samples were recorded, a completion time is unknown,
                or a scene key or ``leg`` was given in some samples only.
        """
        if len(self) < 2:
            raise ConfigError(f"EpisodeRecorder.build needs >= 2 samples, got {len(self)}")
        columns = np.array(self._rows, dtype=np.float64).T
        v = dict(zip(_TRACES, columns, strict=True))
        t = v["t"]
        said = self._said(t, texts or {}, fillers, utterances, leg_of)
        for key, values in (("leg", self._legs), ("path_deviation", self._deviation)):
            if values and len(values) != len(self):
                raise ConfigError(
                    f"EpisodeRecorder.build: info had key {key!r} in {len(values)} of "
                    f"{len(self)} samples (give it in every sample or in none)"
                )

        flags = {name: v[name].astype(bool) for name in FLAG_TRACES}
        floats = {name: v[name] for name in FLOAT_TRACES}
        scene: dict[str, np.ndarray] = {}
        for name, rows in self._scene.items():
            if len(rows) != len(self):
                raise ConfigError(
                    f"EpisodeRecorder.build: info had key {name!r} in {len(rows)} of "
                    f"{len(self)} samples (give it in every sample or in none)"
                )
            scene[name] = np.stack(rows)
        return EpisodeLog(
            policy=self.policy,
            user=self.user,
            utterances=tuple(said),
            t_motion=self._end_time(t_motion, "t_motion", "motion_done", v),
            t_speech=self._end_time(t_speech, "t_speech", "speech_done", v),
            ret=float(ret),
            **floats,
            **flags,
            **scene,
            path=path,
            phrase_graph=phrase_graph,
            voice=voice,
            leg=np.array(self._legs, np.int64) if self._legs else None,
            leg_names=tuple(leg_names),
            spoken_legs=tuple(spoken_legs),
            path_deviation=np.array(self._deviation) if self._deviation else None,
        )

    def _said(
        self,
        t: np.ndarray,
        texts: Mapping[str, str],
        fillers: Collection[str],
        utterances: Sequence[Any] | None,
        leg_of: Mapping[str, str | None] | None,
    ) -> list[Utterance]:
        """The utterances: ``utterances`` given (labelled with ``texts``, fillers marked), else
        read off the recorded ``phrase`` key; each with its leg from ``leg_of``."""
        if utterances is not None:
            said = [
                Utterance(
                    str(u.phrase),
                    "" if getattr(u, "length", None) is not None else texts.get(str(u.phrase), ""),
                    u.t_start,
                    u.t_end,
                    getattr(u, "length", None),
                    str(u.phrase) in fillers,
                )
                for u in utterances
            ]
        else:
            said = self._phrase_runs(t, texts)
        if leg_of:
            said = [replace(u, leg=leg_of.get(u.phrase) or "") for u in said]
        return said

    def _end_time(
        self, given: float | None, key: str, flag: str, v: Mapping[str, np.ndarray]
    ) -> float:
        """An end time: ``given``, else the last sample's ``key``, else the time from which the
        ``flag`` trace (in ``v``, with ``t``) stays set (a speech may end, then go on)."""
        if given is not None:
            return float(given)
        last = self._last.get(key)
        if last is not None and math.isfinite(float(last)):
            return float(last)
        done = v[flag].astype(bool)
        if not done.size or not done[-1]:
            raise ConfigError(f"EpisodeRecorder.build: {key} unknown ({flag} not set at the end)")
        unset = np.flatnonzero(~done)
        return float(v["t"][int(unset[-1]) + 1 if unset.size else 0])

    def _phrase_runs(self, t: np.ndarray, texts: Mapping[str, str]) -> list[Utterance]:
        """One utterance per run of samples with the same non-empty phrase id."""
        utterances: list[Utterance] = []
        k = 0
        while k < len(self._phrases):
            ph = self._phrases[k]
            j = k + 1
            while j < len(self._phrases) and self._phrases[j] == ph:
                j += 1
            if ph is not None:
                t_end = float(t[j]) if j < len(t) else float(t[-1])
                utterances.append(Utterance(ph, texts.get(ph, ""), float(t[k]), t_end))
            k = j
        return utterances
