"""Kinematic Jacobians (paper §4.4, Eq. 16) by the implicit-function theorem.

The refined equations ``G(z, x, rho) = 0`` (9 equations, :mod:`flexkin.kinematics.system`;
``z`` the six rod-chart coordinates, ``x`` the pose, ``rho`` the inputs) define the solution
branch through an equilibrium.  Differentiating along it, with the load held fixed,

    G_z dz + G_x dx + G_rho drho = 0,

gives the two Jacobians of Eq. (16) of the paper,

    dx   = J_IK drho,   J_IK = -[A_FK^-1 G_rho]_x,   A_FK = [G_z  G_x],
    drho = J_FK dx,     J_FK = -[A_IK^-1 G_x]_rho,   A_IK = [G_z  G_rho],

(``A_FK`` is the Newton matrix of the forward kinematics, ``A_IK`` that of the inverse
kinematics) and ``J_IK J_FK = I`` where both exist.  Following the paper's naming, an
**IK singularity** is where ``A_IK`` is singular (``det J_IK -> 0``, ``J_FK`` blows up; the
IK solution folds, typically on the workspace boundary) and an **FK singularity** where
``A_FK`` is singular (``det J_FK -> 0``; with the actuators locked the platform gains a
zero-stiffness direction, where stability changes).  ``det A_IK`` and ``det A_FK`` (scaled
by their column norms) are smooth along a branch and change sign at those singularities.

All quantities are dimensionless: positions and prismatic/length inputs in units of the
mechanism's length scale ``L_ref``, angles in radians.  The partial derivatives are central
differences of the closed-form residual (relative accuracy ~1e-9).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .system import REVOLUTE, MechArrays, residual

__all__ = ["JacobianArrays", "system_derivatives", "kinematic_jacobians"]


def system_derivatives(m: MechArrays, zrod: NDArray, pose: NDArray, inputs: NDArray, step: float = 1e-6
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Partial derivatives ``(G_z, G_x, G_rho)``, shapes (n, 9, 6), (n, 9, 3), (n, 9, 3).

    Derivatives are with respect to the dimensionless pose ``(x/L_ref, y/L_ref, theta)`` and
    inputs (``rho/L_ref`` or radians) and the chart coordinates.
    """
    zrod, pose, inputs = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (zrod, pose, inputs))
    n = len(zrod)
    X = np.concatenate([zrod, pose, inputs], axis=1)  # (n, 12)
    scale = np.concatenate([np.ones(6), [m.L_ref, m.L_ref, 1.0],
                            [1.0 if k == REVOLUTE else m.L_ref for k in m.kind]])
    E = np.eye(12)[None] * (step * scale)[None, None, :]       # (1, 12, 12) row j = perturbation j
    Xp = (X[:, None, :] + E).reshape(-1, 12)
    Xm = (X[:, None, :] - E).reshape(-1, 12)
    zero = np.zeros(3)
    Rp = residual(m, Xp[:, :6], Xp[:, 6:9], Xp[:, 9:], zero)
    Rm = residual(m, Xm[:, :6], Xm[:, 6:9], Xm[:, 9:], zero)
    D = ((Rp - Rm) / (2 * step)).reshape(n, 12, 9).transpose(0, 2, 1)  # (n, 9, 12)
    return D[:, :, :6], D[:, :, 6:9], D[:, :, 9:]


def _scaled_det(A: NDArray[np.float64]) -> NDArray[np.float64]:
    """``det A`` divided by the product of its column norms (in [-1, 1], same sign)."""
    norms = np.linalg.norm(A, axis=1)
    return np.linalg.det(A / np.where(norms > 0, norms, 1.0)[:, None, :])


@dataclass(frozen=True)
class JacobianArrays:
    """Jacobians of ``n`` equilibria (dimensionless; see the module docstring).

    Attributes
    ----------
    J_IK : (n, 3, 3) ``dx = J_IK drho`` (Eq. 16); ``inf`` entries at an FK singularity.
    J_FK : (n, 3, 3) ``drho = J_FK dx``; ``inf`` entries at an IK singularity.
    det_ik, det_fk : (n,) their determinants.
    cond : (n,) 2-norm condition number of ``J_FK`` (equal to that of ``J_IK``).
    sing_ik, sing_fk : (n,) scaled ``det A_IK`` and ``det A_FK``, smooth along a branch;
        zero at IK and FK singularities respectively.
    """

    J_IK: NDArray[np.float64]
    J_FK: NDArray[np.float64]
    det_ik: NDArray[np.float64]
    det_fk: NDArray[np.float64]
    cond: NDArray[np.float64]
    sing_ik: NDArray[np.float64]
    sing_fk: NDArray[np.float64]

    def as_dict(self, i: int) -> dict[str, float | None | list[list[float]]]:
        """JSON-ready ``jacobian`` entry of solution ``i`` (SPEC §4); non-finite values are ``None``."""
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        def mat(a: NDArray) -> list[list[float]] | None:
            return a.tolist() if np.all(np.isfinite(a)) else None

        return {"det_ik": num(self.det_ik[i]), "det_fk": num(self.det_fk[i]), "cond": num(self.cond[i]),
                "J_IK": mat(self.J_IK[i]), "J_FK": mat(self.J_FK[i]),
                "sing_ik": num(self.sing_ik[i]), "sing_fk": num(self.sing_fk[i])}


def _solve_block(A: NDArray, B: NDArray) -> NDArray:
    """``-[A^-1 B]`` rows 6..8, ``inf`` where ``A`` is numerically singular."""
    out = np.full(B.shape[:1] + (3, 3), np.inf)
    c = np.linalg.cond(A)
    ok = c < 1e14
    if np.any(ok):
        out[ok] = -np.linalg.solve(A[ok], B[ok])[:, 6:9, :]
    return out


def kinematic_jacobians(m: MechArrays, zrod: NDArray, pose: NDArray, inputs: NDArray) -> JacobianArrays:
    """J_IK and J_FK (Eq. 16) at ``n`` refined equilibria (arrays of shape (n, ...))."""
    Gz, Gx, Gu = system_derivatives(m, zrod, pose, inputs)
    A_ik = np.concatenate([Gz, Gu], axis=2)
    A_fk = np.concatenate([Gz, Gx], axis=2)
    J_IK = _solve_block(A_fk, Gu)
    J_FK = _solve_block(A_ik, Gx)
    with np.errstate(invalid="ignore", over="ignore"):
        det_ik = np.where(np.all(np.isfinite(J_IK), axis=(1, 2)), np.linalg.det(np.where(np.isfinite(J_IK), J_IK, 0)),
                          np.inf)
        det_fk = np.where(np.all(np.isfinite(J_FK), axis=(1, 2)), np.linalg.det(np.where(np.isfinite(J_FK), J_FK, 0)),
                          np.inf)
        cond = np.full(len(Gz), np.inf)
        okc = np.all(np.isfinite(J_FK), axis=(1, 2))
        if np.any(okc):
            cond[okc] = np.linalg.cond(J_FK[okc])
    return JacobianArrays(J_IK, J_FK, det_ik, det_fk, cond, _scaled_det(A_ik), _scaled_det(A_fk))
