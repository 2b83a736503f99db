"""A rod with a free tip amplitude (clamped joints, paper §8) in its wrench chart, compiled.

Chart coordinates: the dimensionless base wrench of the unit rod (``L = EI = 1``) in its clamp
frame, ``z = (a, b, m0)``: ``(a, b)`` the force ON the rod tip BY the platform (the constant
internal force ``n``, Eq. 7) and ``m0 = theta'(0)``.  The chart is global and smooth: every
rod of a clamped leg is one point of it, whatever its shape.  The closed form (paper §2, with
``phi_2`` free as §8 asks) distinguishes the two kinds of elastica, with ``lambda = |n|^(1/2)``,
``psi`` the direction of ``n`` in ``[0, 2 pi)``, ``c = cos(psi/2)``, ``s = sin(psi/2)``:

* **libration** (``|m0| < 2 lambda s``, the inflectional elastica, ``k < 1``): the paper's
  substitution ``cos((theta - psi)/2) = k sin(phi)``, ``theta' = 2 lambda k cos(phi)`` with
  ``k sin(phi1) = c``, ``k cos(phi1) = m0 / (2 lambda)`` and the tip amplitude
  ``phi2 = am(F(phi1) + lambda | k^2)`` (no longer ``(2q - 1) pi/2``); tip by Eqs. (12)-(13);
* **rotation** (``|m0| > 2 lambda s``, non-inflectional: the curvature keeps its sign, as in a
  rod bent into an arc by end moments), with ``K = lambda k = sqrt(lambda^2 c^2 + m0^2/4)``,
  the modulus ``kappa = 1/k = lambda / K``, ``chi = (theta - psi)/2 + pi/2``:
  ``chi' = sigma K Delta(chi | kappa^2)``, ``sigma = sign(m0)``, ``chi(0) = pi/2 - psi/2``,

      x_f = sigma (2/K) [D(chi2) - D(chi0)] - 1,    y_f = -(2 sigma / K) (sin^2 chi2 - sin^2 chi0) / (Delta2 + Delta0),

  in the frame of the force (``D`` of :mod:`~flexkin.rod.elliptic`), ``theta(L) = psi + 2 chi2 - pi``,
  ``m(L) = 2 sigma K Delta2``, energy ``2 sigma K [E(chi2) - E(chi0)]``;
* near the unloaded straight rod (``max(lambda, |m0|/2) <`` :data:`W_TAYLOR`), where both
  closed forms lose digits like ``1e-16 / lambda``, a Taylor series of the rod's ODE
  (Eqs. 5, 7) in the arc length, to machine precision in one step.

The d-mode of a rod clamped at both ends is the number of inflections strictly inside (SPEC §2;
a clamped tip is not an inflection): the points ``phi = pi/2 + j pi`` inside ``(phi1, phi2)``
for a librating rod, none for a rotating one (a C-shaped rod is 0, the buckled arch 2).
Derivatives with respect to ``(a, b, m0)`` are analytic (chain rule through the elliptic
integrals' classical derivatives, DLMF 19.4).  Near the separatrix (``|m0| ~ 2 lambda s`` with
the arc passing close to the saddle) the rod is physically ill-conditioned in this chart.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.jit import njit
from .elliptic import HALF_PI, complete, fedb, inverse_f
from .slots import EN, FX, FY, M0, ML, PHI, TH, X, Y

__all__ = ["wrench_eval", "wrench_profile", "wrench_mode", "W_TAYLOR"]

#: below this ``max(lambda, |m0|/2)`` the rod is evaluated by its Taylor series
W_TAYLOR = 0.1
#: Taylor order (the terms decay like W_TAYLOR^k / k!)
_P = 32
TWO_PI = 2.0 * math.pi


@njit
def _sin_powers(chi: float, n: int) -> float:
    """``int_0^chi sin^(2n) t dt`` (recurrence I_n = ((2n-1) I_{n-1} - sin^(2n-1) cos) / (2n))."""
    s, c = math.sin(chi), math.cos(chi)
    I = chi
    for j in range(1, n + 1):
        I = ((2 * j - 1) * I - s ** (2 * j - 1) * c) / (2 * j)
    return I


@njit
def _H(chi: float, m: float, B: float, D: float) -> float:
    """``int_0^chi sin^4 / Delta^3 = (B - D) / m``; a series in ``m`` where that cancels."""
    if m > 1e-4:
        return (B - D) / m
    # 1/Delta^3 = 1 + (3/2) m sin^2 + (15/8) m^2 sin^4 + (35/16) m^3 sin^6
    return (_sin_powers(chi, 2) + 1.5 * m * _sin_powers(chi, 3) + 1.875 * m * m * _sin_powers(chi, 4)
            + 2.1875 * m ** 3 * _sin_powers(chi, 5))


@njit
def _taylor(a: float, b: float, m0: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Near-straight rod: Taylor series of ``theta' = m, m' = a sin theta - b cos theta,
    x' = cos theta, y' = sin theta`` about the clamp, with the derivatives of every coefficient
    with respect to ``(a, b, m0)`` (forward-mode), summed at ``s = 1``."""
    P = _P
    th = np.zeros(P + 1)
    mm = np.zeros(P + 1)
    xx = np.zeros(P + 1)
    yy = np.zeros(P + 1)
    S = np.zeros(P + 1)
    C = np.zeros(P + 1)
    dth = np.zeros((P + 1, 3))
    dmm = np.zeros((P + 1, 3))
    dxx = np.zeros((P + 1, 3))
    dyy = np.zeros((P + 1, 3))
    dS = np.zeros((P + 1, 3))
    dC = np.zeros((P + 1, 3))
    mm[0] = m0
    dmm[0, 2] = 1.0
    C[0] = 1.0
    for k in range(P):
        if k >= 1:
            sk = 0.0
            ck = 0.0
            for j in range(1, k + 1):
                sk += j * th[j] * C[k - j]
                ck -= j * th[j] * S[k - j]
            S[k] = sk / k
            C[k] = ck / k
            for q in range(3):
                dsk = 0.0
                dck = 0.0
                for j in range(1, k + 1):
                    dsk += j * (dth[j, q] * C[k - j] + th[j] * dC[k - j, q])
                    dck -= j * (dth[j, q] * S[k - j] + th[j] * dS[k - j, q])
                dS[k, q] = dsk / k
                dC[k, q] = dck / k
        inv = 1.0 / (k + 1)
        th[k + 1] = mm[k] * inv
        mm[k + 1] = (a * S[k] - b * C[k]) * inv
        xx[k + 1] = C[k] * inv
        yy[k + 1] = S[k] * inv
        for q in range(3):
            dth[k + 1, q] = dmm[k, q] * inv
            dmm[k + 1, q] = (a * dS[k, q] - b * dC[k, q]) * inv
            dxx[k + 1, q] = dC[k, q] * inv
            dyy[k + 1, q] = dS[k, q] * inv
        dmm[k + 1, 0] += S[k] * inv
        dmm[k + 1, 1] -= C[k] * inv
    grad[:, :] = 0.0
    x = y = t = mL = U = 0.0
    for k in range(P, -1, -1):
        x += xx[k]
        y += yy[k]
        t += th[k]
        mL += mm[k]
        for q in range(3):
            grad[X, q] += dxx[k, q]
            grad[Y, q] += dyy[k, q]
            grad[TH, q] += dth[k, q]
            grad[ML, q] += dmm[k, q]
    for i in range(P + 1):
        for j in range(P + 1):
            f = 0.5 / (i + j + 1)
            U += f * mm[i] * mm[j]
            for q in range(3):
                grad[EN, q] += 2.0 * f * mm[i] * dmm[j, q]
    out[X], out[Y], out[TH], out[ML], out[EN] = x, y, t, mL, U


@njit
def _half_angles(a: float, b: float):
    """``psi`` in [0, 2 pi), ``cos(psi/2)``, ``sin(psi/2)``, ``R = |n|`` of the force ``(a, b)``."""
    R = math.hypot(a, b)
    psi = math.atan2(b, a)
    if psi < 0.0:
        psi += TWO_PI
    return psi, math.cos(0.5 * psi), math.sin(0.5 * psi), R


@njit
def wrench_eval(a: float, b: float, m0: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Unit rod with base wrench ``(a, b, m0)`` -> ``out`` (NQ,) and ``grad`` (NQ, 3) = d/d(a, b, m0)."""
    psi, c, s, R = _half_angles(a, b)
    lam = math.sqrt(R)
    half = 0.5 * abs(m0)
    out[FX], out[FY], out[M0], out[PHI] = a, b, m0, lam
    grad[:, :] = 0.0
    grad[FX, 0] = 1.0
    grad[FY, 1] = 1.0
    grad[M0, 2] = 1.0
    if max(lam, half) < W_TAYLOR:
        _taylor(a, b, m0, out, grad)
        grad[FX, 0] = 1.0
        grad[FY, 1] = 1.0
        grad[M0, 2] = 1.0
        if lam > 0.0:
            grad[PHI, 0] = a / (2.0 * lam * R)
            grad[PHI, 1] = b / (2.0 * lam * R)
        return
    # d(lambda), d(psi), d(m0) with respect to (a, b, m0)
    dlam = np.zeros(3)
    dpsi = np.zeros(3)
    dm0 = np.zeros(3)
    dm0[2] = 1.0
    if R > 0.0:
        dlam[0] = a / (2.0 * lam * R)
        dlam[1] = b / (2.0 * lam * R)
        dpsi[0] = -b / (R * R)
        dpsi[1] = a / (R * R)
    grad[PHI, :] = dlam
    dc = -0.5 * s * dpsi
    cp, sp = c * c - s * s, 2.0 * c * s
    dcp = -sp * dpsi
    dsp = cp * dpsi
    if half < lam * s:
        # ---- libration: k < 1 ---------------------------------------------------------------
        mu = m0 / (2.0 * lam)
        dmu = (dm0 - 2.0 * mu * dlam) / (2.0 * lam)
        k2 = c * c + mu * mu
        kp2 = (s - abs(mu)) * (s + abs(mu))
        k = math.sqrt(k2)
        phi1 = math.atan2(c, mu)
        dphi1 = (mu * dc - c * dmu) / k2
        dm = 2.0 * (c * dc + mu * dmu)
        dk = 0.5 * dm / k
        K, Ec, Dc, Bc = complete(k2, kp2)
        F1, E1, D1, B1, d1 = fedb(phi1, k2, kp2, K, Ec, Dc, Bc)
        phie = inverse_f(F1 + lam, k2, kp2, K, phi1 + lam)
        Fe, Ee, De, Be, de = fedb(phie, k2, kp2, K, Ec, Dc, Bc)
        dF1 = dphi1 / d1 + 0.5 * B1 * dm
        dphie = de * (dF1 + dlam - 0.5 * Be * dm)
        DE = Ee - E1
        dDE = de * dphie - d1 * dphi1 - 0.5 * (De - D1) * dm
        G = 2.0 * DE - lam
        dG = 2.0 * dDE - dlam
        se, ce = math.sin(phie), math.cos(phie)
        Cd = ce - math.cos(phi1)
        dCd = -se * dphie + math.sin(phi1) * dphi1
        Nx = cp * G + 2.0 * k * sp * Cd
        Ny = sp * G - 2.0 * k * cp * Cd
        x = -Nx / lam
        y = -Ny / lam
        dNx = dcp * G + cp * dG + 2.0 * (dk * sp * Cd + k * dsp * Cd + k * sp * dCd)
        dNy = dsp * G + sp * dG - 2.0 * (dk * cp * Cd + k * dcp * Cd + k * cp * dCd)
        Xa, Ya = k * se, -de
        dXa = dk * se + k * ce * dphie
        dde = (-se * se * dm - 2.0 * k2 * se * ce * dphie) / (2.0 * de)
        out[X], out[Y] = x, y
        out[TH] = psi + 2.0 * math.atan2(Ya, Xa)
        out[ML] = 2.0 * lam * k * ce
        out[EN] = 2.0 * lam * (DE - kp2 * lam)
        for q in range(3):
            grad[X, q] = (-dNx[q] - x * dlam[q]) / lam
            grad[Y, q] = (-dNy[q] - y * dlam[q]) / lam
            grad[TH, q] = dpsi[q] + 2.0 * (Xa * (-dde[q]) - Ya * dXa[q])
            grad[ML, q] = 2.0 * (dlam[q] * k * ce + lam * dk[q] * ce - lam * k * se * dphie[q])
            grad[EN, q] = (2.0 * dlam[q] * (DE - kp2 * lam)
                           + 2.0 * lam * (dDE[q] + dm[q] * lam - kp2 * dlam[q]))
        return
    # ---- rotation: k > 1 (non-inflectional) ---------------------------------------------------
    sig = 1.0 if m0 > 0.0 else -1.0
    Ke = math.sqrt(lam * lam * c * c + 0.25 * m0 * m0)
    dKe = (lam * c * c * dlam + lam * lam * c * dc + 0.25 * m0 * dm0) / Ke
    mr = (lam / Ke) ** 2
    kp2 = (half - lam * s) * (half + lam * s) / (Ke * Ke)
    dmr = 2.0 * (lam / Ke) * (dlam / Ke - lam * dKe / (Ke * Ke))
    chi0 = HALF_PI - 0.5 * psi
    dchi0 = -0.5 * dpsi
    K, Ec, Dc, Bc = complete(mr, kp2)
    F0, E0, D0, B0, d0 = fedb(chi0, mr, kp2, K, Ec, Dc, Bc)
    chie = inverse_f(F0 + sig * Ke, mr, kp2, K, chi0 + sig * Ke)
    Fe, Ee, De, Be, de = fedb(chie, mr, kp2, K, Ec, Dc, Bc)
    dF0 = dchi0 / d0 + 0.5 * B0 * dmr
    dchie = de * (dF0 + sig * dKe - 0.5 * Be * dmr)
    s0, c0_ = math.sin(chi0), math.cos(chi0)
    se, ce = math.sin(chie), math.cos(chie)
    He = _H(chie, mr, Be, De)
    H0 = _H(chi0, mr, B0, D0)
    DD = De - D0
    dDD = (se * se / de) * dchie - (s0 * s0 / d0) * dchi0 + 0.5 * (He - H0) * dmr
    DE = Ee - E0
    dDE = de * dchie - d0 * dchi0 - 0.5 * (De - D0) * dmr
    xf = sig * 2.0 * DD / Ke - 1.0
    dxf = sig * 2.0 * (dDD / Ke - DD * dKe / (Ke * Ke))
    Sd = se * se - s0 * s0
    Ds = de + d0
    yf = -2.0 * sig * Sd / (Ke * Ds)
    dSd = 2.0 * se * ce * dchie - 2.0 * s0 * c0_ * dchi0
    dde = (-se * se * dmr - 2.0 * mr * se * ce * dchie) / (2.0 * de)
    dd0 = (-s0 * s0 * dmr - 2.0 * mr * s0 * c0_ * dchi0) / (2.0 * d0)
    dyf = -2.0 * sig * (dSd / (Ke * Ds) - Sd * dKe / (Ke * Ke * Ds) - Sd * (dde + dd0) / (Ke * Ds * Ds))
    out[X] = cp * xf - sp * yf
    out[Y] = sp * xf + cp * yf
    out[TH] = psi + 2.0 * chie - math.pi
    out[ML] = 2.0 * sig * Ke * de
    out[EN] = 2.0 * sig * Ke * DE
    for q in range(3):
        grad[X, q] = dcp[q] * xf + cp * dxf[q] - dsp[q] * yf - sp * dyf[q]
        grad[Y, q] = dsp[q] * xf + sp * dxf[q] + dcp[q] * yf + cp * dyf[q]
        grad[TH, q] = dpsi[q] + 2.0 * dchie[q]
        grad[ML, q] = 2.0 * sig * (dKe[q] * de + Ke * dde[q])
        grad[EN, q] = 2.0 * sig * (dKe[q] * DE + Ke * dDE[q])


@njit
def wrench_profile(a: float, b: float, m0: float, s: np.ndarray, out: np.ndarray) -> None:
    """The rod of base wrench ``(a, b, m0)`` at unit arc lengths ``s`` (increasing):
    ``out[:, 0:4] = x, y, theta, m`` (local clamp frame)."""
    psi, c, sh, R = _half_angles(a, b)
    lam = math.sqrt(R)
    half = 0.5 * abs(m0)
    n = s.shape[0]
    if max(lam, half) < W_TAYLOR:
        # Taylor series summed at every s (the series of _taylor, values only)
        q = np.empty(9)
        g = np.empty((9, 3))
        for j in range(n):
            _taylor(a * s[j] ** 2, b * s[j] ** 2, m0 * s[j], q, g)  # scaling: a rod of length s
            out[j, 0] = q[X] * s[j]
            out[j, 1] = q[Y] * s[j]
            out[j, 2] = q[TH]
            out[j, 3] = q[ML] / s[j] if s[j] > 0.0 else m0
        return
    cp, sp = c * c - sh * sh, 2.0 * c * sh
    if half < lam * sh:
        mu = m0 / (2.0 * lam)
        k2 = c * c + mu * mu
        kp2 = (sh - abs(mu)) * (sh + abs(mu))
        k = math.sqrt(k2)
        phi1 = math.atan2(c, mu)
        K, Ec, Dc, Bc = complete(k2, kp2)
        F1, E1, D1, B1, d1 = fedb(phi1, k2, kp2, K, Ec, Dc, Bc)
        phi = phi1
        for j in range(n):
            if s[j] > 0.0:
                phi = inverse_f(F1 + lam * s[j], k2, kp2, K, phi)
            Fp, Ep, Dp, Bp, dp = fedb(phi, k2, kp2, K, Ec, Dc, Bc)
            G = 2.0 * (Ep - E1) - lam * s[j]
            Cd = math.cos(phi) - math.cos(phi1)
            out[j, 0] = -(cp * G + 2.0 * k * sp * Cd) / lam
            out[j, 1] = -(sp * G - 2.0 * k * cp * Cd) / lam
            out[j, 2] = psi + 2.0 * math.atan2(-dp, k * math.sin(phi))
            out[j, 3] = 2.0 * lam * k * math.cos(phi)
        return
    sig = 1.0 if m0 > 0.0 else -1.0
    Ke = math.sqrt(lam * lam * c * c + 0.25 * m0 * m0)
    mr = (lam / Ke) ** 2
    kp2 = (half - lam * sh) * (half + lam * sh) / (Ke * Ke)
    chi0 = HALF_PI - 0.5 * psi
    K, Ec, Dc, Bc = complete(mr, kp2)
    F0, E0, D0, B0, d0 = fedb(chi0, mr, kp2, K, Ec, Dc, Bc)
    s0 = math.sin(chi0)
    chi = chi0
    for j in range(n):
        if s[j] > 0.0:
            chi = inverse_f(F0 + sig * Ke * s[j], mr, kp2, K, chi)
        Fp, Ep, Dp, Bp, dp = fedb(chi, mr, kp2, K, Ec, Dc, Bc)
        xf = sig * 2.0 * (Dp - D0) / Ke - s[j]
        sc = math.sin(chi)
        yf = -2.0 * sig * (sc * sc - s0 * s0) / (Ke * (dp + d0))
        out[j, 0] = cp * xf - sp * yf
        out[j, 1] = sp * xf + cp * yf
        out[j, 2] = psi + 2.0 * chi - math.pi
        out[j, 3] = 2.0 * sig * Ke * dp


@njit
def wrench_mode(a: float, b: float, m0: float, tol: float) -> tuple[int, bool]:
    """d-mode (the inflections strictly inside, SPEC §2) of the rod of base wrench ``(a, b, m0)`` and
    whether an inflection sits at an end to within ``tol`` in ``|cos phi|`` (``mode_boundary``)."""
    psi, c, sh, R = _half_angles(a, b)
    lam = math.sqrt(R)
    if not 0.5 * abs(m0) < lam * sh:
        return 0, False  # rotating: the curvature never changes sign
    mu = m0 / (2.0 * lam)
    k2 = c * c + mu * mu
    kp2 = (sh - abs(mu)) * (sh + abs(mu))
    phi1 = math.atan2(c, math.copysign(max(abs(mu), 1e-300), mu))
    K, Ec, Dc, Bc = complete(k2, kp2)
    F1 = fedb(phi1, k2, kp2, K, Ec, Dc, Bc)[0]
    phie = inverse_f(F1 + lam, k2, kp2, K, phi1 + lam)
    lo = math.floor((phi1 - HALF_PI) / math.pi) + 1   # smallest j with pi/2 + j pi > phi1
    hi = math.ceil((phie - HALF_PI) / math.pi) - 1    # largest j with pi/2 + j pi < phie
    # an inflection within tol of an end is at that end, not inside, whichever side rounding
    # put it: a rod on the boundary between two d-modes carries the lower label (SPEC §2)
    at_base = abs(math.cos(phi1)) < tol
    at_tip = abs(math.cos(phie)) < tol
    if at_base and lo == round((phi1 - HALF_PI) / math.pi):
        lo += 1
    if at_tip and hi == round((phie - HALF_PI) / math.pi):
        hi -= 1
    mode = max(0, int(hi - lo + 1))
    boundary = at_base or at_tip
    return mode, boundary
