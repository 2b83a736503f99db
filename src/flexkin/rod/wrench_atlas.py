"""Dimensionless atlas of the rods with a free tip (clamped joints), over their wrench chart.

Every rod of a clamped leg is a scaled unit rod (:mod:`flexkin.rod.wrench`), so one grid of
unit rods serves every clamped leg of every mechanism, as :mod:`flexkin.rod.atlas` does for
pinned rods.  The grid is polar in the base force and scaled in the base moment:

* ``lambda = sqrt(|n|)`` from 0 to :func:`lambda_max` (denser near 0);
* ``psi`` (the force direction) over ``[0, 2 pi)``, periodic;
* ``m0 = (2 lambda + c_w) t`` with ``t`` in [-1, 1] and ``c_w = pi + 2 pi w_max + 1``
  (:func:`moment_extra`): a librating rod has ``|m0| < 2 lambda``, a rotating one turns its
  tangent by about ``|m0|`` when the force is small.

Scope (SPEC §2): d-mode (inflections strictly inside) ``<= q_max`` and winding
``|w| <= w_max``, where the total turning is ``theta(L) - theta(0) = delta + 2 pi w`` with
``delta`` in ``(-pi, pi]`` (:func:`winding`), so the turning is at most ``pi + 2 pi w_max``
(:func:`turning_max`).  The scope has no force cap; the *grid* has one, ``lambda L <=
lambda_max(q_max) = 4 + 6 q_max`` (forces up to ``256 EI/L^2`` for ``q_max = 2``), a numerical
limit of the search: the solvers report a search that reaches it (``complete: false``).
The arrays are cached on disk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.cache import cached_arrays
from ..core.geometry2d import wrap_to_pi
from ..core.jit import njit
from .slots import ML, NQ, TH, X, Y
from .wrench import wrench_eval, wrench_mode

__all__ = ["WrenchAtlas", "get_wrench_atlas", "lambda_max", "turning_max", "moment_extra", "winding",
           "in_wrench_scope"]

N_LAM, N_PSI, N_T = 48, 96, 97


def lambda_max(max_mode: int) -> float:
    """Largest ``lambda L`` of the grid of clamped rods searched with d-modes up to ``max_mode``
    (the search's numerical limit, not a bound of the scope)."""
    return 4.0 + 6.0 * max_mode


def turning_max(max_winding: int) -> float:
    """Largest total turning ``|theta(L) - theta(0)|`` (rad) of a rod with ``|w| <= max_winding``."""
    return math.pi * (1.0 + 2.0 * max_winding)


def moment_extra(max_winding: int) -> float:
    """The grid's base-moment half-range beyond ``2 lambda`` (a rotating rod under a small force
    turns by about ``|m0|``): :func:`turning_max` plus a margin of 1."""
    return turning_max(max_winding) + 1.0


def moment_scale(lam: NDArray, max_winding: int) -> NDArray:
    """The base-moment range ``2 lambda + c_w`` of the grid at ``lambda``."""
    return 2.0 * np.asarray(lam) + moment_extra(max_winding)


def winding(turning: ArrayLike) -> NDArray[np.int64]:
    """Winding ``w`` (SPEC §2) of clamped rods of total turning ``theta(L) - theta(0)`` (rad):
    ``turning = delta + 2 pi w`` with ``delta`` in ``(-pi, pi]``."""
    t = np.asarray(turning, dtype=float)
    return np.rint((t - wrap_to_pi(t)) / (2.0 * math.pi)).astype(np.int64)


def in_wrench_scope(th: NDArray, mode: NDArray, max_mode: int, max_winding: int) -> NDArray[np.bool_]:
    """Whether clamped rods of total turning ``th`` and d-mode ``mode`` are in the scope of
    SPEC §2: ``mode <= max_mode`` and ``|winding(th)| <= max_winding`` (no force cap)."""
    return (np.abs(winding(th)) <= max_winding) & (np.asarray(mode) <= max_mode)


@njit
def _fill(lam, psi, t, mscale, x, y, th, ml, mode) -> None:
    q = np.empty(NQ)
    g = np.empty((NQ, 3))
    for i in range(lam.shape[0]):
        R = lam[i] * lam[i]
        for j in range(psi.shape[0]):
            a, b = R * math.cos(psi[j]), R * math.sin(psi[j])
            for k in range(t.shape[0]):
                m0 = mscale[i] * t[k]
                wrench_eval(a, b, m0, q, g)
                x[i, j, k], y[i, j, k], th[i, j, k], ml[i, j, k] = q[X], q[Y], q[TH], q[ML]
                mode[i, j, k] = wrench_mode(a, b, m0, 1e-9)[0]


@dataclass(frozen=True)
class WrenchAtlas:
    """Unit rods on the ``(lambda, psi, t)`` grid: ``x, y, th, ml`` (n_lam, n_psi, n_t) tip
    position, tip angle and tip moment, ``mode`` (d-mode), ``valid`` (in scope)."""

    max_mode: int
    max_winding: int
    lam: NDArray[np.float64]
    psi: NDArray[np.float64]
    t: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    th: NDArray[np.float64]
    ml: NDArray[np.float64]
    mode: NDArray[np.int64]
    valid: NDArray[np.bool_]

    @property
    def mscale(self) -> NDArray[np.float64]:
        """Base-moment scale at each ``lambda`` node."""
        return moment_scale(self.lam, self.max_winding)

    def wrench(self, i: NDArray, j: NDArray, k: NDArray) -> NDArray[np.float64]:
        """Chart coordinates ``(a, b, m0)`` of (fractional) grid indices (n, 3)."""
        lam = np.interp(i, np.arange(len(self.lam)), self.lam)
        psi = np.asarray(j, dtype=float) * (2 * np.pi / len(self.psi))
        tt = np.interp(k, np.arange(len(self.t)), self.t)
        R = lam**2
        return np.stack([R * np.cos(psi), R * np.sin(psi), moment_scale(lam, self.max_winding) * tt], -1)


@lru_cache(maxsize=6)
def get_wrench_atlas(max_mode: int, max_winding: int = 1) -> WrenchAtlas:
    """The atlas of clamped unit rods with d-modes up to ``max_mode`` and windings up to
    ``max_winding`` (memory and disk cache)."""
    lam = lambda_max(max_mode) * np.linspace(0.0, 1.0, N_LAM) ** 1.5
    psi = np.arange(N_PSI) * (2 * np.pi / N_PSI)
    t = np.linspace(-1.0, 1.0, N_T)

    def build():
        shape = (N_LAM, N_PSI, N_T)
        x, y, th, ml = np.empty(shape), np.empty(shape), np.empty(shape), np.empty(shape)
        mode = np.empty(shape, np.int64)
        _fill(lam, psi, t, moment_scale(lam, max_winding), x, y, th, ml, mode)
        return {"x": x, "y": y, "th": th, "ml": ml, "mode": mode}

    # key version 3: d-mode = interior inflections (SPEC §2), moment range by winding
    a = cached_arrays("wrench-atlas", (max_mode, max_winding, N_LAM, N_PSI, N_T, 3), build)
    valid = (a["mode"] <= max_mode) & (np.abs(a["th"]) <= turning_max(max_winding)) & np.isfinite(a["x"])
    return WrenchAtlas(max_mode, max_winding, lam, psi, t, a["x"], a["y"], a["th"], a["ml"], a["mode"], valid)
