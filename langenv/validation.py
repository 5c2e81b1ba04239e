"""Input checks shared by the package's constructors and entry points."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["as_vec3"]


def as_vec3(value: ArrayLike, name: str, error: type[Exception]) -> NDArray[np.float64]:
    """``value`` as a finite, contiguous float64 array of shape (3,).

    Args:
        value: Anything numpy can turn into three numbers.
        name: The argument or field, named in the error message.
        error: Exception type to raise (the package's own, e.g. ``ConfigError``).

    Returns:
        A new or the given float64 array, shape (3,).

    Raises:
        error: if ``value`` is not three finite numbers.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be a 3-vector of numbers, got {value!r}") from exc
    if arr.shape != (3,):
        raise error(f"{name} must have shape (3,), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise error(f"{name} must be finite, got {arr.tolist()}")
    return np.ascontiguousarray(arr)
