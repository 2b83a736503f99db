"""argparse type converters shared by every flexkin command line (``flexkin``, ``explore``,
``study``, ``calibrate``).

A converter raises :class:`argparse.ArgumentTypeError` with what is wrong with the text;
argparse puts the option's name in front (``argument --load: expected a number, got 'x'``),
so the message is one line that names the option.  The ranges are those of
:mod:`flexkin.core.validation` (the d-mode limit :data:`~flexkin.core.validation.MAX_MODE_LIMIT`).
"""

from __future__ import annotations

import argparse
import math
from typing import Callable

from .validation import MAX_MODE_LIMIT, MAX_WINDING_LIMIT

__all__ = ["finite", "positive", "integer_in", "max_mode", "max_winding", "count"]


def finite(text: str) -> float:
    """A finite number.

    Parameters
    ----------
    text : str
        The command-line word, e.g. ``"-1e-3"``.

    Returns
    -------
    float
        The number (``nan`` and ``inf`` are refused).
    """
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def positive(text: str) -> float:
    """A finite number > 0 (a length, a stiffness, a number of seconds).

    Parameters
    ----------
    text : str
        The command-line word.

    Returns
    -------
    float
        The number, > 0.
    """
    v = finite(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def integer_in(lo: int, hi: int) -> Callable[[str], int]:
    """A converter to an integer in ``[lo, hi]``.

    Parameters
    ----------
    lo, hi : int
        The smallest and largest value accepted.

    Returns
    -------
    callable
        ``str -> int``.
    """
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must be between {lo} and {hi}, got {v}")
        return v

    conv.__name__ = f"integer in [{lo}, {hi}]"
    return conv


#: the largest d-mode searched: an integer from 1 to MAX_MODE_LIMIT
max_mode = integer_in(1, MAX_MODE_LIMIT)
max_winding = integer_in(0, MAX_WINDING_LIMIT)
#: a number of steps, points or jobs: an integer from 1 to 100000 (core.validation.check_count)
count = integer_in(1, 100_000)
