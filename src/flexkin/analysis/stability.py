"""Stability of an equilibrium with the actuators locked (paper §4.3): the verdict and the
Morse index from the closed form, the margin from a banded discretisation.

**The second variation.**  The potential of the mechanism is
``V = sum_i (EI_i/2) int_0^{L_i} theta_i'^2 ds - F . P - M theta_P`` on configurations with every
rod clamped at its base (actuators locked), its tip at ``B_i = P + Rot(theta_P) b_i`` and, for a
clamped joint, its tip tangent at ``theta_P + tip_angle_i``.  With the tip forces ``n_i`` (on the
rod, by the platform; the constant internal force of Eq. 7) as the multipliers of the tip
constraints, the second variation on perturbations ``(eta_i, dq)``, ``eta_i = d theta_i``,
``eta_i(0) = 0``, ``dq = (dP, d theta_P)`` is

    Q = sum_i int_0^{L_i} [EI_i eta_i'^2 + (n_i . t_i) eta_i^2] ds - (sum_i n_i . a_i) dtheta_P^2     (S1)

(``t_i`` the unit tangent, ``a_i = B_i - P``) on the admissible subspace

    delta r_i = int (-sin theta_i, cos theta_i) eta_i ds = dP + dtheta_P perp(a_i)                     (S2)
    eta_i(L_i) = dtheta_P                    (clamped tip only)                                        (S3)

The equilibrium is **stable** when ``Q`` is positive definite there (``EI > 0``: Legendre's
condition holds, so positive definite is coercive), and its **index** is the number of
negative directions.

**Jacobi fields from the closed form.**  Scale rod ``i`` to the unit rod (``L = EI = 1``) in
its clamp frame.  Its equilibria form the three-parameter family of the base wrench
``p = (a, b, m0)``: ``theta'' = a sin theta - b cos theta`` (Eq. 8 with ``n = (a, b)``),
``theta(0) = 0``, ``theta'(0) = m0``, in closed form in every chart
(:mod:`flexkin.rod.wrench`; every chart's evaluation provides the base wrench in the ``FX``,
``FY``, ``M0`` slots).  Differentiating the family:

    u = d theta / d m0:            u'' = q u,             u(0) = 0, u'(0) = 1,   q = n . t         (J1)
    d theta / da, d theta / db:    w'' = q w + (sin theta, -cos theta),  w(0) = w'(0) = 0         (J2)

``u`` is the Jacobi field of the unconstrained problem, the others are the constrained Jacobi
fields of the isoperimetric constraints (S2), and their tip values are the closed-form
Jacobian ``D = d(x, y, theta, m)(1) / d(a, b, m0)`` (``m = theta'``).  The bending moment
``m = theta'`` solves (J1) too (the family is autonomous in ``s``), with the Wronskian

    u m' - u' m = -m0.                                                                                (J3)

**One rod, unconstrained.**  (i) *Clamped-clamped* (``eta(0) = eta(1) = 0``): by the Morse
index theorem its index is the number ``Z_u`` of zeros of ``u`` in (0, 1).  By Sturm's separation
theorem the zeros of ``u`` and ``m`` interlace (J3), and ``u = m m0 int_0^s m^-2`` between zeros of
``m``; hence, with ``J`` the zeros of ``m`` strictly inside (the inflections, at
``u = (2 j + 1) K`` in the elliptic argument ``u = F(phi)``, ``phi(s) = am(F(phi_1) + lambda s)``):

    Z_u = J - 1 + [u(1) m(1) m0 > 0],     Z_u = J for a pinned tip (m(1) = 0)                        (J4)

and an inflection at an end (within ``|cos phi| < 1e-8``) is left out of ``J`` and the bracket
(the limit of both sides).  A non-inflectional (rotating) rod has ``Z_u = 0``.
(ii) *Free tip* (``eta(1)`` free, the dead-load cantilever): the Prüfer angle of ``u`` gives

    index_free = Z_u + [u(1) u'(1) < 0]                                                               (J5)

with ``u(1) = -m0 / m'(1)`` from (J3) when ``m(1) = 0``.  Both are 0 when ``lambda L < pi/2``
(Poincaré: ``Q >= (pi^2/4 - lambda^2) int eta^2``).

**The mechanism: a bordered matrix.**  Split each rod's perturbation into the clamped-clamped
space ``A_cc`` and the tip rotation ``t_i``: ``eta = eta0 + t_i xi``, ``xi = u / u(1)``.  ``xi`` is a
Jacobi field with ``xi(1) = 1``, so it is ``Q``-orthogonal to ``A_cc`` and
``Q_i = Q_cc[eta0] + t_i^2 u'(1) / u(1)``.  The admissible subspace is then ``A = (+)_i A_cc,i``
times the finite variables ``y = (dq, t_i)`` (``t_i = dtheta_P`` for a clamped tip) under the
constraints (S2) ``C_i eta0 + E_i y = 0``.  Haynsworth's inertia additivity on the KKT matrix
(Maddocks 1985, restricted quadratic forms; nondegenerate ``A``) gives

    index(Q) = sum_i index(A_i) + neg(B) - m,     nullity(Q) = nullity(B),
    B = [[Y, E^T], [E, -G]],     G = blockdiag(G_i),   G_i = C_i A_i^-1 C_i^T                        (M1)

with ``m`` the rows of ``E``.  ``Y`` holds ``-sum n_i . a_i`` on ``dtheta_P`` and ``u'(1)/u(1)`` on each
``t_i``; ``E`` the rows ``-(I, perp a_i)`` on ``dq`` and ``delta r(xi) = (dr/dm0)/u(1)`` on ``t_i``;
``G_i`` is the rod's tip compliance at a held tip angle, the Schur complement of ``D``:

    G_i = dr/d(a, b) - (dr/dm0) (d theta/d(a, b)) / u(1)                                               (M2)

(rotated to the world and scaled by ``l_i^3/e_i``).  Where ``u(1)`` is small compared with
``u'(1)`` a rod uses the free base instead: ``index(A_i) = index_free`` (J5), no ``t_i``, ``G_i`` the
compliance at a held tip moment (Schur complement w.r.t. ``(m, m0)``) and, for a clamped tip,
the full 3 x 3 compliance ``d(x, y, theta)/d(f_x, f_y, m(1))`` with the row ``eta(1) = dtheta_P``.
Every base used is nondegenerate (``(u(1), u'(1)) != 0``), so (M1) holds wherever ``Q`` is
nondegenerate -- no condition on conjugate points at the tips.  Equivalently, where the rods
held at their tips are nondegenerate, index(Q) = sum_i index(rod i held) + index(K) with ``K``
the pose stiffness (:func:`output_stiffness`), the decomposition ``tests/stability_oracle.py``
checks independently.  ``det B`` changes sign wherever an eigenvalue of ``Q`` crosses zero (the
bordered determinant along a continuation).

**Validity and fallback.**  The entries of ``B`` carry the errors of ``D`` (relative
``1e-15 (1 + 1/k')``, measured against ODE integration and against the pinned chart's own
compliance), propagated through (M2).  The closed-form inertia is accepted when the smallest
``|eigenvalue|`` of the equilibrated ``B`` exceeds :data:`GAP_SAFETY` times that error bound
(Weyl's inequality).  Otherwise -- ``Q`` nearly singular (a near-marginal equilibrium), a
rod straight under compression (``k^2 < 1e-12``, where the wrench chart's derivatives
cancel), non-finite derivatives, inflections at both ends of a clamped rod -- the verdict
and the index come from the discretised second variation
(:mod:`flexkin.analysis.second_variation`): ``stable`` when its smallest eigenvalue exceeds
three times its resolution, unstable below minus that, and ``None`` with a ``note`` between.

**Margin.**  ``stability_margin`` is the smallest eigenvalue of ``Q`` on the admissible
subspace in the metric ``sum_i int eta_i^2 ds / L_ref + |dP / L_ref|^2 + dtheta_P^2`` (units
``EI_ref / L_ref``), from the banded discretisation.  It is computed where it matters: in the
fallback, when asked (``margin=True``; ``flexkin ik --margin``), and for the JSON
(:meth:`flexkin.results.Solution.to_dict` fills it in); elsewhere it is ``NaN`` until asked.
Along a continuation the previous eigenvector starts the next computation (:class:`Eigenpairs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from ..core.jit import njit
from ..core.linalg_threads import single_threaded_blas
from ..rod.closed_form import seam_to_chart
from ..rod.elliptic import rf
from ..rod.kernels import CHART_SEAM, CHART_UNIFIED, CHART_WRENCH, FX, FY, M0, ML, NQ, PHI, TH, X, Y, eval_rod
from ..rod.state import RodState
from ..rod.wrench import _half_angles, wrench_eval
from ..system import System
from .second_variation import P_FINE, _F, element_rule, elements_for, fe_stability, rod_nodes

__all__ = ["Stability", "StabilityArrays", "Eigenpairs", "mechanism_stability", "closed_form_index", "rod_stability",
           "RodStability", "output_stiffness", "solution_margins", "GAP_SAFETY"]


@dataclass(frozen=True)
class Stability:
    """Stability of an equilibrium with the actuators locked (paper §4.3).

    Attributes
    ----------
    stable : bool or None
        From the closed form (:mod:`flexkin.analysis.stability`); ``None`` where the closed form
        is not conclusive and the smallest eigenvalue of the discretised second variation is
        below the resolution the computation can guarantee (``note`` says why).
    margin : float
        Smallest eigenvalue of the dimensionless second variation; positive iff stable.
        ``NaN`` until computed: :attr:`Solution.stability_margin` and :meth:`Solution.to_dict`
        compute it on first use (``ik(..., margin=True)`` computes it up front).
    index : int or None
        Number of negative eigenvalues (unstable directions) where resolved.
    resolution : float
        The guaranteed resolution of ``margin`` (``NaN`` until computed).
    note : str
        Why the verdict is undecided, or ``""``.
    """

    stable: bool | None
    margin: float
    index: int | None
    resolution: float = 0.0
    note: str = ""

#: below this lambda L both base problems of a rod are positive definite (J5)
LAM_SAFE = 0.5 * math.pi * 0.999
#: an inflection within this |cos phi| of an end of a rod is at that end
INFL_TOL = 1e-8
#: a librating rod with k^2 below this is straight under compression (fallback)
K2_MIN = 1e-12
#: the closed-form inertia is accepted when the equilibrated B's smallest |eigenvalue| exceeds
#: this many times its propagated error bound
GAP_SAFETY = 10.0
#: why the closed form was not accepted (bits of :attr:`StabilityArrays.flags`)
F_STRAIGHT, F_NONFINITE, F_GAP, F_ENDS, F_DISAGREE, F_LOST = 1, 2, 4, 8, 16, 32
_WHY = {F_STRAIGHT: "a rod straight under compression", F_NONFINITE: "non-finite rod derivatives",
        F_LOST: "rod derivatives lost to round-off (a rod straight to ~1e-45)",
        F_GAP: "the second variation is nearly singular", F_ENDS: "a clamped rod with inflections at both ends",
        F_DISAGREE: "the closed form and the discretisation disagree"}
#: methods (:attr:`StabilityArrays.method`)
CLOSED_FORM, DISCRETISED = 0, 1


# ================================================================================================
# the closed form
# ================================================================================================
@njit
def rod_terms(a, b, m0, clamped_tip, D, res) -> None:
    """One unit rod of base wrench ``(a, b, m0)`` (clamp frame; module docstring), with a tip
    moment (``clamped_tip``) or of the pinned family (``m(1) = 0`` by construction):
    ``D`` (4, 3) = d(x, y, theta, m)(1)/d(a, b, m0); ``res`` (7,) = [lambda L, u(1), u'(1),
    index of the clamped-clamped base (J4), index of the free base (J5), flags, relative error
    of ``D``]."""
    out = np.empty(NQ)
    g = np.empty((NQ, 3))
    wrench_eval(a, b, m0, out, g)
    flag = 0
    for c in range(3):
        D[0, c] = g[X, c]
        D[1, c] = g[Y, c]
        D[2, c] = g[TH, c]
        D[3, c] = g[ML, c]
        for r in range(4):
            if not np.isfinite(D[r, c]):
                flag |= F_NONFINITE
    u1 = D[2, 2]
    up1 = D[3, 2]
    _, c, sh, R = _half_angles(a, b)
    lam = math.sqrt(R)
    # the Jacobi field u = d theta / d m0 starts at (u, u') = (0, 1) and (lambda u, u') grows or
    # shrinks at most like exp(+-lambda): far below that at s = 1, the closed-form derivatives
    # were lost (a rod bent by ~1e-45 under tension gave u(1) ~ 1e-31 and a wrong index)
    if lam * abs(u1) + abs(up1) < 1e-6 * math.exp(-lam):
        flag |= F_LOST
    idx_cc = 0
    idx_free = 0
    kp2 = 1.0
    if lam >= LAM_SAFE:
        half = 0.5 * abs(m0)
        if half < lam * sh:
            # libration: m = 2 lambda k cn(u), u = F(phi_1) + lambda s (rod/wrench.py)
            mu = m0 / (2.0 * lam)
            k2 = c * c + mu * mu
            kp2 = (sh - abs(mu)) * (sh + abs(mu))
            if not k2 >= K2_MIN:
                flag |= F_STRAIGHT
            phi1 = math.atan2(c, mu)
            K = rf(0.0, kp2, 1.0)
            F1 = _F(phi1, kp2, K)
            ue = F1 + lam
            # the zeros of m at u = (2 j + 1) K strictly inside (F1, ue)
            lo = math.floor((F1 / K - 1.0) / 2.0) + 1
            bz = abs(math.cos(phi1)) < INFL_TOL
            if bz and lo == round((F1 / K - 1.0) / 2.0):
                lo += 1
            s0 = 1.0 if math.cos(phi1) > 0.0 else -1.0                 # sign of m(0)
            s1 = 1.0 if (ue + K) % (4.0 * K) < 2.0 * K else -1.0       # sign of m(1) = sign cn(ue)
            sp1 = -1.0 if ue % (4.0 * K) < 2.0 * K else 1.0            # sign of m'(1) = -2 lambda^2 k sn dn
            if clamped_tip:
                hi = math.ceil((ue / K - 1.0) / 2.0) - 1
                jz = round((ue / K - 1.0) / 2.0)
                tz = abs(ue - (2.0 * jz + 1.0) * K) * math.sqrt(kp2) < INFL_TOL   # |cos phi| ~ k' |du|
                if tz and hi == jz:
                    hi -= 1
                J = max(0, hi - lo + 1)
                if bz and tz:
                    flag |= F_ENDS
                su = 1.0 if u1 > 0.0 else -1.0
                if tz:
                    su = -s0 * sp1             # (J3) with m(1) = 0: u(1) = -m0 / m'(1)
                if bz or tz:
                    idx_cc = J
                else:
                    idx_cc = J - 1 + (1 if su * s1 * s0 > 0.0 else 0)
                idx_free = idx_cc + (1 if su * up1 < 0.0 else 0)
            else:
                # the pinned tip is a zero of m: J counts those before it
                hi = math.ceil((ue / K - 2.0) / 2.0) - 1
                J = max(0, hi - lo + 1)
                idx_cc = J
                if bz:
                    idx_free = J + 1           # u ~ m: u(1) = 0, the Prüfer angle is (J + 1) pi
                else:
                    idx_free = J + (1 if -s0 * sp1 * up1 < 0.0 else 0)
        else:
            # rotation: m keeps its sign, u = m m0 int m^-2 > 0 has no zero
            Ke2 = lam * lam * c * c + 0.25 * m0 * m0
            kp2 = (half - lam * sh) * (half + lam * sh) / Ke2
            idx_free = 1 if up1 < 0.0 else 0
    res[0] = lam
    res[1] = u1
    res[2] = up1
    res[3] = idx_cc
    res[4] = idx_free
    res[5] = flag
    res[6] = 1e-15 * (1.0 + 1.0 / math.sqrt(max(kp2, 1e-300)))


@njit
def _rotated(G00, G01, G10, G11, ca, sa):
    """``R G R^T`` (symmetric part) for the rotation by the clamp angle."""
    Gs = 0.5 * (G01 + G10)
    r00 = ca * ca * G00 - 2.0 * ca * sa * Gs + sa * sa * G11
    r11 = sa * sa * G00 + 2.0 * ca * sa * Gs + ca * ca * G11
    r01 = ca * sa * (G00 - G11) + (ca * ca - sa * sa) * Gs
    return r00, r01, r11


@njit
def bordered(ch, z, alpha, ell, e, force, arm, clamped, B) -> tuple[int, float, int, int]:
    """The closed-form index of one equilibrium (Eq. M1).

    ``ch`` (3,) charts, ``z`` (3, 3) chart coordinates, ``alpha`` (3,) clamp angles, ``ell``, ``e``
    (3,) lengths and stiffnesses (L_ref, EI_ref), ``force`` (3, 2) tip forces (world, F_ref),
    ``arm`` (3, 2) ``B_i - P`` (L_ref), ``clamped`` (3,); ``B`` (12, 12) receives the bordered
    matrix.  Returns (index, gap: the equilibrated B's smallest |eigenvalue| over its error
    bound, flags, sign of det B).
    """
    q = np.empty(NQ)
    gq = np.empty((NQ, 3))
    D = np.empty((4, 3))
    res = np.empty(7)
    terms = np.empty((3, 7))
    Ds = np.empty((3, 4, 3))
    use_cc = np.zeros(3, np.bool_)
    flag = 0
    ny = 3
    for i in range(3):
        eval_rod(ch[i], z[i], q, gq)
        rod_terms(q[FX], q[FY], q[M0], clamped[i], D, res)
        terms[i, :] = res
        Ds[i] = D
        flag |= int(res[5])
        use_cc[i] = abs(res[1]) >= abs(res[2])
        if use_cc[i] and not clamped[i]:
            ny += 1
    nrow = 0
    for i in range(3):
        nrow += 3 if (clamped[i] and not use_cc[i]) else 2
    n = ny + nrow
    dB = np.zeros((12, 12))
    B[:, :] = 0.0
    for i in range(3):
        B[2, 2] -= force[i, 0] * arm[i, 0] + force[i, 1] * arm[i, 1]
    dB[2, 2] = 1e-15 * abs(B[2, 2])
    base = 0
    t = 3
    row = ny
    for i in range(3):
        D = Ds[i]
        u1 = terms[i, 1]
        up1 = terms[i, 2]
        ep = terms[i, 6]
        ca, sa = math.cos(alpha[i]), math.sin(alpha[i])
        li = ell[i]
        sc = li * li * li / e[i]
        # (S2): C eta0 + E y = 0 with -(I, perp a_i) on dq
        B[row, 0] = -1.0
        B[row + 1, 1] = -1.0
        B[row, 2] = arm[i, 1]
        B[row + 1, 2] = -arm[i, 0]
        if use_cc[i]:
            base += int(terms[i, 3])
            G00 = D[0, 0] - D[0, 2] * D[2, 0] / u1      # (M2)
            G01 = D[0, 1] - D[0, 2] * D[2, 1] / u1
            G10 = D[1, 0] - D[1, 2] * D[2, 0] / u1
            G11 = D[1, 1] - D[1, 2] * D[2, 1] / u1
            aG = ep * (abs(D[0, 0]) + abs(D[0, 1]) + abs(D[1, 0]) + abs(D[1, 1])
                       + (abs(D[0, 2]) + abs(D[1, 2])) * (abs(D[2, 0]) + abs(D[2, 1])) / abs(u1))
            # the tip rotation: xi = u/u(1), Q(xi) = u'(1)/u(1), delta r(xi) = (dr/dm0)/u(1)
            cx = li * (ca * D[0, 2] - sa * D[1, 2]) / u1
            cy = li * (sa * D[0, 2] + ca * D[1, 2]) / u1
            ytt = e[i] / li * up1 / u1
            col = 2 if clamped[i] else t
            B[row, col] += cx
            B[row + 1, col] += cy
            B[col, col] += ytt
            dB[row, col] += 2.0 * ep * (abs(cx) + abs(cy))
            dB[row + 1, col] += 2.0 * ep * (abs(cx) + abs(cy))
            dB[col, col] += 2.0 * ep * abs(ytt)
            if not clamped[i]:
                t += 1
            nr = 2
        else:
            base += int(terms[i, 4])
            aG = ep * (abs(D[0, 0]) + abs(D[0, 1]) + abs(D[1, 0]) + abs(D[1, 1])
                       + (abs(D[0, 2]) + abs(D[1, 2])) * (abs(D[3, 0]) + abs(D[3, 1])) / abs(up1))
            G00 = D[0, 0] - D[0, 2] * D[3, 0] / up1      # compliance at a held tip moment
            G01 = D[0, 1] - D[0, 2] * D[3, 1] / up1
            G10 = D[1, 0] - D[1, 2] * D[3, 0] / up1
            G11 = D[1, 1] - D[1, 2] * D[3, 1] / up1
            nr = 2
            if clamped[i]:
                # the full tip compliance d(x, y, theta)/d(f_x, f_y, m(1)) and eta(1) = dtheta_P
                C20 = D[2, 0] - D[2, 2] * D[3, 0] / up1
                C21 = D[2, 1] - D[2, 2] * D[3, 1] / up1
                s2 = li * li / e[i]
                gx = 0.5 * s2 * ((ca * D[0, 2] - sa * D[1, 2]) / up1 + (ca * C20 - sa * C21))
                gy = 0.5 * s2 * ((sa * D[0, 2] + ca * D[1, 2]) / up1 + (sa * C20 + ca * C21))
                aC = ep * (abs(D[2, 0]) + abs(D[2, 1]) + abs(D[2, 2]) * (1.0 + abs(D[3, 0]) + abs(D[3, 1]))
                           / abs(up1))
                B[row + 2, row] = -gx
                B[row + 2, row + 1] = -gy
                B[row, row + 2] = -gx
                B[row + 1, row + 2] = -gy
                B[row + 2, row + 2] = -li / e[i] * D[2, 2] / up1
                B[row + 2, 2] = -1.0
                dB[row + 2, row + 2] = li / e[i] * aC
                dB[row + 2, row] = s2 * (aG + aC)
                dB[row + 2, row + 1] = s2 * (aG + aC)
                nr = 3
        r00, r01, r11 = _rotated(G00, G01, G10, G11, ca, sa)
        B[row, row] = -sc * r00
        B[row + 1, row + 1] = -sc * r11
        B[row, row + 1] = -sc * r01
        B[row + 1, row] = -sc * r01
        dB[row, row] = sc * aG
        dB[row + 1, row + 1] = sc * aG
        dB[row + 1, row] = sc * aG
        row += nr
    for r in range(ny, n):
        for c in range(ny):
            B[c, r] = B[r, c]
    for r in range(n):
        for c in range(r):
            v = max(dB[r, c], dB[c, r])
            dB[r, c] = v
            dB[c, r] = v
    for r in range(n):
        for c in range(n):
            if not abs(B[r, c]) < math.inf:  # a taut rod's Jacobi fields overflow: undecided here
                return 0, 0.0, flag | F_NONFINITE, 1
    # equilibrate (Ruiz: symmetric scaling by the rows' maxima; congruent, same inertia)
    Bn = B[:n, :n].copy()
    d = np.empty(n)
    for _ in range(6):
        for r in range(n):
            mx = 0.0
            for c in range(n):
                mx = max(mx, abs(Bn[r, c]))
            d[r] = 1.0 / math.sqrt(mx) if mx > 0.0 else 1.0
        for r in range(n):
            for c in range(n):
                Bn[r, c] *= d[r] * d[c]
                dB[r, c] *= d[r] * d[c]
    ev = np.linalg.eigvalsh(Bn)
    neg = 0
    mn = np.inf
    mx = 0.0
    for v in ev:
        if v < 0.0:
            neg += 1
        mn = min(mn, abs(v))
        mx = max(mx, abs(v))
    s = 0.0
    for r in range(n):
        for c in range(n):
            s += dB[r, c] * dB[r, c]
    err = math.sqrt(s) + 1e-14 * mx
    gap = mn / err
    if not gap >= GAP_SAFETY:
        flag |= F_GAP
    return base + neg - nrow, gap, flag, -1 if neg % 2 else 1


@njit
def _closed_batch(ch, z, alpha, ell, e, force, arm, clamped, idx, gap, flag, sign) -> None:
    B = np.empty((12, 12))
    for k in range(z.shape[0]):
        idx[k], gap[k], flag[k], sign[k] = bordered(ch[k], z[k], alpha[k], ell[k], e, force[k], arm[k], clamped, B)


# ================================================================================================
# arrays of equilibria
# ================================================================================================
def _arrays(system: System, X: NDArray, charts: NDArray) -> dict[str, NDArray]:
    """What the kernels read for equilibria ``X`` in ``charts``."""
    lay = system.layout
    n = len(X)
    z = np.zeros((n, 3, 3))
    for i in range(3):
        zi = X[:, lay.rod[i]]
        z[:, i, :zi.shape[1]] = zi
    _, alpha, L = system.clamps(X[:, lay.inputs])
    q, _ = system.unit_rods(X, charts)
    force = (system.EI[None] / L**2)[..., None] * rotate(q[..., [FX, FY]], alpha) / system.F_ref
    P = X[:, lay.pose]
    arm = (system.platform_points(P) - P[:, None, :2]) / system.L_ref
    return {"z": z, "ch": np.ascontiguousarray(charts, dtype=np.int64), "alpha": np.ascontiguousarray(alpha),
            "ell": np.ascontiguousarray(L / system.L_ref), "e": np.asarray(system.EI / system.EI_ref, dtype=float),
            "force": np.ascontiguousarray(force), "arm": np.ascontiguousarray(arm),
            "clamped": np.asarray(system.clamped, dtype=np.bool_), "q": q}


def closed_form_index(system: System, X: NDArray, charts: NDArray
                      ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """The closed-form index of equilibria ``X`` (n, n_unknowns) in ``charts`` (n, 3) (Eq. M1).

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.

    Returns
    -------
    index : (n,) int
        Number of negative directions of the second variation (meaningful where ``flags == 0``).
    gap : (n,) float
        Smallest |eigenvalue| of the equilibrated bordered matrix over its error bound.
    flags : (n,) int
        Why the closed form is not accepted (0: accepted; bits ``F_*``).
    sign : (n,) int
        Sign of the bordered determinant.
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    n = len(X)
    idx = np.zeros(n, np.int64)
    gap = np.zeros(n)
    flag = np.zeros(n, np.int64)
    sign = np.zeros(n, np.int64)
    if n:
        a = _arrays(system, X, charts)
        with single_threaded_blas():
            _closed_batch(a["ch"], a["z"], a["alpha"], a["ell"], a["e"], a["force"], a["arm"], a["clamped"], idx,
                          gap, flag, sign)
    return idx, gap, flag, sign


# ================================================================================================
# the margin (banded discretisation, :mod:`.second_variation`)
# ================================================================================================
@dataclass(frozen=True)
class Eigenpairs:
    """The lowest eigenvector of the discretised second variation of ``n`` equilibria, to start
    the next computation along a continuation (:mod:`flexkin.analysis.second_variation`; the
    vector is dimensionless, in the scaled variables of Eq. F1).

    Attributes
    ----------
    elements : ndarray (n, 3) of int
        Number of finite elements of each rod; a guess is used only where the next
        equilibrium has the same elements.
    rods : ndarray (n, 3, nmax)
        Coefficients of each rod's tangent-angle perturbation ``eta_i`` in the hierarchical
        p-version basis (degree ``P_FINE``, element by element; ``nmax`` = the largest
        ``elements`` times ``P_FINE``, zero-padded).
    pose : ndarray (n, 3)
        The platform part ``(dx / L_ref, dy / L_ref, dtheta)``.
    valid : ndarray (n,) of bool
        The eigenvector was computed (the margin is finite); only valid rows start a later
        computation.
    """

    elements: NDArray[np.int64]
    rods: NDArray[np.float64]
    pose: NDArray[np.float64]
    valid: NDArray[np.bool_]

    def take(self, rows: NDArray) -> "Eigenpairs":
        """The pairs of rows ``rows``."""
        return Eigenpairs(self.elements[rows], self.rods[rows], self.pose[rows], self.valid[rows])


@njit
def _fe_batch(ch, z, alpha, ell, e, fu, force, arm, clamped, E, c0, xg, wg, sh, guess, vr_all, vp_all,
              mu, res, idx, nfs, want_index) -> None:
    ng = xg.shape[0]
    T = np.zeros((3, 3, 3))
    Pp = np.zeros((3, 3))
    mi = np.empty(3, np.int64)
    code = np.empty(3, np.int64)
    gn = np.zeros((3, 2))
    for k in range(z.shape[0]):
        emax = 0
        for i in range(3):
            emax = max(emax, E[k, i])
        th = np.empty((3, emax * ng))
        for i in range(3):
            rod_nodes(ch[k, i], z[k, i], E[k, i], xg, th[i, :E[k, i] * ng])
        Ptt = 0.0
        L0 = 0.0
        for i in range(3):
            Ptt -= force[k, i, 0] * arm[k, i, 0] + force[k, i, 1] * arm[k, i, 1]
            lam2 = math.hypot(fu[k, i, 0], fu[k, i, 1])
            # lower bound of the spectrum: Q_i >= (e/l)(pi^2/4 - lambda^2) int eta^2 (Poincaré)
            L0 = min(L0, e[i] / (ell[k, i] * ell[k, i]) * (0.25 * math.pi * math.pi - lam2))
            mi[i] = 3 if clamped[i] else 2
            code[i] = 1 if clamped[i] else 0
            T[i, :, :] = 0.0
            T[i, 0, 0] = -1.0
            T[i, 1, 1] = -1.0
            T[i, 0, 2] = arm[k, i, 1]
            T[i, 1, 2] = -arm[k, i, 0]
            if clamped[i]:
                T[i, 2, 2] = -1.0
        Pp[2, 2] = Ptt
        L0 = min(L0, Ptt) - 1.0
        vr = vr_all[k, :, :emax * P_FINE]
        vp = vp_all[k]
        mu[k], res[k], idx[k], nfs[k] = fe_stability(th, fu[k], alpha[k], ell[k], e, E[k], mi, code, gn, T, Pp, 3,
                                                     3, xg, wg, sh, L0, c0[k], vr, vp, guess[k], want_index)


def _margins(system: System, X: NDArray, charts: NDArray, c0: NDArray, want_index: bool,
             guess: Eigenpairs | None = None, a: dict | None = None
             ) -> tuple[NDArray, NDArray, NDArray, Eigenpairs]:
    """Margin, resolution, discretised index (with ``want_index``) and eigenpairs of equilibria."""
    a = _arrays(system, X, charts) if a is None else a
    n = len(X)
    ch = a["ch"].copy()
    z = a["z"].copy()
    for i in range(3):
        seam = ch[:, i] == CHART_SEAM
        if np.any(seam):  # the tangent angles are evaluated in the unified chart
            v, ph = seam_to_chart(z[seam, i, 0], z[seam, i, 1])
            z[seam, i, 0], z[seam, i, 1] = v, ph
            ch[seam, i] = CHART_UNIFIED
    E = elements_for(a["q"][..., PHI])
    use = np.zeros(n, bool)
    if guess is not None:
        # the previous eigenvector starts the iteration where the elements are the same
        use = guess.valid & np.all(guess.elements == E, axis=1)
        E = np.where(use[:, None], guess.elements, E)
    nmax = int(E.max()) * P_FINE if n else P_FINE
    vr = np.zeros((n, 3, nmax))
    vp = np.zeros((n, 3))
    if guess is not None and np.any(use):
        w = min(nmax, guess.rods.shape[2])
        vr[use, :, :w] = guess.rods[use, :, :w]
        vp[use] = guess.pose[use]
    xg, wg, sh = element_rule(P_FINE)
    mu = np.empty(n)
    res = np.empty(n)
    idx = np.empty(n, np.int64)
    nfs = np.empty(n, np.int64)
    if n:
        with single_threaded_blas():
            _fe_batch(ch, z, a["alpha"], a["ell"], a["e"], np.ascontiguousarray(a["q"][..., [FX, FY]]), a["force"],
                      a["arm"], a["clamped"], E, np.asarray(c0, dtype=np.int64), xg, wg, sh, use, vr, vp, mu, res,
                      idx, nfs, want_index)
    ok = np.isfinite(mu)
    return mu, res, idx, Eigenpairs(E, vr, vp, ok)


# ================================================================================================
# the public entry
# ================================================================================================
@dataclass(frozen=True)
class StabilityArrays:
    """Stability of ``n`` equilibria (see the module docstring).

    Attributes
    ----------
    stable : (n,) int8: 1 stable, 0 unstable, -1 undecided.
    margin : (n,) smallest eigenvalue of the second variation (EI_ref / L_ref); ``NaN`` where
        it was not computed.
    resolution : (n,) its guaranteed resolution (``NaN`` where not computed).
    index : (n,) number of negative directions, -1 where unresolved.
    method : (n,) ``CLOSED_FORM`` (0) or ``DISCRETISED`` (1): what decided the verdict.
    flags : (n,) why the closed form was not accepted (0 where it was).
    gap : (n,) the closed form's gap (smallest |eigenvalue| of the equilibrated bordered matrix
        over its error bound).
    sign : (n,) sign of the bordered determinant.
    pairs : Eigenpairs or None
        The lowest eigenvectors where margins were computed.
    """

    stable: NDArray[np.int8]
    margin: NDArray[np.float64]
    resolution: NDArray[np.float64]
    index: NDArray[np.int64]
    method: NDArray[np.int8]
    flags: NDArray[np.int64]
    gap: NDArray[np.float64]
    sign: NDArray[np.int64]
    pairs: Eigenpairs | None = None

    def item(self, i: int) -> Stability:
        """The :class:`Stability` of equilibrium ``i``."""
        st = int(self.stable[i])
        note = ""
        if st < 0:
            why = ", ".join(t for b, t in _WHY.items() if int(self.flags[i]) & b) or "ill-conditioned"
            note = (f"undecided: the closed form is not conclusive here ({why}) and the smallest eigenvalue of the "
                    f"discretised second variation, {self.margin[i]:.3g}, is below its resolution "
                    f"{self.resolution[i]:.2g} (typical of a rod near the separatrix: a loop held in tension or a "
                    f"taut rod)")
        idx = int(self.index[i])
        return Stability(None if st < 0 else bool(st), float(self.margin[i]), None if idx < 0 else idx,
                         float(self.resolution[i]), note)


def mechanism_stability(system: System, X: NDArray, charts: NDArray, margin: bool = False,
                        guess: Eigenpairs | None = None) -> StabilityArrays:
    """Stability of equilibria ``X`` (n, n_unknowns) in ``charts`` (n, 3), actuators locked.

    The verdict and the index come from the closed form (module docstring); where it is not
    conclusive, from the discretised second variation.

    Parameters
    ----------
    system : System
        The mechanism's equation system (:meth:`System.from_mechanism`).
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    margin : bool
        Also compute every equilibrium's margin (else only where the closed form falls back).
    guess : Eigenpairs, optional
        Eigenvectors of nearby equilibria (row by row) to start the margin computation from.

    Returns
    -------
    StabilityArrays
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    n = len(X)
    idx, gap, flags, sign = closed_form_index(system, X, charts)
    mg = np.full(n, np.nan)
    res = np.full(n, np.nan)
    method = np.zeros(n, np.int8)
    stable = np.where(idx == 0, 1, 0).astype(np.int8)
    fb = flags != 0
    todo = np.flatnonzero(fb | margin) if n else np.zeros(0, np.int64)
    pairs = None
    if todo.size:
        c0 = np.where(fb[todo], -1, idx[todo])
        g = None if guess is None else guess.take(todo)
        mu, r, fidx, pr = _margins(system, X[todo], charts[todo], c0, bool(np.any(fb)), g)
        mg[todo], res[todo] = mu, r
        # a resolved discretised margin that contradicts the closed-form verdict: undecided
        bad = ~fb[todo] & (np.abs(mu) > 3.0 * r) & ((mu > 0.0) != (idx[todo] == 0))
        if np.any(bad):
            flags[todo[bad]] |= F_DISAGREE
            fb[todo[bad]] = True
        f = fb[todo]
        if np.any(f):
            rows = todo[f]
            method[rows] = DISCRETISED
            stable[rows] = np.where(mu[f] > 3.0 * r[f], 1, np.where(mu[f] < -3.0 * r[f], 0, -1))
            idx[rows] = np.where(stable[rows] == 1, 0, np.where(stable[rows] == 0, fidx[f], -1))
        if margin:
            pairs = Eigenpairs(np.zeros((n,) + pr.elements.shape[1:], np.int64),
                               np.zeros((n,) + pr.rods.shape[1:]), np.zeros((n, 3)), np.zeros(n, bool))
            pairs.elements[todo], pairs.rods[todo], pairs.pose[todo], pairs.valid[todo] = (
                pr.elements, pr.rods, pr.pose, pr.valid)
    return StabilityArrays(stable, mg, res, idx, method, flags, gap, sign, pairs)


def solution_margins(system: System, X: NDArray, charts: NDArray, index: NDArray | None = None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Margins and their resolutions of equilibria ``X`` in ``charts`` (the index, when known,
    saves the discretisation a Sylvester count).

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    index : ndarray (n,), optional
        Their indices where known (-1 elsewhere).

    Returns
    -------
    margin, resolution : ndarray (n,)
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    c0 = np.full(len(X), -1, np.int64) if index is None else np.asarray(index, dtype=np.int64)
    mu, res, _, _ = _margins(system, X, charts, c0, False)
    return mu, res


# ---- the platform's output stiffness ------------------------------------------------------------
def output_stiffness(system: System, X: NDArray, charts: NDArray, load: NDArray) -> NDArray[np.float64]:
    """The platform's stiffness with the actuators locked, ``K = dW/dq`` (n, 3, 3): the change of
    the load wrench ``W = (F_x, F_y, M_z)`` that holds the platform displaced by ``dq = (dx, dy,
    dtheta)`` at equilibrium.  It is the Hessian of the potential reduced to the pose; units N/m
    (force/translation), N (force/rotation and moment/translation), N m/rad (moment/rotation).

    Parameters
    ----------
    system : System
        The mechanism's equation system (:meth:`System.from_mechanism`).
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    load : ndarray (3,)
        Load wrench ``(F_x, F_y, M_z)`` on the platform (N, N, N m).

    Returns
    -------
    ndarray (n, 3, 3)
    """
    from .jacobian import system_blocks

    Gz, Gx, _ = system_blocks(system, X, charts, load)
    # residual rows of the equilibrium are (sum n - W) / scale: dR/dW = -1/scale on them
    lay = system.layout
    n, ne, nz = Gz.shape
    Gw = np.zeros((ne, 3))
    Gw[lay.force.start, 0] = Gw[lay.force.start + 1, 1] = -1.0
    Gw[lay.moment.start, 2] = -1.0
    A = np.concatenate([Gz, np.broadcast_to(Gw, (n, ne, 3))], axis=2)   # unknowns (dz, dW/wscale)
    sol = -np.linalg.solve(A, Gx)                                       # (n, nz + 3, 3) per unit pose
    dW = sol[:, nz:, :] * system.wrench_scale()[None, :, None]          # wrench per dimensionless pose
    return dW / np.array([system.L_ref, system.L_ref, 1.0])[None, None, :]


# ================================================================================================
# one rod: the classical cases
# ================================================================================================
@dataclass(frozen=True)
class RodStability:
    """Stability of one clamped rod under a tip condition (see :func:`rod_stability`).

    Attributes
    ----------
    stable : bool or None
    index : int or None
        Number of unstable directions.
    margin : float
        Smallest eigenvalue of the second variation (EI / L units of the rod).
    resolution : float
    tip : str
    """

    stable: bool | None
    index: int | None
    margin: float
    resolution: float
    tip: str


_TIPS = {"free": (0, 2), "pinned": (2, 0), "slider": (1, 3), "clamped": (3, 1)}


def _rod_closed_form(rod: RodState, tip: str, g: NDArray) -> tuple[int, float]:
    """Closed-form index of one rod under a tip condition (Eq. M1 without the platform; in the
    rod's own clamp frame) and the gap of its bordered matrix."""
    z = np.zeros(3)
    z[:len(rod.coords)] = rod.coords
    q = np.empty(NQ)
    gq = np.empty((NQ, 3))
    eval_rod(int(rod.chart), z, q, gq)
    D = np.empty((4, 3))
    res = np.empty(7)
    rod_terms(q[FX], q[FY], q[M0], int(rod.chart) >= CHART_WRENCH, D, res)   # pinned charts: m(1) = 0
    u1, up1 = res[1], res[2]
    if int(res[5]) & (F_STRAIGHT | F_NONFINITE | F_ENDS | F_LOST):
        return -1, 0.0
    cc = abs(u1) >= abs(up1)
    if tip == "clamped":
        # constraints delta r = 0 and eta(1) = 0: on the cc base t = 0 is imposed (no y)
        if cc:
            base = int(res[3])
            B = -(D[:2, :2] - np.outer(D[:2, 2], D[2, :2]) / u1)
        else:
            base = int(res[4])
            A = np.eye(3)
            A[2] = D[3]
            B = -(D[:3] @ np.linalg.inv(A))
    elif cc:
        base = int(res[3])
        Gc = D[:2, :2] - np.outer(D[:2, 2], D[2, :2]) / u1
        c = D[:2, 2] / u1
        rows = {"free": np.zeros((0, 2)), "pinned": np.eye(2), "slider": g[None, :]}[tip]
        m = len(rows)
        B = np.zeros((1 + m, 1 + m))
        B[0, 0] = up1 / u1
        B[1:, 0] = B[0, 1:] = rows @ c
        B[1:, 1:] = -rows @ Gc @ rows.T
    else:
        base = int(res[4])
        Gf = D[:2, :2] - np.outer(D[:2, 2], D[3, :2]) / up1
        rows = {"free": np.zeros((0, 2)), "pinned": np.eye(2), "slider": g[None, :]}[tip]
        B = -rows @ Gf @ rows.T
    B = 0.5 * (B + B.T)
    m = {"free": 0, "pinned": 2, "slider": 1, "clamped": 2 if cc else 3}[tip]
    ev = np.linalg.eigvalsh(B) if B.size else np.zeros(0)
    gap = float(np.min(np.abs(ev)) / max(np.max(np.abs(ev)), 1e-300)) if ev.size else np.inf
    return base + int(np.sum(ev < 0)) - m, gap


def _rod_discretised(rod: RodState, tip: str, g: NDArray) -> tuple[float, float, int]:
    """Margin, resolution and discretised index of one rod under a tip condition (``g``: a
    slider's normal in the clamp frame), in the rod's own ``EI / L``."""
    chart = int(rod.chart)
    z = np.zeros(3)
    z[:len(rod.coords)] = rod.coords
    if chart == CHART_SEAM:
        v, ph = seam_to_chart(z[0], z[1])
        z[0], z[1] = float(v), float(ph)
        chart = CHART_UNIFIED
    with single_threaded_blas():
        q = np.empty(NQ)
        gq = np.empty((NQ, 3))
        eval_rod(chart, z, q, gq)
        lam = float(np.sqrt(np.hypot(q[FX], q[FY])))
        E = elements_for(np.array([lam, 0.0, 0.0]))
        E[1:] = 2
        xg, wg, sh = element_rule(P_FINE)
        th = np.zeros((3, int(E.max()) * len(xg)))
        rod_nodes(chart, z, int(E[0]), xg, th[0, :int(E[0]) * len(xg)])
        mi_, code_ = _TIPS[tip]
        gn = np.zeros((3, 2))
        gn[0] = g
        fu = np.zeros((3, 2))
        fu[0] = q[FX], q[FY]
        L0 = min(0.0, 0.25 * math.pi**2 - lam**2) - 1.0
        mu, res, fidx, _ = fe_stability(th, fu, np.zeros(3), np.ones(3), np.ones(3), E,
                                        np.array([mi_, 0, 0], np.int64), np.array([code_, 2, 2], np.int64), gn,
                                        np.zeros((3, 3, 3)), np.zeros((3, 3)), 1, 0, xg, wg, sh, L0, -1,
                                        np.zeros((3, int(E.max()) * P_FINE)), np.zeros(3), False, True)
    return float(mu), float(res), int(fidx)


def rod_stability(rod: RodState, tip: str = "pinned", slider_angle: float | None = None) -> RodStability:
    """Stability of one rod clamped at its base, with its tip

    * ``"free"``: a dead load on a free tip (the cantilever);
    * ``"pinned"``: held at a fixed point, free to turn;
    * ``"slider"``: sliding on a line of angle ``slider_angle`` (rad, world), free to turn;
    * ``"clamped"``: held at a fixed point with a fixed tangent.

    The rod must be an equilibrium of that problem (for ``"free"`` and ``"slider"`` the tip
    force is the dead load).  The index from the closed form (module docstring, Eq. M1 with
    the tip's constraints), the margin from the banded discretisation, in the rod's own ``EI / L``.

    Parameters
    ----------
    rod : RodState
        The rod (its clamp angle, chart coordinates, length, EI and tip force are used).
    tip : {"pinned", "slider", "free", "clamped"}
        The tip condition.
    slider_angle : float, optional
        Direction of the slider's line (rad, world); required for ``tip="slider"``.

    Returns
    -------
    RodStability
    """
    if tip not in _TIPS:
        raise ValueError(f"tip must be 'free', 'pinned', 'slider' or 'clamped', got {tip!r}")
    if tip == "slider" and slider_angle is None:
        raise ValueError("tip='slider' needs slider_angle (rad)")
    g = np.zeros(2)
    if tip == "slider":       # the slider's normal in the clamp frame
        ang = float(slider_angle) - rod.clamp_angle
        g = np.array([-math.sin(ang), math.cos(ang)])
    with single_threaded_blas():
        cf_index, gap = _rod_closed_form(rod, tip, g)
    mu, res, fidx = _rod_discretised(rod, tip, g)
    if cf_index >= 0 and gap > 1e-10:
        index: int | None = cf_index
        stable: bool | None = cf_index == 0
    else:
        stable = None if abs(mu) <= 3.0 * res else bool(mu > 0.0)
        index = 0 if stable else (None if fidx < 0 else int(fidx))
    return RodStability(stable, index, float(mu), float(res), tip)
