"""The grid of a constant-orientation workspace (:func:`default_grid`): kept apart from the
solver so that the grid of a study can be checked without loading the solvers."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_grid

__all__ = ["default_grid"]


def default_grid(mech: Any, step: float | None = None, bounds: ArrayLike | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Grid from ``bounds = (x0, x1, y0, y1)`` (default: the box of the legs' origins, grown
    by a quarter of the rods' length) and ``step`` (default: 1/100 of the box's larger side).

    Parameters
    ----------
    mech : Mechanism
        The mechanism (legs' origins and rod lengths for the default box).
    step : float, optional
        Grid step (m).
    bounds : (x0, x1, y0, y1), optional
        Grid box (m).

    Returns
    -------
    x, y : ndarray
        Grid coordinates (m).
    """
    if bounds is None:
        o = np.array([leg.origin for leg in mech.legs], dtype=float)
        L = max((leg.rod.length or 0.0) for leg in mech.legs) or float(mech.length_scale)
        lo, hi = o.min(0) - 0.25 * L, o.max(0) + 0.25 * L
        bounds = (lo[0], hi[0], lo[1], hi[1])
    b, step, nx, ny = check_grid(bounds, step)
    return b[0] + step * np.arange(nx), b[2] + step * np.arange(ny)
