"""Compiled kernels: the planar Cosserat rod ODE with its variational equations.

State along the rod, in the reduced arc length ``sigma = s / L`` in [0, 1]::

    y = (x, y, th, nx, ny, m)

    c, s = cos th, sin th
    nt = nx c + ny s            (force along the material axis d1)
    nn = -nx s + ny c           (force along d2)
    vx = 1 + tau ce nt          (ce = 1/EA)
    vy = tau cs nn              (cs = 1/(kappa G A))
    x'  = L (vx c - vy s)
    y'  = L (vx s + vy c)
    th' = L m / EI
    n'  = -L tau f              (f: distributed force per unit length, world frame)
    m'  = -(x' ny - y' nx) = -L nn (1 + tau (ce - cs) nt)

Quadratures carried along (no derivatives): the elastic energy
``U = int m^2/(2 EI) + tau (ce nt^2 + cs nn^2)/2 ds`` (the complementary form, regular at
tau = 0; equal to ``(EA/2)(vx-1)^2 + (kappa G A/2) vy^2`` for tau = 1), the potential of the
distributed load ``-tau int f . p ds`` and the elongation ``int (vx - 1) ds``.

Variational equations: the six columns ``d y / d (th0, nx0, ny0, m0, L, tau)`` (the right-hand
side does not depend on x, y, so ``d y / d (x0, y0)`` is the identity on the position rows and
is not integrated).  They are integrated with the same Runge–Kutta scheme as the state, so they
are the exact derivatives of the discrete map (no finite differences).

Integrator: fixed-step Dormand–Prince 8th-order Runge–Kutta (12 stages, the propagating
scheme of DOP853: :mod:`flexkin.core.dop853`).  The global error of the tip state is O(h^8); the step count is chosen by
:func:`flexkin.cosserat.rod.auto_steps` from the rod's force and curvature scales.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from ..core.dop853 import STAGES as _NS, advance, stage_state
from ..core.jit import njit

__all__ = ["NPAR", "NQ", "shoot_batch", "shape_batch"]

#: parameters per rod: L, EI, ce, cs, fx, fy, tau
NPAR = 7
#: quadratures: energy, load potential, elongation
NQ = 3
_NV = 6                      # variational columns: th0, nx0, ny0, m0, L, tau
_NY = 6 + 6 * _NV + NQ      # full integrated vector length


@njit(cache=True, inline="always")
def _rhs(Y, out, L, EI, ce, cs, fx, fy, tau, nvar):
    th = Y[2]
    nx = Y[3]
    ny = Y[4]
    m = Y[5]
    c = np.cos(th)
    s = np.sin(th)
    nt = nx * c + ny * s
    nn = -nx * s + ny * c
    d = ce - cs
    vx = 1.0 + tau * ce * nt
    vy = tau * cs * nn
    xp = L * (vx * c - vy * s)
    yp = L * (vx * s + vy * c)
    g = 1.0 + tau * d * nt
    out[0] = xp
    out[1] = yp
    out[2] = L * m / EI
    out[3] = -L * tau * fx
    out[4] = -L * tau * fy
    out[5] = -L * nn * g
    x = Y[0]
    y = Y[1]
    q0 = 6 + 6 * nvar
    out[q0] = L * (0.5 * m * m / EI + 0.5 * tau * (ce * nt * nt + cs * nn * nn))
    out[q0 + 1] = -L * tau * (fx * x + fy * y)
    out[q0 + 2] = L * tau * ce * nt
    if nvar == 0:
        return
    # Jacobian of the right-hand side w.r.t. (th, nx, ny, m)
    cc = c * c
    ss = s * s
    sc = s * c
    a_x_th = L * (-s + tau * d * (nn * c - nt * s))
    a_x_nx = L * tau * (ce * cc + cs * ss)
    a_x_ny = L * tau * d * sc
    a_y_th = L * (c + tau * d * (nn * s + nt * c))
    a_y_nx = a_x_ny
    a_y_ny = L * tau * (ce * ss + cs * cc)
    a_t_m = L / EI
    a_m_th = L * (nt * g - tau * d * nn * nn)
    a_m_nx = -L * (-s * g + nn * tau * d * c)
    a_m_ny = -L * (c * g + nn * tau * d * s)
    for k in range(_NV):
        b = 6 + 6 * k
        wth = Y[b + 2]
        wnx = Y[b + 3]
        wny = Y[b + 4]
        wm = Y[b + 5]
        out[b] = a_x_th * wth + a_x_nx * wnx + a_x_ny * wny
        out[b + 1] = a_y_th * wth + a_y_nx * wnx + a_y_ny * wny
        out[b + 2] = a_t_m * wm
        out[b + 3] = 0.0
        out[b + 4] = 0.0
        out[b + 5] = a_m_th * wth + a_m_nx * wnx + a_m_ny * wny
    # parameter columns: d/dL (the right-hand side is proportional to L) and d/dtau
    b = 6 + 6 * 4
    out[b] += xp / L
    out[b + 1] += yp / L
    out[b + 2] += m / EI
    out[b + 3] += -tau * fx
    out[b + 4] += -tau * fy
    out[b + 5] += -nn * g
    b = 6 + 6 * 5
    out[b] += L * (ce * nt * c - cs * nn * s)
    out[b + 1] += L * (ce * nt * s + cs * nn * c)
    out[b + 3] += -L * fx
    out[b + 4] += -L * fy
    out[b + 5] += -L * nn * d * nt


@njit(cache=True)
def _integrate(Y, n, L, EI, ce, cs, fx, fy, tau, nvar, nsteps, K, Yt, store, stride):
    """Advance Y (length n) over sigma in [0, 1] in ``nsteps`` steps; optionally store states."""
    h = 1.0 / nsteps
    row = 0
    if stride > 0:
        for j in range(store.shape[1]):
            store[0, j] = Y[j]
        row = 1
    for step in range(nsteps):
        _rhs(Y, K[0], L, EI, ce, cs, fx, fy, tau, nvar)
        for i in range(1, _NS):
            stage_state(i, Y, h, K, Yt, n)
            _rhs(Yt, K[i], L, EI, ce, cs, fx, fy, tau, nvar)
        advance(Y, h, K, Y, n)
        if stride > 0 and (step + 1) % stride == 0:
            for j in range(store.shape[1]):
                store[row, j] = Y[j]
            row += 1


@njit(cache=True)
def _shoot_one(b, y0, par, nsteps, nvar, yL, W, Q):
    Y = np.zeros(_NY)
    K = np.empty((_NS, _NY))
    Yt = np.zeros(_NY)
    dummy = np.empty((1, 1))
    n = 6 + 6 * nvar + NQ
    for j in range(6):
        Y[j] = y0[b, j]
    if nvar:
        # identity columns for th0, nx0, ny0, m0 (state indices 2..5); L, tau start at 0
        for k in range(4):
            Y[6 + 6 * k + 2 + k] = 1.0
    _integrate(Y, n, par[b, 0], par[b, 1], par[b, 2], par[b, 3], par[b, 4], par[b, 5], par[b, 6],
               nvar, nsteps[b], K, Yt, dummy, 0)
    for j in range(6):
        yL[b, j] = Y[j]
    if nvar:
        for k in range(_NV):
            for j in range(6):
                W[b, j, k] = Y[6 + 6 * k + j]
    for j in range(NQ):
        Q[b, j] = Y[6 + 6 * nvar + j]


@njit(cache=True, parallel=True)
def _shoot_parallel(y0, par, nsteps, nvar, yL, W, Q):
    for b in prange(y0.shape[0]):
        _shoot_one(b, y0, par, nsteps, nvar, yL, W, Q)


@njit(cache=True)
def _shoot_serial(y0, par, nsteps, nvar, yL, W, Q):
    for b in range(y0.shape[0]):
        _shoot_one(b, y0, par, nsteps, nvar, yL, W, Q)


#: total Runge-Kutta steps of a batch above which the threaded kernel is used
PARALLEL_WORK = 4000


def shoot_batch(y0, par, nsteps, with_var):
    """Shoot ``B`` rods.

    Parameters
    ----------
    y0 : (B, 6) initial states (x, y, th, nx, ny, m) at the clamp.
    par : (B, 7) rows (L, EI, ce, cs, fx, fy, tau).
    nsteps : (B,) int64 step counts.
    with_var : integrate the variational equations.

    Returns
    -------
    yL : (B, 6) tip states; W : (B, 6, 6) ``d yL / d (th0, nx0, ny0, m0, L, tau)`` (columns;
    zeros without ``with_var``); Q : (B, 3) energy, load potential, elongation.
    """
    nb = y0.shape[0]
    yL = np.empty((nb, 6))
    W = np.zeros((nb, 6, _NV))
    Q = np.empty((nb, NQ))
    nvar = _NV if with_var else 0
    work = int(np.sum(nsteps)) * (7 if with_var else 1)
    if work >= PARALLEL_WORK and nb > 1:
        _shoot_parallel(y0, par, nsteps, nvar, yL, W, Q)
    else:
        _shoot_serial(y0, par, nsteps, nvar, yL, W, Q)
    return yL, W, Q


@njit(cache=True)
def _shape_one(b, y0, par, nsteps, stride, out):
    Y = np.zeros(6 + NQ)
    K = np.empty((_NS, 6 + NQ))
    Yt = np.zeros(6 + NQ)
    for j in range(6):
        Y[j] = y0[b, j]
    _integrate(Y, 6 + NQ, par[b, 0], par[b, 1], par[b, 2], par[b, 3], par[b, 4], par[b, 5], par[b, 6],
               0, nsteps[b], K, Yt, out[b], stride)


@njit(cache=True, parallel=True)
def _shape_parallel(y0, par, nsteps, stride, out):
    for b in prange(y0.shape[0]):
        _shape_one(b, y0, par, nsteps, stride, out)


@njit(cache=True)
def _shape_serial(y0, par, nsteps, stride, out):
    for b in range(y0.shape[0]):
        _shape_one(b, y0, par, nsteps, stride, out)


def shape_batch(y0, par, nsteps, stride):
    """States (x, y, th, nx, ny, m, U, W, elong) at every ``stride``-th step: (B, nsteps/stride + 1, 9).

    All rods of the batch must have the same step count.
    """
    nb = y0.shape[0]
    nout = int(nsteps[0]) // stride + 1
    out = np.empty((nb, nout, 6 + NQ))
    if int(np.sum(nsteps)) >= PARALLEL_WORK and nb > 1:
        _shape_parallel(y0, par, nsteps, stride, out)
    else:
        _shape_serial(y0, par, nsteps, stride, out)
    return out
