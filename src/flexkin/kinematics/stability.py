"""Stability of an equilibrium with the actuators locked (paper §4.3), exactly.

The total potential of the mechanism is

    V = sum_i (EI_i/2) int_0^{L_i} theta_i'(s)^2 ds  -  F . P  -  M theta_P,

on the configurations with every rod clamped (actuators locked) and every rod tip pinned to
its platform point ``B_i = P + Rot(theta_P) b_i``.  An equilibrium is stable when the second
variation of V is positive definite on the admissible perturbations.  The second variation
is split exactly (Schur complement; Haynsworth inertia additivity) into

1. **each rod with its tip pinned** (the platform held still): Jacobi's conjugate-point test
   for the isoperimetric problem (Manning, Rogers & Maddocks 1998).  The number of
   conjugate points on (0, L) is the number of unstable directions of that rod;
2. **the platform**, moving the rod tips: the reduced Hessian of
   ``V(q) = sum_i U_i(p_i(q)) - F.P - M theta`` over the pose ``q``, where ``U_i(p)`` is the
   rod's equilibrium energy with its tip at ``p``, ``grad U_i = n_i`` (the force on the tip)
   and ``hess U_i = K_i = dn_i/dp_i`` (the rod's tip stiffness, from the closed form):

       H = sum_i J_i^T K_i J_i  -  diag(0, 0, sum_i n_i . (B_i - P)),   J_i = [I, perp(B_i - P)].

The Morse index (number of unstable directions) of the equilibrium is the sum of the rods'
conjugate-point counts and the number of negative eigenvalues of H; the equilibrium is
stable when the index is 0.  The same Jacobi test, with the tip free under a dead load or
sliding on a line, gives the classical cantilever and column results (:func:`rod_stability`).

Jacobi fields of a unit rod (``EI = L = 1``, local clamp frame), linearising
``theta' = m``, ``m' = n_x sin(theta) - n_y cos(theta)``, ``r' = (cos theta, sin theta)``:

    dtheta' = dm
    dm'     = dn_x sin(theta) - dn_y cos(theta) + (n_x cos(theta) + n_y sin(theta)) dtheta
    dx'     = -sin(theta) dtheta,     dy' = cos(theta) dtheta,

with ``dtheta(0) = 0`` (clamp), ``dm(0)`` free and ``dn = G mu`` in the span of the
constrained tip directions ``G`` (2 columns for a pinned tip, the slider's normal for a
slider, none for a free tip under a dead load).  A conjugate point is an ``s`` where a
non-trivial field has ``dm(s) = 0`` (moment-free end) and ``G^T dr(s) = 0``, i.e. a zero of
``D(s) = det [dm(s); G^T dr(s)]`` over the ``1 + c`` fields.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ..rod.closed_form import tangent_angles, tip_chart
from ..rod.state import RodState
from .system import MechArrays, clamp_arrays, platform_points, rod_world

__all__ = ["jacobi_conjugate_points", "rod_tip_stiffness", "reduced_hessian", "mechanism_stability",
           "rod_stability", "RodStability", "JACOBI_STEPS"]

#: RK4 steps along a unit rod for the Jacobi fields (theta sampled at twice this rate)
JACOBI_STEPS = 256
#: the reference sign of D(s) is taken at s = S_REF (no conjugate point can be closer to the
#: clamp than ~pi / sqrt(R L^2/EI), i.e. 0.08 L at the largest forces in scope)
S_REF = 0.02


@njit(cache=True)
def _rhs(y: NDArray, th: float, fx: float, fy: float, G: NDArray, out: NDArray) -> None:
    """Jacobi equations (module docstring) for the fields ``y`` (4 + c, d), in place."""
    s, c = np.sin(th), np.cos(th)
    q = fx * c + fy * s
    nc = G.shape[1]
    for j in range(y.shape[1]):
        dnx = 0.0
        dny = 0.0
        for a in range(nc):
            dnx += G[0, a] * y[4 + a, j]
            dny += G[1, a] * y[4 + a, j]
        out[0, j] = y[1, j]
        out[1, j] = dnx * s - dny * c + q * y[0, j]
        out[2, j] = -s * y[0, j]
        out[3, j] = c * y[0, j]
        for a in range(nc):
            out[4 + a, j] = 0.0


@njit(cache=True)
def _det_small(C: NDArray) -> float:
    d = C.shape[0]
    if d == 1:
        return C[0, 0]
    if d == 2:
        return C[0, 0] * C[1, 1] - C[0, 1] * C[1, 0]
    return (C[0, 0] * (C[1, 1] * C[2, 2] - C[1, 2] * C[2, 1])
            - C[0, 1] * (C[1, 0] * C[2, 2] - C[1, 2] * C[2, 0])
            + C[0, 2] * (C[1, 0] * C[2, 1] - C[1, 1] * C[2, 0]))


@njit(cache=True)
def _jacobi_kernel(theta: NDArray, force: NDArray, G: NDArray, j_ref: int,
                   count: NDArray, first: NDArray) -> None:
    n, ns = theta.shape
    N = (ns - 1) // 2
    h = 1.0 / N
    c = G.shape[2]
    d = 1 + c
    dim = 4 + c
    y = np.zeros((dim, d))
    k1 = np.zeros((dim, d))
    k2 = np.zeros((dim, d))
    k3 = np.zeros((dim, d))
    k4 = np.zeros((dim, d))
    tmp = np.zeros((dim, d))
    C = np.zeros((d, d))
    for r in range(n):
        y[:, :] = 0.0
        y[1, 0] = 1.0                      # field 0: base moment
        for a in range(c):
            y[4 + a, 1 + a] = 1.0          # fields 1..c: constraint reactions
        fx, fy = force[r, 0], force[r, 1]
        Gr = G[r]
        acc = 1.0
        prev = 0.0
        count[r] = 0
        first[r] = np.inf
        for j in range(N):
            t0, tm, t1 = theta[r, 2 * j], theta[r, 2 * j + 1], theta[r, 2 * j + 2]
            _rhs(y, t0, fx, fy, Gr, k1)
            tmp[:, :] = y + 0.5 * h * k1
            _rhs(tmp, tm, fx, fy, Gr, k2)
            tmp[:, :] = y + 0.5 * h * k2
            _rhs(tmp, tm, fx, fy, Gr, k3)
            tmp[:, :] = y + h * k3
            _rhs(tmp, t1, fx, fy, Gr, k4)
            y += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            # modified Gram-Schmidt: the fields stay a well-conditioned basis; the product of
            # the pivots' signs (all positive here) keeps the sign of det(C Y) exact
            for a in range(d):
                for b in range(a):
                    proj = 0.0
                    for i in range(dim):
                        proj += y[i, a] * y[i, b]
                    for i in range(dim):
                        y[i, a] -= proj * y[i, b]
                nrm = 0.0
                for i in range(dim):
                    nrm += y[i, a] * y[i, a]
                nrm = np.sqrt(nrm)
                for i in range(dim):
                    y[i, a] /= nrm
            for b in range(d):
                C[0, b] = y[1, b]
                for a in range(c):
                    C[1 + a, b] = Gr[0, a] * y[2, b] + Gr[1, a] * y[3, b]
            D = _det_small(C) * acc
            if j + 1 > j_ref and prev != 0.0 and (D > 0.0) != (prev > 0.0):
                s_cross = h * (j + prev / (prev - D))
                if s_cross < first[r]:
                    first[r] = s_cross
                count[r] += 1
            if j + 1 >= j_ref:
                prev = D


def jacobi_conjugate_points(theta: NDArray[np.float64], force: NDArray[np.float64], G: NDArray[np.float64]
                            ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Conjugate points of unit rods (Jacobi test).

    The fields are integrated by RK4 on the grid of ``theta`` (midpoints at odd indices) and
    re-orthonormalised after every step (Gram-Schmidt with positive pivots, which leaves the
    sign of ``D(s)`` unchanged); sign changes of ``D`` after ``s = S_REF`` are counted.

    Parameters
    ----------
    theta : ndarray, shape (n, 2 N + 1)
        Tangent angle at ``s = linspace(0, 1, 2 N + 1)`` (local frame, ``theta[:, 0] = 0``).
    force : ndarray, shape (n, 2)
        Force on the tip (= internal force), unit rod (``EI = L = 1``), local frame.
    G : ndarray, shape (n, 2, c)
        Constrained tip directions (orthonormal columns), ``c`` in {0, 1, 2}.

    Returns
    -------
    count : ndarray of int, shape (n,)
        Number of conjugate points in ``(0, 1)`` (the rod's Morse index).
    first : ndarray, shape (n,)
        Arc length of the first conjugate point (``inf`` if none).
    """
    theta = np.ascontiguousarray(theta, dtype=float)
    f = np.ascontiguousarray(force, dtype=float)
    G = np.ascontiguousarray(G, dtype=float)
    n = theta.shape[0]
    N = (theta.shape[1] - 1) // 2
    count = np.zeros(n, dtype=np.int64)
    first = np.full(n, np.inf)
    if n:
        _jacobi_kernel(theta, f, G, max(1, int(np.ceil(S_REF * N))), count, first)
    return count, first


def _theta_nodes(v: NDArray, phis: NDArray, steps: int) -> NDArray[np.float64]:
    return tangent_angles(v, phis, np.linspace(0.0, 1.0, 2 * steps + 1))


def _pinned_G(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Constrained directions of a pinned tip: both axes, unless the rod is (numerically)
    straight, when the axial constraint is vacuous to first order (inextensible rod) and
    only the lateral one is kept (the rod then behaves like a tip on an axial slider)."""
    n = theta.shape[0]
    w = np.full(theta.shape[1], 1.0)
    w[0] = w[-1] = 0.5
    w /= w.sum()
    s, c = np.sin(theta), np.cos(theta)
    gram = np.stack([np.stack([(w * s * s).sum(1), -(w * s * c).sum(1)], -1),
                     np.stack([-(w * s * c).sum(1), (w * c * c).sum(1)], -1)], -2)
    ev, vec = np.linalg.eigh(gram)
    degenerate = ev[:, 0] < 1e-14 * ev[:, 1]
    G = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    return G, degenerate, vec[:, :, 1:2]


def rod_conjugate_points(v: ArrayLike, phis: ArrayLike, steps: int = JACOBI_STEPS
                         ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Conjugate points of clamped rods with their tip pinned (chart coordinates).

    Returns the count on (0, L) and the first one as a fraction of L (``inf`` if none).
    """
    v = np.atleast_1d(np.asarray(v, dtype=float))
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    theta = _theta_nodes(v, phis, steps)
    t = tip_chart(v, phis)
    f = np.stack([t.fx, t.fy], -1)
    G, degenerate, lateral = _pinned_G(theta)
    count = np.zeros(len(v), dtype=np.int64)
    first = np.full(len(v), np.inf)
    if np.any(~degenerate):
        ok = ~degenerate
        count[ok], first[ok] = jacobi_conjugate_points(theta[ok], f[ok], G[ok])
    if np.any(degenerate):
        count[degenerate], first[degenerate] = jacobi_conjugate_points(theta[degenerate], f[degenerate],
                                                                       lateral[degenerate])
    return count, first


def rod_tip_stiffness(v: ArrayLike, phis: ArrayLike, step: float = 1e-6) -> NDArray[np.float64]:
    """Tip stiffness ``K = dn/dp`` of unit rods, local frame, shape (n, 2, 2).

    ``K`` is the Hessian of the rod's equilibrium energy as a function of its tip position
    (``grad U = n``), so it is symmetric; computed as ``(dn/dz) (dp/dz)^-1`` on the chart
    ``z = (v, phis)`` by central differences of the closed form (Eqs. 9, 12, 13).
    """
    v = np.atleast_1d(np.asarray(v, dtype=float))
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    cols_p, cols_f = [], []
    for dv, dp in ((step, 0.0), (0.0, step)):
        a, b = tip_chart(v + dv, phis + dp), tip_chart(v - dv, phis - dp)
        cols_p.append(np.stack([a.x - b.x, a.y - b.y], -1) / (2 * step))
        cols_f.append(np.stack([a.fx - b.fx, a.fy - b.fy], -1) / (2 * step))
    Jp = np.stack(cols_p, -1)
    Jf = np.stack(cols_f, -1)
    return Jf @ np.linalg.inv(Jp)


def reduced_hessian(m: MechArrays, zrod: NDArray, pose: NDArray, inputs: NDArray) -> NDArray[np.float64]:
    """Reduced Hessian ``H`` (n, 3, 3) of the potential over the pose (module docstring).

    Dimensionless: translations in units of ``L_ref``, energy in ``EI_ref / L_ref``.
    """
    zrod = np.atleast_2d(zrod)
    pose = np.atleast_2d(pose)
    inputs = np.atleast_2d(inputs)
    n = len(zrod)
    _, alpha, L = clamp_arrays(m, inputs)
    _, force = rod_world(m, zrod, inputs)
    B = platform_points(m, pose)
    arm = B - pose[:, None, :2]
    H = np.zeros((n, 3, 3))
    for i in range(3):
        Kl = rod_tip_stiffness(zrod[:, 2 * i], zrod[:, 2 * i + 1]) * (m.EI[i] / L[:, i] ** 3)[:, None, None]
        ca, sa = np.cos(alpha[:, i]), np.sin(alpha[:, i])
        Rm = np.stack([np.stack([ca, -sa], -1), np.stack([sa, ca], -1)], -2)
        K = Rm @ Kl @ np.swapaxes(Rm, 1, 2)
        J = np.zeros((n, 2, 3))
        J[:, 0, 0] = J[:, 1, 1] = 1.0
        J[:, 0, 2] = -arm[:, i, 1]
        J[:, 1, 2] = arm[:, i, 0]
        H += np.swapaxes(J, 1, 2) @ K @ J
        H[:, 2, 2] -= np.sum(force[:, i] * arm[:, i], axis=1)
    S = np.array([m.L_ref, m.L_ref, 1.0])
    return H * S[None, :, None] * S[None, None, :] / (m.F_ref * m.L_ref)


@dataclass(frozen=True)
class StabilityArrays:
    """Stability of ``n`` equilibria (arrays; see :func:`mechanism_stability`)."""

    stable: NDArray[np.bool_]        # (n,)
    index: NDArray[np.int64]         # (n,) number of unstable directions (Morse index)
    margin: NDArray[np.float64]      # (n,) see mechanism_stability
    rod_conjugate: NDArray[np.int64]  # (n, 3) conjugate points of each rod with its tip pinned
    rod_first: NDArray[np.float64]    # (n, 3) first conjugate point / L (inf if none)
    hessian: NDArray[np.float64]      # (n, 3, 3) reduced Hessian (dimensionless)


def mechanism_stability(m: MechArrays, zrod: NDArray, pose: NDArray, inputs: NDArray,
                        steps: int = JACOBI_STEPS) -> StabilityArrays:
    """Stability of equilibria of the mechanism with the actuators locked.

    Parameters
    ----------
    m : MechArrays
    zrod, pose, inputs : ndarray, shapes (n, 6), (n, 3), (n, 3)
        Refined equilibria (the load enters through the rods' tip forces).
    steps : int
        RK4 steps of the Jacobi fields along each rod.

    Returns
    -------
    StabilityArrays
        ``stable`` iff no rod has a conjugate point and the reduced Hessian is positive
        definite.  ``margin`` is the smallest eigenvalue of the dimensionless reduced Hessian
        when every rod passes its own test; when a rod buckles on its own (pinned at both
        ends), it is ``sigma/L - 1 < 0`` for the rod's first conjugate point ``sigma`` (the
        rod would be stable if it were shorter than ``sigma``), so ``margin > 0`` iff stable.
    """
    zrod = np.atleast_2d(np.asarray(zrod, dtype=float))
    n = len(zrod)
    cnt, first = rod_conjugate_points(zrod[:, 0::2].ravel(), zrod[:, 1::2].ravel(), steps)
    cnt, first = cnt.reshape(n, 3), first.reshape(n, 3)
    H = reduced_hessian(m, zrod, pose, inputs)
    H = 0.5 * (H + np.swapaxes(H, 1, 2))
    finite = np.all(np.isfinite(H), axis=(1, 2))
    ev = np.full((n, 3), -np.inf)
    if np.any(finite):
        ev[finite] = np.linalg.eigvalsh(H[finite])
    index = cnt.sum(1) + np.sum(ev < 0.0, axis=1)
    rods_ok = cnt.sum(1) == 0
    margin = np.where(rods_ok, ev[:, 0], np.min(first, axis=1) - 1.0)
    margin = np.where(np.isfinite(margin), margin, -1.0)
    return StabilityArrays(index == 0, index.astype(np.int64), margin, cnt, first, H)


# ---- a single rod: the classical cases -----------------------------------------------------------


@dataclass(frozen=True)
class RodStability:
    """Stability of one clamped rod under a tip condition (see :func:`rod_stability`).

    Attributes
    ----------
    stable : bool
    index : int
        Number of conjugate points on (0, L) = number of unstable directions.
    first_conjugate : float
        Arc length of the first conjugate point (m), ``inf`` if none on (0, L).
    tip : str
        ``"pinned"``, ``"slider"`` or ``"free"``.
    """

    stable: bool
    index: int
    first_conjugate: float
    tip: str


def rod_stability(rod: RodState, tip: str = "pinned", slider_angle: float | None = None,
                  steps: int = JACOBI_STEPS) -> RodStability:
    """Stability of one rod clamped at its base, with its tip force treated as

    * ``"pinned"``: a reaction, the tip held at a fixed point (rotation free);
    * ``"slider"``: a dead load along a line of angle ``slider_angle`` (rad, world frame) on
      which the tip slides, plus the lateral reaction (rotation free);
    * ``"free"``: a dead load on a free tip (the cantilever).

    The rod must be an equilibrium of that problem (zero tip moment, as every
    :class:`RodState` is; for ``"slider"`` and ``"free"`` the tip force must be the dead
    load).  Jacobi's conjugate-point test, see the module docstring.
    """
    if tip not in ("pinned", "slider", "free"):
        raise ValueError(f"tip must be 'pinned', 'slider' or 'free', got {tip!r}")
    theta = _theta_nodes(np.array([rod.v]), np.array([rod.phis]), steps)
    t = tip_chart(rod.v, rod.phis)
    f = np.array([[float(t.fx), float(t.fy)]])
    if tip == "pinned":
        G, degenerate, lateral = _pinned_G(theta)
        G = lateral if degenerate[0] else G
    elif tip == "slider":
        if slider_angle is None:
            raise ValueError("tip='slider' needs slider_angle (rad)")
        a = float(slider_angle) - rod.clamp_angle  # local frame
        G = np.array([[[-np.sin(a)], [np.cos(a)]]])
    else:
        G = np.zeros((1, 2, 0))
    cnt, first = jacobi_conjugate_points(theta, f, G)
    return RodStability(bool(cnt[0] == 0), int(cnt[0]), float(first[0] * rod.length), tip)
