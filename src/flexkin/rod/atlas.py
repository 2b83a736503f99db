"""Dimensionless atlas of all clamped–pinned rods up to a d-mode (paper Figs. 2, 6).

The atlas samples the unified chart ``(ku = tanh v, phis)`` of :mod:`flexkin.rod.closed_form` on a
tensor grid and stores the unit-rod tip quantities.  Because every rod is a scaled unit rod
(tip ~ L, force ~ EI/L**2), one atlas per maximum d-mode serves every rod of every
mechanism: the geometric-condition curves of the inverse kinematics (Fig. 7) are level
sets on it and the single-rod inverse problem searches its triangles.

Grid design: ``ku = tanh(v)``, uniform in ``arcsin(ku)`` plus a logarithmic refinement
in ``k'`` towards ``|ku| -> 1`` (where the tip force grows like ``log(1/k')**2``); ``phis`` uniform from
``pi/2`` (unloaded straight rod) down to ``-(Q - 1) pi - pi/2`` (end of d-mode Q), and a margin of
:data:`MODE_MARGIN` cells of d-mode Q + 1 beyond it (so that no search cuts its curves or boxes at
the last d-mode boundary).

The atlas is computed once (:func:`~flexkin.rod.closed_form.tip_chart`, with
:mod:`scipy.special`) and kept on disk (:mod:`flexkin.core.cache`, keyed by the source of this
module and of :mod:`~flexkin.rod.closed_form`), so that an IK in a new process reads it instead
of importing :mod:`scipy.special` and evaluating 30 000 rods.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..core.cache import cached_arrays
from ..core.validation import check_max_mode
from .closed_form import HALF_PI, tip_chart

__all__ = ["Atlas", "get_atlas", "KPRIME_MIN", "in_scope"]

#: smallest complementary modulus sqrt(1 - k^2) in scope.  Rods beyond it (tight loops, or
#: rods in tension with lambda L beyond ~ 15; dimensionless force R L^2/EI beyond
#: ~ (2 q K(k))^2 ~ 900 q^2) are outside the searched set: their shape depends on the tip
#: force with a condition number ~ 1/k'^2 > 1e12, so no double-precision computation (closed
#: form or ODE) can confirm them.  Solvers drop solutions with a rod below KPRIME_MIN / 2.
KPRIME_MIN = 1e-6


def _v_nodes(n_uniform: int = 121, n_log: int = 20) -> NDArray[np.float64]:
    """Nodes of the chart variable ``v`` (``ku = tanh v``, ``k' = sech v``).

    Uniform in the angle ``arcsin(ku)`` for ``k' >= 1e-2``, then logarithmic in ``k'``
    down to :data:`KPRIME_MIN`.
    """
    a_edge = np.arccos(1e-2)  # k' = 1e-2
    a = np.linspace(-a_edge, a_edge, n_uniform)
    v = np.arcsinh(np.tan(a))
    kp = np.logspace(np.log10(1e-2), np.log10(KPRIME_MIN), n_log + 1)[1:]
    v_end = np.arccosh(1.0 / kp)
    return np.concatenate([-v_end[::-1], v, v_end])


def in_scope(v: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether rods with chart variable ``v`` (``k' = sech v``) are in scope, per row.

    Accepts any array; the test is applied over the last axis (all rods of a solution).
    """
    v = np.asarray(v, dtype=float)
    return np.all(np.abs(v) <= np.arccosh(2.0 / KPRIME_MIN), axis=-1)


#: cells of d-mode ``max_mode + 1`` the atlas carries beyond the end of d-mode ``max_mode``
#: (:func:`_phis_nodes`)
MODE_MARGIN = 2


def _phis_nodes(max_mode: int, per_pi: int = 96) -> NDArray[np.float64]:
    """``phis`` nodes from ``pi/2`` down to the end of d-mode ``max_mode`` and :data:`MODE_MARGIN`
    cells beyond it.  The margin is there for the searches, not for the solutions (they are
    filtered by d-mode): a curve on the atlas that crosses or touches the end of the last d-mode
    would otherwise be cut there, and its last marching-squares vertex, interpolated on the grid
    edge rather than on the curve, may lie a cell's curvature away from the rods next to the
    boundary (issue 27: a 112 solution of the loaded mixed example, whose length leg's curve turns
    at the 2/3 boundary, was found with max_mode 3 and missed with max_mode 2).  With the margin a
    rod next to the boundary lies inside its curve, like any other."""
    lo = -(max_mode - 1) * np.pi - HALF_PI
    n = per_pi * max_mode + 1
    # the first node sits just below pi/2 (pi/2 itself is the degenerate straight rod)
    nodes = np.linspace(HALF_PI, lo, n)
    nodes[0] = HALF_PI - 1e-3
    step = np.pi / per_pi
    return np.concatenate([nodes, lo - step * np.arange(1, MODE_MARGIN + 1)])


@dataclass(frozen=True)
class Atlas:
    """Unit-rod tip quantities on a ``(ku, phis)`` grid; arrays have shape (n_k, n_phi)."""

    max_mode: int
    v: NDArray[np.float64]
    ku: NDArray[np.float64]
    phis: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    theta: NDArray[np.float64]
    R: NDArray[np.float64]
    psi: NDArray[np.float64]
    m0: NDArray[np.float64]
    energy: NDArray[np.float64]

    @property
    def V(self) -> NDArray[np.float64]:
        """``v`` broadcast to the grid."""
        return np.broadcast_to(self.v[:, None], self.x.shape)

    @property
    def KU(self) -> NDArray[np.float64]:
        """``ku`` broadcast to the grid."""
        return np.broadcast_to(self.ku[:, None], self.x.shape)

    @property
    def PHIS(self) -> NDArray[np.float64]:
        """``phis`` broadcast to the grid."""
        return np.broadcast_to(self.phis[None, :], self.x.shape)

    @property
    def phis_min(self) -> float:
        """End of d-mode ``max_mode`` in the chart (the grid goes :data:`MODE_MARGIN` cells beyond)."""
        return -(self.max_mode - 1) * np.pi - HALF_PI


_FIELDS = ("x", "y", "theta", "R", "psi", "m0", "energy")


def _source_key() -> str:
    """Fingerprint of the code that computes an atlas (this module and the closed form)."""
    h = hashlib.sha256()
    for f in (Path(__file__), Path(__file__).with_name("closed_form.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


@lru_cache(maxsize=8)
def get_atlas(max_mode: int) -> Atlas:
    """Atlas of all rods with d-mode <= ``max_mode`` (cached per process and on disk)."""
    max_mode = check_max_mode(max_mode)
    v = _v_nodes()
    phis = _phis_nodes(max_mode)

    def build() -> dict[str, NDArray]:
        V, PH = np.meshgrid(v, phis, indexing="ij")
        t = tip_chart(V, PH)
        return {name: np.ascontiguousarray(getattr(t, name), dtype=float) for name in _FIELDS}

    got = cached_arrays("pinned-atlas", (max_mode, v.size, phis.size, _source_key()), build)
    arrays = {}
    for name in _FIELDS:
        a = np.ascontiguousarray(got[name], dtype=float)
        a.setflags(write=False)
        arrays[name] = a
    return Atlas(max_mode=max_mode, v=v, ku=np.tanh(v), phis=phis, **arrays)
