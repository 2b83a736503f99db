"""Points of a pendulum orbit in elliptic time, with full precision near the separatrix (compiled).

A clamped rod of the elastica (paper §2 with both end amplitudes free, §8) is a *window* of
one phase orbit of the pendulum equation ``beta'' = sin(beta)`` (``beta = theta - psi``, the
tangent angle measured from the internal force, primes with respect to the scaled arc length
``tau = lambda s``).  Every orbit is the Jacobi elliptic motion of one modulus ``k``
(libration, ``k < 1``) or ``kappa = 1/k`` (rotation), and a point of it is given by its
*elliptic time* ``u`` (the argument of ``sn, cn, dn``; the amplitude is ``am(u)``).  The
separatrix (``k = 1``) is where rods are taut or tightly looped; there the amplitude ``am(u)``
piles up at the saddle (``pi/2 + j pi``) and loses all precision, while the time ``u`` does
not: near a *top* ``u = (2j + 1) K`` the functions are evaluated from the small offset ``w``
by the shift formulas (DLMF 22.4.3, 19.7.3 in Jacobi's form)

    sn(K + w) = cd w,   cn(K + w) = -k' sd w,   dn(K + w) = k' nd w,
    E(K + w)  = E + E(w) - m sn w cd w,

so that ``cn`` and ``dn`` keep their full *relative* precision however small ``k'`` is.

:func:`orbit_point` returns, at one time ``u``, ``sn, cn, dn``, the incomplete integrals
``E(u) = int_0^u dn^2`` and ``Dphi(u) = int_0^u sn^2`` (Carlson's ``D`` at the amplitude,
:mod:`~flexkin.rod.elliptic`) and the continuous amplitude ``am(u)`` -- each of these three
as a base (a whole multiple of its complete value, at the nearest top or bottom) plus a local
part, so that differences between two points near one top are exact -- and their derivatives with
respect to the chart variable ``v`` at fixed ``u`` (``k = tanh v``, ``k' = sech v``, so
``dm/dv = 2 k k'^2``).  From ``F(am(u)) = u`` and DLMF 19.4.1-19.4.4:

    d am/dv = k [sn cn - dn (u - Dphi)],      d dn/dv = -k sn^2 dn + k^3 sn cn (u - Dphi),
    d E/dv  = dn d am/dv - k k'^2 Dphi,       d Dphi/dv = (sn^2/dn) d am/dv + k k'^2 H

with ``H = int sin^4/Delta^3``; none of them divides by ``k'``.  The derivatives with respect
to ``u`` follow from the values (``sn' = cn dn``, ``cn' = -sn dn``, ``dn' = -m sn cn``,
``E' = dn^2``, ``Dphi' = sn^2``, ``am' = dn``).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.jit import njit
from .elliptic import complete, fedb, inverse_f

__all__ = ["NP", "SN", "CN", "DN", "EU", "DU", "AM", "EB", "DB", "AB", "DV", "orbit_point", "orbit_constants",
           "modulus"]

#: slots of :func:`orbit_point`'s output: ``sn, cn, dn`` and the *local* parts of ``E(u), Dphi(u),
#: am(u)``, their *bases* (whole multiples of the complete values, so that the difference of two
#: points near one top or bottom is exact), then the d/dv at fixed u of the full values
SN, CN, DN, EU, DU, AM, EB, DB, AB = range(9)
DV = 9
NP = 15


@njit(cache=True)
def modulus(v: float) -> tuple[float, float]:
    """``(k, k') = (tanh v, sech v)`` with ``k'`` exact for large ``|v|`` (capped at 350)."""
    av = min(abs(v), 350.0)
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
    k = math.tanh(v)
    return k, kp


@njit(cache=True)
def orbit_constants(k: float, kp: float):
    """``(m, m', K, E, Dc, Bc)`` of the orbit of modulus ``k`` (``k' = sqrt(1 - k^2)`` given)."""
    m = k * k
    mp = kp * kp
    K, Ec, Dc, Bc = complete(m, mp)
    return m, mp, K, Ec, Dc, Bc


@njit(cache=True)
def _hfun(phi: float, m: float, B: float, D: float) -> float:
    """``H(phi) = int_0^phi sin^4/Delta^3 = (B - D)/m``, by its series where that cancels."""
    if m > 1e-4:
        return (B - D) / m
    # 1/Delta^3 = 1 + (3/2) m s^2 + (15/8) m^2 s^4 + (35/16) m^3 s^6 + ...
    s, c = math.sin(phi), math.cos(phi)
    acc = 0.0
    coef = (1.0, 1.5, 1.875, 2.1875, 2.4609375)
    mk = 1.0
    I = phi
    # I_n = int_0^phi sin^(2n), recurrence I_n = ((2n-1) I_{n-1} - sin^(2n-1) cos) / (2n)
    for j in range(1, 7):
        I = ((2 * j - 1) * I - s ** (2 * j - 1) * c) / (2 * j)
        if j >= 2:
            acc += coef[j - 2] * mk * I
            mk *= m
    return acc


@njit(cache=True)
def orbit_point(k: float, kp: float, m: float, mp: float, K: float, Ec: float, Dc: float, Bc: float,
                u: float, out: np.ndarray) -> None:
    """The orbit of modulus ``k`` at elliptic time ``u`` -> ``out`` (:data:`NP`): ``sn, cn, dn,
    E(u), Dphi(u), am(u)`` and then their derivatives with respect to ``v`` (``k = tanh v``) at
    fixed ``u`` (see the module docstring).  ``m, m', K, E, Dc, Bc`` from :func:`orbit_constants`."""
    n = math.floor(u / (2.0 * K) + 0.5)
    r = u - 2.0 * n * K
    sg = 1.0 if (int(n) % 2) == 0 else -1.0
    if m < 0.5 or abs(r) <= 0.5 * K:
        phi = inverse_f(r, m, mp, K, r)
        F, E, D, B, d = fedb(phi, m, mp, K, Ec, Dc, Bc)
        S = math.sin(phi)
        C = math.cos(phi)
        sn, cn, dn = sg * S, sg * C, d
        nb = 2.0 * n
        Es, Ds, As = E, D, phi
        if m < 0.5:
            Bu = B + (nb * Bc if n != 0.0 else 0.0)
            H = _hfun(n * math.pi + phi, m, Bu, nb * Dc + D)
        else:
            H = 0.0
    else:
        # near the top t K (t = +-1): shift formulas in the offset w (module docstring);
        # E(tK + w) = t E + k'^2 (w + m B(w)) (int nd^2 = F + m B), Dphi = t Dc + Dphi(w) + sn cd
        t = 1.0 if r > 0.0 else -1.0
        w = r - t * K
        phw = inverse_f(w, m, mp, K, w)
        F, Ew, Dw, Bw, dw = fedb(phw, m, mp, K, Ec, Dc, Bc)
        Sw = math.sin(phw)
        Cw = math.cos(phw)
        sn = sg * t * Cw / dw
        cn = -sg * t * kp * Sw / dw
        dn = kp / dw
        nb = 2.0 * n + t
        Es = mp * (w + m * Bw)
        Ds = Dw + Sw * Cw / dw
        As = math.atan2(kp * Sw, Cw)
        H = 0.0
    out[SN], out[CN], out[DN] = sn, cn, dn
    out[EU], out[DU], out[AM] = Es, Ds, As
    out[EB], out[DB], out[AB] = nb * Ec, nb * Dc, nb * 0.5 * math.pi
    Du = out[DB] + Ds
    # ---- d/dv at fixed u (dm/dv = 2 k k'^2) ---------------------------------------------------
    g = u - Du
    am_v = k * (sn * cn - dn * g)
    out[DV + SN] = cn * am_v
    out[DV + CN] = -sn * am_v
    out[DV + DN] = -k * sn * sn * dn + k * k * k * sn * cn * g
    out[DV + EU] = dn * am_v - k * mp * Du
    if m < 0.5:
        out[DV + DU] = sn * sn / dn * am_v + k * mp * H
    else:
        out[DV + DU] = -(dn * am_v + k * mp * Du) / m
    out[DV + AM] = am_v
