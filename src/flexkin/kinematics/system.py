"""The one equation system of a planar PCM (paper Eqs. 15 and 17), in pure arrays.

Unknowns, for ``n`` candidates at once:

* ``zrod``  (n, 6): the chart coordinates ``(v_i, phis_i)`` (``ku = tanh v``) of the three rods,
* ``pose``  (n, 3): platform pose ``(x, y, theta)`` (rad),
* ``inputs`` (n, 3): actuator inputs (m for prismatic and length legs, rad for revolute).

Equations (9), all scaled to be O(1):

* tip closure, 6: ``A_i(u_i) + L_i Rot(alpha_i) tip_unit_i - (P + Rot(theta) b_i) = 0``
  (rigid-body closure; equivalent to Eq. (17) once the pose is eliminated);
* platform equilibrium, 3 (Eq. 15 with the sign fixed by SPEC §2: the platform receives
  ``-n_i`` at ``B_i``):  ``sum_i n_i = F``  and  ``sum_i (B_i - P) x n_i = M``.

The inverse kinematics holds the pose fixed and solves for (zrod, inputs); the forward
kinematics holds the inputs fixed and solves for (zrod, pose); path following and the
workspace reuse the same residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..rod.closed_form import SEAM_OFFSET, is_seam, tip_any
from ..rod.state import RodState, project_chart

__all__ = ["MechArrays", "PRISMATIC", "REVOLUTE", "LENGTH", "clamp_arrays", "residual", "rod_states",
           "project_zrod"]

PRISMATIC, REVOLUTE, LENGTH = 0, 1, 2
_CODES = {"prismatic": PRISMATIC, "revolute": REVOLUTE, "length": LENGTH}


@dataclass(frozen=True)
class MechArrays:
    """A mechanism as plain arrays (the hot loops never touch the dataclasses)."""

    kind: NDArray[np.int64]      # (3,) PRISMATIC | REVOLUTE | LENGTH
    origin: NDArray[np.float64]  # (3, 2)
    angle: NDArray[np.float64]   # (3,) guide angle (rad)
    length: NDArray[np.float64]  # (3,) rod length, NaN for length legs
    EI: NDArray[np.float64]      # (3,)
    attach: NDArray[np.float64]  # (3, 2) b_i in the platform frame
    L_ref: float
    EI_ref: float

    @classmethod
    def from_mechanism(cls, mech) -> "MechArrays":
        """Extract the arrays from a :class:`flexkin.mechanism.Mechanism`."""
        kind = np.array([_CODES[leg.actuation] for leg in mech.legs])
        origin = np.array([leg.origin for leg in mech.legs], dtype=float)
        angle = np.array([leg.angle for leg in mech.legs], dtype=float)
        length = np.array([np.nan if leg.actuation == "length" else leg.rod.length for leg in mech.legs],
                          dtype=float)
        EI = np.array([leg.rod.EI for leg in mech.legs], dtype=float)
        attach = np.array(mech.platform.attach, dtype=float)
        L_ref = float(mech.length_scale)
        return cls(kind, origin, angle, length, EI, attach, L_ref, float(np.mean(EI)))

    @property
    def F_ref(self) -> float:
        """Force scale EI/L^2."""
        return self.EI_ref / self.L_ref**2

    def wrench_scale(self) -> NDArray[np.float64]:
        """Scales of (Fx, Fy, Mz)."""
        return np.array([self.F_ref, self.F_ref, self.F_ref * self.L_ref])


def clamp_arrays(m: MechArrays, inputs: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
    """Clamp point ``A`` (n, 3, 2), tangent angle ``alpha`` (n, 3) and free length ``L`` (n, 3)."""
    u = np.asarray(inputs, dtype=float)
    n = u.shape[0]
    kind = m.kind[None, :]
    e = np.stack([np.cos(m.angle), np.sin(m.angle)], -1)[None]  # (1, 3, 2)
    A = m.origin[None] + np.where((kind == PRISMATIC)[..., None], u[..., None] * e, 0.0)
    alpha = np.where(kind == REVOLUTE, u, np.broadcast_to(m.angle, (n, 3)))
    L = np.where(kind == LENGTH, u, np.broadcast_to(m.length, (n, 3)))
    return A, alpha, L


def platform_points(m: MechArrays, pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """World attach points ``B_i = P + Rot(theta) b_i``, shape (n, 3, 2)."""
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    bx, by = m.attach[:, 0][None], m.attach[:, 1][None]
    return pose[:, None, :2] + np.stack([c[:, None] * bx - s[:, None] * by, s[:, None] * bx + c[:, None] * by], -1)


def rod_world(m: MechArrays, zrod: NDArray[np.float64], inputs: NDArray[np.float64]):
    """Tips (n, 3, 2) and tip forces on the rods (n, 3, 2), world frame."""
    A, alpha, L = clamp_arrays(m, inputs)
    t = tip_any(zrod[:, 0::2], zrod[:, 1::2])
    ca, sa = np.cos(alpha), np.sin(alpha)
    tip = A + L[..., None] * np.stack([ca * t.x - sa * t.y, sa * t.x + ca * t.y], -1)
    scale = m.EI[None] / L**2
    fx, fy = t.fx * scale, t.fy * scale
    force = np.stack([ca * fx - sa * fy, sa * fx + ca * fy], -1)
    return tip, force


def residual(m: MechArrays, zrod: NDArray, pose: NDArray, inputs: NDArray, load: NDArray) -> NDArray[np.float64]:
    """Scaled residual of the 9 equations, shape (n, 9)."""
    tip, force = rod_world(m, zrod, inputs)
    B = platform_points(m, pose)
    r_pos = (tip - B).reshape(-1, 6) / m.L_ref
    r_f = (force.sum(axis=1) - load[:2]) / m.F_ref
    arm = B - pose[:, None, :2]
    mom = np.sum(arm[..., 0] * force[..., 1] - arm[..., 1] * force[..., 0], axis=1)
    r_m = (mom - load[2]) / (m.F_ref * m.L_ref)
    return np.concatenate([r_pos, r_f, r_m[:, None]], axis=1)


def project_zrod(zrod: NDArray[np.float64]) -> NDArray[np.float64]:
    """Keep every rod's chart coordinates admissible (see :func:`project_chart`); rods in the
    seam chart keep ``|psi_s| < pi`` and ``0 < chi < pi/2``."""
    out = np.array(zrod, dtype=float)
    z0, z1 = out[:, 0::2], out[:, 1::2]
    seam = is_seam(z1)
    ku, ph = project_chart(np.where(seam, 0.0, z0), np.where(seam, 0.0, z1))
    ps = np.clip(z0, -np.pi + 1e-9, np.pi - 1e-9)
    chi = np.clip(z1 - SEAM_OFFSET, 1e-12, 0.5 * np.pi - 1e-9) + SEAM_OFFSET
    out[:, 0::2] = np.where(seam, ps, ku)
    out[:, 1::2] = np.where(seam, chi, ph)
    return out


def rod_states(m: MechArrays, zrod: NDArray[np.float64], inputs: NDArray[np.float64]) -> tuple[RodState, ...]:
    """World-frame :class:`RodState` of the three rods of one solution."""
    A, alpha, L = clamp_arrays(m, np.asarray(inputs, dtype=float)[None])
    return tuple(
        RodState.from_chart(zrod[2 * i], zrod[2 * i + 1], L[0, i], m.EI[i], A[0, i], alpha[0, i])
        for i in range(3)
    )
