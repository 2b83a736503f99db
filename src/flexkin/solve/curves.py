"""Geometric-condition curves of the inverse kinematics (paper §4.1, Figs. 5, 7–9).

For a given platform pose each leg's attach point ``B_i`` is known, and the rods that can
reach it form a one-parameter family: a curve in the rod's parameter space, one
:class:`~flexkin.solve.leg_curve.LegCurve` per leg.  :func:`leg_curves` sends each leg to the
builder of its platform joint: :func:`flexkin.solve.pinned_curves.pinned_leg_curve` (level sets
on the atlas) or :func:`flexkin.solve.clamped_curves.clamped_leg_curve` (curves traced in the
rod's wrench chart).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import NDArray

from ..core.budget import Deadline
from .clamped_curves import clamped_leg_curve
from .leg_curve import LegCurve
from .pinned_curves import pinned_leg_curve

__all__ = ["LegCurve", "leg_curves"]


def leg_curves(mech, B: NDArray[np.float64], max_mode: int, *, max_winding: int = 1, theta: float = 0.0,
               force_tol: float = 0.05, passes: int = 8, progress: Callable[[float, str], None] | None = None,
               deadline: Deadline | None = None) -> list[LegCurve]:
    """Geometric-condition curves of the legs for world attach points ``B`` (3, 2) and platform
    orientation ``theta``: pinned legs by :func:`~flexkin.solve.pinned_curves.pinned_leg_curve`,
    clamped legs by :func:`~flexkin.solve.clamped_curves.clamped_leg_curve`.

    Parameters
    ----------
    mech : Mechanism
    B : (3, 2) world attach points at the imposed pose.
    max_mode : int
        Largest d-mode represented.
    max_winding : int
        Largest ``|winding|`` of a clamped rod represented (SPEC §2).
    theta : float
        Platform orientation (rad; used by clamped legs).
    force_tol : float
        Relative force resolution of the refined polylines (pinned legs).
    passes : int
        Maximum number of bisection passes (pinned legs).
    progress : callable, optional
        Called as ``progress(legs done / 3, "leg i")`` after each leg.
    deadline : Deadline, optional
        Looked at before each leg: once it has expired (it is then
        :attr:`~flexkin.core.budget.Deadline.hit`), the remaining legs get no curves.  One leg's
        curves are not interrupted (a clamped leg's take up to about half a second).

    Returns
    -------
    list of LegCurve
        One per leg.
    """
    out = []
    for i, leg in enumerate(mech.legs):
        if deadline is not None and deadline.expired():
            out.append(LegCurve(i, leg.actuation, ()))
            continue
        if progress is not None and i:
            progress(i / 3, f"leg {i + 1}")
        if leg.platform_joint.carries_moment:
            out.append(clamped_leg_curve(mech, i, B[i], theta, max_mode, max_winding))
        else:
            out.append(pinned_leg_curve(mech, i, B[i], max_mode, force_tol=force_tol, passes=passes))
    return out
