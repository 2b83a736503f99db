"""Validation of arguments at the public API boundary (done once, there).

Every check raises :class:`ValueError` with a message that names the argument and says what
was expected; library code below the boundary trusts its inputs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["as_triple", "as_pair", "check_max_mode", "check_budget", "check_positive", "check_count",
           "MAX_MODE_LIMIT"]

#: largest d-mode any search accepts
MAX_MODE_LIMIT = 6


def as_triple(value: ArrayLike, what: str) -> NDArray[np.float64]:
    """Three finite numbers as a float array, or a ValueError naming ``what``."""
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}")
    return a


def as_pair(value: ArrayLike, what: str) -> NDArray[np.float64]:
    """Two finite numbers as a float array, or a ValueError naming ``what``."""
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be two finite numbers, got {value!r}") from None
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be two finite numbers, got {value!r}")
    return a


def check_max_mode(max_mode: Any) -> int:
    """An integer d-mode between 1 and :data:`MAX_MODE_LIMIT`."""
    if isinstance(max_mode, bool) or not isinstance(max_mode, (int, np.integer)) \
            or not 1 <= max_mode <= MAX_MODE_LIMIT:
        raise ValueError(f"max_mode must be an integer between 1 and {MAX_MODE_LIMIT}, got {max_mode!r}")
    return int(max_mode)


def check_budget(budget: Any) -> float:
    """A positive finite number of seconds."""
    try:
        b = float(budget)
    except (TypeError, ValueError):
        raise ValueError(f"time_budget must be a number of seconds > 0, got {budget!r}") from None
    if not (math.isfinite(b) and b > 0):
        raise ValueError(f"time_budget must be a number of seconds > 0, got {budget!r}")
    return b


def check_positive(value: Any, what: str, limits: tuple[float, float] | None = None, unit: str = "") -> float:
    """A finite number > 0 (and within ``limits`` when given)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(value)) or not float(value) > 0:
        raise ValueError(f"{what} must be a finite number > 0, got {value!r}")
    v = float(value)
    if limits is not None and not limits[0] <= v <= limits[1]:
        u = f" {unit}" if unit else ""
        raise ValueError(f"{what} = {v:g}{u} is outside the supported range [{limits[0]:g}, {limits[1]:g}]{u}")
    return v


def check_count(value: Any, what: str, lo: int = 1, hi: int = 100_000) -> int:
    """An integer in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{what} must be an integer between {lo} and {hi}, got {value!r}")
    return int(value)
