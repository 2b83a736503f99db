"""Constant-orientation workspaces by wave propagation (paper §6, Fig. 17).

From one IK solution at a seed pose, the solution is continued over a square grid of
platform positions ``(x, y)`` at fixed orientation ``theta``: every wave takes the solved
points of the front, continues each of them to its 4 grid neighbours not yet visited
(:func:`~flexkin.kinematics.continuation.continue_ik`, all at once), and classifies the new
points.  Propagation stops

* across an **IK singularity**: the continuation fails (the branch folds back) or the
  smooth function ``det A_IK`` changes sign (black boundary);
* across an **FK singularity / loss of stability**: the new point is an unstable
  equilibrium or ``det A_FK`` changes sign (orange boundary; with the actuators locked the
  two coincide, paper §6).

d-mode changes of a rod are followed (every d-mode is one strip of the rod chart).  A cell
of the reached region is a boundary cell when one of its neighbours was not entered for one
of these reasons; cells beyond ``bounds`` are not boundaries.

Aspects: started from every stable IK solution at the seed pose, the maps of seeds whose
regions share a grid point with the same solution (inputs equal) are merged into one aspect.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..analysis.jacobian import kinematic_jacobians
from ..analysis.stability import mechanism_stability
from ..core.validation import check_budget, check_max_mode
from ..results import Solution
from ..rod.kernels import CHART_UNIFIED
from ..system import System
from .continuation import SEAM_V, continue_ik
from .finish import build_solutions, rod_modes
from .ik import as_load, ik, refine_ik

__all__ = ["workspace", "Workspace", "WorkspaceMap", "load_workspace", "REACHED", "UNSTABLE", "FAILED", "SEAM"]

#: status codes of a grid point
UNVISITED, REACHED, UNSTABLE, FAILED, SEAM = 0, 1, 2, 3, 4
_NEIGHBOURS = ((1, 0), (-1, 0), (0, 1), (0, -1))


@dataclass(frozen=True)
class WorkspaceMap:
    """The region reached from one seed solution (one aspect), on the grid of its
    :class:`Workspace`.  Arrays have shape ``(ny, nx)`` (``inputs``: ``(ny, nx, 3)``,
    ``modes``: ``(ny, nx, 3)``), with meaningful values where ``status == REACHED``.

    ``status``: 0 unvisited, 1 reached (stable equilibrium), 2 unstable (not entered),
    3 continuation failed (not entered), 4 not resolved: the step failed while a rod was
    close to straight under tension, where the elliptic chart has its seam (``|k| = 1``):
    a limitation of the rod parameterisation, not a singularity of the mechanism.
    ``boundary_seam``: reached cells next to such cells.  ``boundary_ik`` / ``boundary_fk``: reached cells
    with a neighbour not entered because of an IK singularity / an FK singularity or
    instability.  ``seeds``: indices (in the seed IK result) of the solutions merged here.
    """

    status: NDArray[np.int8]
    inputs: NDArray[np.float64]
    modes: NDArray[np.int8]
    margin: NDArray[np.float64]
    det_ik: NDArray[np.float64]
    det_fk: NDArray[np.float64]
    cond: NDArray[np.float64]
    boundary_ik: NDArray[np.bool_]
    boundary_fk: NDArray[np.bool_]
    seeds: tuple[int, ...]
    zrod: NDArray[np.float64] = field(repr=False, default=None)
    boundary_seam: NDArray[np.bool_] = field(repr=False, default=None)
    charts: NDArray[np.int64] = field(repr=False, default=None)

    @property
    def reached(self) -> NDArray[np.bool_]:
        return self.status == REACHED

    @property
    def area_cells(self) -> int:
        return int(np.count_nonzero(self.reached))


@dataclass(frozen=True)
class Workspace:
    """Constant-orientation workspace of a mechanism (see the module docstring).

    Attributes
    ----------
    mechanism_name : str
    theta : float
        Platform orientation (rad).
    load : (Fx, Fy, Mz)
    x, y : ndarray
        Grid coordinates (m); cell ``[j, i]`` is at ``(x[i], y[j])``.
    seed : (x, y)
        Seed position (snapped to the grid).
    maps : tuple of WorkspaceMap
        One per aspect (merged seeds), largest first.
    elapsed : float
        Seconds.
    steps : int
        Continuation steps attempted.
    """

    mechanism_name: str
    kinds: tuple[str, ...]
    theta: float
    load: tuple[float, float, float]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    seed: tuple[float, float]
    maps: tuple[WorkspaceMap, ...]
    elapsed: float = 0.0
    steps: int = 0
    message: str = ""

    @property
    def step(self) -> float:
        """Grid step (m)."""
        return float(self.x[1] - self.x[0]) if len(self.x) > 1 else 0.0

    def solution(self, mech, aspect: int, j: int, i: int) -> Solution:
        """The equilibrium mapped at cell ``[j, i]`` of aspect ``aspect`` (0-based), with its
        stability and Jacobians, as a :class:`~flexkin.results.Solution` of ``mech``."""
        mp = self.maps[aspect]
        if mp.status[j, i] != REACHED:
            raise ValueError(f"cell ({j}, {i}) was not reached in aspect {aspect}")
        system = System.from_mechanism(mech)
        lay = system.layout
        x = np.zeros(lay.n_unknowns)
        x[:lay.n_rod] = mp.zrod[j, i]
        x[lay.pose] = (self.x[i], self.y[j], self.theta)
        x[lay.inputs] = mp.inputs[j, i]
        ch = mp.charts[j, i] if mp.charts is not None else system.default_charts(1)[0]
        return build_solutions(system, mech, x[None], ch[None], np.asarray(self.load))[0]

    def union(self) -> NDArray[np.bool_]:
        """Cells reached by any aspect."""
        out = np.zeros((len(self.y), len(self.x)), bool)
        for m in self.maps:
            out |= m.reached
        return out

    def save(self, path: str) -> None:
        """Save to a ``.npz`` file (:func:`load_workspace` reads it back)."""
        data: dict[str, Any] = {"mechanism_name": self.mechanism_name, "kinds": np.array(self.kinds),
                                "theta": self.theta, "load": np.array(self.load), "x": self.x, "y": self.y,
                                "seed": np.array(self.seed), "elapsed": self.elapsed, "steps": self.steps,
                                "message": self.message, "n_maps": len(self.maps)}
        for k, m in enumerate(self.maps):
            for name in ("status", "inputs", "modes", "margin", "det_ik", "det_fk", "cond", "boundary_ik",
                         "boundary_fk", "zrod", "boundary_seam", "charts"):
                data[f"map{k}_{name}"] = getattr(m, name)
            data[f"map{k}_seeds"] = np.array(m.seeds)
        np.savez_compressed(path, **data)

    def summary(self) -> str:
        """One line per aspect: cells reached, area, d-mode combinations, boundary cells."""
        h = self.step
        lines = [f"{self.mechanism_name}: workspace at theta = {np.degrees(self.theta):g} deg, grid "
                 f"{len(self.x)} x {len(self.y)} (step {h:g} m), {len(self.maps)} aspect(s), "
                 f"{self.steps} continuation steps in {self.elapsed:.1f} s"]
        for k, m in enumerate(self.maps):
            r = m.reached
            combos = sorted({"".join(map(str, q)) for q in m.modes[r]})
            lines.append(f"  aspect {k + 1} (seed solutions {', '.join(str(s + 1) for s in m.seeds)}): "
                         f"{int(r.sum())} cells, area {r.sum() * h * h:.4g} m^2, d-modes {', '.join(combos)}; "
                         f"boundary cells: IK {int(m.boundary_ik.sum())}, FK/instability {int(m.boundary_fk.sum())}, "
                         f"unresolved (rod straight under tension) {int(m.boundary_seam.sum())}")
        if self.message:
            lines.append(self.message)
        return "\n".join(lines)

    def plot(self, path: str | None = None, **kwargs: Any):
        """Figure like the paper's Fig. 17 (see :func:`flexkin.plot.workspace.plot_workspace`)."""
        from .plot.workspace import plot_workspace

        return plot_workspace([self], path=path, **kwargs)


def load_workspace(path: str) -> Workspace:
    """Read a workspace written by :meth:`Workspace.save`."""
    d = np.load(path, allow_pickle=False)
    maps = []
    for k in range(int(d["n_maps"])):
        g = {name: d[f"map{k}_{name}"] for name in ("status", "inputs", "modes", "margin", "det_ik", "det_fk", "cond",
                                                      "boundary_ik", "boundary_fk", "zrod", "boundary_seam", "charts")}
        maps.append(WorkspaceMap(seeds=tuple(int(s) for s in d[f"map{k}_seeds"]), **g))
    return Workspace(str(d["mechanism_name"]), tuple(str(k) for k in d["kinds"]), float(d["theta"]),
                     tuple(float(v) for v in d["load"]), d["x"], d["y"], tuple(float(v) for v in d["seed"]),
                     tuple(maps), float(d["elapsed"]), int(d["steps"]), str(d["message"]))


def default_grid(mech, step: float | None = None, bounds: ArrayLike | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Grid from ``bounds = (x0, x1, y0, y1)`` (default: the box of the legs' origins, grown
    by the rods' length) and ``step`` (default: 1/100 of the box's larger side)."""
    if bounds is None:
        o = np.array([leg.origin for leg in mech.legs], dtype=float)
        L = max((leg.rod.length or 0.0) for leg in mech.legs) or float(mech.length_scale)
        lo, hi = o.min(0) - 0.25 * L, o.max(0) + 0.25 * L
        bounds = (lo[0], hi[0], lo[1], hi[1])
    b = np.asarray(bounds, dtype=float).reshape(-1)
    if b.shape != (4,) or not np.all(np.isfinite(b)) or b[1] <= b[0] or b[3] <= b[2]:
        raise ValueError(f"bounds must be four finite numbers x0 < x1, y0 < y1, got {bounds!r}")
    if step is None:
        step = max(b[1] - b[0], b[3] - b[2]) / 100.0
    step = float(step)
    if not np.isfinite(step) or step <= 0:
        raise ValueError(f"step must be a finite number > 0, got {step!r}")
    nx = int(np.floor((b[1] - b[0]) / step + 1e-9)) + 1
    ny = int(np.floor((b[3] - b[2]) / step + 1e-9)) + 1
    if nx * ny > 4_000_000:
        raise ValueError(f"grid of {nx} x {ny} points is too large: increase step or shrink bounds")
    return b[0] + step * np.arange(nx), b[2] + step * np.arange(ny)


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


def _propagate(m: System, x0: NDArray, c0: NDArray, seed_ij: tuple[int, int], X: NDArray, Y: NDArray,
               theta: float, w: NDArray, claimed: list[tuple[NDArray, NDArray]],
               progress: Callable[[int], None] | None,
               deadline: float | None = None) -> tuple[dict[str, NDArray], int, set[int]]:
    """Wave propagation of one seed. Returns the map arrays, the number of continuation
    steps, and the indices of earlier maps that this one joins (same solution at a cell)."""
    ny, nx = len(Y), len(X)
    status = np.zeros((ny, nx), np.int8)
    lay = m.layout
    nu = lay.n_unknowns
    sol = np.full((ny, nx, nu), np.nan)
    chs = np.zeros((ny, nx, 3), np.int64)
    margin = np.zeros((ny, nx))
    dik = np.full((ny, nx), np.inf)
    dfk = np.full((ny, nx), np.inf)
    cond = np.full((ny, nx), np.inf)
    sik = np.zeros((ny, nx))
    sfk = np.zeros((ny, nx))
    bik = np.zeros((ny, nx), bool)
    bfk = np.zeros((ny, nx), bool)
    bseam = np.zeros((ny, nx), bool)
    su = m.input_scale()
    iu = lay.inputs
    joins: set[int] = set()

    def record(xs, cs):
        return mechanism_stability(m, xs, cs), kinematic_jacobians(m, xs, cs, w)

    j0, i0 = seed_ij
    x0 = x0.copy()
    x0[lay.pose] = (X[i0], Y[j0], theta)
    st, jac = record(x0[None], c0[None])
    status[j0, i0] = REACHED
    sol[j0, i0] = x0
    chs[j0, i0] = c0
    margin[j0, i0], dik[j0, i0], dfk[j0, i0], cond[j0, i0] = st.margin[0], jac.det_ik[0], jac.det_fk[0], jac.cond[0]
    sik[j0, i0], sfk[j0, i0] = jac.sing_ik[0], jac.sing_fk[0]
    front = [(j0, i0)]
    steps = 0
    while front:
        if deadline is not None and time.perf_counter() > deadline:
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
        S = np.array(src)
        D = np.array(dst)
        xs = sol[S[:, 0], S[:, 1]]
        cs = chs[S[:, 0], S[:, 1]]
        p1 = np.stack([X[D[:, 1]], Y[D[:, 0]], np.full(len(D), theta)], -1)
        xn, cn, ok = _continue_adaptive(m, xs, cs, p1, w)
        steps += len(D)
        new_front = []
        if np.any(ok):
            idx = np.flatnonzero(ok)
            st, jac = record(xn[idx], cn[idx])
            for k, r in enumerate(idx):
                jj, ii = D[r]
                j, i = S[r]
                crossed_ik = np.sign(jac.sing_ik[k]) != np.sign(sik[j, i])
                crossed_fk = np.sign(jac.sing_fk[k]) != np.sign(sfk[j, i])
                if crossed_ik:
                    status[jj, ii] = FAILED
                    bik[j, i] = True
                elif st.stable[k] != 1 or crossed_fk:
                    status[jj, ii] = UNSTABLE
                    bfk[j, i] = True
                else:
                    status[jj, ii] = REACHED
                    sol[jj, ii] = xn[r]
                    chs[jj, ii] = cn[r]
                    margin[jj, ii], dik[jj, ii], dfk[jj, ii] = st.margin[k], jac.det_ik[k], jac.det_fk[k]
                    cond[jj, ii], sik[jj, ii], sfk[jj, ii] = jac.cond[k], jac.sing_ik[k], jac.sing_fk[k]
                    # joining a region mapped from an earlier seed: same solution at this cell
                    hit = False
                    for q, (st_q, sol_q) in enumerate(claimed):
                        if st_q[jj, ii] == REACHED and np.max(np.abs(sol_q[jj, ii, iu] - xn[r, iu]) / su) < 1e-6:
                            joins.add(q)
                            hit = True
                    if not hit:
                        new_front.append((jj, ii))
        for r in np.flatnonzero(~ok):
            jj, ii = D[r]
            j, i = S[r]
            taut = np.array([(cs[r, i] == CHART_UNIFIED and abs(xs[r, lay.rod[i].start]) > SEAM_V) or cs[r, i] == 1
                             for i in range(3)])
            if np.any(taut) and not np.any(taut & m.angular):
                # a rod of a prismatic or length leg is close to straight under tension, where
                # the elliptic chart has its seam: the step failed for the chart, not for the
                # mechanism (a revolute leg's taut rod is at its reach |B - A| = L instead:
                # a true boundary)
                if status[jj, ii] == UNVISITED:
                    status[jj, ii] = SEAM
                bseam[j, i] = True
                continue
            if status[jj, ii] in (UNVISITED, SEAM):
                status[jj, ii] = FAILED
            bik[j, i] = True
        if progress is not None:
            progress(len(D))
        front = new_front
    # a neighbour reached from elsewhere later does not make a cell a boundary
    reached = status == REACHED
    bik &= reached
    bfk &= reached
    bseam &= reached & ~bik & ~bfk
    return ({"status": status, "sol": sol, "charts": chs, "margin": margin, "det_ik": dik, "det_fk": dfk, "cond": cond,
             "boundary_ik": bik, "boundary_fk": bfk, "boundary_seam": bseam}, steps, joins)


def workspace(mech, theta: float, seed: ArrayLike | Solution | None = None, load: ArrayLike | None = None,
              step: float | None = None, bounds: ArrayLike | None = None, max_mode: int = 2,
              all_aspects: bool = True, progress: bool | Callable[[int], None] = False,
              time_budget: float | None = None) -> Workspace:
    """Constant-orientation workspace of ``mech`` at orientation ``theta`` (rad).

    Parameters
    ----------
    mech : Mechanism
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
        Grid box (m); default: the legs' origins grown by a quarter rod length.
    max_mode : int
        Largest d-mode for the seed IK (continuation may then enter higher modes? no:
        rods follow their branch; modes are whatever the branch takes).
    all_aspects : bool
        Start from every stable seed solution (default) or only the first stable one.
    progress : bool or callable
        ``True`` shows a tqdm progress bar; a callable receives the number of continuation
        steps of each wave.
    time_budget : float, optional
        Seconds; when they run out the propagation stops and ``message`` says so (the maps
        hold what was reached).

    Returns
    -------
    Workspace
    """
    t0 = time.perf_counter()
    deadline = None if time_budget is None else t0 + check_budget(time_budget)
    th = float(theta)
    if not np.isfinite(th):
        raise ValueError(f"theta must be finite, got {theta!r}")
    w = as_load(mech, load)
    m = System.from_mechanism(mech)
    X, Y = default_grid(mech, step, bounds)
    if isinstance(seed, Solution):
        if abs(((seed.pose[2] - th) + np.pi) % (2 * np.pi) - np.pi) > 1e-9:
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
    if isinstance(seed, Solution):
        x = np.array(seed.x, dtype=float)
        x[m.layout.pose] = pose
        moved = refine_ik(m, mech, x[None], np.array(seed.charts)[None], w, 6)
        starts = [(0, moved[0].x, moved[0].charts)] if moved else []
    else:
        res = ik(mech, pose, load=w, max_mode=check_max_mode(max_mode))
        res_sols = list(res.solutions)
        stable = [k for k, s in enumerate(res_sols) if s.stable]
        if not all_aspects:
            stable = stable[:1]
        starts = [(k, np.array(res_sols[k].x), np.array(res_sols[k].charts)) for k in stable]
    if not starts:
        return Workspace(mech.name, kinds, th, tuple(map(float, w)), X, Y, (float(X[i0]), float(Y[j0])), (),
                         time.perf_counter() - t0, 0, "no stable IK solution at the seed pose")
    bar = None
    cb: Callable[[int], None] | None = None
    if progress is True:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(X) * len(Y) * len(starts), unit="pt", desc=f"workspace theta={np.degrees(th):g} deg",
                   leave=False)
        cb = bar.update
    elif callable(progress):
        cb = progress
    raw: list[dict[str, NDArray]] = []
    seeds: list[list[int]] = []
    claimed: list[tuple[NDArray, NDArray]] = []
    total = 0
    iu = m.layout.inputs
    for k, x0, c0 in starts:
        # a seed already inside a mapped region (same solution at the seed cell) adds nothing
        dup = [q for q, (st_q, sol_q) in enumerate(claimed)
               if st_q[j0, i0] == REACHED and np.allclose(sol_q[j0, i0, iu], x0[iu], atol=1e-9 * m.L_ref)]
        if dup:
            seeds[dup[0]].append(k)
            continue
        if deadline is not None and time.perf_counter() > deadline:
            break
        maps_k, n, joins = _propagate(m, x0, c0, (j0, i0), X, Y, th, w, claimed, cb, deadline)
        total += n
        raw.append(maps_k)
        seeds.append([k])
        claimed.append((maps_k["status"], maps_k["sol"]))
        for q in sorted(joins):
            seeds[-1].extend(seeds[q])
            seeds[q] = []
    if bar is not None:
        bar.close()
    maps = []
    for r, s in zip(raw, seeds):
        if not s:
            continue  # merged into a later one
        sol = r["sol"]
        reached = r["status"] == REACHED
        modes = np.zeros(sol.shape[:2] + (3,), np.int8)
        if np.any(reached):
            modes[reached] = rod_modes(m, sol[reached], r["charts"][reached])
        maps.append(WorkspaceMap(r["status"], np.nan_to_num(sol[..., m.layout.inputs]), modes, r["margin"],
                                 r["det_ik"], r["det_fk"], r["cond"], r["boundary_ik"], r["boundary_fk"],
                                 tuple(sorted(set(s))), np.nan_to_num(sol[..., :m.layout.n_rod]), r["boundary_seam"],
                                 r["charts"]))
    # merged maps: a map joined by a later seed is reported within that later map's union
    maps.sort(key=lambda mp: -mp.area_cells)
    msg = ("time budget exhausted: the maps hold what was reached"
           if deadline is not None and time.perf_counter() > deadline else "")
    return Workspace(mech.name, kinds, th, tuple(map(float, w)), X, Y, (float(X[i0]), float(Y[j0])), tuple(maps),
                     time.perf_counter() - t0, total, msg)
