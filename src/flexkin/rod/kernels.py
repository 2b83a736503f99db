"""Compiled closed-form rod kernels with analytic derivatives (numba, ``cache=True``).

One evaluation returns the dimensionless tip quantities of a unit rod (``L = EI = 1``,
clamp at the origin, clamp tangent along +x) and their derivatives with respect to the
rod's chart coordinates.  The output slots are

    X, Y   tip position (Eqs. 12-13 at the tip amplitude)
    TH     tangent angle at the tip (continuous value)
    FX, FY force ON the tip BY the platform, local frame (Eq. 9: R = Phi^2, direction psi)
    M0, ML bending moment EI theta' at the clamp and at the tip
    EN     bending energy (EI/2) int theta'^2 ds
    PHI    lambda L = F(phi_e) - F(phi_s)

and scale with ``L``, ``EI`` as: positions ~ L, forces ~ EI/L^2, moments and energy ~ EI/L.

Charts (all share the substitution of paper §2, ``cos((theta - psi)/2) = k sin(phi)``,
``theta' = 2 lambda k cos(phi)``, ``phi' = lambda Delta(phi)``):

* ``CHART_UNIFIED`` ``(v, phis)``: a pinned rod, ``ku = tanh v`` (``k' = sech v`` exact),
  tip amplitude ``pi/2`` (inflection at the pinned tip, Eq. 11), clamp amplitude
  ``phis = phi1 - (q - 1) pi`` (every d-mode in one chart, see :mod:`~flexkin.rod.closed_form`).
* ``CHART_SEAM`` ``(psi_s, chi)``: the same pinned rods near straight under tension, with the
  signed force direction and the complementary amplitude (regular across the seam ``|k| = 1``).
* ``CHART_WRENCH`` ``(fx, fy, m0)``: a rod with a free tip (clamped joints), given by its
  dimensionless base wrench; evaluated in closed form through the libration (``k^2 < 1``) or
  rotation (``k^2 > 1``, non-inflectional) elastica.
* ``CHART_LIB``, ``CHART_ROT`` ``(v, u_s, u_e)``: the same clamped rods as windows of a
  librating or rotating elastica orbit in elliptic time (:mod:`~flexkin.rod.elastica`), well
  conditioned for taut rods (orbits passing close to the saddle), where the wrench chart loses
  the tip's digits like ``exp(lambda L)``.

The derivative formulas follow from DLMF 19.4.1-19.4.4 (see :mod:`~flexkin.rod.elliptic`);
with ``m = tanh(v)^2``: ``dF/dv = ku (F - D - sin cos / Delta)``, ``dE/dv = -k'^2 ku D``.
"""

from __future__ import annotations

import math

import numpy as np
from ..core.jit import njit

from .elliptic import HALF_PI, complete, fedb, inverse_f
from .elastica import V_CAP, lib_eval, rot_eval, window_mode, window_peak, window_profile
from .slots import (CHART_DIM, CHART_LIB, CHART_ROT, CHART_SEAM, CHART_UNIFIED, CHART_WRENCH, EN, FX, FY, M0, ML,
                    NQ, PHI, TH, X, Y)
from .wrench import wrench_eval, wrench_mode, wrench_profile

__all__ = [
    "NQ", "X", "Y", "TH", "FX", "FY", "M0", "ML", "EN", "PHI",
    "CHART_UNIFIED", "CHART_SEAM", "CHART_WRENCH", "CHART_LIB", "CHART_ROT", "CHART_DIM", "clamped_mode",
    "clamped_peak",
    "unified_eval", "seam_eval", "eval_rod", "project", "V_MAX", "eval_rods", "profile", "profile_batch", "tangents",
]


@njit(cache=True)
def unified_eval(v: float, phis: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Pinned unit rod in the solvers' chart ``(v, phis)``; ``grad[:, 0:2]`` = d/d(v, phis).

    The unloaded straight rod (``phis >= pi/2``, ``Phi = 0``) returns the straight rod and a
    zero gradient (the chart's pole; the solvers never stop there).
    """
    grad[:, :] = 0.0
    av = abs(v)
    if av > 350.0:
        av = 350.0
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))  # sech |v|
    ku = math.tanh(v)
    kp2 = kp * kp
    m = ku * ku
    K, Ec, Dc, Bc = complete(m, kp2)
    Fs, Es, Ds, Bs, ds = fedb(phis, m, kp2, K, Ec, Dc, Bc)
    Phi = K - Fs
    if not Phi > 0.0:
        out[:] = 0.0
        out[X] = 1.0
        return
    ss = math.sin(phis)
    cs = math.cos(phis)
    DE = Ec - Es
    G = 2.0 * DE - Phi
    c = ku * ss           # cos(psi/2)
    cp = c * c - ds * ds  # cos psi  (sin(psi/2) = Delta(phis))
    sp = 2.0 * c * ds     # sin psi
    Nx = G * cp - 2.0 * ku * sp * cs
    Ny = G * sp + 2.0 * ku * cp * cs
    x = -Nx / Phi
    y = -Ny / Phi
    psi = 2.0 * math.atan2(ds, c)
    out[X] = x
    out[Y] = y
    out[TH] = psi + 2.0 * math.atan2(-kp, ku)
    P2 = Phi * Phi
    out[FX] = P2 * cp
    out[FY] = P2 * sp
    out[M0] = 2.0 * Phi * ku * cs
    out[ML] = 0.0
    out[EN] = 2.0 * Phi * (DE - kp2 * Phi)
    out[PHI] = Phi
    # ---- derivatives: column 0 = d/dv, column 1 = d/dphis
    dku = (kp2, 0.0)
    dkp2 = (-2.0 * ku * kp2, 0.0)
    dK_v = ku * (K - Dc)
    dEc_v = -kp2 * ku * Dc
    dFs = (ku * (Fs - Ds - ss * cs / ds), 1.0 / ds)
    dEs = (-kp2 * ku * Ds, ds)
    dds = (-ku * kp2 * ss * ss / ds, -m * ss * cs / ds)
    dss = (0.0, cs)
    dcs = (0.0, -ss)
    for j in range(2):
        dPhi = (dK_v if j == 0 else 0.0) - dFs[j]
        dDE = (dEc_v if j == 0 else 0.0) - dEs[j]
        dG = 2.0 * dDE - dPhi
        dc = dku[j] * ss + ku * dss[j]
        dcp = 2.0 * c * dc - 2.0 * ds * dds[j]
        dsp = 2.0 * (dc * ds + c * dds[j])
        dNx = dG * cp + G * dcp - 2.0 * (dku[j] * sp * cs + ku * dsp * cs + ku * sp * dcs[j])
        dNy = dG * sp + G * dsp + 2.0 * (dku[j] * cp * cs + ku * dcp * cs + ku * cp * dcs[j])
        grad[X, j] = (-dNx - x * dPhi) / Phi
        grad[Y, j] = (-dNy - y * dPhi) / Phi
        dpsi = 2.0 * (c * dds[j] - ds * dc)
        grad[TH, j] = dpsi + (2.0 * kp if j == 0 else 0.0)
        grad[FX, j] = 2.0 * Phi * dPhi * cp + P2 * dcp
        grad[FY, j] = 2.0 * Phi * dPhi * sp + P2 * dsp
        grad[M0, j] = 2.0 * (dPhi * ku * cs + Phi * dku[j] * cs + Phi * ku * dcs[j])
        grad[EN, j] = 2.0 * (dPhi * DE + Phi * dDE) - 2.0 * dkp2[j] * P2 - 4.0 * kp2 * Phi * dPhi
        grad[PHI, j] = dPhi


#: bound on the unified chart's v (k' = sech v ~ 2 exp(-|v|))
V_MAX = 40.0


@njit(cache=True)
def project(chart: int, z: np.ndarray) -> None:
    """Map chart coordinates ``z`` back into their chart, in place.

    Unified chart: a step across ``phis = pi/2`` passes through the unloaded straight rod,
    where the chart is polar (``sqrt(R) ~ pi/2 - phis``, ``psi = 2 arccos(ku)``); it continues
    on the other side with the force reversed: ``phis -> pi - phis`` and ``psi -> psi +- pi``,
    i.e. ``a -> a -+ pi/2`` for the Gudermannian angle ``a = arcsin(ku)`` of ``v``.  ``|v|`` is
    capped at :data:`V_MAX`.  Seam chart: ``|psi_s| < pi`` and ``0 < chi < pi/2``.  Elastica
    windows: ``|v| <=`` :data:`~flexkin.rod.elastica.V_CAP`.
    """
    if chart == CHART_UNIFIED:
        if z[1] > HALF_PI - 1e-12:
            z[1] = min(math.pi - z[1], HALF_PI - 1e-12)
            a = math.atan(math.sinh(min(max(z[0], -700.0), 700.0)))
            a = a - HALF_PI if a >= 0.0 else a + HALF_PI
            z[0] = math.asinh(math.tan(a))
        z[0] = min(max(z[0], -V_MAX), V_MAX)
    elif chart == CHART_SEAM:
        z[0] = min(max(z[0], -math.pi + 1e-9), math.pi - 1e-9)
        z[1] = min(max(z[1], 1e-12), HALF_PI - 1e-9)
    elif chart == CHART_LIB:
        z[0] = min(max(z[0], -V_CAP), V_CAP)
    elif chart == CHART_ROT:
        z[0] = min(abs(z[0]), V_CAP)  # only kappa^2 enters a rotating window


@njit(cache=True)
def seam_eval(psi_s: float, chi: float, out: np.ndarray, grad: np.ndarray) -> None:
    """Pinned unit rod in the seam chart ``(psi_s, chi)``; ``grad[:, 0:2]`` = d/d(psi_s, chi).

    ``psi_s`` in ``(-pi, pi)`` is the signed direction of the tip force from the clamp axis and
    ``chi`` in ``(0, pi/2)`` the complementary amplitude of the clamp (Jacobi:
    ``F(phis) + F(chi) = K`` when ``tan(phis) tan(chi) = 1/k'``), so that, with ``h = |psi_s|/2``,

        k' = sin h cos chi / sqrt(cos^2 chi + cos^2 h sin^2 chi),
        pi/2 - phis = atan2(sin h sin chi, sqrt(cos^2 chi + cos^2 h sin^2 chi)),
        lambda L = F(chi | k^2),   E(pi/2) - E(phis) = E(chi) - k^2 cos(phis) sin(chi)   (Legendre)

    and nothing cancels as ``k' -> 0``: the straight rod under tension (``psi_s = 0``) is an
    ordinary point and the rod and its mirror image (``psi_s -> -psi_s``) are neighbours.
    The derivatives are taken with ``sign(psi_s)`` held (the composite is smooth across 0).
    """
    grad[:, :] = 0.0
    sgn = 1.0 if psi_s >= 0.0 else -1.0
    h = 0.5 * abs(psi_s)
    sh, chh = math.sin(h), math.cos(h)
    sc, cc = math.sin(chi), math.cos(chi)
    D2 = cc * cc + chh * chh * sc * sc
    den = math.sqrt(D2)
    kp = sh * cc / den
    Yv = sh * sc
    eps = math.atan2(Yv, den)
    kp2 = kp * kp
    ku = sgn * math.sqrt(max(1.0 - kp2, 0.0))
    m = ku * ku
    K, Ec, Dc, Bc = complete(m, kp2)
    Fx_, Ex_, Dx_, Bx_, dx_ = fedb(chi, m, kp2, K, Ec, Dc, Bc)
    Phi = Fx_
    if not Phi > 0.0:
        out[:] = 0.0
        out[X] = 1.0
        return
    ce, se = math.cos(eps), math.sin(eps)
    DE = Ex_ - m * ce * sc
    cp, sp = math.cos(psi_s), math.sin(psi_s)
    cph = se
    G = 2.0 * DE - Phi
    Nx = G * cp - 2.0 * ku * sp * cph
    Ny = G * sp + 2.0 * ku * cp * cph
    x = -Nx / Phi
    y = -Ny / Phi
    out[X] = x
    out[Y] = y
    psi = psi_s if psi_s >= 0.0 else 2.0 * math.pi + psi_s
    out[TH] = psi + 2.0 * math.atan2(-kp, ku)
    P2 = Phi * Phi
    out[FX] = P2 * cp
    out[FY] = P2 * sp
    out[M0] = 2.0 * ku * Phi * cph
    out[ML] = 0.0
    out[EN] = 2.0 * Phi * (DE - kp2 * Phi)
    out[PHI] = Phi
    for j in range(2):
        dh = 0.5 * sgn if j == 0 else 0.0
        dchi = 1.0 if j == 1 else 0.0
        dps = 1.0 if j == 0 else 0.0
        dsh = chh * dh
        dchh = -sh * dh
        dsc = cc * dchi
        dcc = -sc * dchi
        dD2 = 2.0 * cc * dcc + 2.0 * chh * dchh * sc * sc + 2.0 * chh * chh * sc * dsc
        dden = dD2 / (2.0 * den)
        dkp = (dsh * cc + sh * dcc) / den - kp * dden / den
        dY = dsh * sc + sh * dsc
        deps = den * dY - Yv * dden
        dku = -kp * dkp / ku
        dkp2 = 2.0 * kp * dkp
        dm = -dkp2
        dPhi = dchi / dx_ + 0.5 * Bx_ * dm
        dE = dx_ * dchi - 0.5 * Dx_ * dm
        dDE = dE - dm * ce * sc + m * se * deps * sc - m * ce * dsc
        dcp = -sp * dps
        dsp = cp * dps
        dcph = ce * deps
        dG = 2.0 * dDE - dPhi
        dNx = dG * cp + G * dcp - 2.0 * (dku * sp * cph + ku * dsp * cph + ku * sp * dcph)
        dNy = dG * sp + G * dsp + 2.0 * (dku * cp * cph + ku * dcp * cph + ku * cp * dcph)
        grad[X, j] = (-dNx - x * dPhi) / Phi
        grad[Y, j] = (-dNy - y * dPhi) / Phi
        grad[TH, j] = dps + 2.0 * (-ku * dkp + kp * dku)
        grad[FX, j] = 2.0 * Phi * dPhi * cp + P2 * dcp
        grad[FY, j] = 2.0 * Phi * dPhi * sp + P2 * dsp
        grad[M0, j] = 2.0 * (dku * Phi * cph + ku * dPhi * cph + ku * Phi * dcph)
        grad[EN, j] = 2.0 * (dPhi * DE + Phi * dDE) - 2.0 * dkp2 * P2 - 4.0 * kp2 * Phi * dPhi
        grad[PHI, j] = dPhi


@njit(cache=True)
def eval_rod(chart: int, z: np.ndarray, out: np.ndarray, grad: np.ndarray) -> None:
    """One unit rod in chart ``chart`` at coordinates ``z`` -> ``out`` (NQ,), ``grad`` (NQ, 3)."""
    if chart == CHART_UNIFIED:
        unified_eval(z[0], z[1], out, grad)
    elif chart == CHART_SEAM:
        seam_eval(z[0], z[1], out, grad)
    elif chart == CHART_LIB:
        lib_eval(z[0], z[1], z[2], out, grad)
    elif chart == CHART_ROT:
        rot_eval(z[0], z[1], z[2], out, grad)
    else:
        wrench_eval(z[0], z[1], z[2], out, grad)


@njit(cache=True)
def eval_rods(chart: np.ndarray, z: np.ndarray, out: np.ndarray, grad: np.ndarray) -> None:
    """Evaluate ``n`` unit rods: ``chart`` (n,) codes, ``z`` (n, 3) coordinates -> ``out`` (n, NQ),
    ``grad`` (n, NQ, 3)."""
    for i in range(z.shape[0]):
        eval_rod(chart[i], z[i], out[i], grad[i])


@njit(cache=True)
def unified_profile(v: float, phis: float, s: np.ndarray, out: np.ndarray) -> None:
    """Pinned unit rod ``(v, phis)`` sampled at arc lengths ``s`` (in [0, 1], increasing):
    ``out[:, 0:4]`` = ``x, y, theta, m`` (moment ``theta'``), local clamp frame.

    The amplitude along the rod is the Jacobi amplitude ``phi(s) = am(F(phis) + Phi s)``
    (``phi' = lambda Delta``), found by safeguarded Newton on ``F`` with ``k'`` exact, so
    rods near the separatrix keep full precision.
    """
    av = min(abs(v), 350.0)
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
    ku = math.tanh(v)
    kp2 = kp * kp
    m = ku * ku
    K, Ec, Dc, Bc = complete(m, kp2)
    Fs, Es, Ds, Bs, ds = fedb(phis, m, kp2, K, Ec, Dc, Bc)
    Phi = K - Fs
    if not Phi > 0.0:
        for j in range(s.shape[0]):
            out[j, 0] = s[j]
            out[j, 1] = 0.0
            out[j, 2] = 0.0
            out[j, 3] = 0.0
        return
    c = ku * math.sin(phis)
    cp = c * c - ds * ds
    sp = 2.0 * c * ds
    psi = 2.0 * math.atan2(ds, c)
    cs = math.cos(phis)
    phi = phis
    for j in range(s.shape[0]):
        u = Fs + Phi * s[j]
        phi = inverse_f(u, m, kp2, K, phi) if s[j] > 0.0 else phis
        Fp, Ep, Dp, Bp, dp = fedb(phi, m, kp2, K, Ec, Dc, Bc)
        G = 2.0 * (Ep - Es) - (Fp - Fs)
        dcos = math.cos(phi) - cs
        out[j, 0] = -(G * cp + 2.0 * ku * sp * dcos) / Phi
        out[j, 1] = -(G * sp - 2.0 * ku * cp * dcos) / Phi
        out[j, 2] = psi + 2.0 * math.atan2(-dp, ku * math.sin(phi))
        out[j, 3] = 2.0 * Phi * ku * math.cos(phi)


@njit(cache=True)
def profile(chart: int, z: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """Unit rod in chart ``chart`` sampled at arc lengths ``s``: ``out[:, 0:4] = x, y, theta, m``."""
    if chart == CHART_UNIFIED:
        unified_profile(z[0], z[1], s, out)
    elif chart == CHART_LIB or chart == CHART_ROT:
        window_profile(chart == CHART_ROT, z[0], z[1], z[2], s, out)
    else:
        wrench_profile(z[0], z[1], z[2], s, out)


@njit(cache=True)
def profile_batch(charts: np.ndarray, z: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """:func:`profile` of many unit rods: ``out[i] = profile(charts[i], z[i], s)``."""
    for i in range(charts.shape[0]):
        profile(charts[i], z[i], s, out[i])


@njit
def unified_tangents(v: float, phis: float, s: np.ndarray, out: np.ndarray) -> None:
    """Tangent angle ``theta(s)`` of a pinned unit rod ``(v, phis)`` at increasing arc lengths
    ``s`` (local frame): ``theta = psi + 2 atan2(-Delta(phi), k sin phi)`` with the Jacobi
    amplitude ``phi(s) = am(F(phis) + Phi s)`` (the positions of :func:`unified_profile` are not
    needed here)."""
    av = min(abs(v), 350.0)
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
    ku = math.tanh(v)
    kp2 = kp * kp
    m = ku * ku
    K, Ec, Dc, Bc = complete(m, kp2)
    Fs, Es, Ds, Bs, ds = fedb(phis, m, kp2, K, Ec, Dc, Bc)
    Phi = K - Fs
    if not Phi > 0.0:
        out[:] = 0.0
        return
    psi = 2.0 * math.atan2(ds, ku * math.sin(phis))
    phi = phis
    s_prev = 0.0
    sp = math.sin(phi)
    d = ds
    for j in range(s.shape[0]):
        if s[j] > 0.0:
            # seed: second-order Taylor step of phi' = Phi Delta(phi), phi'' = -m Phi^2 sin cos
            h = Phi * (s[j] - s_prev)
            guess = phi + h * d - 0.5 * h * h * m * sp * math.cos(phi)
            phi = inverse_f(Fs + Phi * s[j], m, kp2, K, guess)
            s_prev = s[j]
        sp = math.sin(phi)
        d = math.sqrt(math.cos(phi) ** 2 + kp2 * sp * sp)
        out[j] = psi + 2.0 * math.atan2(-d, ku * sp)


@njit
def tangents(chart: int, z: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """Tangent angles of a unit rod in chart ``chart`` at arc lengths ``s`` (unified or wrench
    chart; convert seam coordinates first)."""
    if chart == CHART_UNIFIED:
        unified_tangents(z[0], z[1], s, out)
    else:
        prof = np.empty((s.shape[0], 4))
        profile(chart, z, s, prof)
        out[:] = prof[:, 2]


@njit(cache=True)
def clamped_mode(chart: int, z: np.ndarray, tol: float) -> tuple[int, bool]:
    """d-mode of a clamped unit rod (SPEC §2: its inflections strictly inside) and whether an
    inflection sits at an end to within ``tol`` (``mode_boundary``: it then counts at the end)."""
    if chart == CHART_LIB or chart == CHART_ROT:
        return window_mode(chart == CHART_ROT, z[0], z[1], z[2], tol)
    return wrench_mode(z[0], z[1], z[2], tol)


@njit(cache=True)
def clamped_peak(chart: int, z: np.ndarray) -> float:
    """Largest ``|theta'|`` along a clamped unit rod in an elastica-window chart (closed form);
    NaN in the wrench chart (sample its profile)."""
    if chart == CHART_LIB or chart == CHART_ROT:
        return window_peak(chart == CHART_ROT, z[0], z[1], z[2])
    return math.nan
