"""The mechanism equations in the Cosserat model, batched: residual and analytic Jacobians.

Unknowns of one candidate (scaled, see below):

* ``z[0:9]`` per rod the shooting unknowns ``(n_x(0), n_y(0), m(0))``;
* ``z[9:12]`` = ``w``: the pose ``(x, y, theta)`` (FK: inputs fixed) or the inputs
  ``(u1, u2, u3)`` (IK: pose fixed);
* then, for rods cut into ``K_i > 1`` segments (multiple shooting), the states
  ``(x, y, th, n_x, n_y, m)`` at the start of segments ``1..K_i-1``, rod after rod.

Equations: per rod the tip position ``p_i(L) - B_i`` (2) and the tip condition (pinned
``m_i(L) = 0``; clamped ``th_i(L) - theta - beta_i = 0``), the platform equilibrium
``sum n_i(L) - F = 0`` (2) and ``sum (B_i - P) x n_i(L) + sum m_i(L) - M_z = 0`` (1), then the
continuity of the state at every segment junction (6 each).

Multiple shooting keeps the Newton corrector well conditioned for rods under large forces,
whose single-shot map grows like ``exp(L sqrt(R/EI))``: a rod is cut so that every segment has
``L_k sqrt(R_max/EI) <= SEGMENT_GROWTH``.

Scaling: lengths by the mean rod length ``Lref``, forces by ``EIref/Lref^2``, moments by
``EIref/Lref`` (``EIref`` the mean bending stiffness); ``tau`` is the homotopy parameter of
:mod:`flexkin.cosserat.rod`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from ..core.geometry2d import rotate
from ..core.jit import njit
from numpy.typing import NDArray

from .rod import MIN_STEPS, auto_steps, shoot

__all__ = ["MechData", "Evaluation", "Layout", "evaluate", "TWO_PI", "SEGMENT_GROWTH"]

TWO_PI = 2.0 * math.pi
#: largest ``L_k sqrt(R_max / EI)`` of one shooting segment (growth of the map ~ e^SEGMENT_GROWTH)
SEGMENT_GROWTH = 2.5
_MAX_SEGMENTS = 64


@dataclass(frozen=True)
class MechData:
    """What the equations need from a mechanism, validated once."""

    problem: str                      # "ik" or "fk"
    legs: tuple[Any, Any, Any]
    kinds: tuple[str, str, str]
    b: NDArray[np.float64]            # (3, 2) attach points, platform frame
    load: NDArray[np.float64]         # (3,)
    EI: NDArray[np.float64]           # (3,)
    clamped: NDArray[np.bool_]        # (3,) tip joint clamped?
    beta: NDArray[np.float64]         # (3,) tip angle in the platform frame (clamped joints)
    ce: NDArray[np.float64]           # (3,) 1/EA
    cs: NDArray[np.float64]           # (3,) 1/(kappa G A)
    f: NDArray[np.float64]            # (3, 2) distributed load at tau = 1 (N/m)
    Lref: float
    EIref: float

    @property
    def Fs(self) -> float:
        return self.EIref / self.Lref ** 2

    @property
    def Ms(self) -> float:
        return self.EIref / self.Lref

    @property
    def sz(self) -> NDArray[np.float64]:
        """Scale of the first 12 unknowns."""
        Fs, Ms = self.Fs, self.Ms
        if self.problem == "fk":
            w = [self.Lref, self.Lref, 1.0]
        else:
            w = list(self.input_scales())
        return np.array([Fs, Fs, Ms] * 3 + w)

    def input_scales(self) -> NDArray[np.float64]:
        """Scale of each leg's input (``Lref``, or 1 for an angle: the actuators' ``input_scale``)."""
        return np.array([leg.actuator.input_scale(self.Lref) for leg in self.legs])

    @property
    def sr(self) -> NDArray[np.float64]:
        """Scale of the first 12 equations."""
        r = []
        for c in self.clamped:
            r += [self.Lref, self.Lref, 1.0 if c else self.Ms]
        return np.array(r + [self.Fs, self.Fs, self.Ms])

    @property
    def s_state(self) -> NDArray[np.float64]:
        """Scale of a rod state (x, y, th, n_x, n_y, m)."""
        return np.array([self.Lref, self.Lref, 1.0, self.Fs, self.Fs, self.Ms])

    def clamps(self, u: NDArray[np.float64], deriv: bool = False):
        """Clamp point, angle and length of the three legs for inputs ``u`` (B, 3).

        Returns ``A (B,3,2), alpha (B,3), L (B,3)`` and their derivatives w.r.t. each leg's own
        input: the clamp map is affine, ``(A, alpha, L) = c0 + c1 u`` (``leg.actuator.affine``),
        so the derivatives are ``c1`` exactly (zeros without ``deriv``).
        """
        B = u.shape[0]
        A = np.empty((B, 3, 2))
        al = np.empty((B, 3))
        L = np.empty((B, 3))
        dA = np.zeros((B, 3, 2))
        dal = np.zeros((B, 3))
        dL = np.zeros((B, 3))
        for i, leg in enumerate(self.legs):
            a, t, l = leg.clamp(u[:, i])
            A[:, i], al[:, i], L[:, i] = a, t, l
            if deriv:
                c1 = leg.actuator.affine()[1]
                dA[:, i], dal[:, i], dL[:, i] = c1[:2], c1[2], c1[3]
        return A, al, L, dA, dal, dL

    def attach(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """``B_i - P`` in the world frame, (B, 3, 2)."""
        return rotate(self.b[None], pose[:, 2:3])


@dataclass(frozen=True)
class Layout:
    """Discretisation of one candidate: RK steps and shooting segments per rod (fixed on a branch)."""

    steps: tuple[int, int, int]
    segments: tuple[int, int, int]
    force_scale: float = 1.0          # forces scaled by Fs * force_scale, moments by Ms * sqrt(force_scale)

    @property
    def size(self) -> int:
        return 12 + 6 * (sum(self.segments) - 3)

    def offset(self, i: int, k: int) -> int:
        """Index of the state block of segment ``k >= 1`` of rod ``i``."""
        return 12 + 6 * (sum(self.segments[:i]) - i + k - 1)

    def doubled(self) -> "Layout":
        return Layout(tuple(2 * s for s in self.steps), self.segments, self.force_scale)


def make_layout(md: MechData, Z: NDArray[np.float64], fixed: NDArray[np.float64], tol: float) -> Layout:
    """Steps and segments for a candidate with SI unknowns ``Z`` (first 12) at full load."""
    u = fixed if md.problem == "fk" else Z[9:12]
    _, _, L, *_ = md.clamps(u[None])
    L = L[0]
    n0 = Z[:9].reshape(3, 3)
    steps = auto_steps(L, md.EI, n0[:, :2], n0[:, 2], md.f, tol)
    R = np.hypot(n0[:, 0], n0[:, 1]) + np.hypot(md.f[:, 0], md.f[:, 1]) * L
    K = np.clip(np.ceil(L * np.sqrt(R / md.EI) / SEGMENT_GROWTH), 1, _MAX_SEGMENTS).astype(int)
    steps = np.maximum(np.ceil(steps / K) * K, K * MIN_STEPS).astype(int)
    phi = max(1.0, float(np.max(R)) / md.Fs)
    return Layout(tuple(int(s) for s in steps), tuple(int(k) for k in K), phi)


def initial_segments(md: MechData, Zs: list, fixed: NDArray[np.float64], layouts: list, tau: float = 0.0,
                     tips: NDArray[np.float64] | None = None) -> list:
    """Full SI unknown vectors: each ``Z`` (first 12) plus its segment states.

    The segment states of the first half of a rod are integrated forward from the clamp; with
    ``tips`` (B, 3, 6: the known tip states ``(x, y, th, n_x, n_y, m)`` at ``s = L``, e.g. of a
    Kirchhoff solution) those of the second half are integrated backward from the tip, so the
    error amplification of a rod under a large force stays ~ exp(L sqrt(R/EI) / 2) instead of
    its square.  Batched: one shooting call per segment index.
    """
    B = len(Zs)
    outs = []
    for b in range(B):
        o = np.zeros(layouts[b].size)
        o[:12] = Zs[b][:12]
        outs.append(o)
    head = np.array([z[:12] for z in Zs]).reshape(B, 12)
    u = fixed if md.problem == "fk" else head[:, 9:12]
    A, al, L, *_ = md.clamps(u)
    K = np.array([lay.segments for lay in layouts]).reshape(B, 3)
    steps = np.array([lay.steps for lay in layouts]).reshape(B, 3)
    cur = np.zeros((B, 3, 6))
    cur[..., 0:2] = A
    cur[..., 2] = al
    cur[..., 3:6] = head[:, :9].reshape(B, 3, 3)
    backward = np.zeros((B, 3), dtype=bool) if tips is None else np.ones((B, 3), dtype=bool)

    def put(bi, state, k):
        for j, (b, i) in enumerate(bi):
            o = layouts[b].offset(i, k)
            outs[b][o:o + 6] = state[j]

    for k in range(1, int(K.max())):
        bi = np.argwhere((K > k) & ~(backward & (2 * k > K)))     # forward: first half (all without tips)
        if bi.size:
            b_, i_ = bi[:, 0], bi[:, 1]
            y = cur[b_, i_]
            res = shoot(y[:, 0:2], y[:, 2], L[b_, i_] / K[b_, i_], md.EI[i_], y[:, 3:5], y[:, 5],
                        axial_compliance=md.ce[i_], shear_compliance=md.cs[i_], line_load=md.f[i_], tau=tau,
                        steps=steps[b_, i_] // K[b_, i_], jacobian=False)
            cur[b_, i_] = res.state
            put(bi, res.state, k)
    if tips is not None:
        for k in range(1, int(K.max())):
            bi = np.argwhere((K > k) & (2 * k > K))
            if bi.size == 0:
                continue
            b_, i_ = bi[:, 0], bi[:, 1]
            y = tips[b_, i_]
            frac = (K[b_, i_] - k) / K[b_, i_]                  # integrate from L back to s_k
            res = shoot(y[:, 0:2], y[:, 2], -L[b_, i_] * frac, md.EI[i_], y[:, 3:5], y[:, 5],
                        axial_compliance=md.ce[i_], shear_compliance=md.cs[i_], line_load=md.f[i_], tau=tau,
                        steps=np.maximum(1, (steps[b_, i_] * frac).astype(int)), jacobian=False,
                        _allow_negative_length=True)
            put(bi, res.state, k)
    return outs


def _scales(md: MechData, lay: Layout) -> tuple[float, float]:
    return md.Fs * lay.force_scale, md.Ms * math.sqrt(lay.force_scale)


def scale_vector(md: MechData, lay: Layout) -> NDArray[np.float64]:
    """Scale of every unknown of a candidate (forces by ``Fs * force_scale``, moments by
    ``Ms * sqrt(force_scale)``, so that a branch under large forces is measured relative to them)."""
    Fs, Ms = _scales(md, lay)
    head = md.sz.copy()
    head[:9] = [Fs, Fs, Ms] * 3
    state = np.array([md.Lref, md.Lref, 1.0, Fs, Fs, Ms])
    return np.concatenate([head, np.tile(state, sum(lay.segments) - 3)])


def residual_scale(md: MechData, lay: Layout) -> NDArray[np.float64]:
    """Scale of every equation of a candidate (see :func:`scale_vector`)."""
    Fs, Ms = _scales(md, lay)
    r = []
    for c in md.clamped:
        r += [md.Lref, md.Lref, 1.0 if c else Ms]
    state = np.array([md.Lref, md.Lref, 1.0, Fs, Fs, Ms])
    return np.concatenate([np.array(r + [Fs, Fs, Ms]), np.tile(state, sum(lay.segments) - 3)])


def canonical(md: MechData, lay: Layout, zhat: NDArray[np.float64]) -> NDArray[np.float64]:
    """The first 12 unknowns in the mechanism-wide scaling (for comparing branches)."""
    return (zhat[:12] * scale_vector(md, lay)[:12]) / md.sz


@njit(cache=True)
def _offset(K, i, k):
    tot = 0
    for a in range(i):
        tot += K[a]
    return 12 + 6 * (tot - i + k - 1)


@njit(cache=True)
def _put_tip(J, rows_i, sel, rx, ry, g, col):
    """Add d(tip state of rod i)/d(unknown ``col``) = ``g`` (6,) to the tip and platform rows."""
    J[3 * rows_i, col] += g[0]
    J[3 * rows_i + 1, col] += g[1]
    J[3 * rows_i + 2, col] += g[sel]
    J[9, col] += g[3]
    J[10, col] += g[4]
    J[11, col] += rx * g[4] - ry * g[3] + g[5]


@njit(cache=True)
def _assemble_one(n, ik, K, j0, seg_end, Phi, dlen, dtau, Zc, r, Bp, pose, clamped, beta, wrap, load,
                  dA, dal, dL, sc, rs, jac):
    """Scaled residual, Jacobian and tau-derivative of one candidate (see module doc for the layout)."""
    R = np.zeros(n)
    J = np.zeros((n, n))
    Jt = np.zeros(n)
    Mtot = 0.0
    for i in range(3):
        last = j0[i] + K[i] - 1
        st = seg_end[last]
        R[3 * i] = st[0] - Bp[i, 0]
        R[3 * i + 1] = st[1] - Bp[i, 1]
        if clamped[i]:
            R[3 * i + 2] = st[2] - pose[2] - beta[i] - wrap[i]
        else:
            R[3 * i + 2] = st[5]
        R[9] += st[3]
        R[10] += st[4]
        Mtot += r[i, 0] * st[4] - r[i, 1] * st[3] + st[5]
        for k in range(1, K[i]):
            o = _offset(K, i, k)
            for a in range(6):
                R[o + a] = seg_end[j0[i] + k - 1, a] - Zc[o + a]
    R[9] -= load[0]
    R[10] -= load[1]
    R[11] = Mtot - load[2]
    if jac:
        g = np.empty(6)
        for i in range(3):
            rx = r[i, 0]
            ry = r[i, 1]
            sel = 2 if clamped[i] else 5
            for k in range(K[i]):
                j = j0[i] + k
                tip = k == K[i] - 1
                o_next = 0 if tip else _offset(K, i, k + 1)
                # columns of this segment's start and their derivative vectors
                if k == 0:
                    ncol = 3
                else:
                    ncol = 6
                for c in range(ncol + 2):
                    if c < ncol:
                        if k == 0:
                            col = 3 * i + c
                            for a in range(6):
                                g[a] = Phi[j, a, 3 + c]
                        else:
                            col = _offset(K, i, k) + c
                            for a in range(6):
                                g[a] = Phi[j, a, c]
                    elif c == ncol:      # the leg's input (IK)
                        if not ik:
                            continue
                        col = 9 + i
                        for a in range(6):
                            g[a] = dlen[j, a] * dL[i] / K[i]
                            if k == 0:
                                g[a] += Phi[j, a, 0] * dA[i, 0] + Phi[j, a, 1] * dA[i, 1] + Phi[j, a, 2] * dal[i]
                    else:                # tau
                        col = -1
                        for a in range(6):
                            g[a] = dtau[j, a]
                    if tip:
                        if col >= 0:
                            _put_tip(J, i, sel, rx, ry, g, col)
                        else:
                            Jt[3 * i] += g[0]
                            Jt[3 * i + 1] += g[1]
                            Jt[3 * i + 2] += g[sel]
                            Jt[9] += g[3]
                            Jt[10] += g[4]
                            Jt[11] += rx * g[4] - ry * g[3] + g[5]
                    else:
                        for a in range(6):
                            if col >= 0:
                                J[o_next + a, col] += g[a]
                            else:
                                Jt[o_next + a] += g[a]
                if not tip:
                    for a in range(6):
                        J[o_next + a, o_next + a] -= 1.0
        if not ik:
            sn = 0.0
            for i in range(3):
                J[3 * i, 9] -= 1.0
                J[3 * i + 1, 10] -= 1.0
                J[3 * i, 11] += r[i, 1]
                J[3 * i + 1, 11] -= r[i, 0]
                if clamped[i]:
                    J[3 * i + 2, 11] -= 1.0
                st = seg_end[j0[i] + K[i] - 1]
                sn += r[i, 0] * st[3] + r[i, 1] * st[4]
            J[11, 11] -= sn
        for a in range(n):
            Jt[a] /= rs[a]
            for c in range(n):
                J[a, c] *= sc[c] / rs[a]
    for a in range(n):
        R[a] /= rs[a]
    return R, J, Jt


@dataclass(frozen=True)
class Evaluation:
    """Scaled residuals and Jacobians of a batch of candidates, plus the rods' tip data (SI)."""

    R: list                           # per candidate (n,)
    Jz: list | None                   # per candidate (n, n)
    Jt: list | None                   # per candidate (n,)
    state: NDArray[np.float64]        # (B, 3, 6) tip states
    quad: NDArray[np.float64]         # (B, 3, 3) energy, load potential, elongation (summed)
    clamp: NDArray[np.float64]        # (B, 3, 2)
    clamp_angle: NDArray[np.float64]  # (B, 3)
    length: NDArray[np.float64]       # (B, 3)
    pose: NDArray[np.float64]         # (B, 3)
    inputs: NDArray[np.float64]       # (B, 3)
    strain_bound: NDArray[np.float64]  # (B,) upper bound of |v - e1| over all rods


def evaluate(md: MechData, Zhat: list, tau: NDArray[np.float64], fixed: NDArray[np.float64],
             wrap: NDArray[np.float64], layouts: list, jac: bool = True) -> Evaluation:
    """Residual (and Jacobians) at scaled unknowns ``Zhat`` (list of vectors, one per candidate).

    ``fixed`` (B, 3) is the pose (IK) or the inputs (FK) held fixed; ``wrap`` (B, 3) the multiple
    of 2 pi added to the clamped tip condition; ``layouts`` the :class:`Layout` of each candidate.
    """
    B = len(Zhat)
    scales = [scale_vector(md, lay) for lay in layouts]
    Z = [zh * sc for zh, sc in zip(Zhat, scales)]
    head = np.array([z[:12] for z in Z])
    n0 = head[:, :9].reshape(B, 3, 3)
    if md.problem == "fk":
        pose, u = head[:, 9:], fixed
        A, al, L, dA, dal, dL = md.clamps(u, deriv=False)
    else:
        pose, u = fixed, head[:, 9:]
        A, al, L, dA, dal, dL = md.clamps(u, deriv=jac)
    r = md.attach(pose)                                      # (B, 3, 2) = B_i - P
    Bp = pose[:, None, :2] + r

    # ---- one flat batch of segments ------------------------------------------------------
    y0, Lseg, EIs, ces, css, fs, taus, ns, owner = [], [], [], [], [], [], [], [], []
    for b in range(B):
        lay = layouts[b]
        for i in range(3):
            K = lay.segments[i]
            for k in range(K):
                if k == 0:
                    y0.append(np.r_[A[b, i], al[b, i], n0[b, i]])
                else:
                    o = lay.offset(i, k)
                    y0.append(Z[b][o:o + 6])
                Lseg.append(L[b, i] / K)
                EIs.append(md.EI[i])
                ces.append(md.ce[i])
                css.append(md.cs[i])
                fs.append(md.f[i])
                taus.append(tau[b])
                ns.append(lay.steps[i] // K)
                owner.append((b, i, k))
    y0 = np.array(y0)
    res = shoot(y0[:, 0:2], y0[:, 2], np.array(Lseg), np.array(EIs), y0[:, 3:5], y0[:, 5],
                axial_compliance=np.array(ces), shear_compliance=np.array(css), line_load=np.array(fs),
                tau=np.array(taus), steps=np.array(ns), jacobian=jac)
    state = np.zeros((B, 3, 6))
    quad = np.zeros((B, 3, 3))
    Q = np.stack([res.energy, res.load_potential, res.elongation], -1)
    first = {}
    for j, (b, i, k) in enumerate(owner):
        quad[b, i] += Q[j]
        if k == 0:
            first[(b, i)] = j
        if k == layouts[b].segments[i] - 1:
            state[b, i] = res.state[j]

    # ---- residuals and Jacobians (compiled, per candidate) -------------------------------
    Rs, Jzs, Jts = [], [], []
    Phi = res.d_start if jac else np.zeros((1, 6, 6))
    dlen = res.d_length if jac else np.zeros((1, 6))
    dtau = res.d_tau if jac else np.zeros((1, 6))
    seg_end = np.ascontiguousarray(res.state)
    ik = md.problem == "ik"
    for b in range(B):
        lay = layouts[b]
        K = np.array(lay.segments, dtype=np.int64)
        j0 = np.array([first[(b, i)] for i in range(3)], dtype=np.int64)
        R, J, Jt = _assemble_one(lay.size, ik, K, j0, seg_end, Phi, dlen, dtau, Z[b], r[b], Bp[b], pose[b],
                                 md.clamped, md.beta, wrap[b], md.load, dA[b], dal[b], dL[b], scales[b],
                                 residual_scale(md, lay), jac)
        Rs.append(R)
        Jzs.append(J)
        Jts.append(Jt)
    # |n(s)| <= |n(0)| + tau |f| L (n' = -tau f), so the strains are bounded by c |n|max
    nmax = np.hypot(n0[..., 0], n0[..., 1]) + tau[:, None] * np.hypot(md.f[:, 0], md.f[:, 1])[None] * L
    strain = tau * np.max(np.maximum(md.ce, md.cs)[None] * nmax, axis=1)
    return Evaluation(R=Rs, Jz=Jzs if jac else None, Jt=Jts if jac else None, state=state, quad=quad,
                      clamp=A, clamp_angle=al, length=L, pose=pose, inputs=u, strain_bound=strain)
