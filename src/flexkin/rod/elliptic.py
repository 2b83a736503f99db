"""Elliptic integrals for the closed-form rods, compiled (numba, ``cache=True``).

Conventions
-----------
The parameter is ``m = k**2`` (as in scipy.special and DLMF), the complementary parameter
``kp2 = 1 - m`` is passed *separately* so that rods near the separatrix (``|k| -> 1``, tight
loops and taut rods) keep full precision: ``1 - m sin^2 phi = cos^2 phi + kp2 sin^2 phi``
has no cancellation (DLMF 19.25.5).  Every function accepts any real amplitude ``phi``: with
``phi = n pi + r``, ``|r| <= pi/2``, the quasi-periodicity ``F(phi) = F(r) + 2 n K`` (and the
same for ``E`` and ``D``) reduces it.

Integrals (DLMF 19.2.4-19.2.6 and 19.25.5-19.25.13, in Carlson's symmetric form)

    F(phi|m) = int_0^phi dt / Delta(t)            = s R_F(c^2, Delta^2, 1)
    E(phi|m) = int_0^phi Delta(t) dt              = F - m D
    D(phi|m) = int_0^phi sin^2 t / Delta(t) dt    = (s^3/3) R_D(c^2, Delta^2, 1) = (F - E)/m
    B(phi|m) = int_0^phi sin^2 t / Delta(t)^3 dt  = (s^3/3) R_D(c^2, 1, Delta^2)

with ``s = sin r``, ``c = cos r``, ``Delta(t)^2 = 1 - m sin^2 t``.  ``D`` has no ``1/m``
cancellation for small ``m``, and ``B = 2 dF/dm`` is the derivative the closed-form
Jacobians need (finite at ``m = 1`` for arcs that stay away from ``t = pi/2 + n pi``).

Classical derivatives (DLMF 19.4.1-19.4.4):  ``dF/dphi = 1/Delta``, ``dE/dphi = Delta``,
``dF/dm = B/2``, ``dE/dm = -D/2``.

Carlson's duplication algorithm (Carlson 1995, Numer. Algorithms 10, 13-26) with the
fifth-order series; relative error below 1e-15 for the arguments used here.
"""

from __future__ import annotations

import math

from ..core.jit import njit

__all__ = ["rf", "rd", "fedb", "complete", "inverse_f", "HALF_PI"]

HALF_PI = 0.5 * math.pi
#: Carlson's error control: (3 r)^(-1/6) for R_F, (r/4)^(-1/6) for R_D, with r = 1e-16
_QF = (3e-16) ** (-1.0 / 6.0)
_QD = (0.25e-16) ** (-1.0 / 6.0)


@njit(cache=True)
def rf(x: float, y: float, z: float) -> float:
    """Carlson's symmetric integral ``R_F(x, y, z)`` (x, y, z >= 0, at most one zero)."""
    a0 = (x + y + z) / 3.0
    q = _QF * max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    a = a0
    xm, ym, zm = x, y, z
    f = 1.0
    for _ in range(60):
        if q * f < abs(a):
            break
        sx, sy, sz = math.sqrt(xm), math.sqrt(ym), math.sqrt(zm)
        lam = sx * sy + sy * sz + sz * sx
        xm = 0.25 * (xm + lam)
        ym = 0.25 * (ym + lam)
        zm = 0.25 * (zm + lam)
        a = 0.25 * (a + lam)
        f *= 0.25
    X = (a0 - x) * f / a
    Y = (a0 - y) * f / a
    Z = -(X + Y)
    e2 = X * Y - Z * Z
    e3 = X * Y * Z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(a)


@njit(cache=True)
def rd(x: float, y: float, z: float) -> float:
    """Carlson's symmetric integral ``R_D(x, y, z)`` (x, y >= 0, not both zero, z > 0)."""
    a0 = (x + y + 3.0 * z) / 5.0
    q = _QD * max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    a = a0
    xm, ym, zm = x, y, z
    f = 1.0
    acc = 0.0
    for _ in range(60):
        if q * f < abs(a):
            break
        sx, sy, sz = math.sqrt(xm), math.sqrt(ym), math.sqrt(zm)
        lam = sx * sy + sy * sz + sz * sx
        acc += f / (sz * (zm + lam))
        xm = 0.25 * (xm + lam)
        ym = 0.25 * (ym + lam)
        zm = 0.25 * (zm + lam)
        a = 0.25 * (a + lam)
        f *= 0.25
    X = (a0 - x) * f / a
    Y = (a0 - y) * f / a
    Z = -(X + Y) / 3.0
    xy = X * Y
    z2 = Z * Z
    e2 = xy - 6.0 * z2
    e3 = (3.0 * xy - 8.0 * z2) * Z
    e4 = 3.0 * (xy - z2) * z2
    e5 = xy * z2 * Z
    s = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0
         - 9.0 * e2 * e3 / 52.0 + 3.0 * e5 / 26.0)
    return f * s / (a * math.sqrt(a)) + 3.0 * acc


@njit(cache=True)
def complete(m: float, kp2: float):
    """Complete integrals ``(K, E, Dc, Bc)`` at ``phi = pi/2`` (``Bc`` is ``inf`` at ``kp2 = 0``)."""
    K = rf(0.0, kp2, 1.0)
    Dc = rd(0.0, kp2, 1.0) / 3.0
    Bc = rd(0.0, 1.0, kp2) / 3.0 if kp2 > 0.0 else math.inf
    return K, K - m * Dc, Dc, Bc


@njit(cache=True)
def fedb(phi: float, m: float, kp2: float, K: float, Ec: float, Dc: float, Bc: float):
    """``F, E, D, B`` of the module docstring at any real ``phi``, and ``Delta(phi)``.

    ``K, Ec, Dc, Bc`` are the complete integrals of :func:`complete` (passed in because a
    rod evaluates several amplitudes at one ``m``).  ``B`` is only finite where ``Delta``
    does not vanish on ``[0, phi]``.
    """
    n = math.floor(phi / math.pi + 0.5)
    r = phi - n * math.pi
    s = math.sin(r)
    c = math.cos(r)
    c2 = c * c
    d2 = c2 + kp2 * s * s
    s3 = s * s * s
    F = s * rf(c2, d2, 1.0)
    D = s3 * rd(c2, d2, 1.0) / 3.0
    if d2 > 0.0:
        B = s3 * rd(c2, 1.0, d2) / 3.0
    else:
        B = math.inf if s > 0.0 else -math.inf
    if n != 0.0:
        F += 2.0 * n * K
        D += 2.0 * n * Dc
        B += 2.0 * n * Bc
    return F, F - m * D, D, B, math.sqrt(d2)


@njit(cache=True)
def inverse_f(u: float, m: float, kp2: float, K: float, guess: float) -> float:
    """Jacobi amplitude ``phi = am(u | m)``: the root of ``F(phi | m) = u``.

    Safeguarded Newton (``dF/dphi = 1/Delta``) on the reduced amplitude in
    ``[-pi/2, pi/2]`` after ``u = 2 n K + u_r``; ``guess`` (any real, e.g. the amplitude of
    a neighbouring point) seeds it when it lies in the same period, otherwise the blend of
    ``u_r`` (``m = 0``) and the Gudermannian ``atan(sinh u_r)`` (``m = 1``) does.
    """
    if K == math.inf:  # m = 1: the separatrix, am = gd(u)
        return math.atan(math.sinh(u))
    n = math.floor(u / (2.0 * K) + 0.5)
    ur = u - 2.0 * n * K
    g = guess - n * math.pi
    if not (-HALF_PI <= g <= HALF_PI):
        g = (1.0 - m) * ur + m * math.atan(math.sinh(ur))
        g = min(max(g, -HALF_PI), HALF_PI)
    lo, hi = -HALF_PI, HALF_PI
    x = g
    for _ in range(60):
        s = math.sin(x)
        c = math.cos(x)
        d2 = c * c + kp2 * s * s
        fx = s * rf(c * c, d2, 1.0) - ur
        if fx > 0.0:
            hi = x
        else:
            lo = x
        step = fx * math.sqrt(d2)
        xn = x - step
        if not (lo < xn < hi):  # Newton left the bracket: bisect
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= 1e-15 * max(1.0, abs(x)) or hi - lo < 1e-15:
            x = xn
            break
        x = xn
    return x + n * math.pi
