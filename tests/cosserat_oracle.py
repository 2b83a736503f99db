"""Independent oracle for the Cosserat refinement: a discrete planar beam minimising its potential energy.

Written from scratch for the tests; it imports nothing from flexkin.

Discretisation (staggered, second order): each rod of reference length L is cut into N
elements of length h = L/N.  Unknowns are the node positions p_0..p_N and one material angle
phi_e per element (at the element midpoint).  The energy of a rod is

    sum_e h [ EA/2 (v_x - 1)^2 + kGA/2 v_y^2 ],   v = R(phi_e)^T (p_e - p_{e-1}) / h     (stretch, shear)
  + sum_{j=1}^{N-1} EI/(2h) (phi_{j+1} - phi_j)^2                                      (bending at nodes)
  + EI/h (phi_1 - alpha)^2  [+ EI/h (theta_P + beta - phi_N)^2 for a clamped tip]         (half cells)
  - sum_j w_j h f . p_j   (trapezoidal weights w_0 = w_N = 1/2)                            (dead load)

with p_0 = A (clamp) and p_N = B_i(q) = P + R(theta_P) b_i (tip tied to the platform).  The
platform adds ``-F . P - M theta_P``.  Equilibrium: Newton on the exact gradient/Hessian
(written out by hand below) in the reduced unknowns (interior nodes, all element angles,
platform pose), inputs fixed (actuators locked).  Stability: the smallest eigenvalue of the
reduced Hessian relative to a lumped metric (``h/L`` per node or element and coordinate,
positions in units of L; weight 1 per platform coordinate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg


@dataclass(frozen=True)
class OracleRod:
    clamp: tuple[float, float]
    clamp_angle: float
    length: float
    EI: float
    EA: float
    kGA: float
    load: tuple[float, float] = (0.0, 0.0)      # distributed force per length (N/m)
    clamped_tip: bool = False
    tip_angle: float = 0.0                      # beta (platform frame), clamped tips only


@dataclass
class OracleResult:
    converged: bool
    iterations: int
    pose: np.ndarray
    nodes: list            # per rod (N+1, 2)
    angles: list           # per rod (N,)
    energy: float
    gradient_norm: float
    min_eigenvalue: float
    index: int


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


class _Layout:
    """Index bookkeeping of the reduced unknown vector."""

    def __init__(self, N: int):
        self.N = N
        self.per_rod = 2 * (N - 1) + N           # interior nodes + element angles
        self.n = 3 * self.per_rod + 3

    def node(self, r, j):  # j = 1..N-1
        return r * self.per_rod + 2 * (j - 1)

    def angle(self, r, e):  # e = 1..N
        return r * self.per_rod + 2 * (self.N - 1) + (e - 1)

    @property
    def q(self):
        return 3 * self.per_rod


def _rod_terms(rod: OracleRod, N: int, X: np.ndarray, phi: np.ndarray, thP: float):
    """Energy, gradient and Hessian of one rod in its *extended* variables.

    Extended layout: node positions p_0..p_N (2(N+1)), angles phi_1..phi_N (N), theta_P (1).
    """
    h = rod.length / N
    nE = 2 * (N + 1) + N + 1
    g = np.zeros(nE)
    H = np.zeros((nE, nE))
    ia = 2 * (N + 1)                 # first angle index
    it = nE - 1                      # theta_P
    d = X[1:] - X[:-1]               # (N, 2)
    c, s = np.cos(phi), np.sin(phi)
    vx = (c * d[:, 0] + s * d[:, 1]) / h
    vy = (-s * d[:, 0] + c * d[:, 1]) / h
    EA, G = rod.EA, rod.kGA
    Nf, Q = EA * (vx - 1.0), G * vy
    E = float(np.sum(h * (0.5 * EA * (vx - 1.0) ** 2 + 0.5 * G * vy ** 2)))
    dvx = np.stack([c, s], -1) / h          # d vx / d d
    dvy = np.stack([-s, c], -1) / h
    gd = h * (Nf[:, None] * dvx + Q[:, None] * dvy)             # (N, 2)
    gphi = h * (Nf * vy - Q * vx)
    Hdd = h * (EA * dvx[:, :, None] * dvx[:, None, :] + G * dvy[:, :, None] * dvy[:, None, :])
    d2x = np.stack([-s, c], -1) / h
    d2y = np.stack([-c, -s], -1) / h
    Hdp = h * (EA * dvx * vy[:, None] - G * dvy * vx[:, None] + Nf[:, None] * d2x + Q[:, None] * d2y)
    Hpp = h * (EA * vy ** 2 + G * vx ** 2 - Nf * vx - Q * vy)
    # element e joins nodes e, e+1 and has angle index ia + e: scatter with np.add.at
    e = np.arange(N)
    ia_, ib_, ik_ = 2 * e, 2 * (e + 1), ia + e
    for c in range(2):
        np.add.at(g, ia_ + c, -gd[:, c])
        np.add.at(g, ib_ + c, gd[:, c])
    np.add.at(g, ik_, gphi)
    for c in range(2):
        for d_ in range(2):
            np.add.at(H, (ia_ + c, ia_ + d_), Hdd[:, c, d_])
            np.add.at(H, (ib_ + c, ib_ + d_), Hdd[:, c, d_])
            np.add.at(H, (ia_ + c, ib_ + d_), -Hdd[:, c, d_])
            np.add.at(H, (ib_ + c, ia_ + d_), -Hdd[:, c, d_])
        np.add.at(H, (ia_ + c, ik_), -Hdp[:, c])
        np.add.at(H, (ik_, ia_ + c), -Hdp[:, c])
        np.add.at(H, (ib_ + c, ik_), Hdp[:, c])
        np.add.at(H, (ik_, ib_ + c), Hdp[:, c])
    np.add.at(H, (ik_, ik_), Hpp)
    # bending
    kb = rod.EI / h
    dphi = phi[1:] - phi[:-1]
    E += float(0.5 * kb * np.sum(dphi ** 2))
    j = np.arange(N - 1)
    i0, i1 = ia + j, ia + j + 1
    np.add.at(g, i0, -kb * dphi)
    np.add.at(g, i1, kb * dphi)
    np.add.at(H, (i0, i0), kb)
    np.add.at(H, (i1, i1), kb)
    np.add.at(H, (i0, i1), -kb)
    np.add.at(H, (i1, i0), -kb)
    d0 = phi[0] - rod.clamp_angle
    E += kb * d0 ** 2
    g[ia] += 2 * kb * d0
    H[ia, ia] += 2 * kb
    if rod.clamped_tip:
        dN = thP + rod.tip_angle - phi[-1]
        E += kb * dN ** 2
        iN = ia + N - 1
        g[it] += 2 * kb * dN
        g[iN] -= 2 * kb * dN
        H[it, it] += 2 * kb
        H[iN, iN] += 2 * kb
        H[it, iN] -= 2 * kb
        H[iN, it] -= 2 * kb
    # dead load (linear)
    f = np.asarray(rod.load, float)
    w = np.full(N + 1, h)
    w[0] = w[-1] = 0.5 * h
    E -= float(np.sum(w[:, None] * X * f[None]))
    g[:2 * (N + 1)] -= (w[:, None] * f[None]).reshape(-1)
    return E, g, H


def _assemble(rods, b, load, N, z, lay: _Layout, clamp_pts):
    """Total energy, reduced gradient and Hessian at reduced unknowns z."""
    q = z[lay.q:lay.q + 3]
    P, thP = q[:2], q[2]
    Rq = _rot(thP)
    E = -float(load[0] * P[0] + load[1] * P[1] + load[2] * thP)
    G = np.zeros(lay.n)
    H = np.zeros((lay.n, lay.n))
    G[lay.q:lay.q + 3] -= np.asarray(load, float)
    for r, rod in enumerate(rods):
        Bi = P + Rq @ b[r]
        rB = Rq @ b[r]                                   # B - P
        X = np.empty((N + 1, 2))
        X[0] = clamp_pts[r]
        for j in range(1, N):
            X[j] = z[lay.node(r, j):lay.node(r, j) + 2]
        X[N] = Bi
        phi = np.array([z[lay.angle(r, e)] for e in range(1, N + 1)])
        Er, gr, Hr = _rod_terms(rod, N, X, phi, thP)
        E += Er
        # map extended -> reduced: index list (or -1 for fixed), and the slaved tip
        nE = gr.size
        idx = -np.ones(nE, dtype=int)
        for j in range(1, N):
            idx[2 * j] = lay.node(r, j)
            idx[2 * j + 1] = lay.node(r, j) + 1
        for e in range(1, N + 1):
            idx[2 * (N + 1) + e - 1] = lay.angle(r, e)
        idx[nE - 1] = lay.q + 2
        # tip: p_N = P + R(thP) b ->  d p_N / d q = [[1,0,-rB_y],[0,1,rB_x]]
        T = np.array([[1.0, 0.0, -rB[1]], [0.0, 1.0, rB[0]]])
        qi = np.arange(lay.q, lay.q + 3)
        tip = [2 * N, 2 * N + 1]
        free = np.nonzero(idx >= 0)[0]
        G[idx[free]] += gr[free]
        G[qi] += T.T @ gr[tip]
        H[np.ix_(idx[free], idx[free])] += Hr[np.ix_(free, free)]
        Hft = Hr[np.ix_(free, tip)] @ T                  # (nfree, 3)
        H[np.ix_(idx[free], qi)] += Hft
        H[np.ix_(qi, idx[free])] += Hft.T
        H[np.ix_(qi, qi)] += T.T @ Hr[np.ix_(tip, tip)] @ T
        # curvature of the constraint: d2 p_N / d thP^2 = -(B - P)
        H[lay.q + 2, lay.q + 2] += -float(gr[tip] @ rB)
    return E, G, H


def _metric(rods, N, lay: _Layout, Lref: float) -> np.ndarray:
    m = np.ones(lay.n)
    for r, rod in enumerate(rods):
        h = rod.length / N
        for j in range(1, N):
            m[lay.node(r, j):lay.node(r, j) + 2] = h / Lref / Lref ** 2
        for e in range(1, N + 1):
            m[lay.angle(r, e)] = h / Lref
    m[lay.q:lay.q + 2] = 1.0 / Lref ** 2
    m[lay.q + 2] = 1.0
    return m


def solve_mechanism(rods, attach, load, pose0, shapes0, N: int = 32, tol: float = 1e-10,
                    max_iter: int = 50, eigen: bool = True) -> OracleResult:
    """Equilibrium of the discrete mechanism (actuators locked) by Newton from a nearby guess.

    Parameters
    ----------
    rods : three :class:`OracleRod` (clamps already placed for the inputs).
    attach : (3, 2) attach points b_i in the platform frame.
    load : (Fx, Fy, Mz) at P.
    pose0 : initial pose (x, y, theta).
    shapes0 : per rod a callable ``sigma -> (x, y, theta)`` (sigma in [0, 1], arrays) giving the
        initial centre line and material angle.
    eigen : compute the smallest eigenvalue and the index (dense; ``nan``/-1 otherwise).
    """
    b = np.asarray(attach, float)
    lay = _Layout(N)
    z = np.zeros(lay.n)
    sig_nodes = np.arange(N + 1) / N
    sig_mid = (np.arange(N) + 0.5) / N
    for r in range(3):
        x, y, _ = shapes0[r](sig_nodes)
        _, _, th = shapes0[r](sig_mid)
        for j in range(1, N):
            z[lay.node(r, j)] = x[j]
            z[lay.node(r, j) + 1] = y[j]
        for e in range(1, N + 1):
            z[lay.angle(r, e)] = th[e - 1]
    z[lay.q:lay.q + 3] = pose0
    clamp_pts = [np.asarray(rod.clamp, float) for rod in rods]
    Lref = float(np.mean([rod.length for rod in rods]))
    EIref = float(np.mean([rod.EI for rod in rods]))
    gscale = EIref / Lref ** 2
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        E, G, H = _assemble(rods, b, load, N, z, lay, clamp_pts)
        try:
            dz = scipy.sparse.linalg.spsolve(scipy.sparse.csc_matrix(H), -G)
        except (RuntimeError, ValueError):
            break
        if not np.all(np.isfinite(dz)):
            break
        step = np.max(np.abs(dz))
        if step > 0.05 * Lref:                 # plain Newton with a step limit (no line search:
            dz *= 0.05 * Lref / step           # saddles must be reachable too)
        z = z + dz
        if step < tol * Lref:
            converged = True
            break
    E, G, H = _assemble(rods, b, load, N, z, lay, clamp_pts)
    if eigen:
        m = _metric(rods, N, lay, Lref)
        Ms = np.sqrt(m)
        Hs = H / Ms[:, None] / Ms[None, :] * (Lref / EIref)
        ev = scipy.linalg.eigvalsh(Hs)
    else:
        ev = np.array([np.nan, np.nan])
    nodes, angles = [], []
    for r in range(3):
        X = np.empty((N + 1, 2))
        X[0] = clamp_pts[r]
        for j in range(1, N):
            X[j] = z[lay.node(r, j):lay.node(r, j) + 2]
        X[N] = z[lay.q:lay.q + 2] + _rot(z[lay.q + 2]) @ b[r]
        nodes.append(X)
        angles.append(np.array([z[lay.angle(r, e)] for e in range(1, N + 1)]))
    return OracleResult(converged=converged, iterations=it, pose=z[lay.q:lay.q + 3].copy(), nodes=nodes,
                        angles=angles, energy=E, gradient_norm=float(np.max(np.abs(G)) / gscale),
                        min_eigenvalue=float(ev[0]), index=int(np.sum(ev < 0)) if eigen else -1)


# ---- single heavy/loaded cantilever (free tip), for the classical checks ----------------------
def cantilever(L, EI, EA, kGA, q=(0.0, 0.0), tip_force=(0.0, 0.0), clamp_angle=0.0, N=64, tol=1e-12,
               max_iter=100, load_steps=10):
    """Clamped at the origin, free tip with a dead tip force; returns (tip position, tip angle).

    Load-stepped Newton (minimisation: the cantilever's equilibrium is a minimum).
    """
    OracleRod(clamp=(0.0, 0.0), clamp_angle=clamp_angle, length=L, EI=EI, EA=EA, kGA=kGA, load=q)  # validates the arguments
    h = L / N
    X = np.stack([np.arange(N + 1) * h * np.cos(clamp_angle), np.arange(N + 1) * h * np.sin(clamp_angle)], -1)
    phi = np.full(N, clamp_angle)
    nfree = 2 * N + N                            # nodes 1..N (tip free) + angles
    F = np.asarray(tip_force, float)
    q = np.asarray(q, float)
    for ls in range(1, load_steps + 1):
        lam = ls / load_steps
        r = OracleRod(clamp=(0.0, 0.0), clamp_angle=clamp_angle, length=L, EI=EI, EA=EA, kGA=kGA,
                      load=tuple(lam * q))
        for _ in range(max_iter):
            E, g, H = _rod_terms(r, N, X, phi, 0.0)
            ne = g.size
            keep = np.r_[np.arange(2, 2 * (N + 1)), np.arange(2 * (N + 1), ne - 1)]
            gg = g[keep].copy()
            gg[2 * N - 2:2 * N] -= lam * F       # tip node gets the dead tip force
            HH = H[np.ix_(keep, keep)]
            dz = np.linalg.solve(HH, -gg)
            X[1:] += dz[:2 * N].reshape(N, 2)
            phi += dz[2 * N:]
            if np.max(np.abs(dz)) < tol * L:
                break
    assert nfree == keep.size
    return X[-1].copy(), float(phi[-1])
