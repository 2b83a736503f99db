"""Atlas of the pinned rods near straight under tension, in the seam chart.

The unified chart ``(v, phis)`` of :mod:`flexkin.rod.atlas` squeezes every rod straight under
tension into one corner, ``|v| -> inf`` and ``phis -> pi/2``: a taut rod (its tip at full
length ``L`` from the clamp) of any tension is that one point, and a rod ``d`` short of taut lies
within about ``sqrt(d)`` of it.  No grid of the unified chart resolves these rods, and a
revolute leg whose platform point is almost ``L`` from its joint needs exactly them (the rods
that reach it are near taut).

In the seam chart ``(psi_s, chi)`` of :func:`~flexkin.rod.closed_form.tip_seam` the taut rods
are the ordinary line ``psi_s = 0`` (all tensions, ``lambda L = atanh(sin chi)`` on it) and a
rod and its mirror image are neighbours.  This module samples the patch
``|psi_s| <= PSI_OUT`` of it (force within ``PSI_OUT`` rad of the clamp tangent, every tension in
scope), and says which nodes of the unified atlas it takes over (:func:`unified_corner`:
``|psi_s| < PSI_IN``).  The band ``PSI_IN <= |psi_s| <= PSI_OUT`` is in both, so that a curve
leaving one chart is continued by the other without a gap.

Scope: the unified atlas reaches ``k' = KPRIME_MIN`` (:mod:`flexkin.rod.atlas`), i.e. mode-1
rods with ``lambda L <= K(KPRIME_MIN)`` ~ 15.2 in this corner; the seam patch covers the same
tensions (nodes up to ``lambda L`` = :data:`T_MAX`), and solvers keep a rod in the seam chart
when ``lambda L <= LAMBDA_SCOPE`` (the tension of ``k' = KPRIME_MIN / 2`` on the taut line,
matching the unified chart's ``k' >= KPRIME_MIN / 2``).  Unlike ``k'``, which goes to zero on the
taut line at any tension, ``lambda L`` measures what makes rods ill-conditioned (a boundary layer
of width ``L / (lambda L)``), so taut rods of moderate tension are in scope.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from ..core.cache import cached_arrays
from .atlas import KPRIME_MIN, Atlas, _source_key
from .closed_form import HALF_PI, tip_seam
from .elliptic import complete

__all__ = ["SeamAtlas", "get_seam_atlas", "unified_corner", "PSI_IN", "PSI_OUT", "T_MAX", "LAMBDA_SCOPE",
           "seam_in_scope"]

#: the unified atlas leaves rods with |psi_s| < PSI_IN (mode 1, 0 < phis < pi/2) to the seam patch
PSI_IN = 0.25
#: half width of the seam patch in psi_s (the overlap band PSI_IN..PSI_OUT is in both charts)
PSI_OUT = 0.5
#: lambda L of a rod in the seam chart beyond which it is out of scope: the tension of a taut rod
#: with k' = KPRIME_MIN / 2 (K(k') - F(pi/2 - 0) on the taut line, the unified chart's limit)
LAMBDA_SCOPE = float(complete(1.0 - (0.5 * KPRIME_MIN) ** 2, (0.5 * KPRIME_MIN) ** 2)[0])
#: largest tension sampled, as t = atanh(sin chi) (= lambda L on the taut line), beyond the scope
T_MAX = LAMBDA_SCOPE + 0.5


def seam_in_scope(Phi: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether seam-chart rods with ``lambda L = Phi`` are in scope (``Phi <= LAMBDA_SCOPE``),
    elementwise."""
    return np.asarray(Phi, dtype=float) <= LAMBDA_SCOPE


def _psi_nodes(n_half: int = 25) -> NDArray[np.float64]:
    """``2 n_half`` nodes on ``[-PSI_OUT, PSI_OUT]``, symmetric, none on the taut line itself (a
    node there would sit exactly on the level set of a taut leg)."""
    h = PSI_OUT / (n_half - 0.5)
    pos = (np.arange(n_half) + 0.5) * h
    return np.concatenate([-pos[::-1], pos])


def _chi_nodes() -> NDArray[np.float64]:
    """``chi`` nodes, uniform in ``t = atanh(sin chi)`` (the tension on the taut line) with a
    geometric refinement towards the unloaded rod ``t -> 0``."""
    n = int(np.ceil((T_MAX - 0.4) / 0.2)) + 1
    t = np.concatenate([np.geomspace(1e-3, 0.4, 12)[:-1], np.linspace(0.4, T_MAX, n)])
    return np.arcsin(np.tanh(t))


@dataclass(frozen=True)
class SeamAtlas:
    """Unit-rod tips on a ``(psi_s, chi)`` grid of the seam chart; arrays (n_psi, n_chi): tip
    position, force on the tip (local frame), tip angle and ``lambda L``."""

    psi_s: NDArray[np.float64]
    chi: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    fx: NDArray[np.float64]
    fy: NDArray[np.float64]
    theta: NDArray[np.float64]
    Phi: NDArray[np.float64]

    @property
    def PSI(self) -> NDArray[np.float64]:
        """``psi_s`` broadcast to the grid."""
        return np.broadcast_to(self.psi_s[:, None], self.x.shape)

    @property
    def CHI(self) -> NDArray[np.float64]:
        """``chi`` broadcast to the grid."""
        return np.broadcast_to(self.chi[None, :], self.x.shape)


@lru_cache(maxsize=1)
def get_seam_atlas() -> SeamAtlas:
    """The seam patch (cached per process and on disk, like the pinned atlas: its closed form
    needs :mod:`scipy.special`, which an IK or FK call does not load)."""
    ps = _psi_nodes()
    chi = _chi_nodes()

    def build() -> dict[str, NDArray]:
        P, C = np.meshgrid(ps, chi, indexing="ij")
        t = tip_seam(P, C)
        return {name: np.ascontiguousarray(getattr(t, name), dtype=float) for name in _FIELDS}

    got = cached_arrays("seam-atlas", (ps.size, chi.size, _source_key(), _own_key()), build)
    arrays = {}
    for name in _FIELDS:
        a = np.ascontiguousarray(got[name], dtype=float)
        a.setflags(write=False)
        arrays[name] = a
    return SeamAtlas(psi_s=ps, chi=chi, **arrays)


_FIELDS = ("x", "y", "fx", "fy", "theta", "Phi")


def _own_key() -> str:
    """Fingerprint of this module (its nodes), beside the closed form's in ``_source_key``."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]


@lru_cache(maxsize=8)
def _corner(max_mode: int) -> NDArray[np.bool_]:
    from .atlas import get_atlas

    A = get_atlas(max_mode)
    psi_abs = np.minimum(A.psi, 2.0 * np.pi - A.psi)  # |psi_s| of the mode-1 rods with 0 < phis < pi/2
    out = (A.PHIS > 0.0) & (A.PHIS < HALF_PI) & (psi_abs < PSI_IN)
    out.setflags(write=False)
    return out


def unified_corner(atlas: Atlas) -> NDArray[np.bool_]:
    """Nodes of the unified ``atlas`` (n_k, n_phi) that the seam patch takes over: mode-1 rods with
    ``0 < phis < pi/2`` whose force is within ``PSI_IN`` of the clamp tangent."""
    return _corner(atlas.max_mode)
