"""Constant-orientation workspaces by wave propagation (paper §6, Fig. 17).

From one IK solution at a seed pose, the solution is continued over a square grid of
platform positions ``(x, y)`` at fixed orientation ``theta``: every wave takes the solved
points of the front, continues each of them to its 4 grid neighbours not yet visited
(:func:`~flexkin.solve.continuation.continue_ik`: tangent predictor, compiled corrector, all
at once), and classifies the new points.  Propagation stops

* across an **IK singularity**: the continuation fails (the branch folds back) or the
  IK singularity measure ``sing_ik`` (:mod:`flexkin.analysis.jacobian`; the sign of
  ``det A_IK``) changes sign (black boundary);
* across an **FK singularity / loss of stability**: ``sing_fk`` changes sign or the new
  point is not a stable equilibrium (orange boundary);
* on request (``constrained=True``), at **infeasible** cells: an input outside its leg's
  ``range`` (revolute ranges modulo 360 deg), a bending strain over ``max_strain``, or (with
  ``collisions=True``) rods touching each other, themselves or the platform (purple boundary).

**Stability at every cell.**  Every cell entered gets the closed-form verdict and index of
:mod:`flexkin.analysis.stability` (the rods' Jacobi fields and a small bordered matrix, a few
tens of microseconds; the discretised second variation where the closed form is not
conclusive), so no cell is admitted on the strength of its neighbour (an earlier opt-in
"wave" mode carried the sign of ``det A_FK`` from cell to cell instead, and on the unit 3-RFR
with L = 1.1 m at 10 deg and a 0.1 m step it admitted a cell with margin -7.5; ``"wave"`` is
now a synonym of ``"full"``).  The margin -- the smallest eigenvalue of the discretised
second variation -- is computed where the closed form falls back, at every cell with
``stability="margins"`` (each cell's eigenvector started from its source cell's, a full
computation at a d-mode change or when the update fails), and on demand by
:meth:`Workspace.margins`; elsewhere the maps hold ``NaN``.

d-mode changes of a rod are followed (every d-mode is one strip of the rod chart).  A cell
of the reached region is a boundary cell when one of its neighbours was not entered for one
of these reasons.  **Grid edge**: with default bounds the box grows (same step, at most
``grow`` times) on every side the region touches, until it closes; reached cells still on the
grid's outermost rows/columns are ``boundary_edge`` (the region is cut there).  A grown grid
resumes every wave from its cells next to the new ones; the region mapped so far is kept.

Aspects: started from every stable IK solution at the seed pose, the maps of seeds whose
regions share a grid point with the same solution (inputs equal) are merged into one aspect.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..analysis.jacobian import kinematic_jacobians
from ..analysis.stability import Eigenpairs, mechanism_stability
from ..core.budget import Deadline, Rate, timed_slices
from ..core.geometry2d import wrap_to_pi
from ..core.validation import MAX_GRID_POINTS, MAX_MODE_LIMIT, as_load, check_max_mode
from ..results import Solution
from ..rod.closed_form import pinned_chart
from ..rod.kernels import CHART_UNIFIED, CHART_WRENCH, FX, FY, M0
from ..system import System
from .continuation import SEAM_V, continue_ik
from .finish import rod_modes
from .grid import default_grid
from .finish import refine
from .ik import ik
from .workspace_map import (FAILED, INFEASIBLE, REACHED, SEAM, UNSTABLE, UNVISITED, VIOLATION_COLLISION,
                            VIOLATION_RANGE, VIOLATION_STRAIN, _NEIGHBOURS, Workspace, WorkspaceMap,
                            _ring, load_workspace, singularity_distance_map)

# the map data model (:mod:`~flexkin.solve.workspace_map`) is re-exported: users import it from here
__all__ = ["workspace", "Workspace", "WorkspaceMap", "load_workspace", "dexterous_workspace", "DexterousWorkspace",
           "singularity_distance_map", "REACHED", "UNSTABLE", "FAILED", "SEAM", "INFEASIBLE", "VIOLATION_RANGE",
           "VIOLATION_STRAIN", "VIOLATION_COLLISION"]

#: points per rod centre line for the collision checks of a workspace cell
COLLISION_SAMPLES = 60
#: seconds per cell of a wave (continuation, Jacobians, stability, checks) before anything is
#: measured, to size the slices under a time budget
CELL_COST = 2e-3


def _next_to(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Cells with a 4-neighbour in ``mask``."""
    out = np.zeros_like(mask)
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    return out


def _continue_adaptive(system: System, x: NDArray, ch: NDArray, p1: NDArray, w: NDArray, levels: int = 3
                       ) -> tuple[NDArray, NDArray, NDArray]:
    """:func:`continue_ik` of ``x`` (pose columns: the start poses) to ``p1``; failed rows are
    retried with the step cut into 2, 4, ... ``2**levels`` sub-steps before the target is
    declared out of reach."""
    lay = system.layout
    p0 = x[:, lay.pose].copy()
    xn, cn, ok = continue_ik(system, x, ch, p1, w)
    for lev in range(1, levels + 1):
        bad = np.flatnonzero(~ok)
        if bad.size == 0:
            break
        k = 2 ** lev
        xb, cb, alive = x[bad].copy(), ch[bad].copy(), np.ones(bad.size, bool)
        for step in range(k):
            b = p0[bad] + ((step + 1) / k) * (p1[bad] - p0[bad])
            idx = np.flatnonzero(alive)
            if idx.size == 0:
                break
            xs, cs, oks = continue_ik(system, xb[idx], cb[idx], b[idx], w)
            xb[idx], cb[idx] = xs, cs
            alive[idx[~oks]] = False
        xn[bad[alive]] = xb[alive]
        cn[bad[alive]] = cb[alive]
        ok[bad[alive]] = True
    return xn, cn, ok


def cell_peak_curvature(system: System, mech: Any, X: NDArray, charts: NDArray) -> NDArray[np.float64]:
    """Peak curvature ``max_s |theta'(s)|`` (1/m) of every rod of equilibria ``X``, (n, 3).

    Pinned rods in closed form (:func:`flexkin.analysis.feasibility.rod_max_curvature`, in the
    unit rod's terms: ``L max|theta'| = 2 sqrt(R L^2/EI) |ku|`` if ``phis <= 0``, else
    ``|m0| L/EI``, at least the clamp value; the same formula batched over the cells);
    clamped-tip rods by :func:`~flexkin.analysis.feasibility.rod_max_curvature` itself.

    Parameters
    ----------
    system : System
        The mechanism's equation system.
    mech : Mechanism
        The mechanism (rods' joints).
    X : (n, n_unknowns) ndarray
        Equilibria.
    charts : (n, 3) ndarray
        Their rods' charts.

    Returns
    -------
    (n, 3) ndarray
    """
    from ..analysis.feasibility import rod_max_curvature

    X = np.atleast_2d(X)
    lay = system.layout
    n = len(X)
    out = np.zeros((n, 3))
    if n == 0:
        return out
    q, _ = system.unit_rods(X, charts)
    _, _, L = system.clamps(X[:, lay.inputs])
    other = np.zeros(n, bool)
    for i in range(3):
        ch = charts[:, i]
        pinned = (ch < CHART_WRENCH) & (mech.legs[i].joint != "clamped")
        other |= ~pinned
        c = lay.rod[i].start
        v, ph = pinned_chart(X[:, c:c + 2], ch)
        peak = 2.0 * np.sqrt(np.hypot(q[:, i, FX], q[:, i, FY])) * np.abs(np.tanh(v))
        k = np.maximum(np.where(ph <= 0.0, peak, peak * np.abs(np.cos(ph))), np.abs(q[:, i, M0]))
        out[:, i] = np.where(pinned, k / L[:, i], 0.0)
    rows = np.flatnonzero(other)
    if rows.size:
        rods = system.rods(X[rows], charts[rows])
        for r, trio in zip(rows, rods):
            for i in range(3):
                if charts[r, i] >= CHART_WRENCH or mech.legs[i].joint == "clamped":
                    out[r, i] = rod_max_curvature(trio[i])
    return out


class _CellChecks:
    """The design's constraints at workspace cells: strain and the violations bit mask."""

    def __init__(self, system: System, mech: Any, collisions: bool) -> None:
        self.system, self.mech, self.collisions = system, mech, bool(collisions)
        radii = [leg.rod.radius for leg in mech.legs]
        self.radius = None if any(r is None for r in radii) else np.array(radii, dtype=float)
        self.limit = mech.max_strain
        self.ranged = [k for k, leg in enumerate(mech.legs) if leg.range is not None]
        names = []
        if self.ranged:
            names.append("ranges")
        if self.limit is not None and self.radius is not None:
            names.append("strain")
        if self.collisions:
            names.append("collisions")
        self.names = tuple(names)

    def __call__(self, X: NDArray, charts: NDArray) -> tuple[NDArray[np.float64], NDArray[np.int8]]:
        """Peak strain (n,) (``NaN`` without radii) and violations (n,) of equilibria ``X``."""
        n = len(X)
        bad = np.zeros(n, np.int8)
        strain = np.full(n, np.nan)
        if n == 0:
            return strain, bad
        if self.radius is not None:
            strain = np.max(cell_peak_curvature(self.system, self.mech, X, charts) * self.radius[None], axis=1)
            if self.limit is not None:
                bad |= np.where(strain > self.limit, VIOLATION_STRAIN, 0).astype(np.int8)
        u = X[:, self.system.layout.inputs]
        for k in self.ranged:
            bad |= np.where(self.mech.legs[k].in_range(u[:, k]), 0, VIOLATION_RANGE).astype(np.int8)
        if self.collisions:
            bad |= np.where(self._collide(X, charts), VIOLATION_COLLISION, 0).astype(np.int8)
        return strain, bad

    def _collide(self, X: NDArray, charts: NDArray) -> NDArray[np.bool_]:
        """Rod-rod, self and rod-platform contact (:func:`~flexkin.analysis.feasibility.check_feasibility`)."""
        from ..analysis.feasibility import check_feasibility

        lay = self.system.layout
        out = np.zeros(len(X), bool)
        modes = rod_modes(self.system, X, charts)
        for k, rods in enumerate(self.system.rods(X, charts, modes)):
            sol = Solution(mechanism=self.mech, pose=tuple(X[k, lay.pose]), inputs=tuple(X[k, lay.inputs]),
                           modes=tuple(int(q) for q in modes[k]), rods=rods, x=X[k], charts=charts[k])
            f = check_feasibility(self.mech, sol, n_samples=COLLISION_SAMPLES, max_strain=1.0)
            out[k] = bool(f.rod_collisions or f.self_intersecting or f.platform_collisions)
        return out


#: the arrays of a wave's state (besides the map arrays of :data:`~flexkin.solve.workspace_map._MAP_ARRAYS`)
_FILL = {"status": (np.int8, UNVISITED), "margin": (float, np.nan), "det_ik": (float, np.inf),
         "det_fk": (float, np.inf), "cond": (float, np.inf), "sik": (float, 0.0), "sfk": (float, 0.0),
         "strain": (float, np.nan), "violations": (np.int8, 0), "boundary_ik": (bool, False),
         "boundary_fk": (bool, False), "boundary_seam": (bool, False), "boundary_infeasible": (bool, False)}


class _Wave:
    """The wave propagation of one seed solution (module docstring): its state arrays on the
    grid, which it can grow (padding them) and resume from the cells next to the new ones."""

    def __init__(self, m: System, shape: tuple[int, int], theta: float, w: NDArray, checks: _CellChecks,
                 constrained: bool, margins: bool) -> None:
        self.m, self.theta, self.w, self.checks = m, theta, w, checks
        self.constrained, self.margins = constrained, margins
        ny, nx = shape
        self.a = {k: np.full(shape, v, dt) for k, (dt, v) in _FILL.items()}
        self.a["sol"] = np.full((ny, nx, m.layout.n_unknowns), np.nan)
        self.a["charts"] = np.zeros((ny, nx, 3), np.int64)
        self.pairs: dict[tuple[int, int], tuple] = {}   # eigenvectors of the front (margins mode)
        self.joins: set[int] = set()
        self.steps = 0
        self.rate = Rate(CELL_COST)   # seconds per cell, sizing the slices under a time budget

    def seed(self, x0: NDArray, c0: NDArray, ij: tuple[int, int], X: NDArray, Y: NDArray) -> None:
        """Place the seed solution at cell ``ij``."""
        a, m = self.a, self.m
        j0, i0 = ij
        x0 = x0.copy()
        x0[m.layout.pose] = (X[i0], Y[j0], self.theta)
        st = mechanism_stability(m, x0[None], c0[None], margin=self.margins)
        jac = kinematic_jacobians(m, x0[None], c0[None], self.w)
        s0, v0 = self.checks(x0[None], c0[None])
        a["status"][j0, i0] = REACHED
        a["sol"][j0, i0], a["charts"][j0, i0] = x0, c0
        for name, v in (("margin", st.margin), ("det_ik", jac.det_ik), ("det_fk", jac.det_fk), ("cond", jac.cond),
                        ("sik", jac.sing_ik), ("sfk", jac.sing_fk), ("strain", s0), ("violations", v0)):
            a[name][j0, i0] = v[0]
        self._keep_pairs(st.pairs, [(j0, i0)], [0])

    def _keep_pairs(self, pairs, cells, rows) -> None:
        if self.margins and pairs is not None:
            for c, r in zip(cells, rows):
                self.pairs[c] = (pairs.elements[r], pairs.rods[r], pairs.pose[r], pairs.valid[r])

    def _guess(self, src: list[tuple[int, int]], pairs: dict[tuple[int, int], tuple]):
        """The source cells' eigenvectors (``pairs``, by cell) as the start of the new cells'
        (margins mode)."""
        if not self.margins or not src:
            return None
        have = [pairs.get(c) for c in src]
        width = max((h[1].shape[1] for h in have if h is not None), default=1)
        E = np.zeros((len(src), 3), np.int64)
        R = np.zeros((len(src), 3, width))
        P = np.zeros((len(src), 3))
        V = np.zeros(len(src), bool)
        for k, h in enumerate(have):
            if h is not None:
                E[k], P[k], V[k] = h[0], h[2], h[3]
                R[k, :, :h[1].shape[1]] = h[1]
        return Eigenpairs(E, R, P, V)

    def grow(self, before: tuple[int, int], shape: tuple[int, int]) -> None:
        """Pad the state to the grown grid: ``before`` = (rows, columns) added below and left."""
        dj, di = before
        ny, nx = shape
        for k, v in self.a.items():
            dt, fill = (v.dtype, np.nan) if k == "sol" else ((v.dtype, 0) if k == "charts" else _FILL[k])
            out = np.full((ny, nx) + v.shape[2:], fill, dtype=v.dtype)
            out[dj:dj + v.shape[0], di:di + v.shape[1]] = v
            self.a[k] = out
        self.pairs = {(j + dj, i + di): p for (j, i), p in self.pairs.items()}

    def edge_front(self, inner: tuple[slice, slice]) -> list[tuple[int, int]]:
        """Reached cells of the old grid (``inner``) with a neighbour outside it: where a
        resumed wave continues."""
        reached = self.a["status"] == REACHED
        old = np.zeros_like(reached)
        old[inner] = True
        near_new = _next_to(~old)
        jj, ii = np.nonzero(reached & old & near_new)
        return list(zip(jj.tolist(), ii.tolist()))

    def run(self, front: list[tuple[int, int]], X: NDArray, Y: NDArray, claimed: list[tuple[NDArray, NDArray]],
            progress: Callable[[int], None] | None, deadline: Deadline) -> None:
        """Propagate from ``front`` until the wave stops (module docstring) or the ``deadline``
        expires (the front is advanced in slices, so that the clock is looked at often enough)."""
        m, a = self.m, self.a
        lay = m.layout
        status, sol, chs = a["status"], a["sol"], a["charts"]
        ny, nx = status.shape
        su = m.input_scale()
        iu = lay.inputs
        while front:
            if deadline.expired():
                break
            src, dst = [], []
            seen: set[tuple[int, int]] = set()
            for (j, i) in front:
                for dj, di in _NEIGHBOURS:
                    jj, ii = j + dj, i + di
                    if 0 <= jj < ny and 0 <= ii < nx and status[jj, ii] == UNVISITED and (jj, ii) not in seen:
                        seen.add((jj, ii))
                        src.append((j, i))
                        dst.append((jj, ii))
            if not dst:
                break
            S_all, D_all = np.array(src), np.array(dst)
            new_front = []
            source_pairs, self.pairs = self.pairs, {}
            for lo, hi in timed_slices(len(D_all), deadline, self.rate, max_slice=len(D_all)):
                t_slice = time.perf_counter()
                S, D = S_all[lo:hi], D_all[lo:hi]
                xs = sol[S[:, 0], S[:, 1]]
                cs = chs[S[:, 0], S[:, 1]]
                p1 = np.stack([X[D[:, 1]], Y[D[:, 0]], np.full(len(D), self.theta)], -1)
                xn, cn, ok = _continue_adaptive(m, xs, cs, p1, self.w)
                self.steps += len(D)
                idx = np.flatnonzero(ok)
                if idx.size:
                    jac = kinematic_jacobians(m, xn[idx], cn[idx], self.w)
                    Sj, Si = S[idx, 0], S[idx, 1]
                    crossed_ik = np.sign(jac.sing_ik) != np.sign(a["sik"][Sj, Si])
                    crossed_fk = np.sign(jac.sing_fk) != np.sign(a["sfk"][Sj, Si])
                    # stability at every cell: the closed-form index (and the margin, carried from
                    # the source cell's eigenvector, in the margins mode)
                    stable = np.ones(idx.size, bool)
                    mg = np.full(idx.size, np.nan)
                    chk = np.flatnonzero(~crossed_ik & ~crossed_fk)
                    st = None
                    if chk.size:
                        rows = idx[chk]
                        guess = self._guess([tuple(S[r]) for r in rows], source_pairs)
                        if guess is not None:
                            # a d-mode change restarts the eigenvector from scratch
                            same = np.all(rod_modes(m, xn[rows], cn[rows]) == rod_modes(m, xs[rows], cs[rows]), axis=1)
                            guess = Eigenpairs(guess.elements, guess.rods, guess.pose, guess.valid & same)
                        st = mechanism_stability(m, xn[rows], cn[rows], margin=self.margins, guess=guess)
                        stable[chk] = st.stable == 1
                        mg[chk] = st.margin
                    pos = {int(k): q for q, k in enumerate(chk)}
                    cstrain, cviol = self.checks(xn[idx], cn[idx])
                    kept_cells, kept_rows = [], []
                    for k, r in enumerate(idx):
                        jj, ii = D[r]
                        j, i = S[r]
                        if crossed_ik[k]:
                            status[jj, ii] = FAILED
                            a["boundary_ik"][j, i] = True
                            continue
                        if crossed_fk[k] or not stable[k]:
                            status[jj, ii] = UNSTABLE
                            a["boundary_fk"][j, i] = True
                            continue
                        if self.constrained and cviol[k]:
                            status[jj, ii] = INFEASIBLE
                            a["violations"][jj, ii] = cviol[k]
                            a["boundary_infeasible"][j, i] = True
                            continue
                        status[jj, ii] = REACHED
                        sol[jj, ii], chs[jj, ii] = xn[r], cn[r]
                        a["margin"][jj, ii], a["det_ik"][jj, ii], a["det_fk"][jj, ii] = mg[k], jac.det_ik[k], jac.det_fk[k]
                        a["cond"][jj, ii], a["sik"][jj, ii], a["sfk"][jj, ii] = jac.cond[k], jac.sing_ik[k], jac.sing_fk[k]
                        a["strain"][jj, ii], a["violations"][jj, ii] = cstrain[k], cviol[k]
                        if k in pos:
                            kept_cells.append((int(jj), int(ii)))
                            kept_rows.append(pos[k])
                        # joining a region mapped from an earlier seed: same solution at this cell
                        hit = False
                        for q, (st_q, sol_q) in enumerate(claimed):
                            if st_q[jj, ii] == REACHED and np.max(np.abs(sol_q[jj, ii, iu] - xn[r, iu]) / su) < 1e-6:
                                self.joins.add(q)
                                hit = True
                        if not hit:
                            new_front.append((int(jj), int(ii)))
                    if st is not None:
                        self._keep_pairs(st.pairs, kept_cells, kept_rows)
                for r in np.flatnonzero(~ok):
                    jj, ii = D[r]
                    j, i = S[r]
                    taut = np.array([(cs[r, i] == CHART_UNIFIED and abs(xs[r, lay.rod[i].start]) > SEAM_V)
                                     or cs[r, i] == 1 for i in range(3)])
                    if np.any(taut) and not np.any(taut & m.angular):
                        # a rod of a prismatic or length leg is close to straight under tension, where
                        # the elliptic chart has its seam: the step failed for the chart, not for the
                        # mechanism (a revolute leg's taut rod is at its reach |B - A| = L instead:
                        # a true boundary)
                        if status[jj, ii] == UNVISITED:
                            status[jj, ii] = SEAM
                        a["boundary_seam"][j, i] = True
                        continue
                    if status[jj, ii] in (UNVISITED, SEAM):
                        status[jj, ii] = FAILED
                    a["boundary_ik"][j, i] = True
                if progress is not None:
                    progress(len(D))
                self.rate.add(len(D), time.perf_counter() - t_slice)
            front = new_front

    def arrays(self) -> dict[str, NDArray]:
        """The map arrays (copies), boundaries cleaned: a neighbour reached from elsewhere later
        does not make a cell a boundary."""
        out = {k: v.copy() for k, v in self.a.items() if k not in ("sik", "sfk")}
        reached = out["status"] == REACHED
        out["boundary_ik"] &= reached
        out["boundary_fk"] &= reached
        out["boundary_seam"] &= reached & ~out["boundary_ik"] & ~out["boundary_fk"]
        ok_cells = reached & (out["violations"] == 0)
        out["boundary_infeasible"] = (out["boundary_infeasible"] | _next_to(reached & (out["violations"] != 0))) \
            & ok_cells
        return out


def _merge_into(new: dict[str, NDArray], old: dict[str, NDArray]) -> None:
    """Add to map ``new`` the cells of an earlier map ``old`` that it joined (the wave of
    ``new`` stops where it meets ``old``'s solution, so together they are the aspect)."""
    add = (old["status"] == REACHED) & (new["status"] != REACHED)
    for name, a in new.items():
        if name.startswith("boundary_"):
            a |= old[name] & add
        else:
            a[add] = old[name][add]
    reached = new["status"] == REACHED
    for name in ("boundary_ik", "boundary_fk", "boundary_seam", "boundary_infeasible"):
        new[name] &= reached


class _Aspects:
    """The waves of every seed solution on one grid (resumable when the grid grows)."""

    def __init__(self, m: System, starts: list[tuple[int, NDArray, NDArray]], theta: float, w: NDArray,
                 checks: _CellChecks, constrained: bool, margins: bool) -> None:
        self.m, self.starts, self.theta, self.w = m, starts, theta, w
        self.checks, self.constrained, self.margins = checks, constrained, margins
        self.waves: list[_Wave] = []
        self.seeds: list[list[int]] = []

    @property
    def steps(self) -> int:
        """Continuation steps attempted."""
        return sum(wv.steps for wv in self.waves)

    def reached(self) -> NDArray[np.bool_]:
        """Cells reached by any wave."""
        out = np.zeros(self.waves[0].a["status"].shape if self.waves else (0, 0), bool)
        for wv in self.waves:
            out |= wv.a["status"] == REACHED
        return out

    def _claimed(self, k: int) -> list[tuple[NDArray, NDArray]]:
        return [(wv.a["status"], wv.a["sol"]) for wv in self.waves[:k]]

    def run(self, ij: tuple[int, int], X: NDArray, Y: NDArray, cb, deadline: Deadline) -> None:
        """Start a wave from every seed solution at cell ``ij``."""
        j0, i0 = ij
        iu = self.m.layout.inputs
        for k, x0, c0 in self.starts:
            # a seed already inside a mapped region (same solution at the seed cell) adds nothing
            dup = [q for q, wv in enumerate(self.waves) if wv.a["status"][j0, i0] == REACHED
                   and np.allclose(wv.a["sol"][j0, i0, iu], x0[iu], atol=1e-9 * self.m.L_ref)]
            if dup:
                self.seeds[dup[0]].append(k)
                continue
            if deadline.expired():
                break
            wv = _Wave(self.m, (len(Y), len(X)), self.theta, self.w, self.checks, self.constrained, self.margins)
            wv.seed(x0, c0, ij, X, Y)
            wv.run([ij], X, Y, self._claimed(len(self.waves)), cb, deadline)
            self.waves.append(wv)
            self.seeds.append([k])

    def grow(self, before: tuple[int, int], old_shape: tuple[int, int], X: NDArray, Y: NDArray, cb,
             deadline: Deadline) -> None:
        """Pad every wave to the grown grid and resume it from its cells next to the new ones
        (the wave is not restarted)."""
        inner = (slice(before[0], before[0] + old_shape[0]), slice(before[1], before[1] + old_shape[1]))
        for wv in self.waves:
            wv.grow(before, (len(Y), len(X)))
        for k, wv in enumerate(self.waves):
            wv.run(wv.edge_front(inner), X, Y, self._claimed(k), cb, deadline)

    def maps(self) -> list[WorkspaceMap]:
        """The merged aspects, largest first."""
        m = self.m
        iu = m.layout.inputs
        raw = []
        seeds = [list(s) for s in self.seeds]
        for k, wv in enumerate(self.waves):
            r = wv.arrays()
            for q in sorted(wv.joins):
                _merge_into(r, raw[q])
            raw.append(r)
            for q in sorted(wv.joins):
                seeds[k].extend(seeds[q])
                seeds[q] = []
        maps = []
        for r, s in zip(raw, seeds):
            if not s:
                continue  # merged into a later one
            sol = r.pop("sol")
            reached = r["status"] == REACHED
            modes = np.zeros(sol.shape[:2] + (3,), np.int8)
            if np.any(reached):
                modes[reached] = rod_modes(m, sol[reached], r["charts"][reached])
            maps.append(WorkspaceMap(inputs=np.nan_to_num(sol[..., iu]), modes=modes, seeds=tuple(sorted(set(s))),
                                     zrod=np.nan_to_num(sol[..., :m.layout.n_rod]), boundary_edge=_ring(reached),
                                     **r))
        maps.sort(key=lambda mp: -mp.area_cells)
        return maps


def _grown(X: NDArray, Y: NDArray, u: NDArray[np.bool_]) -> tuple[NDArray, NDArray] | None:
    """The grid grown by half its size (same step) on every side the reached cells ``u``
    touch, or ``None`` if they do not touch the grid's edge."""
    h = X[1] - X[0] if len(X) > 1 else Y[1] - Y[0]
    sides = (u[:, 0].any(), u[:, -1].any(), u[0].any(), u[-1].any())
    if not any(sides):
        return None
    ax, ay = max(len(X) // 2, 2), max(len(Y) // 2, 2)
    x = np.concatenate([X[0] - h * np.arange(ax, 0, -1) if sides[0] else [], X,
                        X[-1] + h * np.arange(1, ax + 1) if sides[1] else []])
    y = np.concatenate([Y[0] - h * np.arange(ay, 0, -1) if sides[2] else [], Y,
                        Y[-1] + h * np.arange(1, ay + 1) if sides[3] else []])
    return (x, y) if len(x) * len(y) <= MAX_GRID_POINTS else None


def _feasible_starts(starts: list[tuple[int, NDArray, NDArray]], checks: _CellChecks, constrained: bool
                     ) -> tuple[list[tuple[int, NDArray, NDArray]], int]:
    """With ``constrained``, the seed solutions that meet the constraints, and how many did not."""
    if not constrained or not starts:
        return starts, 0
    _, bad = checks(np.array([s[1] for s in starts]), np.array([s[2] for s in starts]))
    return [s for s, b in zip(starts, bad) if not b], int(np.count_nonzero(bad))


def _seed_starts(mech: Any, pose: NDArray, w: NDArray, max_mode: int, all_aspects: bool, checks: _CellChecks,
                 constrained: bool, deadline: Deadline) -> tuple[list[tuple[int, NDArray, NDArray]], int]:
    """The stable IK solutions at ``pose`` as seeds ``(id, x, charts)`` (the first only unless
    ``all_aspects``; feasible ones only with ``constrained``), and how many were infeasible
    (the IK runs on the workspace's ``deadline``)."""
    res = ik(mech, pose, load=w, max_mode=max_mode, time_budget=deadline if deadline.limited else None)
    stable = [s for s in res.solutions if s.stable]
    starts, n_bad = _feasible_starts([(int(s.id), np.array(s.x), np.array(s.charts)) for s in stable], checks,
                                     constrained)
    return (starts if all_aspects else starts[:1]), n_bad


#: poses per grid axis sampled by the seed search (``seed_search=True``)
SEED_SEARCH_SAMPLES = 7


def _search_seed(mech: Any, X: NDArray, Y: NDArray, ij: tuple[int, int], th: float, w: NDArray, max_mode: int,
                 all_aspects: bool, checks: _CellChecks, constrained: bool, deadline: Deadline
                 ) -> tuple[tuple[tuple[int, int], list[tuple[int, NDArray, NDArray]]] | None, int]:
    """Seeds elsewhere on the orientation slice: the grid points of a
    :data:`SEED_SEARCH_SAMPLES` x :data:`SEED_SEARCH_SAMPLES` lattice over the grid, nearest to
    the requested seed cell ``ij`` first; the first with a (feasible, when ``constrained``)
    stable IK solution gives the seeds.  Returns ``((cell, starts) or None, poses tried)``."""
    k = SEED_SEARCH_SAMPLES
    ii = np.unique(np.rint(np.linspace(0, len(X) - 1, k + 2)[1:-1]).astype(int))
    jj = np.unique(np.rint(np.linspace(0, len(Y) - 1, k + 2)[1:-1]).astype(int))
    cells = [(j, i) for j in jj for i in ii if (j, i) != tuple(ij)]
    cells.sort(key=lambda c: (np.hypot(X[c[1]] - X[ij[1]], Y[c[0]] - Y[ij[0]]), c))
    tried = 0
    for j, i in cells:
        if deadline.expired():
            break
        tried += 1
        starts, _ = _seed_starts(mech, np.array([X[i], Y[j], th]), w, max_mode, all_aspects, checks, constrained,
                                 deadline)
        if starts:
            return ((int(j), int(i)), starts), tried
    return None, tried


def workspace(mech: Any, theta: float, seed: ArrayLike | Solution | None = None, load: ArrayLike | None = None,
              step: float | None = None, bounds: ArrayLike | None = None, max_mode: int = 2,
              all_aspects: bool = True, progress: bool | Callable[[int], None] = False,
              time_budget: float | Deadline | None = None, *, constrained: bool = False, collisions: bool = False,
              grow: int | None = None, stability: str = "full", seed_search: bool = False) -> Workspace:
    """Constant-orientation workspace of ``mech`` at orientation ``theta`` (rad).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    theta : float
        Platform orientation (rad).
    seed : (x, y) or Solution, optional
        Seed position (default (0, 0)); or one IK solution to start from (its orientation
        must be ``theta``), then only its aspect is mapped.
    load : (Fx, Fy, Mz), optional
        Defaults to the mechanism file's load.
    step : float, optional
        Grid step (m); default 1/100 of the bounding box's larger side.
    bounds : (x0, x1, y0, y1), optional
        Grid box (m); default: the legs' origins grown by a quarter rod length, then grown
        further while a region touches it (see ``grow``).
    max_mode : int
        Largest d-mode of the seed IK (along the wave the rods follow their branch into
        whatever d-modes it takes).
    all_aspects : bool
        Start from every stable seed solution (default) or only the first stable one (with
        ``constrained``, the first stable one that meets the constraints).
    progress : bool or callable
        ``True`` shows a tqdm progress bar; a callable receives the number of continuation
        steps of each wave.
    time_budget : float or Deadline, optional
        Seconds for the whole map (start-up excluded; see :mod:`flexkin.core.budget`): the
        seed IK, the waves with every cell's continuation, Jacobians, stability and checks,
        and the growth of the grid.  When they run out, the propagation stops, the maps hold
        what was reached, ``complete`` is False and ``message`` says so.
    constrained : bool
        Stop the wave at infeasible cells (inputs out of range, strain over the mechanism's
        ``max_strain``, collisions when ``collisions``); by default they are reached and
        marked (:attr:`WorkspaceMap.violations`).
    collisions : bool
        Also check rod-rod, self and rod-platform contact at every cell (a few ms per cell).
    grow : int, optional
        Largest number of times the grid grows (by half its size, same step) on the sides
        a region touches; default 3 with default ``bounds``, 0 with given ``bounds``.  Cells
        still on the edge are ``boundary_edge``.
    stability : {"full", "margins", "wave"}
        The stability verdict at every cell from the closed form (``"full"``, default; margins
        where it falls back), and with ``"margins"`` also the margin at every cell, carried
        along the wave (module docstring).  ``"wave"`` is a synonym of ``"full"``.
    seed_search : bool
        When the seed pose has no stable IK solution (with ``constrained``: no feasible one),
        look for seeds elsewhere on the orientation slice: the poses of a 7 x 7 lattice over
        the grid, nearest first; the first with one seeds every aspect there
        (:attr:`Workspace.seed` is the seed used, ``message`` says so).  The maps are empty
        only when no sampled pose has one.  Default ``False``: the seed pose only.

    Returns
    -------
    Workspace
    """
    t0 = time.perf_counter()
    dl = Deadline.of(time_budget)
    th = float(theta)
    if not np.isfinite(th):
        raise ValueError(f"theta must be finite, got {theta!r}")
    if stability not in ("full", "margins", "wave"):
        raise ValueError(f"stability must be 'full', 'margins' or 'wave', got {stability!r}")
    if stability == "wave":
        stability = "full"
    if grow is None:
        grow = 3 if bounds is None else 0
    if isinstance(grow, bool) or not isinstance(grow, (int, np.integer)) or grow < 0:
        raise ValueError(f"grow must be an integer >= 0, got {grow!r}")
    w = as_load(mech, load)
    m = System.from_mechanism(mech)
    X, Y = default_grid(mech, step, bounds)
    if isinstance(seed, Solution):
        if abs(wrap_to_pi(seed.pose[2] - th)) > 1e-9:
            raise ValueError("the seed solution's orientation differs from theta")
        sxy = np.array(seed.pose[:2])
    else:
        sxy = np.zeros(2) if seed is None else np.asarray(seed, dtype=float).reshape(-1)
        if sxy.shape != (2,) or not np.all(np.isfinite(sxy)):
            raise ValueError(f"seed must be two finite numbers (x, y), got {seed!r}")
    i0 = int(np.argmin(np.abs(X - sxy[0])))
    j0 = int(np.argmin(np.abs(Y - sxy[1])))
    if abs(X[i0] - sxy[0]) > X[1] - X[0] or abs(Y[j0] - sxy[1]) > Y[1] - Y[0]:
        raise ValueError(f"seed ({sxy[0]:g}, {sxy[1]:g}) lies outside the bounds")
    pose = np.array([X[i0], Y[j0], th])
    kinds = tuple(leg.actuation for leg in mech.legs)
    checks = _CellChecks(m, mech, collisions)
    meta = {"constraints": checks.names, "constrained": bool(constrained), "stability": stability}
    notes: list[str] = []
    if isinstance(seed, Solution):
        x = np.array(seed.x, dtype=float)
        x[m.layout.pose] = pose
        moved = refine(m, mech, x[None], np.array(seed.charts)[None], w, MAX_MODE_LIMIT, "pose")
        starts = [(int(seed.id), moved[0].x, moved[0].charts)] if moved else []
        starts, n_bad = _feasible_starts(starts, checks, constrained)
    else:
        max_mode = check_max_mode(max_mode)
        starts, n_bad = _seed_starts(mech, pose, w, max_mode, all_aspects, checks, constrained, dl)
    why = "no feasible stable IK solution" if n_bad else "no stable IK solution"
    if not starts and seed_search and not isinstance(seed, Solution) and not dl.hit:
        found, tried = _search_seed(mech, X, Y, (j0, i0), th, w, max_mode, all_aspects, checks, constrained, dl)
        if found is None:
            why = f"{why} at the seed pose ({X[i0]:.6g}, {Y[j0]:.6g}) nor at any of the {tried} other poses sampled " \
                  f"on the grid"
        else:
            notes.append(f"{why} at the seed pose ({X[i0]:.6g}, {Y[j0]:.6g}); seeded at "
                         f"({X[found[0][1]]:.6g}, {Y[found[0][0]]:.6g}) instead, the nearest of the {tried} poses "
                         f"sampled on the grid with one")
            (j0, i0), starts = found
            n_bad = 0
    elif not starts:
        why += " at the seed pose"
    if not starts:
        if dl.hit:
            why = dl.message("while looking for a seed")
        return Workspace(mech.name, kinds, th, tuple(map(float, w)), X, Y, (float(X[i0]), float(Y[j0])), (),
                         time.perf_counter() - t0, 0, why, complete=not dl.hit, **meta)
    if n_bad:
        notes.append(f"{n_bad} stable seed solution(s) infeasible at the seed pose: not mapped")
    bar = None
    cb: Callable[[int], None] | None = None
    if progress is True:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(X) * len(Y) * len(starts), unit="pt", desc=f"workspace theta={np.degrees(th):g} deg",
                   leave=False)
        cb = bar.update
    elif callable(progress):
        cb = progress
    aspects = _Aspects(m, starts, th, w, checks, constrained, stability == "margins")
    aspects.run((j0, i0), X, Y, cb, dl)
    grown = 0
    while grown < grow and not dl.expired():
        bigger = _grown(X, Y, aspects.reached())
        if bigger is None:
            break
        before = (int(np.count_nonzero(bigger[1] < Y[0])), int(np.count_nonzero(bigger[0] < X[0])))
        old_shape = (len(Y), len(X))
        j0 += before[0]
        i0 += before[1]
        X, Y = bigger
        aspects.grow(before, old_shape, X, Y, cb, dl)
        grown += 1
    maps, total = aspects.maps(), aspects.steps
    if bar is not None:
        bar.close()
    if dl.hit:
        notes.append(dl.message("the maps hold what was reached"))
    if any(mp.cut_by_grid for mp in maps):
        notes.append("the region reaches the grid's edge (boundary_edge cells): it is cut by the bounds, its areas "
                     "are lower bounds")
    return Workspace(mech.name, kinds, th, tuple(map(float, w)), X, Y, (float(X[i0]), float(Y[j0])), tuple(maps),
                     time.perf_counter() - t0, total, "; ".join(notes), grown=grown, complete=not dl.hit, **meta)


@dataclass(frozen=True)
class DexterousWorkspace:
    """The positions reachable at every orientation of a range (issue 15).

    Attributes
    ----------
    thetas : ndarray
        The orientations sampled (rad).
    x, y : ndarray
        Common grid (m); ``mask[j, i]`` is at ``(x[i], y[j])``.
    mask : (ny, nx) bool
        Cells reached by some aspect at every orientation.
    feasible_mask : (ny, nx) bool
        Cells reached by a feasible equilibrium at every orientation.
    workspaces : tuple of Workspace
        One per orientation.
    """

    thetas: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    mask: NDArray[np.bool_]
    feasible_mask: NDArray[np.bool_]
    workspaces: tuple[Workspace, ...]

    @property
    def step(self) -> float:
        """Grid step (m)."""
        return self.workspaces[0].step if self.workspaces else 0.0

    @property
    def area(self) -> float:
        """Area of the dexterous workspace (m^2)."""
        return float(np.count_nonzero(self.mask)) * self.step ** 2

    @property
    def feasible_area(self) -> float:
        """Area of the feasible dexterous workspace (m^2)."""
        return float(np.count_nonzero(self.feasible_mask)) * self.step ** 2

    @property
    def cut_by_grid(self) -> bool:
        """Whether a region at some orientation reaches its grid's edge (the areas are then
        lower bounds)."""
        return any(mp.cut_by_grid for ws in self.workspaces for mp in ws.maps)


def dexterous_workspace(mech: Any, thetas: ArrayLike, **kwargs: Any) -> DexterousWorkspace:
    """The dexterous workspace over the orientations ``thetas``: the grid points ``(x, y)``
    reached (by any aspect) at every orientation.

    All maps share one grid lattice (same step and origin; a grown grid stays on it), so the
    intersection is taken cell by cell.  Sample the orientation range finely enough for its
    purpose: a point is dexterous at the orientations sampled.

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    thetas : array_like
        Orientations (rad), at least one.
    **kwargs
        Passed to :func:`workspace` (``step``, ``bounds``, ``seed``, ``constrained``, ...).

    Returns
    -------
    DexterousWorkspace
    """
    th = np.atleast_1d(np.asarray(thetas, dtype=float))
    if th.ndim != 1 or th.size == 0 or not np.all(np.isfinite(th)):
        raise ValueError(f"thetas must be one or more finite orientations (rad), got {thetas!r}")
    wss = tuple(workspace(mech, float(t), **kwargs) for t in th)
    h = wss[0].step
    x0, y0 = max(ws.x[0] for ws in wss), max(ws.y[0] for ws in wss)
    x1, y1 = min(ws.x[-1] for ws in wss), min(ws.y[-1] for ws in wss)
    nx = max(int(round((x1 - x0) / h)) + 1, 0)
    ny = max(int(round((y1 - y0) / h)) + 1, 0)
    mask = np.ones((ny, nx), bool)
    feas = np.ones((ny, nx), bool)
    for ws in wss:
        i = int(round((x0 - ws.x[0]) / h))
        j = int(round((y0 - ws.y[0]) / h))
        mask &= ws.union()[j:j + ny, i:i + nx]
        feas &= ws.feasible_union()[j:j + ny, i:i + nx]
    return DexterousWorkspace(th, x0 + h * np.arange(nx), y0 + h * np.arange(ny), mask, feas, wss)
