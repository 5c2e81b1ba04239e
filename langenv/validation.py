"""Input checks shared by the package's constructors and entry points."""

from __future__ import annotations

import difflib
import io
import math
import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from langenv.errors import ConfigError

__all__ = [
    "MAX_SESSION_S",
    "MIN_SAMPLE_SPACING",
    "as_vec3",
    "as_vector",
    "check_rates",
    "check_render_mode",
    "check_time_axis",
    "child_blocks",
    "dataclass_from_dict",
    "finite_positive",
    "frozen_vector",
    "non_negative",
    "pixels",
    "session_length",
    "suggest",
    "yaml_text",
]

MAX_SESSION_S = 600.0
"""Longest time span (s) of a session CSV or speech trace: 10 minutes, ten times the env's
60 s episodes. It bounds what a replay or a rendering allocates (a 2 ms force table, an audio
buffer) before any of it is made."""

MIN_SAMPLE_SPACING = 1e-4
"""Smallest spacing (s) between two samples of a session CSV or speech trace (10 kHz). Sparse
samples are fine (values are interpolated in between)."""


T = TypeVar("T")


def yaml_text(text: str, path: str | Path) -> io.StringIO:
    """``text`` as a stream named ``path``, for ``yaml.safe_load`` and ``yaml.compose``: their
    errors then say where (``in "FILE", line L, column C``), not ``"<unicode string>"``."""
    stream = io.StringIO(text)
    stream.name = str(path)
    return stream


def suggest(word: str, known: Iterable[str]) -> str:
    """``" (did you mean 'X'?)"`` for the known name closest to a mistyped ``word``, or ``""``."""
    close = difflib.get_close_matches(str(word), sorted(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def dataclass_from_dict(cls: type[T], data: object, where: str) -> T:
    """The frozen dataclass ``cls`` built from plain data (a config's mapping of its fields).

    Raises:
        ConfigError: naming ``where``, for data that is not a mapping, an unknown field, or a
            field that ``cls`` refuses (its own message, prefixed with ``where``).
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - {f.name for f in fields(cls)})  # type: ignore[arg-type]
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {', '.join(unknown)}")
    try:
        built: Any = cls(**data)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return built


def as_vector(
    value: ArrayLike, name: str, error: type[Exception], n: int | None = None
) -> NDArray[np.float64]:
    """``value`` as a finite, contiguous float64 vector of shape ``(n,)`` (any length if None).

    Args:
        value: Anything numpy can turn into a vector of numbers.
        name: The argument or field, named in the error message.
        error: Exception type to raise (the package's own, e.g. ``ConfigError``).
        n: The length required, or None.

    Returns:
        A new or the given float64 array.

    Raises:
        error: if ``value`` is not a vector of ``n`` finite numbers.
    """
    what = f"a {n}-vector" if n is not None else "a vector"
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be {what} of numbers, got {value!r}") from exc
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        want = f"({n},)" if n is not None else "(n,)"
        raise error(f"{name} must have shape {want}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise error(f"{name} must be finite, got {arr.tolist()}")
    return np.ascontiguousarray(arr)


def frozen_vector(
    value: ArrayLike, name: str, error: type[Exception], n: int | None = None
) -> NDArray[np.float64]:
    """:func:`as_vector`, as a read-only copy of its own (a frozen dataclass's field)."""
    arr = np.array(as_vector(value, name, error, n))
    arr.setflags(write=False)
    return arr


def as_vec3(value: ArrayLike, name: str, error: type[Exception]) -> NDArray[np.float64]:
    """:func:`as_vector` of length 3."""
    return as_vector(value, name, error, 3)


def finite_positive(
    name: str, value: float, error: type[Exception], *, allow_zero: bool = False
) -> float:
    """A scalar argument checked to be a finite number > 0 (or >= 0 with ``allow_zero``).

    Args:
        name: The argument, named in the error message.
        value: The value.
        error: Exception type to raise (the package's own, e.g. ``ConfigError``).
        allow_zero: Accept 0.

    Returns:
        ``value`` as float.

    Raises:
        error: if not a number, not finite, negative, or zero when not allowed.
    """
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise error(f"{name} must be finite and {bound}, got {value!r}")
    return v


def check_time_axis(
    t: NDArray[np.float64],
    where: str,
    error: type[Exception],
    at: Callable[[int], str] = lambda i: f"sample {i}",
    *,
    from_zero: bool = True,
) -> None:
    """Check a finite, strictly increasing time axis for a sane range and sampling.

    Args:
        t: Sample times (n,), s, finite and strictly increasing (checked by the caller).
        where: What holds it (a file name, an argument), named in the message.
        error: Exception type to raise (the package's own).
        at: Names sample ``i`` in messages (e.g. ``"line 5"``).
        from_zero: Times are since the session started: ``t[0] >= 0`` and ``t[-1] <=``
            :data:`MAX_SESSION_S`; otherwise only the span ``t[-1] - t[0]`` is bounded.

    Raises:
        error: a negative start (``from_zero``), a span beyond :data:`MAX_SESSION_S`, or two
            samples closer than :data:`MIN_SAMPLE_SPACING`.
    """
    first, last = float(t[0]), float(t[-1])
    if from_zero and first < 0.0:
        raise error(
            f"{where}: column 't' must start at or after 0 s (time since the session started), "
            f"but {at(0)} has t={first!r}"
        )
    span = last if from_zero else last - first
    if not span <= MAX_SESSION_S or not math.isfinite(span):
        what = f"ends at t={last!r} s" if from_zero else f"spans {span!r} s"
        raise error(
            f"{where}: column 't' {what}, beyond the {MAX_SESSION_S:g} s maximum session length "
            "(are the times in seconds?)"
        )
    gaps = np.diff(t)
    i = int(np.argmin(gaps))
    gap = float(gaps[i])
    if gap < MIN_SAMPLE_SPACING:
        raise error(
            f"{where}: column 't' has samples {gap:.3g} s apart ({at(i)} and {at(i + 1)}), "
            f"closer than the {MIN_SAMPLE_SPACING:g} s minimum spacing (are the times in seconds?)"
        )


def non_negative(name: str, value: Any) -> float:
    """A finite number >= 0, or :class:`ConfigError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ConfigError(f"{name} must be finite and >= 0, got {value!r}")
    return v


def session_length(value: Any, hz: int) -> tuple[float | None, int | None]:
    """``max_seconds`` checked, and its ticks at ``hz`` (rounded up): ``(None, None)`` for no
    limit."""
    if value is None:
        return None, None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f"max_seconds must be a number of seconds or None, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ConfigError(f"max_seconds must be finite and > 0 (s), got {value!r}")
    return v, math.ceil(round(v * hz, 6))


def pixels(name: str, value: Any) -> int:
    """A positive integer (a render size), or :class:`ConfigError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ConfigError(f"{name} must be a positive integer (pixels), got {value!r}")
    return int(value)


def check_rates(decision_hz: Any, choice_mode: Any, hz: int) -> None:
    """The env's ``decision_hz`` a positive integer dividing ``hz`` and ``choice_mode`` a mode, or
    :class:`ConfigError` naming them."""
    if (
        isinstance(decision_hz, bool)
        or not isinstance(decision_hz, int | np.integer)
        or decision_hz <= 0
        or hz % int(decision_hz)
    ):
        raise ConfigError(
            f"decision_hz must be a positive integer dividing {hz}, got {decision_hz!r}"
        )
    if choice_mode not in ("target", "scores"):
        raise ConfigError(f"choice_mode must be 'target' or 'scores', got {choice_mode!r}")


def child_blocks(largest: int, max_children: Any) -> int:
    """The observation's child blocks: at least the graph's ``largest`` out-degree (and 1);
    ``max_children`` checked."""
    blocks = max(1, largest)
    if max_children is None:
        return blocks
    if isinstance(max_children, bool) or not isinstance(max_children, numbers.Integral):
        raise ConfigError(f"max_children must be an int, got {max_children!r}")
    if max_children < blocks:
        raise ConfigError(
            f"max_children must be >= the graph's largest out-degree {blocks}, got {max_children}"
        )
    return int(max_children)


def check_render_mode(render_mode: Any) -> None:
    """The env's ``render_mode``: None or ``"rgb_array"``, or :class:`ConfigError` saying how
    to get a window."""
    if render_mode is None or render_mode == "rgb_array":
        return
    hint = ""
    if render_mode == "human":
        hint = (
            "; LangCtrl-v0 renders off-screen: for a window, wrap an env made with "
            "render_mode='rgb_array' in gymnasium.wrappers.HumanRendering (needs pygame)"
        )
    raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}{hint}")
