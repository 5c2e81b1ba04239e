"""The action a policy gives the env: its values checked and read (the single env's and a
batch's), with one tolerance for ``[-1, 1]``. What the values mean (pace commands, the
phrase choice) is the env's docstring's "Action space"."""

from __future__ import annotations

from typing import Any

import numpy as np

from langenv.errors import ActionError

__all__ = ["BOUND", "parse_action", "parse_actions"]

BOUND = 1.000001
"""An action's values lie in ``[-BOUND, BOUND]``: ``[-1, 1]`` with float32's rounding."""

_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))  # actions taken as they are


def parse_action(action: Any, shape: tuple[int, ...]) -> list[float]:
    """``action``'s values (of ``shape``) as floats, each in ``[-1, 1]``.

    Raises:
        ActionError: ``None``, a string or mapping, not numbers, another shape, a value outside
            ``[-1, 1]`` or NaN, each said with what was given.
    """
    values = _values(action, shape)
    for v in values:
        if not -BOUND <= v <= BOUND:  # also rejects NaN
            raise ActionError(f"action must be finite and lie in [-1, 1], got {values}")
    return values


def _values(action: Any, shape: tuple[int, ...]) -> list[float]:
    """``action``'s values (of ``shape``) as floats, or :class:`ActionError`."""
    if type(action) is np.ndarray and action.dtype in _FLOAT_DTYPES and action.shape == shape:
        return action.tolist()  # the common case, without a float64 copy
    if action is None:
        raise ActionError(
            f"action is None; pass an array of shape {shape} with values in [-1, 1] "
            "(env.action_space.sample() gives one)"
        )
    if isinstance(action, str | bytes | dict):
        raise ActionError(
            f"action must be an array of shape {shape} with values in [-1, 1], "
            f"got a {type(action).__name__}: {action!r:.80}"
        )
    try:
        act = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ActionError(
            f"action must be an array of shape {shape} of numbers in [-1, 1], "
            f"got {action!r:.80} ({exc})"
        ) from None
    if act.shape != shape:
        raise ActionError(f"action must have shape {shape}, got shape {act.shape}")
    values: list[float] = act.tolist()
    return values


def parse_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """A batch's ``actions`` as float64 of ``shape`` (sessions first), each in ``[-1, 1]`` as
    :func:`parse_action` has it.

    Raises:
        ActionError: not numbers, another shape, or naming the first session with a bad value.
    """
    try:
        act = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ActionError(
            f"actions must be an array of shape {shape} of numbers, got {actions!r:.80} ({exc})"
        ) from None
    if act.shape != shape:
        raise ActionError(f"actions must have shape {shape}, got shape {act.shape}")
    ok = (act >= -BOUND) & (act <= BOUND)  # also rejects NaN
    if not ok.all():
        i = int(np.flatnonzero(~ok.reshape(shape[0], -1).all(axis=1))[0])
        raise ActionError(
            f"session {i}: action must be finite and lie in [-1, 1], got {act[i].tolist()}"
        )
    return act
