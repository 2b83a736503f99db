"""The Newton corrector over a batch of candidates in slices, under a time budget
(:mod:`flexkin.core.budget`): the refinement is part of a solver's budget, so it looks at the
clock between slices and leaves the candidates it had no time for unrefined.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ..core.budget import Deadline, Rate, timed_slices
from ..system import System
from .corrector import NewtonResult, newton

__all__ = ["newton_within", "NEWTON_COST"]

#: seconds per candidate of the batched Newton corrector before anything is measured: about
#: the cost of a clamped rod's FK start (0.6 ms on the unit 3-PF); pinned IK candidates are
#: ~20x cheaper, which the measured rate then shows
NEWTON_COST = 6e-4


def newton_within(system: System, X: NDArray, charts: NDArray, load: NDArray, fixed: str,
                  deadline: Deadline | None = None, rate: Rate | None = None,
                  deflate: tuple[NDArray, NDArray] | None = None, max_iter: int = 40) -> NewtonResult:
    """:func:`~flexkin.solve.corrector.newton` on the candidates ``X`` in slices while the
    ``deadline`` allows; returns the result for the first candidates, those refined (all of
    them without a budget; fewer, with :attr:`Deadline.hit` set, when the time ran out).

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    X : ndarray (n, n_unknowns)
        Starting points.
    charts : ndarray (n, 3)
        Their rods' charts.
    load : (3,)
        Load wrench.
    fixed : {"pose", "inputs"}
        What the Newton holds.
    deadline : Deadline, optional
        The time budget (default: none).
    rate : Rate, optional
        Measured seconds per candidate (updated here).
    deflate : (roots, counts), optional
        Roots each candidate must not converge to again (see
        :func:`~flexkin.solve.corrector.newton`).
    max_iter : int
        Newton iterations per candidate.

    Returns
    -------
    NewtonResult
        For the refined prefix of ``X``.
    """
    dl = deadline if deadline is not None else Deadline()
    if not dl.limited or len(X) == 0:
        return newton(system, X, charts, load, fixed, deflate=deflate, max_iter=max_iter)
    rate = rate if rate is not None else Rate(NEWTON_COST)
    parts: list[NewtonResult] = []
    for lo, hi in timed_slices(len(X), dl, rate):
        t = time.perf_counter()
        part = None if deflate is None else (deflate[0][lo:hi], deflate[1][lo:hi])
        parts.append(newton(system, X[lo:hi], charts[lo:hi], load, fixed, deflate=part, max_iter=max_iter))
        rate.add(hi - lo, time.perf_counter() - t)
    if not parts:
        n_u = np.asarray(X).shape[1]
        return NewtonResult(x=np.zeros((0, n_u)), charts=np.zeros((0, 3), np.int64), residual=np.zeros(0),
                            converged=np.zeros(0, bool), iterations=np.zeros(0, np.int64))
    if len(parts) == 1:
        return parts[0]
    return NewtonResult(**{f: np.concatenate([getattr(p, f) for p in parts])
                           for f in ("x", "charts", "residual", "converged", "iterations")})
