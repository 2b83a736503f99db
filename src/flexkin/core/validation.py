"""Validation of arguments at the public API boundary (done once, there).

Every check raises :class:`ValueError` with a message that names the argument and says what
was expected; library code below the boundary trusts its inputs.
"""

from __future__ import annotations

import difflib
import math
import os
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["read_text_file", "as_triple", "as_pair", "check_max_mode", "check_max_winding", "check_budget", "check_positive", "check_count",
           "check_angle_deg", "angle_note", "check_grid", "short_text", "MAX_MODE_LIMIT", "ANGLE_LIMIT_DEG",
           "MAX_GRID_POINTS", "KeyPathError", "type_name", "suggest_key", "key_text", "check_table_keys",
           "file_number", "file_choice", "as_load"]

#: largest d-mode any search accepts
MAX_MODE_LIMIT = 6
#: largest |winding| of a clamped rod any search accepts (SPEC §2)
MAX_WINDING_LIMIT = 4
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


def as_load(mech: Any, load: ArrayLike | None) -> NDArray[np.float64]:
    """The load wrench ``(Fx, Fy, Mz)`` (N, N, N m): ``load`` if given, else the mechanism
    file's ``[load]``.

    Parameters
    ----------
    mech : Mechanism
        The mechanism (its ``load``).
    load : array_like of 3 floats, optional
        The load given to a solver.

    Returns
    -------
    ndarray (3,)
    """
    return as_triple(mech.load if load is None else load, "load (Fx, Fy, Mz)")


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


def check_max_winding(max_winding: Any) -> int:
    """An integer winding bound between 0 and :data:`MAX_WINDING_LIMIT` (clamped rods, SPEC §2)."""
    if isinstance(max_winding, bool) or not isinstance(max_winding, (int, np.integer)) \
            or not 0 <= max_winding <= MAX_WINDING_LIMIT:
        raise ValueError(f"max_winding must be an integer between 0 and {MAX_WINDING_LIMIT}, got {max_winding!r}")
    return int(max_winding)


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


# ---- key paths of the input files (mechanism and study TOML) ----------------------------------
class KeyPathError(ValueError):
    """A problem at a key path of an input file; the loaders add the file's name.

    Parameters
    ----------
    path : str
        The key path (``"leg[2].origin"``; empty for the file's top level).
    problem : str
        What is wrong there.
    """

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}" if path else problem)
        self.path = path
        self.problem = problem


def type_name(value: Any) -> str:
    """``value``'s TOML kind with an article (``"a table"``, ``"a number"``, ...), for messages."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, (int, float)):
        return "a number"
    return f"a {type(value).__name__}"


def _edit_distance(a: str, b: str) -> int:
    """Optimal-string-alignment distance (insertions, deletions, substitutions, transpositions)."""
    prev2: list[int] = []
    prev = list(range(len(b) + 1))
    for i in range(1, len(a) + 1):
        cur = [i] + [0] * len(b)
        for j in range(1, len(b) + 1):
            cost = 0 if a[i - 1] == b[j - 1] else 1
            cur[j] = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost)
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                cur[j] = min(cur[j], prev2[j - 2] + 1)
        prev2, prev = prev, cur
    return prev[-1]


#: keys longer than this are not compared with the allowed ones (no allowed key is anywhere
#: near; a megabyte-long key would take a minute of edit distances) and are shown cut
SUGGEST_MAX_LEN = 64


def suggest_key(key: str, allowed: tuple[str, ...] | list[str]) -> str | None:
    """The allowed key ``key`` is most likely a misspelling of, or None.

    Case is ignored; a key within one edit (two for keys of five or more characters) of an
    allowed key it shares a letter with, or similar to it by difflib's ratio (>= 0.6, as
    :func:`difflib.get_close_matches`), is a candidate; the closest candidate wins.  Keys
    longer than :data:`SUGGEST_MAX_LEN` characters get no suggestion.
    """
    if len(key) > SUGGEST_MAX_LEN:
        return None
    k = key.lower()
    best: tuple[int, float, str] | None = None
    for a in allowed:
        d = _edit_distance(k, a.lower())
        ratio = difflib.SequenceMatcher(None, k, a.lower()).ratio()
        near = d <= (2 if min(len(a), len(k)) >= 5 else 1) and bool(set(k) & set(a.lower()))
        if near or ratio >= 0.6:
            cand = (d, -ratio, a)
            if best is None or cand < best:
                best = cand
    return None if best is None else best[2]


def key_text(key: Any) -> str:
    """A key as written in a key path: bare if it is a plain TOML bare key, quoted otherwise;
    a long key is cut (its length is given)."""
    key = str(key)
    if len(key) > SUGGEST_MAX_LEN:
        return short_text(key)
    if key and all(c.isascii() and (c.isalnum() or c in "_-") for c in key):
        return key
    return repr(key)


def check_table_keys(table: Mapping[str, Any], allowed: tuple[str, ...], path: str) -> None:
    """Reject the first key of ``table`` not in ``allowed`` (:class:`KeyPathError` naming it,
    with a did-you-mean hint and the allowed keys)."""
    for key in table:
        if key in allowed:
            continue
        close = suggest_key(str(key), allowed)
        hint = f" (did you mean {close!r}?)" if close else ""
        shown = key_text(key)
        raise KeyPathError(f"{path}.{shown}" if path else shown,
                           f"unknown key{hint}; allowed keys here: {', '.join(allowed)}")


def file_number(value: Any, path: str) -> float:
    """A finite number read from an input file at key path ``path``, or :class:`KeyPathError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise KeyPathError(path, f"expected a number, got {type_name(value)} {short_text(value)}")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond the float range
        raise KeyPathError(path, "expected a finite number, got an integer too large for a float "
                                 f"({short_text(value)})") from None
    if not math.isfinite(v):
        raise KeyPathError(path, f"expected a finite number, got {v!r}")
    return v


def file_choice(value: Any, choices: tuple[str, ...], path: str, what: str) -> str:
    """One of the names ``choices`` read from an input file at ``path`` (``what`` names the kind,
    e.g. ``"actuation"``), or :class:`KeyPathError` with a did-you-mean hint."""
    if not isinstance(value, str):
        raise KeyPathError(path, f"expected a string, got {type_name(value)} {short_text(value)}")
    if value not in choices:
        close = difflib.get_close_matches(value.lower(), choices, n=1, cutoff=0.5) \
            if len(value) <= SUGGEST_MAX_LEN else []
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise KeyPathError(path, f"unknown {what} {short_text(value)} (expected one of "
                                 f"{', '.join(map(repr, choices))}{hint})")
    return value


def read_text_file(path: Any, kind: str, error: type[Exception], max_bytes: int) -> tuple[str, str]:
    """``(source, text)`` of an input file (mechanism, study, measurements), read once with
    errors that name the file: missing, a directory, unreadable, larger than ``max_bytes``, or
    not UTF-8 (a leading byte-order mark, as Windows editors write, is accepted).

    Parameters
    ----------
    path : str or path-like
        The file.
    kind : str
        What the file should be, for the messages (``"mechanism file"``).
    error : type of Exception
        The error raised, with a one-line message starting with the file name.
    max_bytes : int
        Largest size accepted.

    Returns
    -------
    (str, str)
        The file name as given and its text.
    """
    src = os.fspath(path)
    try:
        with open(src, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except FileNotFoundError:
        raise error(f"{src}: file not found") from None
    except IsADirectoryError:
        raise error(f"{src}: is a directory, not a {kind}") from None
    except OSError as exc:
        raise error(f"{src}: cannot read file ({exc.strerror or exc})") from None
    if len(raw) > max_bytes:
        raise error(f"{src}: file too large for a {kind} (more than {max_bytes} bytes)")
    try:
        return src, raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{src}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
