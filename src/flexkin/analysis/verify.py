"""A-posteriori verification of reported equilibria (issue 12) and the Newton condition number.

Every reported solution is checked independently of the closed form that found it: each rod
is integrated as an initial-value problem from its clamp, with the *reported* base moment and
tip force, by an adaptive, error-controlled Dormand-Prince 8(5,3) scheme (the DOP853 step of
:mod:`flexkin.core.dop853` with Hairer's step-size control, as in
:func:`scipy.integrate.solve_ivp`), compiled with numba.

The ODE of the unit rod (``L = EI = 1``, clamp at the origin, tangent along +x; SPEC §2, the
force ``f`` on the tip by the platform is the constant internal force, paper Eqs. 7-8)::

    x' = cos th,   y' = sin th,   th' = m,   m' = f_x sin th - f_y cos th,

so that ``th'' = R sin(th - psi)`` (Eq. 8 with ``f = R (cos psi, sin psi)``).  The check
evaluates, all scaled to O(1) as in :mod:`flexkin.system`:

* the integrated rod ends at the reported tip: position (``/ L_ref``), tangent (rad) and
  moment (``/ (F_ref L_ref)``), see *Sensitivity* below;
* every reported tip lies on its platform point ``B_i = P + Rot(theta) b_i`` (``/ L_ref``);
* a pinned tip carries no moment; a clamped tip has the tangent ``theta + tip_angle``
  (rad), and its tip moment enters the platform's moment balance;
* the platform is in equilibrium with the load: ``sum n_i = F`` (``/ F_ref``) and
  ``sum (B_i - P) x n_i + sum m_i(L) = M_z`` (``/ (F_ref L_ref)``; Eq. 15, SPEC §2);
* every rod's d-mode equals the inflection count on (0, L] of the integrated shape (SPEC §2):
  the sign changes of the bending moment strictly inside the rod, plus 1 for a pinned tip (a
  clamped tip is not an inflection).  Moments below
  :data:`MOMENT_RTOL` times the rod's largest moment are treated as zero, so an inflection
  at the clamp does not count, and a rod within that resolution of an end inflection (or
  flagged ``mode_boundary``) may carry either neighbouring label.

A solution is ``verified`` when the largest of these scaled residuals is at most
:data:`VERIFY_TOL` and its labels agree with its shape.  A solution that fails is still
reported, with ``verified = False``.

**Sensitivity.**  Shooting amplifies any perturbation of the data along a rod by up to
``exp(lambda s)`` (``lambda = sqrt(R / EI)``; ``|d m'/d th| <= R``), which for the rods under
large tension met in practice (``lambda L`` ~ 30: ``exp(30)`` ~ 1e13) would turn the rounding
of an exact solution into a failed check.  Each rod is therefore shot in ``N = ceil(lambda L /
3)`` equal segments (at least one): the first from the clamp with the reported base moment
and tip force, each further one from the reported tangent and moment at its start (the
closed-form profile, :func:`flexkin.rod.kernels.profile`), and every segment's end must meet
the reported tangent and moment (the last one the reported tip's).  The position is carried
through from the clamp without restarts (it does not act back on the tangent and moment, so
it amplifies nothing) and must end at the reported tip point.  The amplification is then
at most ``exp(3)`` per segment; a rod with ``lambda L <= 3`` is shot in one piece.  The
mismatches (position in ``L_ref``, tangent in rad, moment in ``F_ref L_ref``) join the
residuals above.

**Condition number.**  ``condition`` is the 2-norm condition number (ratio of the extreme
singular values) of the square Newton matrix of the inverse kinematics, ``A_IK = [G_z G_rho]``
(pose held fixed; :mod:`flexkin.analysis.jacobian`), in the scaled equations and the
dimensionless unknowns of :func:`~flexkin.analysis.jacobian.system_blocks`; with
``fixed="inputs"`` it is that of the forward kinematics, ``A_FK = [G_z G_x]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.dop853 import STAGES, advance, error_norm, stage_state, step_factor
from ..core.geometry2d import rotate, wrap_to_pi
from ..core.geometry2d_kernels import wrap_angle
from ..core.jit import njit
from ..rod.closed_form import pinned_chart
from ..rod.kernels import CHART_SEAM, CHART_UNIFIED, profile
from ..system import System
from .jacobian import system_blocks

__all__ = ["Verification", "verify_solutions", "newton_condition", "integrate_rod",
           "VERIFY_TOL", "RTOL", "ATOL", "MOMENT_RTOL"]

#: a solution is verified when every scaled residual of the check is at most this
VERIFY_TOL = 1e-8
#: relative and absolute tolerances of the step-size control (dimensionless rod units)
RTOL = 1e-12
ATOL = 1e-12
#: bending moments below this times the rod's largest moment count as zero (inflection count)
MOMENT_RTOL = 1e-8
#: a rod is shot in segments over which perturbations grow at most by exp(SEGMENT_GROWTH)
SEGMENT_GROWTH = 3.0
#: largest step (unit rod length), so that no step spans two inflections
H_MAX = 1.0 / 32.0
#: steps allowed per half rod before the integration gives up (the solution is then not verified)
MAX_STEPS = 100_000


# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _rhs(y, fx, fy, out) -> None:
    """The planar elastica of the unit rod (module docstring)."""
    c = math.cos(y[2])
    s = math.sin(y[2])
    out[0] = c
    out[1] = s
    out[2] = y[3]
    out[3] = fx * s - fy * c


@njit(cache=True)
def _dop853(y0, fx, fy, direction, span, rtol, atol, hmax, max_steps, y, mbuf):
    """Integrate the unit rod over ``span`` of its length from state ``y0`` (x, y, th, m) into
    ``y``, forward (``direction`` = +1) or backward (-1); the bending moment after every accepted
    step is stored in ``mbuf`` (``mbuf[0]`` the start).  Returns the number of stored moments,
    or -1 if the integration failed (non-finite values, step underflow, too many steps)."""
    K = np.empty((STAGES, 4))
    yt = np.empty(4)
    yn = np.empty(4)
    for i in range(4):
        y[i] = y0[i]
    mbuf[0] = y[3]
    nm = 1
    t = 0.0
    lam = math.sqrt(math.sqrt(fx * fx + fy * fy))
    h = min(hmax, 0.05 / (1.0 + lam + abs(y[3])), span)
    _rhs(y, fx, fy, K[0])
    rejected = False
    for _ in range(max_steps):
        if t >= span:
            return nm
        last = h >= span - t
        if last:
            h = span - t
        hs = direction * h
        for st in range(1, STAGES):
            stage_state(st, y, hs, K, yt, 4)
            _rhs(yt, fx, fy, K[st])
        advance(y, hs, K, yn, 4)
        err = error_norm(y, yn, hs, K, rtol, atol, 4)
        if not math.isfinite(err):
            return -1
        fac = step_factor(err, rejected)
        if err < 1.0:
            t = span if last else t + h
            for i in range(4):
                y[i] = yn[i]
            mbuf[nm] = y[3]
            nm += 1
            _rhs(y, fx, fy, K[0])
            rejected = False
        else:
            rejected = True
        h = min(hmax, h * fac)
        if h < 1e-14:
            return -1
    return nm if t >= span else -1


@njit(cache=True)
def _sign_changes(ms, n, eps, sign) -> tuple:
    """Sign changes of the entries of ``ms[:n]`` with ``|m| > eps`` (the others count as zero),
    continuing from ``sign`` (0: none yet).  Returns (changes, last sign)."""
    changes = 0
    for j in range(n):
        m = ms[j]
        if abs(m) <= eps:
            continue
        sg = 1 if m > 0.0 else -1
        if sign != 0 and sg != sign:
            changes += 1
        sign = sg
    return changes, sign


@njit(cache=True)
def _shoot_rods(nodes, offsets, force, rtol, atol, hmax, max_steps, gap, counts, mmax):
    """Multiple shooting of unit rods (module docstring), batched over rods.

    Rod ``r`` has the states ``nodes[offsets[r]:offsets[r + 1]]`` ``(x, y, th, m)`` at equally
    spaced arc lengths from its clamp (``s = 0``) to its tip (``s = 1``) and the tip force
    ``force[r]`` (local frame, unit rod).  Every segment is integrated forward from the tangent
    and moment of its first node; the position is carried through from the clamp (it does not
    act back on ``(th, m)``, so it amplifies nothing, and the interior nodes' positions are not
    used).  Outputs: ``gap`` (n, 3), the mismatch of the position at the tip and the largest
    mismatch of tangent and moment at the segments' ends (NaN if an integration failed);
    ``counts`` (n,), the sign changes of the moment strictly inside the rod, moments below
    ``MOMENT_RTOL * mmax`` counting as zero (-1 if an integration failed); ``mmax`` (n,), the
    largest moment met.
    """
    buf = np.empty(max_steps + 1)
    ms = np.empty(max_steps + 1)
    y = np.empty(4)
    y0 = np.empty(4)
    for r in range(offsets.shape[0] - 1):
        fx = force[r, 0]
        fy = force[r, 1]
        span = 1.0 / (offsets[r + 1] - offsets[r] - 1)
        gap[r, :] = 0.0
        n_ms = 0
        y[0] = nodes[offsets[r], 0]
        y[1] = nodes[offsets[r], 1]
        for k in range(offsets[r], offsets[r + 1] - 1):
            y0[0] = y[0]
            y0[1] = y[1]
            y0[2] = nodes[k, 2]
            y0[3] = nodes[k, 3]
            nm = _dop853(y0, fx, fy, 1.0, span, rtol, atol, hmax, max_steps, y, buf)
            if nm < 0 or n_ms + nm > ms.shape[0]:
                n_ms = -1
                break
            ms[n_ms:n_ms + nm] = buf[:nm]
            n_ms += nm
            e = nodes[k + 1]
            d = y[2] - e[2]
            gap[r, 1] = max(gap[r, 1], abs(wrap_angle(d)))
            gap[r, 2] = max(gap[r, 2], abs(y[3] - e[3]))
        e = nodes[offsets[r + 1] - 1]
        gap[r, 0] = math.hypot(y[0] - e[0], y[1] - e[1])
        if n_ms < 0:
            gap[r, :] = np.nan
            counts[r] = -1
            mmax[r] = np.nan
            continue
        mx = 0.0
        for j in range(n_ms):
            mx = max(mx, abs(ms[j]))
        counts[r], _ = _sign_changes(ms, n_ms, MOMENT_RTOL * mx, 0)
        mmax[r] = mx


def integrate_rod(m0: float, force: tuple[float, float], s_end: float = 1.0) -> NDArray[np.float64]:
    """State ``(x, y, th, m)`` at ``s_end`` of the unit rod clamped at the origin (tangent +x)
    with base moment ``m0`` and tip force ``force``, by the compiled DOP853 of this module.

    Parameters
    ----------
    m0 : float
        Dimensionless base moment ``M0 L / EI``.
    force : tuple of float
        Dimensionless tip force ``n L^2 / EI`` in the clamp frame.
    s_end : float, optional
        Arc length to integrate to (unit rod), in (0, 1].

    Returns
    -------
    ndarray (4,)

    Raises
    ------
    ValueError
        If ``s_end`` is outside (0, 1].
    FloatingPointError
        If the integration fails.
    """
    if not 0.0 < s_end <= 1.0:
        raise ValueError(f"s_end must lie in (0, 1], got {s_end!r}")
    y = np.empty(4)
    n = _dop853(np.array([0.0, 0.0, 0.0, float(m0)]), float(force[0]), float(force[1]), 1.0, float(s_end),
                RTOL, ATOL, H_MAX, MAX_STEPS, y, np.empty(MAX_STEPS + 1))
    if n < 0:
        raise FloatingPointError("the rod's integration failed")
    return y


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Verification:
    """Outcome of :func:`verify_solutions` for ``n`` equilibria.

    Attributes
    ----------
    verified : (n,) bool
        Every scaled residual at most :data:`VERIFY_TOL` and every d-mode equal to the
        inflection count of the integrated shape.
    error : (n,) float
        The largest scaled residual (``inf`` when an integration failed).
    inflections : (n, 3) int
        d-mode of each rod read from the integrated shape (sign changes of the moment strictly
        inside the rod, plus 1 for a pinned tip; -1 when the integration failed).
    modes_agree : (n, 3) bool
        The reported d-mode agrees with ``inflections`` (to the end tolerance, module docstring).
    condition : (n,) float
        Condition number of the Newton matrix (module docstring).
    """

    verified: NDArray[np.bool_]
    error: NDArray[np.float64]
    inflections: NDArray[np.int64]
    modes_agree: NDArray[np.bool_]
    condition: NDArray[np.float64]


def newton_condition(system: System, X: NDArray, charts: NDArray, load: NDArray,
                     fixed: str = "pose") -> NDArray[np.float64]:
    """2-norm condition number of the scaled Newton matrix at equilibria ``X`` (n, n_unknowns).

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    load : ndarray (3,)
        Load wrench ``(F_x, F_y, M_z)`` (N, N, N m).
    fixed : {"pose", "inputs"}
        Held fixed: the pose (inverse kinematics, ``A_IK = [G_z G_rho]``) or the inputs
        (forward kinematics, ``A_FK = [G_z G_x]``).

    Returns
    -------
    ndarray (n,)
        ``sigma_max / sigma_min`` (``inf`` where singular).
    """
    if fixed not in ("pose", "inputs"):
        raise ValueError(f"fixed must be 'pose' or 'inputs', got {fixed!r}")
    Gz, Gx, Gu = system_blocks(system, X, charts, load)
    A = np.concatenate([Gz, Gu if fixed == "pose" else Gx], axis=2)
    out = np.full(len(A), np.inf)
    fin = np.all(np.isfinite(A), axis=(1, 2))
    if np.any(fin):
        sv = np.linalg.svd(A[fin], compute_uv=False)
        with np.errstate(divide="ignore"):
            out[fin] = np.where(sv[:, -1] > 0, sv[:, 0] / sv[:, -1], np.inf)
    return out


@njit(cache=True)
def _interior_nodes(charts, z, offsets, nodes) -> None:
    """The closed-form states at the interior nodes of every rod (equally spaced in ``s``)."""
    for r in range(charts.shape[0]):
        n_seg = offsets[r + 1] - offsets[r] - 1
        if n_seg > 1:
            s = np.arange(1, n_seg) / n_seg
            profile(charts[r], z[r], s, nodes[offsets[r] + 1:offsets[r + 1] - 1])


def _segments(lam: NDArray) -> NDArray[np.int64]:
    """Shooting segments per rod: ``lambda L / segments <= SEGMENT_GROWTH`` (one for a non-finite
    force, whose integration then fails)."""
    lam = np.where(np.isfinite(lam), lam, 0.0)
    return np.maximum(1, np.ceil(lam / SEGMENT_GROWTH)).astype(np.int64)


def _nodes(system: System, X: NDArray, charts: NDArray, w: dict[str, NDArray], A: NDArray, al: NDArray,
           L: NDArray, force: NDArray) -> tuple[NDArray, NDArray]:
    """Shooting nodes of every rod (rows ``j * 3 + i``): the clamp ``(0, 0, 0, m0)`` with the
    reported base moment, the reported shape at interior nodes (the closed form's profile,
    :func:`flexkin.rod.kernels.profile`), and the reported tip point, tangent and moment; unit
    rod, clamp frame.  Returns ``(nodes (N, 4), offsets (3 n + 1,))``."""
    n = len(X)
    EI = system.EI[None]
    seg = _segments(np.sqrt(np.hypot(force[..., 0], force[..., 1]))).reshape(-1)
    offsets = np.zeros(3 * n + 1, np.int64)
    offsets[1:] = np.cumsum(seg + 1)
    nodes = np.empty((offsets[-1], 4))
    first = offsets[:-1]
    last = offsets[1:] - 1
    nodes[first] = 0.0
    nodes[first, 3] = (w["base_moment"] * L / EI).reshape(-1)
    nodes[last, :2] = (rotate(w["tip"] - A, -al) / L[..., None]).reshape(-1, 2)
    nodes[last, 2] = (w["tip_angle"] - al).reshape(-1)
    nodes[last, 3] = (w["tip_moment"] * L / EI).reshape(-1)
    z = np.stack([system.rod_x(X, i) for i in range(3)], axis=1).reshape(-1, 3)
    ch = np.asarray(charts, np.int64).reshape(-1).copy()
    seam = ch == CHART_SEAM
    if np.any(seam):   # the profile is evaluated in the unified chart; seam pairs are stored raw
        z[seam, 0], z[seam, 1] = pinned_chart(z[seam, :2], ch[seam])   # or offset-encoded
        ch[seam] = CHART_UNIFIED
    _interior_nodes(ch, z, offsets, nodes)
    return nodes, offsets


def verify_solutions(system: System, X: NDArray, charts: NDArray, load: NDArray, modes: NDArray,
                     boundary: NDArray | None = None, fixed: str = "pose") -> Verification:
    """Check equilibria ``X`` by integrating every rod (module docstring).

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    X : ndarray (n, n_unknowns)
        Reported equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    load : ndarray (3,)
        Load wrench ``(F_x, F_y, M_z)`` (N, N, N m).
    modes : ndarray (n, 3)
        Reported d-modes.
    boundary : ndarray (n, 3) of bool, optional
        Reported ``mode_boundary`` flags (such a rod may also carry the label one below the
        inflection count).
    fixed : {"pose", "inputs"}
        Which Newton matrix :func:`newton_condition` measures.

    Returns
    -------
    Verification
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    n = len(X)
    modes = np.asarray(modes, dtype=np.int64).reshape(n, 3)
    bnd = np.zeros((n, 3), bool) if boundary is None else np.asarray(boundary, bool).reshape(n, 3)
    load = np.asarray(load, dtype=float)
    if n == 0:
        return Verification(np.zeros(0, bool), np.zeros(0), np.zeros((0, 3), np.int64), np.zeros((0, 3), bool),
                            np.zeros(0))
    w = system.rod_world(X, charts)
    A, al, L = system.clamps(X[:, system.layout.inputs])
    EI = system.EI[None]
    force = rotate(w["force"], -al) * (L**2 / EI)[..., None]     # unit rod, clamp frame
    nodes, offsets = _nodes(system, X, charts, w, A, al, L, force)
    gap = np.empty((n * 3, 3))
    counts = np.empty(n * 3, np.int64)
    mmax = np.empty(n * 3)
    with np.errstate(all="ignore"):
        _shoot_rods(nodes, offsets, np.ascontiguousarray(force.reshape(-1, 2)), RTOL, ATOL, H_MAX, MAX_STEPS,
                    gap, counts, mmax)
        counts = counts.reshape(n, 3)
        res = _residuals(system, X, load, w, L, gap.reshape(n, 3, 3))
        err = np.max(res, axis=1)
        err = np.where(np.isfinite(err) & np.all(counts >= 0, axis=1), err, np.inf)
        # an inflection within the count's zero tolerance of the clamp, or of a clamped tip,
        # may or may not have been counted
        eps = MOMENT_RTOL * mmax.reshape(n, 3)
        end = (np.abs(w["base_moment"] * L / EI) <= eps) | (system.clamped[None]
                                                             & (np.abs(w["tip_moment"] * L / EI) <= eps))
    infl = np.where(counts >= 0, counts + np.where(system.clamped[None], 0, 1), -1)
    agree = (counts >= 0) & (modes >= infl - bnd) & (modes <= infl + end)
    verified = (err <= VERIFY_TOL) & np.all(agree, axis=1)
    return Verification(verified, err, infl, agree, newton_condition(system, X, charts, load, fixed))


def _residuals(system: System, X: NDArray, load: NDArray, w: dict[str, NDArray], L: NDArray,
               gap: NDArray) -> NDArray[np.float64]:
    """Scaled residuals (n, 22) of the check (module docstring); ``gap`` (n, 3, 4) is the
    largest mismatch of the shooting segments of each unit rod (position, tangent, moment)."""
    pose = X[:, system.layout.pose]
    EI = system.EI[None]
    Mref = system.F_ref * system.L_ref
    B = system.platform_points(pose)                                  # (n, 3, 2)
    clamped = system.clamped[None]
    tip_th = wrap_to_pi(w["tip_angle"] - pose[:, 2:3] - system.tip_angle[None])
    arm = B - pose[:, None, :2]
    moment = np.sum(arm[..., 0] * w["force"][..., 1] - arm[..., 1] * w["force"][..., 0] + w["tip_moment"], axis=1)
    return np.concatenate([
        gap[..., 0] * L / system.L_ref,                              # the integrated shape ...
        gap[..., 1],                                                 # ... meets the reported one
        gap[..., 2] * EI / L / Mref,
        np.linalg.norm(w["tip"] - B, axis=2) / system.L_ref,        # tips on the platform points
        np.where(clamped, 0.0, np.abs(w["tip_moment"]) / Mref),       # pinned: no tip moment
        np.where(clamped, np.abs(tip_th), 0.0),                      # clamped: theta + tip_angle
        np.abs(np.sum(w["force"], axis=1) - load[:2]) / system.F_ref,  # platform equilibrium (Eq. 15)
        np.abs(moment - load[2])[:, None] / Mref,
    ], axis=1)
