"""Closed-form clamped–pinned Kirchhoff rod (paper §2, Eqs. 8–14).

Conventions
-----------
The rod is clamped at the origin of its *local frame* with its tangent along +x and
pinned at its tip (zero tip moment).  ``(R, psi)`` are the magnitude and direction,
in the local frame, of the force applied **on the rod tip by the platform**; it equals
the (constant) internal force ``n`` of Eq. (7), so that Eq. (8) reads
``theta'' = (R/EI) sin(theta - psi)``.  A compressive axial tip load has ``psi = pi``.

The paper's substitution behind Eqs. (9)–(13) is

    cos((theta - psi)/2) = k sin(phi),   sin((theta - psi)/2) = -sqrt(1 - k^2 sin^2 phi),
    theta' = 2 lambda k cos(phi),        phi' = lambda sqrt(1 - k^2 sin^2 phi),

with ``lambda = sqrt(R/EI)``.  Hence the base moment is ``m0 = 2 EI lambda k cos(phi1)``
and, since ``phi1 = arcsin(cos(psi/2)/k)`` lies in [-pi/2, pi/2], **the sign of k is the
sign of the base moment** (k > 0: the rod leaves the clamp curving counter-clockwise).
The continuous tangent angle stays in ``(psi - 2 pi, psi)``, so with ``theta(0) = 0`` the
force direction satisfies ``psi`` in [0, 2 pi].

Two charts of the same family of rods are used:

* the paper's chart ``(k, psi, q)`` with ``|k_min| = |cos(psi/2)| <= |k| <= 1`` and the
  d-mode ``q`` (Eqs. 10–11), and its rectangular variant ``(k_r, psi)`` of Eq. (14);
* the *unified chart* ``(ku, phis)``: shifting ``phi`` by ``(q - 1) pi`` puts every tip at
  ``phi = pi/2`` and the clamp at ``phis = phi1 - (q - 1) pi``, with
  ``ku = (-1)**(q - 1) k``.  Then ``cos(psi/2) = ku sin(phis)``, so ``(ku, phis)`` with
  ``-1 < ku < 1`` and ``phis <= pi/2`` determines the rod uniquely *for every d-mode at
  once*: the d-mode is ``q = ceil((pi/2 - phis)/pi)``, and a rod that changes mode moves
  continuously across the lines ``phis = -pi/2 - n pi`` (where its base moment vanishes).
  The unloaded straight rod is the line ``phis = pi/2`` (``R = 0``), and ``ku = 0`` is the
  straight rod under axial compression (``psi = pi``) of any magnitude.

All functions here are pure, vectorised over numpy arrays, and dimensionless unless they
take ``L`` and ``EI``: the tip position scales with ``L``, the force with ``EI/L**2``, the
base moment and the energy with ``EI/L``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .slots import CHART_SEAM

__all__ = [
    "pinned_chart",
    "ellipf",
    "ellipe_inc",
    "mode_of",
    "to_unified",
    "to_paper",
    "phi1_of",
    "k_min",
    "kr_from_k",
    "k_from_kr",
    "tip_unit",
    "tip_chart",
    "rod_tip",
    "rod_shape",
    "RodTipArrays",
]

HALF_PI = 0.5 * np.pi


def _special():
    """:mod:`scipy.special` (``m = k**2``), imported on first use: the solvers evaluate rods with
    their compiled elliptic functions (:mod:`flexkin.rod.elliptic`), so an IK or FK call never
    needs it (the pinned atlas they start from is cached on disk, :mod:`flexkin.rod.atlas`)."""
    import scipy.special

    return scipy.special


# ----------------------------------------------------------------------------------------
# Elliptic integrals for any real amplitude (scipy uses the parameter m = k**2)
# ----------------------------------------------------------------------------------------
def ellipf(phi: ArrayLike, m: ArrayLike) -> NDArray[np.float64]:
    """Incomplete elliptic integral of the first kind F(phi | m) for any real ``phi``.

    Uses the quasi-periodicity F(phi + n pi) = F(phi) + 2 n K(m) so that the reduced
    amplitude handed to :func:`scipy.special.ellipkinc` lies in [-pi/2, pi/2].
    """
    phi = np.asarray(phi, dtype=float)
    n = np.round(phi / np.pi)
    red = phi - n * np.pi
    out = _special().ellipkinc(red, m)
    return np.where(n != 0, out + 2.0 * n * _special().ellipk(m), out)


def ellipe_inc(phi: ArrayLike, m: ArrayLike) -> NDArray[np.float64]:
    """Incomplete elliptic integral of the second kind E(phi | m) for any real ``phi``."""
    phi = np.asarray(phi, dtype=float)
    n = np.round(phi / np.pi)
    red = phi - n * np.pi
    out = _special().ellipeinc(red, m)
    return np.where(n != 0, out + 2.0 * n * _special().ellipe(m), out)


# ----------------------------------------------------------------------------------------
# Charts
# ----------------------------------------------------------------------------------------
def mode_of(phis: ArrayLike) -> NDArray[np.int64]:
    """d-mode of a rod from its unified clamp amplitude ``phis`` (>= 1).

    ``q`` counts the inflection points ``phi = pi/2 - n pi`` in ``(phis, pi/2]``: the tip
    always counts, a base inflection (zero base moment, ``phis = -pi/2 - n pi``) does not.
    """
    phis = np.asarray(phis, dtype=float)
    q = np.ceil((HALF_PI - phis) / np.pi - 1e-13)
    return np.maximum(q, 1).astype(np.int64)


def k_min(psi: ArrayLike) -> NDArray[np.float64]:
    """Smallest admissible ``|k|`` for a force direction ``psi``: ``|cos(psi/2)|`` (Eq. 10)."""
    return np.abs(np.cos(0.5 * np.asarray(psi, dtype=float)))


def phi1_of(k: ArrayLike, psi: ArrayLike) -> NDArray[np.float64]:
    """Clamp amplitude of Eq. (10), ``phi1 = arcsin(cos(psi/2)/k)`` (principal branch)."""
    k = np.asarray(k, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(k != 0, np.cos(0.5 * np.asarray(psi, dtype=float)) / np.where(k != 0, k, 1.0), 0.0)
    return np.arcsin(np.clip(ratio, -1.0, 1.0))


def to_unified(k: ArrayLike, psi: ArrayLike, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Paper chart ``(k, psi, q)`` -> unified chart ``(ku, phis)``."""
    q = np.asarray(q)
    k = np.asarray(k, dtype=float)
    sign = np.where(q % 2 == 1, 1.0, -1.0)
    phis = phi1_of(k, psi) - (q - 1) * np.pi
    return sign * k, phis


def to_paper(ku: ArrayLike, phis: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Unified chart ``(ku, phis)`` -> paper chart ``(k, psi, q)`` with psi in [0, 2 pi]."""
    ku = np.asarray(ku, dtype=float)
    phis = np.asarray(phis, dtype=float)
    q = mode_of(phis)
    sign = np.where(q % 2 == 1, 1.0, -1.0)
    c = np.clip(ku * np.sin(phis), -1.0, 1.0)
    psi = 2.0 * np.arccos(c)
    return sign * ku, psi, q


def kr_from_k(k: ArrayLike, psi: ArrayLike) -> NDArray[np.float64]:
    """Rectangular parameter of Eq. (14): ``k_r = sign(k) (|k| - |k_min|)/(1 - |k_min|)``."""
    k = np.asarray(k, dtype=float)
    km = k_min(psi)
    with np.errstate(divide="ignore", invalid="ignore"):
        kr = np.where(km < 1.0, (np.abs(k) - km) / (1.0 - km), 0.0)
    return np.copysign(np.clip(kr, 0.0, 1.0), k)


def k_from_kr(kr: ArrayLike, psi: ArrayLike) -> NDArray[np.float64]:
    """Inverse of Eq. (14).  ``k_r = -0.0`` and ``+0.0`` select the two sides ``k = -/+ k_min``."""
    kr = np.asarray(kr, dtype=float)
    km = k_min(psi)
    return np.copysign(km + np.abs(kr) * (1.0 - km), kr)


# ----------------------------------------------------------------------------------------
# Tip quantities in the unified chart
# ----------------------------------------------------------------------------------------
class RodTipArrays:
    """Dimensionless tip quantities of unit rods (L = 1, EI = 1) as parallel arrays.

    Attributes
    ----------
    x, y : tip position in the local frame (Eqs. 12–13 at ``phi2``).
    theta : tangent angle at the tip (rad, continuous value in ``(psi - 2 pi, psi)``).
    R : tip force magnitude (Eq. 9), ``R = Phi**2`` with ``Phi = lambda L``.
    psi : tip force direction in the local frame (rad, in [0, 2 pi]).
    m0 : base moment ``EI theta'(0)``.
    energy : bending energy ``(EI/2) int theta'^2 ds``.
    Phi : ``lambda L = F(k, phi2) - F(k, phi1)``.
    """

    __slots__ = ("x", "y", "theta", "R", "psi", "m0", "energy", "Phi")

    def __init__(self, x, y, theta, R, psi, m0, energy, Phi):  # noqa: D107
        self.x, self.y, self.theta, self.R = x, y, theta, R
        self.psi, self.m0, self.energy, self.Phi = psi, m0, energy, Phi

    @property
    def fx(self) -> NDArray[np.float64]:
        """Local x component of the force on the tip."""
        return self.R * np.cos(self.psi)

    @property
    def fy(self) -> NDArray[np.float64]:
        """Local y component of the force on the tip."""
        return self.R * np.sin(self.psi)


def _carlson_fe(phi: NDArray[np.float64], m: NDArray[np.float64], kp2: NDArray[np.float64]):
    """F(phi|m) and E(phi|m) for any real ``phi`` via Carlson's R_F, R_D.

    ``kp2 = 1 - m`` is passed separately so that rods near ``|k| = 1`` keep full precision:
    ``1 - m sin^2 phi = cos^2 phi + kp2 sin^2 phi`` (DLMF 19.25.5, 19.25.9).
    """
    n = np.round(phi / np.pi)
    r = phi - n * np.pi
    s, c = np.sin(r), np.cos(r)
    c2, s2 = c * c, s * s
    d2 = c2 + kp2 * s2
    rf = _special().elliprf(c2, d2, 1.0)
    rd = _special().elliprd(c2, d2, 1.0)
    F = s * rf
    E = s * rf - (m / 3.0) * s * s2 * rd
    Kc = _special().elliprf(0.0, kp2, 1.0)
    Ec = Kc - (m / 3.0) * _special().elliprd(0.0, kp2, 1.0)
    return F + 2.0 * n * Kc, E + 2.0 * n * Ec, Kc, Ec


def tip_unit(ku: ArrayLike, phis: ArrayLike, kprime: ArrayLike | None = None) -> RodTipArrays:
    """Tip quantities of a unit rod (L = EI = 1) in the unified chart.

    Closed form of Eqs. (9), (12), (13) evaluated at ``phi2`` (where ``cos phi2 = 0``),
    plus the base moment ``m0 = 2 lambda k cos(phi1)`` and the elastic energy

        U = (EI/2) int theta'^2 ds = 2 EI lambda [ (E(phi2) - E(phi1)) - (1 - k^2) (F(phi2) - F(phi1)) ],

    which follows from ``k^2 cos^2 phi / Delta = Delta - (1 - k^2)/Delta``.

    Parameters
    ----------
    ku : array_like
        Unified modulus, ``-1 < ku < 1``.
    phis : array_like
        Unified clamp amplitude, ``phis < pi/2``.
    kprime : array_like, optional
        ``sqrt(1 - ku**2)`` if known more accurately than from ``ku`` (rods near
        ``|k| = 1``); see :func:`tip_chart`.
    """
    ku = np.asarray(ku, dtype=float)
    phis = np.asarray(phis, dtype=float)
    m = ku * ku
    if kprime is None:
        kp2 = np.maximum((1.0 - ku) * (1.0 + ku), 0.0)
    else:
        kp2 = np.asarray(kprime, dtype=float) ** 2
    F1, E1, Kc, Ec = _carlson_fe(phis, m, kp2)
    Phi = Kc - F1  # lambda L, Eq. (9)
    DE = Ec - E1
    c = np.clip(ku * np.sin(phis), -1.0, 1.0)  # cos(psi/2)
    s = np.sqrt(np.maximum(1.0 - c * c, 0.0))  # sin(psi/2) >= 0
    cpsi = 2.0 * c * c - 1.0
    spsi = 2.0 * c * s
    cph = np.cos(phis)
    G = 2.0 * DE - Phi
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / Phi
        x = -(G * cpsi - 2.0 * ku * spsi * cph) * inv  # Eq. (12) at phi2
        y = -(G * spsi + 2.0 * ku * cpsi * cph) * inv  # Eq. (13) at phi2
    psi = 2.0 * np.arctan2(s, c)
    theta = psi + 2.0 * np.arctan2(-np.sqrt(kp2), ku)
    m0 = 2.0 * ku * Phi * cph
    energy = 2.0 * Phi * (DE - kp2 * Phi)
    straight = Phi <= 0.0
    if np.any(straight):  # the unloaded straight rod (phis = pi/2)
        x = np.where(straight, 1.0, x)
        y = np.where(straight, 0.0, y)
        theta = np.where(straight, 0.0, theta)
    return RodTipArrays(x, y, theta, Phi * Phi, psi, m0, energy, Phi)


def tip_chart(v: ArrayLike, phis: ArrayLike) -> RodTipArrays:
    """:func:`tip_unit` in the solvers' chart ``ku = tanh(v)``, ``k' = 1/cosh(v)``.

    The solvers iterate on ``v`` (real line) rather than ``ku``: near ``|k| = 1`` (tight
    loops, rods in strong tension) ``k' = sech(v)`` keeps its full relative precision, and
    so does the tip force, which grows like ``log(1/k')**2``.
    """
    v = np.asarray(v, dtype=float)
    return tip_unit(np.tanh(v), phis, 1.0 / np.cosh(v))


def rod_tip(ku: ArrayLike, phis: ArrayLike, L: ArrayLike = 1.0, EI: ArrayLike = 1.0) -> RodTipArrays:
    """Tip quantities of a rod of length ``L`` and bending stiffness ``EI`` (local frame)."""
    t = tip_unit(ku, phis)
    L = np.asarray(L, dtype=float)
    EI = np.asarray(EI, dtype=float)
    return RodTipArrays(
        t.x * L, t.y * L, t.theta, t.R * EI / L**2, t.psi, t.m0 * EI / L, t.energy * EI / L, t.Phi
    )


def rod_shape(
    ku: float, phis: float, L: float = 1.0, EI: float = 1.0, n: int = 101, kprime: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Deformed shape sampled uniformly in arc length (Eqs. 12–13), local frame.

    The amplitude along the rod is the Jacobi amplitude
    ``phi(s) = am(F(phis) + lambda s | k^2)`` because ``phi' = lambda Delta(phi)``; it is
    taken from :func:`scipy.special.ellipj` and polished by Newton on ``F(phi) = u`` with the
    Carlson forms, so that rods near ``|k| = 1`` (pass ``kprime``) keep full precision.

    Returns
    -------
    s, x, y, theta, moment : ndarray
        Arc length, position, tangent angle and bending moment ``EI theta'(s)``.
    """
    ku = float(ku)
    phis = float(phis)
    m = ku * ku
    kp2 = (1.0 - ku) * (1.0 + ku) if kprime is None else float(kprime) ** 2
    s = np.linspace(0.0, L, n)
    t = tip_unit(ku, phis, None if kprime is None else kprime)
    Phi = float(t.Phi)
    if Phi <= 0.0:
        z = np.zeros_like(s)
        return s, s.copy(), z, z.copy(), z.copy()
    F1, E1, _, _ = _carlson_fe(np.array(phis), m, kp2)
    F1, E1 = float(F1), float(E1)
    u = F1 + Phi * s / L
    phi = _special().ellipj(u, m)[3]
    phi[0] = phis
    for _ in range(8):  # Newton on F(phi) = u, dF/dphi = 1/Delta
        Fp, _, _, _ = _carlson_fe(phi, m, kp2)
        delta = np.sqrt(np.cos(phi) ** 2 + kp2 * np.sin(phi) ** 2)
        step = (Fp - u) * delta
        phi = phi - step
        if np.max(np.abs(step)) < 1e-15:
            break
    c = np.clip(ku * np.sin(phis), -1.0, 1.0)
    sn = np.sqrt(max(1.0 - c * c, 0.0))
    cpsi, spsi = 2.0 * c * c - 1.0, 2.0 * c * sn
    _, Ep, _, _ = _carlson_fe(phi, m, kp2)
    G = 2.0 * (Ep - E1) - (u - F1)
    dc = np.cos(phi) - np.cos(phis)
    scale = L / Phi
    x = -scale * (cpsi * G + 2.0 * ku * spsi * dc)  # Eq. (12)
    y = -scale * (spsi * G - 2.0 * ku * cpsi * dc)  # Eq. (13)
    delta = np.sqrt(np.cos(phi) ** 2 + kp2 * np.sin(phi) ** 2)
    theta = float(t.psi) + 2.0 * np.arctan2(-delta, ku * np.sin(phi))
    moment = EI * 2.0 * (Phi / L) * ku * np.cos(phi)
    return s, x, y, theta, moment


def tangent_angles(v: ArrayLike, phis: ArrayLike, s: ArrayLike) -> NDArray[np.float64]:
    """Tangent angle ``theta(s)`` of many unit rods at unit arc lengths ``s`` (local frame).

    The batched counterpart of the ``theta`` output of :func:`rod_shape`, in the solvers'
    chart (``ku = tanh v``, ``k' = sech v``): ``phi(s) = am(F(phis) + Phi s | k^2)`` (Jacobi
    amplitude, polished by Newton on ``F(phi) = u``) and
    ``theta = psi + 2 atan2(-Delta(phi), k sin(phi))`` (the tangent form behind Eqs. 10–11).

    Parameters
    ----------
    v, phis : array_like, shape (n,)
        Chart coordinates of ``n`` rods.
    s : array_like, shape (m,)
        Arc lengths in [0, 1] (unit rod).

    Returns
    -------
    ndarray, shape (n, m)
        ``theta(s)`` with ``theta(0) = 0`` (clamp tangent along the local x axis).
    """
    v = np.atleast_1d(np.asarray(v, dtype=float))[:, None]
    phis = np.atleast_1d(np.asarray(phis, dtype=float))[:, None]
    s = np.asarray(s, dtype=float)[None, :]
    ku = np.tanh(v)
    m = ku * ku
    kp2 = (1.0 / np.cosh(v)) ** 2
    F1, _, Kc, _ = _carlson_fe(phis, m, kp2)
    Phi = np.maximum(Kc - F1, 0.0)
    u = F1 + Phi * s
    phi = _special().ellipj(u, np.broadcast_to(m, u.shape))[3]
    # scipy's ellipj loses accuracy as k' -> 0 (it sees only m = k^2): polish those rods
    near = np.flatnonzero(kp2[:, 0] < 1e-6)
    if near.size:
        p, uu, mm, kk = phi[near], u[near], m[near], kp2[near]
        for _ in range(8):  # Newton on F(phi) = u, dF/dphi = 1/Delta
            Fp, _, _, _ = _carlson_fe(p, mm, kk)
            step = (Fp - uu) * np.sqrt(np.cos(p) ** 2 + kk * np.sin(p) ** 2)
            p = p - step
            if np.max(np.abs(step), initial=0.0) < 1e-15:
                break
        phi[near] = p
    c = np.clip(ku * np.sin(phis), -1.0, 1.0)
    psi = 2.0 * np.arctan2(np.sqrt(np.maximum(1.0 - c * c, 0.0)), c)
    delta = np.sqrt(np.cos(phi) ** 2 + kp2 * np.sin(phi) ** 2)
    theta = psi + 2.0 * np.arctan2(-delta, ku * np.sin(phi))
    theta = theta - theta[:, :1] if s[0, 0] == 0.0 else theta
    return np.where(Phi > 0.0, theta, 0.0)


# ---- the seam chart: rods near straight under tension -----------------------------------------------
#
# A mode-1 rod with phis in (0, pi/2) can also be written with the signed direction psi_s in
# (-pi, pi) of its tip force (measured from the clamp axis) and the complementary amplitude
# chi in (0, pi/2) of phis, tan(chi) = tan(pi/2 - phis)/k' (Jacobi: F(phis) + F(chi) = K when
# tan(phis) tan(chi) = 1/k').  Then
#
#     k' = sin(|psi_s|/2) cos(chi) / sqrt(cos^2 chi + cos^2(psi_s/2) sin^2 chi),
#     tan(pi/2 - phis) = sin(|psi_s|/2) sin(chi) / sqrt(cos^2 chi + cos^2(psi_s/2) sin^2 chi),
#     lambda L = K - F(phis) = F(chi),    E - E(phis) = E(chi) - k^2 sin(phis) sin(chi)  (Legendre),
#
# so nothing cancels as k' -> 0.  The straight rod under tension (psi_s = 0, the seam of the
# unified chart where |k| = 1) is an ordinary point: the rod and its mirror image (psi_s -> -psi_s)
# are neighbours.  In arrays of chart coordinates a seam-chart rod is stored as
# (psi_s, chi + SEAM_OFFSET).

#: offset marking seam-chart coordinates in the second slot of a rod's chart pair
SEAM_OFFSET = 10.0


def is_seam(z1: ArrayLike) -> NDArray[np.bool_]:
    """Whether chart pairs ``(z0, z1)`` are stored in the seam chart."""
    return np.asarray(z1, dtype=float) > 0.5 * SEAM_OFFSET


def _seam_params(psi_s: NDArray, chi: NDArray):
    h = 0.5 * np.abs(psi_s)
    sh, ch = np.sin(h), np.cos(h)
    sc, cc = np.sin(chi), np.cos(chi)
    den = np.sqrt(cc * cc + (ch * sc) ** 2)
    kp = sh * cc / den
    eps = np.arctan2(sh * sc, den)  # pi/2 - phis
    sgn = np.where(psi_s >= 0.0, 1.0, -1.0)
    ku = sgn * np.sqrt(np.maximum(1.0 - kp * kp, 0.0))
    return sh, ch, kp, eps, ku, sgn


def tip_seam(psi_s: ArrayLike, chi: ArrayLike) -> RodTipArrays:
    """:func:`tip_unit` in the seam chart (see above): unit rod, local frame."""
    psi_s = np.asarray(psi_s, dtype=float)
    chi = np.asarray(chi, dtype=float)
    sh, ch, kp, eps, ku, sgn = _seam_params(psi_s, chi)
    m = ku * ku
    kp2 = kp * kp
    s, c = np.sin(chi), np.cos(chi)
    d2 = c * c + kp2 * s * s
    rf = _special().elliprf(c * c, d2, 1.0)
    Phi = s * rf                                                          # F(chi | m)
    Echi = s * rf - (m / 3.0) * s ** 3 * _special().elliprd(c * c, d2, 1.0)          # E(chi | m)
    DE = Echi - m * np.cos(eps) * s
    cpsi2 = sgn * ch                    # cos(psi/2) with psi in [0, 2 pi]
    cpsi, spsi = 2.0 * cpsi2 * cpsi2 - 1.0, 2.0 * cpsi2 * sh
    cph = np.sin(eps)                   # cos(phis)
    G = 2.0 * DE - Phi
    with np.errstate(divide="ignore", invalid="ignore"):
        x = -(G * cpsi - 2.0 * ku * spsi * cph) / Phi
        y = -(G * spsi + 2.0 * ku * cpsi * cph) / Phi
    psi = np.where(psi_s >= 0.0, psi_s, 2.0 * np.pi + psi_s)
    theta = psi + 2.0 * np.arctan2(-kp, ku)
    m0 = 2.0 * ku * Phi * cph
    energy = 2.0 * Phi * (DE - kp2 * Phi)
    unloaded = Phi <= 0.0
    if np.any(unloaded):
        x = np.where(unloaded, 1.0, x)
        y = np.where(unloaded, 0.0, y)
        theta = np.where(unloaded, 0.0, theta)
    return RodTipArrays(x, y, theta, Phi * Phi, psi, m0, energy, Phi)


def seam_to_chart(psi_s: ArrayLike, chi: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Seam chart -> solvers' chart ``(v, phis)`` (``|v|`` capped at 40)."""
    psi_s = np.asarray(psi_s, dtype=float)
    chi = np.asarray(chi, dtype=float)
    _, _, kp, eps, _, sgn = _seam_params(psi_s, chi)
    with np.errstate(divide="ignore"):
        v = sgn * np.minimum(np.arccosh(np.minimum(1.0 / np.maximum(kp, 1e-300), 1e300)), 40.0)
    return v, HALF_PI - eps


def chart_to_seam(v: ArrayLike, phis: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solvers' chart -> seam chart, for mode-1 rods with ``0 < phis < pi/2``."""
    v = np.asarray(v, dtype=float)
    phis = np.asarray(phis, dtype=float)
    kp = 1.0 / np.cosh(v)
    ku = np.tanh(v)
    eps = HALF_PI - phis
    # 1 - |c| with c = ku sin(phis), without cancellation
    one_minus_c = 2.0 / (np.exp(2.0 * np.abs(v)) + 1.0) + np.abs(ku) * 2.0 * np.sin(0.5 * eps) ** 2
    half = 2.0 * np.arcsin(np.sqrt(np.clip(0.5 * one_minus_c, 0.0, 1.0)))  # psi/2 for |c|
    psi_s = np.where(ku >= 0.0, 2.0 * half, -2.0 * half)
    chi = np.arctan2(np.sin(eps), kp * np.cos(eps))
    return psi_s, chi


def standard_chart(z0: ArrayLike, z1: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chart pairs in the solvers' chart ``(v, phis)`` whatever chart they are stored in."""
    z0 = np.asarray(z0, dtype=float)
    z1 = np.asarray(z1, dtype=float)
    seam = is_seam(z1)
    if not np.any(seam):
        return z0, z1
    v, ph = seam_to_chart(np.where(seam, z0, 0.0), np.where(seam, z1 - SEAM_OFFSET, 0.5))
    return np.where(seam, v, z0), np.where(seam, ph, z1)


def pinned_chart(z: ArrayLike, charts: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The solvers' chart ``(v, phis)`` of pinned rods with coordinates ``z`` (n, 2) stored in
    ``charts`` (n,): unified pairs as they are, seam pairs converted whether stored raw
    (``(psi_s, chi)``, as the solvers iterate on them) or offset-encoded (:func:`standard_chart`)."""
    z = np.asarray(z, dtype=float).reshape(-1, 2)
    z1 = np.where((np.asarray(charts).reshape(-1) == CHART_SEAM) & ~is_seam(z[:, 1]), z[:, 1] + SEAM_OFFSET, z[:, 1])
    return standard_chart(z[:, 0], z1)
