"""Atlases of the rods with a free tip amplitude (clamped joints) in well-conditioned charts.

The wrench chart (:mod:`flexkin.rod.wrench`) is global and smooth, but near the separatrix a
rod's tip depends on its base wrench with a condition number like ``1/k'^2``: a grid in it
cannot resolve those rods.  For the branch-and-bound of the forward kinematics the clamped
rods are therefore sampled in the elliptic charts of paper §2, where ``k'`` is a coordinate
(as in the pinned rods' atlas):

* **libration** (inflectional elastica): ``(v, phi_e, s)`` with ``k = tanh v`` (``k' = sech v``),
  tip amplitude ``phi_e`` in ``[-pi/2, pi/2]`` and span ``s = phi_e - phi_s`` in
  ``(0, (q_max + 1) pi]`` (at most ``q_max`` inflections inside); the arc ``[phi_s, phi_e]`` of the elastica, Eqs. (9), (12), (13) with
  ``phi_2 = phi_e`` free (paper §8);
* **rotation** (non-inflectional): ``(nu, chi_0, d_chi)`` with modulus ``kappa = 1/k = tanh nu``
  (``kappa' = sech nu``), ``chi_0`` in ``[0, pi]`` and signed span ``d_chi`` in
  ``[-c, c]``, ``c = (w_max + 1/2) pi + 1/4`` (the tangent turns by ``2 d_chi``: every winding
  ``|w| <= w_max`` of SPEC §2 with a margin).

Every node stores the unit rod's tip position, force, tip angle and tip moment, its base
wrench (its coordinates in the wrench chart, where the solvers' Newton runs), its d-mode and
whether it is in the search's scope (:mod:`flexkin.rod.wrench_atlas`).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.jit import njit
from .elliptic import HALF_PI, complete, fedb

__all__ = ["libration_grid", "rotation_grid", "fill_libration", "fill_rotation", "node_windows", "FEATURES"]

#: per node: x, y, fx, fy, theta, m_L, a, b, m0, lambda, mode
FEATURES = 11
#: smallest ``k'`` of the grids: a taut rod crossing the saddle once has ``k' ~ 4 exp(-lambda L / 2)``,
#: so the grids seed taut rods up to ``lambda L ~ 55`` (beyond, the traces continue them)
KP_MIN = 1e-12


def _log_sech_nodes(n_uniform: int, n_log: int, kp_min: float = 1e-6) -> np.ndarray:
    """Non-negative ``v`` nodes: uniform in ``arcsin(tanh v)`` while ``sech v >= 1e-2``, then
    logarithmic in ``sech v`` down to ``kp_min`` (as the pinned atlas)."""
    a = np.linspace(0.0, np.arccos(1e-2), n_uniform)
    v = np.arcsinh(np.tan(a))
    kp = np.logspace(-2.0, np.log10(kp_min), n_log + 1)[1:]
    return np.concatenate([v, np.arccosh(1.0 / kp)])


def libration_grid(max_mode: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``(v, phi_e, s)`` of the libration atlas (``v`` symmetric about 0) for rods with
    up to ``max_mode`` inflections inside."""
    vp = _log_sech_nodes(31, 30, KP_MIN)
    v = np.concatenate([-vp[::-1], vp[1:]])
    phie = np.linspace(-HALF_PI, HALF_PI, 33)
    s = np.linspace(0.0, (max_mode + 1) * math.pi, 32 * (max_mode + 1) + 1)[1:]
    return v, phie, s


def rotation_grid(max_winding: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``(nu, chi_0, d_chi)`` of the rotation atlas for windings up to ``max_winding``."""
    nu = _log_sech_nodes(30, 30, KP_MIN)
    chi0 = np.linspace(0.0, math.pi, 33)
    c = (max_winding + 0.5) * math.pi + 0.25
    dchi = np.linspace(-c, c, 2 * int(math.ceil(24 * c / math.pi)) + 1)
    return nu, chi0, dchi


@njit
def _lib_node(v, phie, span, out) -> None:
    av = min(abs(v), 350.0)
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
    ku = math.tanh(v)
    kp2 = kp * kp
    m = ku * ku
    phis = phie - span
    K, Ec, Dc, Bc = complete(m, kp2)
    Fs, Es, Ds, Bs, ds = fedb(phis, m, kp2, K, Ec, Dc, Bc)
    Fe, Ee, De, Be, de = fedb(phie, m, kp2, K, Ec, Dc, Bc)
    Phi = Fe - Fs
    c = ku * math.sin(phis)
    cp = c * c - ds * ds
    sp = 2.0 * c * ds
    psi = 2.0 * math.atan2(ds, c)
    G = 2.0 * (Ee - Es) - Phi
    dcos = math.cos(phie) - math.cos(phis)
    out[0] = -(G * cp + 2.0 * ku * sp * dcos) / Phi
    out[1] = -(G * sp - 2.0 * ku * cp * dcos) / Phi
    R = Phi * Phi
    out[2], out[3] = R * cp, R * sp
    out[4] = psi + 2.0 * math.atan2(-de, ku * math.sin(phie))
    out[5] = 2.0 * Phi * ku * math.cos(phie)
    out[6], out[7] = R * cp, R * sp
    out[8] = 2.0 * Phi * ku * math.cos(phis)
    out[9] = Phi
    lo = math.floor((phis - HALF_PI) / math.pi) + 1
    hi = math.ceil((phie - HALF_PI) / math.pi) - 1
    out[10] = max(0, hi - lo + 1)


@njit
def _rot_node(nu, chi0, dchi, out) -> None:
    kp = 2.0 * math.exp(-nu) / (1.0 + math.exp(-2.0 * nu))
    kap = math.tanh(nu)
    kp2 = kp * kp
    m = kap * kap
    sig = 1.0 if dchi >= 0.0 else -1.0
    chie = chi0 + dchi
    K, Ec, Dc, Bc = complete(m, kp2)
    F0, E0, D0, B0, d0 = fedb(chi0, m, kp2, K, Ec, Dc, Bc)
    Fe, Ee, De, Be, de = fedb(chie, m, kp2, K, Ec, Dc, Bc)
    Ke = sig * (Fe - F0)
    if not Ke > 0.0:
        for q in range(FEATURES):
            out[q] = 0.0
        out[0] = 1.0
        out[10] = 0
        return
    lam = kap * Ke
    psi = math.pi - 2.0 * chi0
    cps, sps = math.cos(psi), math.sin(psi)
    xf = sig * 2.0 * (De - D0) / Ke - 1.0
    s0, se = math.sin(chi0), math.sin(chie)
    yf = -2.0 * sig * (se * se - s0 * s0) / (Ke * (de + d0))
    out[0] = cps * xf - sps * yf
    out[1] = sps * xf + cps * yf
    R = lam * lam
    out[2], out[3] = R * cps, R * sps
    out[4] = 2.0 * dchi
    out[5] = 2.0 * sig * Ke * de
    out[6], out[7] = R * cps, R * sps
    out[8] = 2.0 * sig * Ke * d0
    out[9] = lam
    out[10] = 0


@njit
def fill_libration(v, phie, span, out) -> None:
    """Evaluate the libration grid into ``out`` (nv, nphie, nspan, FEATURES)."""
    for i in range(v.shape[0]):
        for j in range(phie.shape[0]):
            for k in range(span.shape[0]):
                _lib_node(v[i], phie[j], span[k], out[i, j, k])


@njit
def fill_rotation(nu, chi0, dchi, out) -> None:
    """Evaluate the rotation grid into ``out`` (nnu, nchi0, ndchi, FEATURES)."""
    for i in range(nu.shape[0]):
        for j in range(chi0.shape[0]):
            for k in range(dchi.shape[0]):
                _rot_node(nu[i], chi0[j], dchi[k], out[i, j, k])


@njit
def node_windows(lib: bool, a: np.ndarray, b: np.ndarray, c: np.ndarray, out: np.ndarray) -> None:
    """Elastica-window coordinates ``(v, u_s, u_e)`` (:mod:`~flexkin.rod.elastica`) of grid nodes
    ``(a[r], b[r], c[r])`` into ``out`` (n, 3): a libration node ``(v, phi_e, s)`` is the window
    ``(v, F(phi_e - s), F(phi_e))``, a rotation node ``(nu, chi_0, d_chi)`` the window
    ``(nu, F(chi_0), F(chi_0 + d_chi))`` (elliptic time ``u = F(am u)``, exact in ``k'``)."""
    for r in range(a.shape[0]):
        av = min(abs(a[r]), 350.0)
        kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
        k = math.tanh(a[r])
        m, kp2 = k * k, kp * kp
        K, Ec, Dc, Bc = complete(m, kp2)
        p_s, p_e = (b[r] - c[r], b[r]) if lib else (b[r], b[r] + c[r])
        out[r, 0] = a[r]
        out[r, 1] = fedb(p_s, m, kp2, K, Ec, Dc, Bc)[0]
        out[r, 2] = fedb(p_e, m, kp2, K, Ec, Dc, Bc)[0]
