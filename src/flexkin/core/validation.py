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
           "check_angle_deg", "angle_note", "check_grid", "short_text", "MAX_MODE_LIMIT", "ANGLE_LIMIT_DEG",
           "MAX_GRID_POINTS"]

#: largest d-mode any search accepts
MAX_MODE_LIMIT = 6
#: largest magnitude of an angle given in degrees (files, command line): 2778 turns.  No
#: orientation or input of a mechanism needs more, and far beyond it an angle loses its meaning
#: to rounding (at 1e16 deg one unit in the last place exceeds a degree; 1e300 deg is a mistake)
ANGLE_LIMIT_DEG = 1e6
#: largest number of points of a workspace grid
MAX_GRID_POINTS = 4_000_000


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


def short_text(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to about ``limit`` characters (a megabyte of user text is never echoed)."""
    try:
        s = repr(value) if not isinstance(value, str) or len(value) <= 4 * limit else repr(value[:4 * limit])
    except (ValueError, RecursionError):  # integers with thousands of digits, deep nesting
        return f"<{type(value).__name__} too large to show>"
    if len(s) <= limit:
        return s
    n = len(value) if isinstance(value, (str, bytes, list, tuple, dict)) else None
    return s[:limit - 3] + "..." + (f" ({n} characters)" if isinstance(value, str) else
                                    f" ({n} items)" if n is not None else "")


def check_angle_deg(value: float, what: str) -> float:
    """An angle in degrees within +-:data:`ANGLE_LIMIT_DEG` (ValueError naming ``what`` otherwise)."""
    v = float(value)
    if not (math.isfinite(v) and abs(v) <= ANGLE_LIMIT_DEG):
        raise ValueError(f"{what + ' = ' if what else ''}{v:g} deg is outside the supported range "
                         f"+-{ANGLE_LIMIT_DEG:g} deg ({ANGLE_LIMIT_DEG / 360:.0f} turns): not a meaningful angle")
    return v


def angle_note(value: float, what: str) -> str | None:
    """A warning text when an angle in degrees is more than a full turn (one orientation or
    input, not a range or a path), else None."""
    v = float(value)
    if abs(v) <= 360.0:
        return None
    eq = math.remainder(v, 360.0)
    return f"{what} = {v:g} deg is more than a full turn: it is the same as {eq:.6g} deg"


def check_grid(bounds: ArrayLike, step: float | None) -> tuple[NDArray[np.float64], float, int, int]:
    """Validated workspace grid box ``(x0, x1, y0, y1)`` and step (default: 1/100 of the box's
    larger side): the box, the step and the number of points per side (at least 2 each, at most
    :data:`MAX_GRID_POINTS` in all)."""
    b = np.asarray(bounds, dtype=float).reshape(-1)
    if b.shape != (4,) or not np.all(np.isfinite(b)) or b[1] <= b[0] or b[3] <= b[2]:
        raise ValueError(f"bounds must be four finite numbers x0 < x1, y0 < y1, got {short_text(bounds)}")
    if step is None:
        step = max(b[1] - b[0], b[3] - b[2]) / 100.0
    try:
        step = float(step)
    except (TypeError, ValueError):
        raise ValueError(f"step must be a finite number > 0, got {short_text(step)}") from None
    if not np.isfinite(step) or step <= 0:
        raise ValueError(f"step must be a finite number > 0, got {step!r}")
    w, h = b[1] - b[0], b[3] - b[2]
    if step > min(w, h):
        raise ValueError(f"step = {step:g} m is larger than the grid box ({w:g} m x {h:g} m): the grid needs at "
                         f"least two points per side; give a step of at most {min(w, h):g} m")
    nx = int(np.floor(w / step + 1e-9)) + 1
    ny = int(np.floor(h / step + 1e-9)) + 1
    if nx * ny > MAX_GRID_POINTS:
        raise ValueError(f"step = {step:g} m gives a grid of {nx} x {ny} points, too large (at most "
                         f"{MAX_GRID_POINTS:,} points): increase the step or shrink the bounds")
    return b, step, nx, ny


def check_count(value: Any, what: str, lo: int = 1, hi: int = 100_000) -> int:
    """An integer in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{what} must be an integer between {lo} and {hi}, got {value!r}")
    return int(value)
