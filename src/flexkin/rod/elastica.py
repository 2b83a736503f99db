"""Rods clamped at both ends as windows of an elastica orbit: the libration and rotation charts.

A rod of unit length and stiffness (clamp at the origin, clamp tangent along +x) whose tip
amplitude is free (paper §8) is the arc ``u_s <= u <= u_e`` (elliptic time, see
:mod:`~flexkin.rod.orbit`) of one pendulum orbit: the rod's tangent measured from the internal
force is ``beta(u)`` and the arc length is ``s = (u - u_s) / (u_e - u_s)``.  The rod's chart
coordinates are ``(v, u_s, u_e)``:

* **libration** (``CHART_LIB``, the inflectional elastica, Eqs. 9-13 with ``phi_2`` free):
  ``k = tanh v`` (``k' = sech v`` exact), ``cos(beta/2) = k sn u``, ``sin(beta/2) = -dn u``,
  ``theta' = 2 lambda k cn u`` with ``lambda L = u_e - u_s``;
* **rotation** (``CHART_ROT``, non-inflectional: the curvature keeps its sign, the tangent
  turns without bound): modulus ``kappa = tanh v``, ``beta = 2 am(u) - pi``,
  ``theta' = 2 (u_e - u_s) dn u`` and ``lambda L = kappa |u_e - u_s|``; a negative window
  ``u_e < u_s`` is the rod turning clockwise.

In the force frame the rod's points are ``P(u) / (u_e - u_s)`` with (integrating
``x' = cos beta``, ``y' = sin beta``)

    libration:  P(u) = (u - 2 E(u), 2 k (cn u - 1)),
    rotation:   P(u) = (2 Dphi(u) - u, -2 sn^2 u / (1 + dn u)),

so a window's tip, clamp-frame rotated by the force direction ``psi = -beta(u_s)``, is

    tip = Rot(psi) (P(u_e) - P(u_s)) / (u_e - u_s),      theta(L) = beta(u_e) - beta(u_s),

its force ``lambda^2 (cos psi, sin psi)``, its end moments ``(u_e - u_s) p(u)`` with
``p = 2 k cn`` (libration) or ``2 dn`` (rotation), and its bending energy
``(u_e - u_s) (Q(u_e) - Q(u_s))`` with ``Q = 2 (E - k'^2 u)`` or ``2 E``.  The tip angle
``theta(L)`` is the rod's total turning (continuous, not reduced mod 2 pi).

The charts are smooth and well conditioned wherever the rod is not nearly unloaded and
straight (``u_e - u_s -> 0`` is the charts' pole; the wrench chart of
:mod:`~flexkin.rod.wrench` covers those rods): taut rods, whose orbit passes close to the
saddle, are ordinary points (their times keep full precision where amplitudes would not).
All outputs have analytic derivatives with respect to ``(v, u_s, u_e)``.

The d-mode of a clamped rod (SPEC §2) is the number of inflections strictly inside it: the
tops ``u = (2 j + 1) K`` of a librating window; a rotating rod has none.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.jit import njit
from .elliptic import complete, fedb
from .orbit import (
    AB,
    AM,
    CN,
    DB,
    DN,
    DU,
    DV,
    EB,
    EU,
    NP,
    SN,
    modulus,
    orbit_constants,
    orbit_point,
)
from .slots import EN, FX, FY, M0, ML, NQ, PHI, TH, X, Y
from .wrench import wrench_eval

__all__ = ["lib_eval", "rot_eval", "window_tip", "window_values", "window_profile", "window_mode", "window_peak", "reduce_window",
           "window_of", "taut_windows", "tip_sensitivity", "SENS_WINDOW", "SENS_WRENCH", "V_CAP"]

#: tip sensitivity to the base moment, ``|d(x, y, theta)/d m0|`` of the unit rod, above which a
#: clamped rod is computed in its elastica window (a taut rod: the sensitivity grows like
#: ``exp(lambda L)`` along an orbit near the saddle, and the wrench chart loses the tip's digits),
#: and below which a trace comes back to the wrench chart (hysteresis)
SENS_WINDOW = 1e3
SENS_WRENCH = 1e2
#: cap on |v| of the elliptic charts (k' = sech v ~ 2 exp(-|v|) stays a normal number)
V_CAP = 350.0


@njit(cache=True)
def reduce_window(rot: bool, v: float, us: float, ue: float) -> tuple[float, float]:
    """The window shifted by whole periods (``4K`` libration, ``2K`` rotation) so that ``u_s`` lies
    in ``[-K, 3K)`` resp. ``[-K, K)`` (the same rod)."""
    k, kp = modulus(v)
    m, mp, K, Ec, Dc, Bc = orbit_constants(k, kp)
    per = 2.0 * K if rot else 4.0 * K
    sh = per * math.floor((us + K) / per)
    return us - sh, ue - sh


@njit(cache=True)
def _points(v, us, ue, ps, pe):
    k, kp = modulus(v)
    m, mp, K, Ec, Dc, Bc = orbit_constants(k, kp)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, us, ps)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, ue, pe)
    return k, kp, m, mp


@njit(cache=True)
def window_tip(rot: bool, k: float, m: float, mp: float, ps: np.ndarray, pe: np.ndarray, ell: float):
    """Tip ``(x, y)``, tip angle ``theta(L)`` and the force direction ``(cos psi, sin psi)`` of the
    unit rod of the window between the orbit points ``ps``, ``pe`` (:func:`orbit_point` values)
    of elliptic-time length ``ell = u_e - u_s != 0`` (module docstring)."""
    sn_s, cn_s, dn_s = ps[SN], ps[CN], ps[DN]
    sn_e, cn_e, dn_e = pe[SN], pe[CN], pe[DN]
    dE = (pe[EB] - ps[EB]) + (pe[EU] - ps[EU])
    if rot:
        cpsi = sn_s * sn_s - cn_s * cn_s
        spsi = 2.0 * sn_s * cn_s
        if m >= 0.5:
            # near the separatrix: int cn^2 = (E - k'^2 u)/m and sn^2/(1 + dn) = (1 - dn)/m keep
            # the digits of a taut rod (x = 1 - 2 int cn^2 / ell)
            dPx = ell - 2.0 * (dE - mp * ell) / m
            dPy = -2.0 * (dn_s - dn_e) / m
        else:
            dPx = 2.0 * ((pe[DB] - ps[DB]) + (pe[DU] - ps[DU])) - ell
            dPy = -2.0 * (sn_e * sn_e / (1.0 + dn_e) - sn_s * sn_s / (1.0 + dn_s))
        th = 2.0 * ((pe[AB] - ps[AB]) + (pe[AM] - ps[AM]))
    else:
        cpsi = k * k * sn_s * sn_s - dn_s * dn_s
        spsi = 2.0 * k * sn_s * dn_s
        dPx = ell - 2.0 * dE
        dPy = 2.0 * k * (cn_e - cn_s)
        # theta(L) = beta_e - beta_s in (-2 pi, 2 pi), from the half angles' difference (exact near tops)
        th = 2.0 * math.atan2(k * (sn_e * dn_s - dn_e * sn_s), k * k * sn_e * sn_s + dn_e * dn_s)
    x = (cpsi * dPx - spsi * dPy) / ell
    y = (spsi * dPx + cpsi * dPy) / ell
    return x, y, th, cpsi, spsi


@njit(cache=True)
def window_values(rot: bool, k: float, m: float, mp: float, ps: np.ndarray, pe: np.ndarray, ell: float,
                  out: np.ndarray) -> None:
    """The unit rod of the window between the orbit points ``ps``, ``pe`` (:func:`orbit_point`
    values) of elliptic-time length ``ell = u_e - u_s`` -> ``out`` (NQ,) (module docstring)."""
    if ell == 0.0:
        out[:] = 0.0
        out[X] = 1.0
        return
    x, y, th, cpsi, spsi = window_tip(rot, k, m, mp, ps, pe, ell)
    dE = (pe[EB] - ps[EB]) + (pe[EU] - ps[EU])
    out[X], out[Y], out[TH] = x, y, th
    if rot:
        l2 = m * ell * ell
        out[M0] = 2.0 * ell * ps[DN]
        out[ML] = 2.0 * ell * pe[DN]
        out[EN] = 2.0 * ell * dE
        out[PHI] = abs(k * ell)
    else:
        l2 = ell * ell
        out[M0] = 2.0 * ell * k * ps[CN]
        out[ML] = 2.0 * ell * k * pe[CN]
        out[EN] = 2.0 * ell * (dE - mp * ell)
        out[PHI] = abs(ell)
    out[FX], out[FY] = l2 * cpsi, l2 * spsi


@njit(cache=True)
def lib_eval(v: float, us: float, ue: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Libration window ``(v, u_s, u_e)`` -> ``out`` (NQ,) and ``grad`` (NQ, 3) = d/d(v, u_s, u_e)."""
    ps = np.empty(NP)
    pe = np.empty(NP)
    k, kp, m, mp = _points(v, us, ue, ps, pe)
    ell = ue - us
    grad[:, :] = 0.0
    # d(ell) = (0, -1, 1); derivatives of point quantities: column 0 = v, the own time otherwise
    dell = (0.0, -1.0, 1.0)
    k_v = mp
    sn_s, cn_s, dn_s = ps[SN], ps[CN], ps[DN]
    sn_e, cn_e, dn_e = pe[SN], pe[CN], pe[DN]
    if ell == 0.0:
        out[:] = 0.0
        out[X] = 1.0
        return
    window_values(False, k, m, mp, ps, pe, ell, out)
    cpsi = k * k * sn_s * sn_s - dn_s * dn_s
    spsi = 2.0 * k * sn_s * dn_s
    dE = (pe[EB] - ps[EB]) + (pe[EU] - ps[EU])
    dPx = ell - 2.0 * dE
    dPy = 2.0 * k * (cn_e - cn_s)
    x, y = out[X], out[Y]
    for j in range(3):
        if j == 0:
            dsn_s, dcn_s, ddn_s = ps[DV + SN], ps[DV + CN], ps[DV + DN]
            dsn_e, dcn_e, ddn_e = pe[DV + SN], pe[DV + CN], pe[DV + DN]
            dE_s, dE_e = ps[DV + EU], pe[DV + EU]
            dk = k_v
            dmp = -2.0 * k * mp
        elif j == 1:
            dsn_s, dcn_s, ddn_s = cn_s * dn_s, -sn_s * dn_s, -m * sn_s * cn_s
            dsn_e = dcn_e = ddn_e = 0.0
            dE_s, dE_e = dn_s * dn_s, 0.0
            dk = 0.0
            dmp = 0.0
        else:
            dsn_s = dcn_s = ddn_s = 0.0
            dsn_e, dcn_e, ddn_e = cn_e * dn_e, -sn_e * dn_e, -m * sn_e * cn_e
            dE_s, dE_e = 0.0, dn_e * dn_e
            dk = 0.0
            dmp = 0.0
        dl = dell[j]
        dbs = 2.0 * (dn_s * (dk * sn_s + k * dsn_s) - k * sn_s * ddn_s)
        dbe = 2.0 * (dn_e * (dk * sn_e + k * dsn_e) - k * sn_e * ddn_e)
        dcpsi = spsi * dbs
        dspsi = -cpsi * dbs
        ddE = dE_e - dE_s
        ddPx = dl - 2.0 * ddE
        ddPy = 2.0 * dk * (cn_e - cn_s) + 2.0 * k * (dcn_e - dcn_s)
        grad[X, j] = (dcpsi * dPx + cpsi * ddPx - dspsi * dPy - spsi * ddPy - x * dl) / ell
        grad[Y, j] = (dspsi * dPx + spsi * ddPx + dcpsi * dPy + cpsi * ddPy - y * dl) / ell
        grad[TH, j] = dbe - dbs
        grad[FX, j] = 2.0 * ell * dl * cpsi + ell * ell * dcpsi
        grad[FY, j] = 2.0 * ell * dl * spsi + ell * ell * dspsi
        grad[M0, j] = 2.0 * (dl * k * cn_s + ell * dk * cn_s + ell * k * dcn_s)
        grad[ML, j] = 2.0 * (dl * k * cn_e + ell * dk * cn_e + ell * k * dcn_e)
        grad[EN, j] = 2.0 * dl * (dE - mp * ell) + 2.0 * ell * (ddE - dmp * ell - mp * dl)
        grad[PHI, j] = dl if ell > 0.0 else -dl


@njit(cache=True)
def rot_eval(v: float, us: float, ue: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Rotation window ``(v, u_s, u_e)`` (modulus ``kappa = tanh v``) -> ``out`` (NQ,) and ``grad``
    (NQ, 3) = d/d(v, u_s, u_e)."""
    ps = np.empty(NP)
    pe = np.empty(NP)
    k, kp, m, mp = _points(v, us, ue, ps, pe)
    ell = ue - us
    grad[:, :] = 0.0
    if ell == 0.0:
        out[:] = 0.0
        out[X] = 1.0
        return
    dell = (0.0, -1.0, 1.0)
    sn_s, cn_s, dn_s = ps[SN], ps[CN], ps[DN]
    sn_e, cn_e, dn_e = pe[SN], pe[CN], pe[DN]
    window_values(True, k, m, mp, ps, pe, ell, out)
    cpsi = sn_s * sn_s - cn_s * cn_s
    spsi = 2.0 * sn_s * cn_s
    dE = (pe[EB] - ps[EB]) + (pe[EU] - ps[EU])
    dPx = 2.0 * ((pe[DB] - ps[DB]) + (pe[DU] - ps[DU])) - ell
    dPy = -2.0 * (sn_e * sn_e / (1.0 + dn_e) - sn_s * sn_s / (1.0 + dn_s))
    if m >= 0.5:
        dPx = ell - 2.0 * (dE - mp * ell) / m
        dPy = -2.0 * (dn_s - dn_e) / m
    l2 = m * ell * ell
    x, y = out[X], out[Y]
    for j in range(3):
        if j == 0:
            dsn_s, ddn_s, dam_s, dD_s, dE_s = ps[DV + SN], ps[DV + DN], ps[DV + AM], ps[DV + DU], ps[DV + EU]
            dsn_e, ddn_e, dam_e, dD_e, dE_e = pe[DV + SN], pe[DV + DN], pe[DV + AM], pe[DV + DU], pe[DV + EU]
            dm = 2.0 * k * mp
        elif j == 1:
            dsn_s, ddn_s, dam_s, dD_s, dE_s = cn_s * dn_s, -m * sn_s * cn_s, dn_s, sn_s * sn_s, dn_s * dn_s
            dsn_e = ddn_e = dam_e = dD_e = dE_e = 0.0
            dm = 0.0
        else:
            dsn_s = ddn_s = dam_s = dD_s = dE_s = 0.0
            dsn_e, ddn_e, dam_e, dD_e, dE_e = cn_e * dn_e, -m * sn_e * cn_e, dn_e, sn_e * sn_e, dn_e * dn_e
            dm = 0.0
        dl = dell[j]
        dbs = 2.0 * dam_s
        dcpsi = spsi * dbs
        dspsi = -cpsi * dbs
        dGs = (2.0 * sn_s * dsn_s * (1.0 + dn_s) - sn_s * sn_s * ddn_s) / (1.0 + dn_s) ** 2
        dGe = (2.0 * sn_e * dsn_e * (1.0 + dn_e) - sn_e * sn_e * ddn_e) / (1.0 + dn_e) ** 2
        ddPx = 2.0 * (dD_e - dD_s) - dl
        ddPy = -2.0 * (dGe - dGs)
        grad[X, j] = (dcpsi * dPx + cpsi * ddPx - dspsi * dPy - spsi * ddPy - x * dl) / ell
        grad[Y, j] = (dspsi * dPx + spsi * ddPx + dcpsi * dPy + cpsi * ddPy - y * dl) / ell
        grad[TH, j] = 2.0 * (dam_e - dam_s)
        dl2 = dm * ell * ell + 2.0 * m * ell * dl
        grad[FX, j] = dl2 * cpsi + l2 * dcpsi
        grad[FY, j] = dl2 * spsi + l2 * dspsi
        grad[M0, j] = 2.0 * (dl * dn_s + ell * ddn_s)
        grad[ML, j] = 2.0 * (dl * dn_e + ell * ddn_e)
        grad[EN, j] = 2.0 * (dl * dE + ell * (dE_e - dE_s))
        dk = mp if j == 0 else 0.0
        sgn = 1.0 if k * ell >= 0.0 else -1.0
        grad[PHI, j] = sgn * (dk * ell + k * dl)


@njit(cache=True)
def window_profile(rot: bool, v: float, us: float, ue: float, s: np.ndarray, out: np.ndarray) -> None:
    """The window rod sampled at unit arc lengths ``s`` (increasing, in [0, 1]):
    ``out[:, 0:4] = x, y, theta, m`` (clamp frame, ``m = theta'``)."""
    p = np.empty(NP)
    ps = np.empty(NP)
    us, ue = reduce_window(rot, v, us, ue)
    k, kp = modulus(v)
    m, mp, K, Ec, Dc, Bc = orbit_constants(k, kp)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, us, ps)
    ell = ue - us
    if ell == 0.0:
        for j in range(s.shape[0]):
            out[j, 0], out[j, 1], out[j, 2], out[j, 3] = s[j], 0.0, 0.0, 0.0
        return
    sn_s, cn_s, dn_s = ps[SN], ps[CN], ps[DN]
    if rot:
        cpsi = sn_s * sn_s - cn_s * cn_s
        spsi = 2.0 * sn_s * cn_s
    else:
        cpsi = k * k * sn_s * sn_s - dn_s * dn_s
        spsi = 2.0 * k * sn_s * dn_s
    for j in range(s.shape[0]):
        du = ell * s[j]
        orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, us + du, p)
        dE = (p[EB] - ps[EB]) + (p[EU] - ps[EU])
        if rot:
            if m >= 0.5:
                dx = du - 2.0 * (dE - mp * du) / m
                dy = -2.0 * (dn_s - p[DN]) / m
            else:
                dx = 2.0 * ((p[DB] - ps[DB]) + (p[DU] - ps[DU])) - du
                dy = -2.0 * (p[SN] * p[SN] / (1.0 + p[DN]) - sn_s * sn_s / (1.0 + dn_s))
            th = 2.0 * ((p[AB] - ps[AB]) + (p[AM] - ps[AM]))
            mom = 2.0 * ell * p[DN]
        else:
            dx = du - 2.0 * dE
            dy = 2.0 * k * (p[CN] - cn_s)
            th = 2.0 * math.atan2(k * (p[SN] * dn_s - p[DN] * sn_s), k * k * p[SN] * sn_s + p[DN] * dn_s)
            mom = 2.0 * ell * k * p[CN]
        out[j, 0] = (cpsi * dx - spsi * dy) / ell
        out[j, 1] = (spsi * dx + cpsi * dy) / ell
        out[j, 2] = th
        out[j, 3] = mom


@njit(cache=True)
def _lib_span(v: float, us: float, ue: float):
    """Reduced window, modulus data and the ordered ends of a libration window."""
    k, kp = modulus(v)
    m, mp, K, Ec, Dc, Bc = orbit_constants(k, kp)
    a, b = (us, ue) if ue >= us else (ue, us)
    return k, kp, m, mp, K, Ec, Dc, Bc, a, b


@njit(cache=True)
def window_mode(rot: bool, v: float, us: float, ue: float, tol: float) -> tuple[int, bool]:
    """d-mode of a window rod (inflections strictly inside, SPEC §2) and whether an inflection
    sits at an end to within ``tol`` (``mode_boundary``): an end moment at most ``tol`` times
    the rod's largest moment.  Such an inflection is at the end, not inside, whichever side
    rounding put it (the lower label)."""
    if rot:
        return 0, False
    k, kp, m, mp, K, Ec, Dc, Bc, a, b = _lib_span(v, us, ue)
    if b == a:
        return 0, False
    # tops (2 j + 1) K strictly inside (a, b)
    lo = math.floor((a / K - 1.0) / 2.0) + 1      # smallest j with (2j+1)K > a
    hi = math.ceil((b / K - 1.0) / 2.0) - 1       # largest j with (2j+1)K < b
    count = max(0, int(hi - lo + 1))
    pa = np.empty(NP)
    pb = np.empty(NP)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, a, pa)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, b, pb)
    ca, cb = abs(pa[CN]), abs(pb[CN])
    # the largest |cn| on [a, b]: 1 at a bottom 2jK inside, else at an end
    jb = math.ceil(a / (2.0 * K))
    peak = 1.0 if 2.0 * jb * K <= b else max(ca, cb)
    boundary = False
    if ca <= tol * peak:
        boundary = True
        ja = round((a / K - 1.0) / 2.0)  # the top at a
        if (2 * ja + 1) * K > a and ja >= lo and ja <= hi:
            count -= 1
    if cb <= tol * peak:
        boundary = True
        jt = round((b / K - 1.0) / 2.0)
        if (2 * jt + 1) * K < b and jt >= lo and jt <= hi:
            count -= 1
    return max(count, 0), boundary


@njit(cache=True)
def window_peak(rot: bool, v: float, us: float, ue: float) -> float:
    """Largest ``|theta'|`` of a unit window rod (closed form: at a bottom ``2 j K`` inside the
    window, else at an end)."""
    k, kp, m, mp, K, Ec, Dc, Bc, a, b = _lib_span(v, us, ue)
    ell = abs(ue - us)
    pa = np.empty(NP)
    pb = np.empty(NP)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, a, pa)
    orbit_point(k, kp, m, mp, K, Ec, Dc, Bc, b, pb)
    jb = math.ceil(a / (2.0 * K))
    inside = 2.0 * jb * K <= b
    if rot:
        top = 1.0 if inside else max(pa[DN], pb[DN])
        return 2.0 * ell * top
    top = 1.0 if inside else max(abs(pa[CN]), abs(pb[CN]))
    return 2.0 * ell * abs(k) * top


@njit(cache=True)
def window_of(a: float, b: float, m0: float) -> tuple[bool, float, float, float]:
    """The window ``(rot, v, u_s, u_e)`` of the unit rod of base wrench ``(a, b, m0)`` (the chart
    of :mod:`~flexkin.rod.wrench`), in closed form (``a = b = 0`` has no window: ``v = nan``).

    With ``lambda = |n|^(1/2)``, ``psi`` the force direction in ``[0, 2 pi)``, ``c, s = cos, sin
    (psi/2)`` and ``mu = m0 / (2 lambda)``:

    * libration (``|mu| < s``): ``k^2 = c^2 + mu^2``, ``k'^2 = (s - |mu|)(s + |mu|)`` (no
      cancellation), ``am(u_s) = atan2(c, mu)``, ``u_e = u_s + lambda``;
    * rotation (``|mu| > s``): ``kappa^2 = 1 / (c^2 + mu^2)``, ``am(u_s) = (pi - psi)/2`` and
      ``u_e = u_s + sign(m0) lambda / kappa``;

    and ``v = log((1 + k) / k')`` (``= atanh k`` with ``k'`` exact).
    """
    R = math.hypot(a, b)
    if not R > 0.0:
        return False, math.nan, math.nan, math.nan
    lam = math.sqrt(R)
    psi = math.atan2(b, a)
    if psi < 0.0:
        psi += 2.0 * math.pi
    c, s = math.cos(0.5 * psi), math.sin(0.5 * psi)
    mu = m0 / (2.0 * lam)
    amu = abs(mu)
    rot = amu > s
    q = c * c + mu * mu
    if rot:
        k = 1.0 / math.sqrt(q)
        kp = math.sqrt((amu - s) * (amu + s) / q)
        phis = 0.5 * (math.pi - psi)
    else:
        k = math.sqrt(q)
        kp = math.sqrt((s - amu) * (s + amu))
        phis = math.atan2(c, mu)
    v = math.log1p(k) - math.log(kp) if kp > 0.0 else V_CAP
    m, mp = k * k, kp * kp
    K, Ec, Dc, Bc = complete(m, mp)
    us = fedb(phis, m, mp, K, Ec, Dc, Bc)[0]
    ell = (lam / k if m0 >= 0.0 else -lam / k) if rot else lam
    return rot, v, us, us + ell


@njit(cache=True)
def tip_sensitivity(grad: np.ndarray) -> float:
    """``|d(x, y, theta)/d m0|`` of a unit rod from its wrench-chart gradient (NQ, 3)."""
    return abs(grad[X, 2]) + abs(grad[Y, 2]) + abs(grad[TH, 2])


@njit(cache=True)
def taut_windows(charts: np.ndarray, Z: np.ndarray, wrench: int, lib: int, rot: int) -> int:
    """Move the rods in the wrench chart (code ``wrench``) whose tip sensitivity passes
    :data:`SENS_WINDOW` to their elastica windows (codes ``lib``, ``rot``), in place: ``charts``
    (n,), ``Z`` (n, 3).  Returns how many moved."""
    q = np.empty(NQ)
    g = np.empty((NQ, 3))
    moved = 0
    for r in range(Z.shape[0]):
        if charts[r] != wrench:
            continue
        wrench_eval(Z[r, 0], Z[r, 1], Z[r, 2], q, g)
        if not tip_sensitivity(g) > SENS_WINDOW:
            continue
        is_rot, v, us, ue = window_of(Z[r, 0], Z[r, 1], Z[r, 2])
        if not v == v:
            continue
        charts[r] = rot if is_rot else lib
        Z[r, 0], Z[r, 1], Z[r, 2] = v, us, ue
        moved += 1
    return moved
