"""Derivatives of measured quantities with respect to the mechanism's parameters, by the
implicit-function theorem on the one equation system (as J_IK and J_FK, paper Eq. 16).

At an equilibrium ``G(z, x, u; p) = 0`` (:mod:`flexkin.system`; ``z`` the rods' chart
coordinates, ``x`` the pose, ``u`` the inputs, ``p`` the parameters).  A forward-kinematics
measurement holds the inputs, so along its branch

    [G_z  G_x] d(z, x) = -G_p dp,     dx/dp = -[A_FK^-1 G_p]_x,

and an inverse-kinematics measurement holds the pose: ``du/dp = -[A_IK^-1 G_p]_u``.

``G_p`` is analytic: the parameters enter the system only through the clamp maps
``(A, alpha, L) = c0 + c1 u`` of the legs, their ``EI`` and the attach points ``b_i``
(:func:`flexkin.calibration.params.array_derivatives` gives those derivatives exactly), and the
rods' unit quantities do not depend on them.  The scales ``L_ref``, ``F_ref`` of the equations
are held: they multiply ``G``, which vanishes at an equilibrium.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from ..rod.kernels import FX, FY, ML, X, Y
from ..system import System

__all__ = ["parameter_block", "prediction_derivative"]


def parameter_block(system: System, Xs: NDArray, charts: NDArray, dc0: NDArray, dc1: NDArray, dEI: NDArray,
                    dattach: NDArray) -> NDArray[np.float64]:
    """``G_p``: the derivative of the scaled residual with respect to each parameter.

    Parameters
    ----------
    system : System
        The equation system at the current parameters.
    Xs : ndarray (n, n_unknowns)
        Equilibria (or any points: the formula is that of the residual's explicit dependence).
    charts : ndarray (n, 3)
    dc0, dc1 : ndarray (k, 3, 4)
    dEI : ndarray (k, 3)
    dattach : ndarray (k, 3, 2)
        Derivatives of the system's arrays per parameter
        (:func:`~flexkin.calibration.params.array_derivatives`).

    Returns
    -------
    ndarray (n, n_equations, k)
    """
    Xs = np.atleast_2d(np.asarray(Xs, dtype=float))
    n = len(Xs)
    k = len(dc0)
    lay = system.layout
    q, _ = system.unit_rods(Xs, charts)                       # (n, 3, NQ)
    u = Xs[:, lay.inputs]                                      # (n, 3)
    A, al, L = system.clamps(u)
    th = Xs[:, lay.pose][:, 2]
    ct, st = np.cos(th), np.sin(th)
    Lr, Fr = system.L_ref, system.F_ref
    Mr = Fr * Lr
    rf = lay.force.start
    out = np.zeros((n, lay.n_equations, k))
    for i in range(3):
        r_ = rotate(q[:, i][:, [X, Y]], al[:, i])             # (n, 2): R(alpha) tip_unit
        w_ = rotate(q[:, i][:, [FX, FY]], al[:, i])
        Li = L[:, i]
        EIi = system.EI[i]
        f = (EIi / Li**2)[:, None] * w_                        # world force on the rod tip
        mL = EIi / Li * q[:, i, ML]
        b = system.attach[i]
        bx, by = rotate(b, th).T  # Rot(theta) b_i, (n,) each
        row = lay.tip[i].start
        clamped = bool(system.clamped[i])
        # d G / d (A_x, A_y, alpha, L) of leg i, (n, n_eq, 4)
        dS = np.zeros((n, lay.n_equations, 4))
        dS[:, row, 0] = 1.0 / Lr
        dS[:, row + 1, 1] = 1.0 / Lr
        dS[:, row, 2] = -Li * r_[:, 1] / Lr
        dS[:, row + 1, 2] = Li * r_[:, 0] / Lr
        dS[:, row, 3] = r_[:, 0] / Lr
        dS[:, row + 1, 3] = r_[:, 1] / Lr
        if clamped:
            dS[:, row + 2, 2] = 1.0
        dS[:, rf, 2] = -f[:, 1] / Fr
        dS[:, rf + 1, 2] = f[:, 0] / Fr
        dS[:, rf, 3] = -2.0 * f[:, 0] / Li / Fr
        dS[:, rf + 1, 3] = -2.0 * f[:, 1] / Li / Fr
        dS[:, rf + 2, 2] = (bx * f[:, 0] + by * f[:, 1]) / Mr
        dS[:, rf + 2, 3] = (-2.0 * (bx * f[:, 1] - by * f[:, 0]) - mL) / Li / Mr
        # chain through c0 + c1 u: (k, 4) per candidate
        ds = dc0[None, :, i, :] + u[:, i, None, None] * dc1[None, :, i, :]   # (n, k, 4)
        out += np.einsum("nec,nkc->nek", dS, ds)
        # EI_i: forces and the tip moment are linear in EI
        dE = np.zeros((n, lay.n_equations))
        dE[:, rf] = f[:, 0] / EIi / Fr
        dE[:, rf + 1] = f[:, 1] / EIi / Fr
        dE[:, rf + 2] = (bx * f[:, 1] - by * f[:, 0] + mL) / EIi / Mr
        out += dE[:, :, None] * dEI[None, :, i]
        # attach point b_i (platform frame): B_i = P + R(theta) b_i
        for c, (ex, ey) in enumerate(((ct, st), (-st, ct))):
            dB = np.zeros((n, lay.n_equations))
            dB[:, row] = -ex / Lr
            dB[:, row + 1] = -ey / Lr
            dB[:, rf + 2] = (ex * f[:, 1] - ey * f[:, 0]) / Mr
            out += dB[:, :, None] * dattach[None, :, i, c]
    return out


def prediction_derivative(system: System, Xs: NDArray, charts: NDArray, load: NDArray, fixed: str,
                          Gp: NDArray) -> NDArray[np.float64]:
    """Derivative of the predicted quantities (the pose when ``fixed == "inputs"``, the inputs
    when ``fixed == "pose"``; raw units: m, rad) with respect to the parameters.

    Parameters
    ----------
    system : System
    Xs : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
    load : ndarray (3,)
    fixed : {"inputs", "pose"}
        What the measurement holds (FK rows hold the inputs, IK rows the pose).
    Gp : ndarray (n, n_equations, k)
        From :func:`parameter_block`.

    Returns
    -------
    dY : ndarray (n, n_solved, k)
        Derivative of every solved column (rods, then pose or inputs); the last three rows are
        the predicted quantities.  NaN where the Newton matrix is singular.
    """
    _, J = system.jacobian(Xs, charts, load)
    cols = system.layout.columns(fixed)
    Am = J[:, :, cols]
    out = np.full((len(Am), len(cols), Gp.shape[2]), np.nan)
    for a in range(len(Am)):
        try:
            out[a] = -np.linalg.solve(Am[a], Gp[a])
        except np.linalg.LinAlgError:
            pass
    return out
