"""Kinematic Jacobians (paper §4.4, Eq. 16) by the implicit-function theorem.

The refined equations ``G(z, x, rho) = 0`` (:mod:`flexkin.system`; ``z`` the rods' chart
coordinates, ``x`` the pose, ``rho`` the inputs) define the solution branch through an
equilibrium.  Differentiating along it with the load held fixed,

    G_z dz + G_x dx + G_rho drho = 0,

gives the two Jacobians of Eq. (16),

    dx   = J_IK drho,   J_IK = -[A_FK^-1 G_rho]_x,   A_FK = [G_z  G_x],
    drho = J_FK dx,     J_FK = -[A_IK^-1 G_x]_rho,   A_IK = [G_z  G_rho],

(``A_FK`` is the Newton matrix of the forward kinematics, ``A_IK`` that of the inverse
kinematics) and ``J_IK J_FK = I`` where both exist.  An **IK singularity** is where ``A_IK``
is singular (``det J_IK -> 0``, ``J_FK`` blows up; the IK solution folds, typically on the
workspace boundary), an **FK singularity** where ``A_FK`` is singular (``det J_FK -> 0``;
with the actuators locked the platform gains a zero-stiffness direction, where stability
changes).

**Singularity measures** ``sing_ik``, ``sing_fk`` (dimensionless, in [-1, 1], scale-free).
Near an equilibrium the equilibria form a 3-dimensional manifold in the 6-dimensional space of
(pose, inputs), in the units below; let ``T`` be its tangent space, spanned by the columns of
``[J_IK; I]`` (pose rows first).  Then

    |sing_ik| = the factor by which the orthogonal projection onto the pose coordinates
                scales 3-volumes of T  = prod_i sigma_i / sqrt(1 + sigma_i^2),
    |sing_fk| = the same for the projection onto the inputs = prod_i 1 / sqrt(1 + sigma_i^2),

with ``sigma_i`` the singular values of ``J_IK``: the product of the cosines of the principal
angles between ``T`` and the pose (resp. input) coordinate space.  ``sing_ik = 0`` exactly
where an input motion leaves the pose fixed (IK singularity), ``sing_fk = 0`` exactly where
the pose moves with the inputs locked (FK singularity); both are 1 at most, and
``|sing_fk / sing_ik| = |det J_FK|``.  They depend only on the equilibria (not on the rods'
chart, the equations' scaling, EI or the mechanism's size: a copy scaled by s with any EI has
the same values at the scaled poses), and they are computed from the blocks of the Newton
matrices, so they are finite and smooth through both singularities: ``T`` is the kernel of the
3 x 6 matrix ``M = Q^T [G_x  G_rho]`` with ``Q`` an orthonormal basis of the complement of the
range of ``G_z``.  The sign is that of ``det A_IK`` (resp. ``det A_FK``), which changes at the
singularity, so a sign change between two points of a branch locates it.

Units: dimensionless.  Positions and prismatic/length inputs are measured in the
mechanism's length scale ``L_ref`` (:attr:`flexkin.mechanism.Mechanism.length_scale`),
angles and revolute inputs in radians; so ``J_IK`` maps ``(drho / L_ref or dphi)`` to
``(dx / L_ref, dy / L_ref, dtheta)``.  The partial derivatives are analytic (closed form).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.jsonable import finite_matrix, finite_or_none
from ..system import System

__all__ = ["Jacobians", "JacobianArrays", "kinematic_jacobians", "system_blocks", "singularity_measures"]


@dataclass(frozen=True, eq=False)
class Jacobians:
    """Kinematic Jacobians of Eq. (16) at an equilibrium (:mod:`flexkin.analysis.jacobian`).

    ``J_IK`` (``dx = J_IK drho``) and ``J_FK`` (``drho = J_FK dx``) are dimensionless: positions
    and prismatic/length inputs in units of the mechanism's length scale ``L_ref``, angles in
    radians.  ``None`` where the Jacobian does not exist (at an FK, resp. IK, singularity).
    ``sing_ik``, ``sing_fk`` are the singularity measures (:mod:`flexkin.analysis.jacobian`):
    dimensionless and scale-free, in [-1, 1], smooth along a branch and zero at IK and FK
    singularities (``|sing_ik| = prod sigma_i / sqrt(1 + sigma_i^2)``, ``|sing_fk| =
    prod 1 / sqrt(1 + sigma_i^2)`` with ``sigma_i`` the singular values of ``J_IK``).

    Attributes
    ----------
    J_IK : (3, 3) ndarray or None
        ``dx = J_IK drho`` (dimensionless, see above); ``None`` at an FK singularity.
    J_FK : (3, 3) ndarray or None
        ``drho = J_FK dx`` (dimensionless); ``None`` at an IK singularity.
    det_ik : float
        ``det J_IK`` (dimensionless); ``inf`` where ``J_IK`` does not exist.
    det_fk : float
        ``det J_FK`` (dimensionless); ``inf`` where ``J_FK`` does not exist.
    cond : float
        2-norm condition number of ``J_FK`` (dimensionless); ``inf`` where it does not exist.
    sing_ik : float
        IK singularity measure in [-1, 1] (dimensionless, scale-free; 0 at an IK singularity).
    sing_fk : float
        FK singularity measure in [-1, 1] (dimensionless, scale-free; 0 at an FK singularity).
    L_ref : float
        The length scale (m) of the dimensionless lengths.
    """

    J_IK: NDArray[np.float64] | None
    J_FK: NDArray[np.float64] | None
    det_ik: float
    det_fk: float
    cond: float
    sing_ik: float
    sing_fk: float
    L_ref: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready entry (SPEC §4); non-finite values are ``None``."""
        return {"det_ik": finite_or_none(self.det_ik), "det_fk": finite_or_none(self.det_fk),
                "cond": finite_or_none(self.cond), "J_IK": finite_matrix(self.J_IK), "J_FK": finite_matrix(self.J_FK),
                "sing_ik": finite_or_none(self.sing_ik), "sing_fk": finite_or_none(self.sing_fk),
                "units": f"dimensionless: lengths in L_ref = {self.L_ref:.6g} m, angles in rad"}


#: condition number beyond which a Newton matrix counts as singular
SINGULAR_COND = 1e14


def system_blocks(system: System, X: NDArray, charts: NDArray, load: NDArray
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``(G_z, G_x, G_rho)`` of the scaled equations with respect to the chart coordinates, the
    dimensionless pose ``(x/L_ref, y/L_ref, theta)`` and the dimensionless inputs.

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
    G_z, G_x, G_rho : ndarray (n, n_equations, .)
    """
    _, J = system.jacobian(X, charts, load)
    lay = system.layout
    sx = np.array([system.L_ref, system.L_ref, 1.0])
    su = system.input_scale()
    return J[:, :, :lay.n_rod], J[:, :, lay.pose] * sx, J[:, :, lay.inputs] * su


def singularity_measures(Gz: NDArray[np.float64], Gx: NDArray[np.float64], Gu: NDArray[np.float64]
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The scale-free singularity measures ``(sing_ik, sing_fk)`` (module docstring) of ``n``
    equilibria from the blocks of :func:`system_blocks`.

    Parameters
    ----------
    Gz, Gx, Gu : ndarray (n, n_equations, .)
        Derivatives of the scaled equations with respect to the chart coordinates, the
        dimensionless pose and the dimensionless inputs.

    Returns
    -------
    sing_ik, sing_fk : ndarray (n,)
        In [-1, 1]; zero at an IK (resp. FK) singularity, with the sign of ``det A_IK``
        (resp. ``det A_FK``).
    """
    n, m, nz = Gz.shape
    if n == 0:
        return np.zeros(0), np.zeros(0)
    with np.errstate(all="ignore"):
        Q, _ = np.linalg.qr(Gz, mode="complete")                        # (n, m, m)
        M = np.swapaxes(Q[:, :, nz:], 1, 2) @ np.concatenate([Gx, Gu], axis=2)   # (n, 3, 6): T = ker M
        # an orthonormal basis of the row space of M (= the orthogonal complement of T): the
        # projection of T onto a coordinate 3-space scales volumes by |det| of the complementary
        # 3x3 block of that basis
        B, _ = np.linalg.qr(np.swapaxes(M, 1, 2))                       # (n, 6, 3)
        mag_fk = np.abs(np.linalg.det(B[:, :3, :]))                     # pose rows: inputs locked
        mag_ik = np.abs(np.linalg.det(B[:, 3:, :]))                     # input rows: pose held
        sign_ik = np.linalg.slogdet(np.concatenate([Gz, Gu], axis=2))[0]
        sign_fk = np.linalg.slogdet(np.concatenate([Gz, Gx], axis=2))[0]
    ok = np.all(np.isfinite(M), axis=(1, 2))
    return (np.where(ok, sign_ik * np.minimum(mag_ik, 1.0), np.nan),
            np.where(ok, sign_fk * np.minimum(mag_fk, 1.0), np.nan))


@dataclass(frozen=True)
class JacobianArrays:
    """Jacobians of ``n`` equilibria (see the module docstring).

    Attributes
    ----------
    J_IK, J_FK : (n, 3, 3); ``inf`` entries where they do not exist.
    det_ik, det_fk, cond : (n,)
    sing_ik, sing_fk : (n,) the singularity measures (module docstring): dimensionless,
        scale-free, in [-1, 1], zero at IK (resp. FK) singularities.
    """

    J_IK: NDArray[np.float64]
    J_FK: NDArray[np.float64]
    det_ik: NDArray[np.float64]
    det_fk: NDArray[np.float64]
    cond: NDArray[np.float64]
    sing_ik: NDArray[np.float64]
    sing_fk: NDArray[np.float64]

    def item(self, i: int, L_ref: float = 1.0) -> Jacobians:
        """The :class:`Jacobians` of equilibrium ``i``."""
        def mat(a):
            return a.copy() if np.all(np.isfinite(a)) else None

        return Jacobians(mat(self.J_IK[i]), mat(self.J_FK[i]), float(self.det_ik[i]), float(self.det_fk[i]),
                         float(self.cond[i]), float(self.sing_ik[i]), float(self.sing_fk[i]), L_ref)


def _solve_block(A: NDArray, B: NDArray, rows: slice) -> NDArray:
    """``-[A^-1 B]`` restricted to ``rows``, ``inf`` where ``A`` is numerically singular."""
    out = np.full(B.shape[:1] + (3, 3), np.inf)
    with np.errstate(all="ignore"):
        c = np.linalg.cond(A) if len(A) else np.zeros(0)
    ok = c < SINGULAR_COND
    if np.any(ok):
        out[ok] = -np.linalg.solve(A[ok], B[ok])[:, rows, :]
    return out


def kinematic_jacobians(system: System, X: NDArray, charts: NDArray, load: NDArray) -> JacobianArrays:
    """J_IK and J_FK (Eq. 16) at ``n`` refined equilibria ``X`` (n, n_unknowns).

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
    JacobianArrays
    """
    Gz, Gx, Gu = system_blocks(system, X, charts, load)
    nz = Gz.shape[2]
    A_ik = np.concatenate([Gz, Gu], axis=2)
    A_fk = np.concatenate([Gz, Gx], axis=2)
    J_IK = _solve_block(A_fk, Gu, slice(nz, nz + 3))
    J_FK = _solve_block(A_ik, Gx, slice(nz, nz + 3))
    n = len(Gz)
    with np.errstate(invalid="ignore", over="ignore"):
        fin_ik = np.all(np.isfinite(J_IK), axis=(1, 2))
        fin_fk = np.all(np.isfinite(J_FK), axis=(1, 2))
        det_ik = np.where(fin_ik, np.linalg.det(np.where(np.isfinite(J_IK), J_IK, 0.0)), np.inf)
        det_fk = np.where(fin_fk, np.linalg.det(np.where(np.isfinite(J_FK), J_FK, 0.0)), np.inf)
        cond = np.full(n, np.inf)
        if np.any(fin_fk):
            cond[fin_fk] = np.linalg.cond(J_FK[fin_fk])
    sing_ik, sing_fk = singularity_measures(Gz, Gx, Gu)
    return JacobianArrays(J_IK, J_FK, det_ik, det_fk, cond, sing_ik, sing_fk)
