"""JSON-ready values: the JSON contract (SPEC §4) never carries NaN or infinity.

Every ``to_dict`` of the result objects turns its floats and matrices into JSON values with these
helpers, so that a non-finite number becomes ``null`` in one place.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["finite_or_none", "finite_matrix"]


def finite_or_none(v: Any) -> float | None:
    """``float(v)`` if finite, else ``None`` (the JSON contract never carries NaN).

    Parameters
    ----------
    v : float-like or None
        The value.

    Returns
    -------
    float or None
    """
    if v is None:
        return None
    v = float(v)
    return v if np.isfinite(v) else None


def finite_matrix(a: NDArray | None) -> list[list[float]] | None:
    """A matrix as nested lists, or ``None`` if it is missing or has a non-finite entry.

    Parameters
    ----------
    a : ndarray or None
        The matrix.

    Returns
    -------
    list of list of float, or None
    """
    return None if a is None or not np.all(np.isfinite(a)) else np.asarray(a).tolist()
