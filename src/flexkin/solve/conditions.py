"""The legs' geometric conditions (paper §4.1) in compiled form, with their derivatives.

A condition is a kind code and three parameters (:meth:`Actuator.condition`); evaluated on a
unit rod's tip ``(x, y)`` it gives the residual ``g`` whose zero set the rods reaching ``B`` lie
on, its gradient, and the clamp angle ``alpha`` the actuator then has, with its gradient:

* line (prismatic legs, Fig. 5): ``g = y - h``; ``alpha`` = the guide angle;
* circle (revolute legs, Fig. 8): ``g = |tip| - r``; ``alpha = atan2(B - A) - atan2(y, x)``;
* ray (length legs, Fig. 9): ``g = x sin(beta) - y cos(beta)`` on the half-line
  ``x cos(beta) + y sin(beta) > 0``; ``alpha`` = the guide angle.
"""

from __future__ import annotations

import math

from ..core.jit import njit
from ..mechanism.actuators import COND_CIRCLE, COND_LINE

__all__ = ["condition_eval"]


@njit
def condition_eval(code: int, p0: float, p1: float, x: float, y: float):
    """``(g, g_x, g_y, alpha, alpha_x, alpha_y, admissible)`` of a condition at the tip ``(x, y)``."""
    if code == COND_LINE:
        return y - p0, 0.0, 1.0, p1, 0.0, 0.0, True
    if code == COND_CIRCLE:
        rho = math.hypot(x, y)
        if rho == 0.0:
            return -p0, 0.0, 0.0, p1, 0.0, 0.0, True
        r2 = rho * rho
        return rho - p0, x / rho, y / rho, p1 - math.atan2(y, x), y / r2, -x / r2, True
    sb, cb = math.sin(p0), math.cos(p0)
    return x * sb - y * cb, sb, -cb, p1, 0.0, 0.0, x * cb + y * sb > 1e-9
