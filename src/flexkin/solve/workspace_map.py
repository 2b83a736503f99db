"""The constant-orientation workspace as data: the maps of the aspects, their status codes,
the ``.npz`` file (:meth:`Workspace.save`, :func:`load_workspace`), the workspace-level metrics
and the distance of every reached cell to the nearest singularity.

:func:`flexkin.solve.workspace.workspace` computes a :class:`Workspace` (the wave propagation,
paper §6, Fig. 17); this module knows what one holds, not how it was mapped.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..analysis.stability import Eigenpairs, mechanism_stability
from ..results import Solution
from ..system import System
from .finish import build_solutions

__all__ = ["Workspace", "WorkspaceMap", "load_workspace", "singularity_distance_map", "UNVISITED", "REACHED",
           "UNSTABLE", "FAILED", "SEAM", "INFEASIBLE", "VIOLATION_RANGE", "VIOLATION_STRAIN", "VIOLATION_COLLISION"]

#: status codes of a grid point
UNVISITED, REACHED, UNSTABLE, FAILED, SEAM, INFEASIBLE = 0, 1, 2, 3, 4, 5
#: bits of :attr:`WorkspaceMap.violations`
VIOLATION_RANGE, VIOLATION_STRAIN, VIOLATION_COLLISION = 1, 2, 4
_NEIGHBOURS = ((1, 0), (-1, 0), (0, 1), (0, -1))
#: map arrays stored by :meth:`Workspace.save`
_MAP_ARRAYS = ("status", "inputs", "modes", "margin", "det_ik", "det_fk", "cond", "boundary_ik", "boundary_fk",
               "zrod", "boundary_seam", "charts", "violations", "strain", "boundary_infeasible", "boundary_edge")


def _ring(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``mask`` restricted to the grid's outermost rows and columns."""
    out = np.zeros_like(mask)
    out[0, :], out[-1, :], out[:, 0], out[:, -1] = mask[0, :], mask[-1, :], mask[:, 0], mask[:, -1]
    return out


def _stats(v: ArrayLike) -> dict[str, float | None]:
    """``min``/``mean``/``max`` of the finite values (``None`` when there are none)."""
    a = np.asarray(v, dtype=float).ravel()
    a = a[np.isfinite(a)]
    if not a.size:
        return {"min": None, "mean": None, "max": None}
    return {"min": float(a.min()), "mean": float(a.mean()), "max": float(a.max())}


@dataclass(frozen=True)
class WorkspaceMap:
    """The region reached from one seed solution (one aspect), on the grid of its
    :class:`Workspace`.  Arrays have shape ``(ny, nx)`` (``inputs``, ``modes``, ``charts``:
    ``(ny, nx, 3)``), with meaningful values where ``status == REACHED``.

    Attributes
    ----------
    status : (ny, nx) int8
        0 unvisited, 1 reached (stable equilibrium), 2 unstable or FK singularity crossed
        (not entered), 3 continuation failed or IK singularity crossed (not entered), 4 not
        resolved: the step failed while a rod was close to straight under tension, where the
        elliptic chart has its seam (``|k| = 1``; a limitation of the rod parameterisation,
        not a singularity of the mechanism), 5 infeasible (not entered; only with
        ``constrained=True``).
    inputs : (ny, nx, 3) float
        Actuator inputs (m, rad).
    modes : (ny, nx, 3) int8
        d-modes of the rods.
    margin : (ny, nx) float
        Stability margin (smallest eigenvalue of the dimensionless second variation); ``NaN``
        where it was not computed (:mod:`flexkin.solve.workspace`).
    det_ik, det_fk, cond : (ny, nx) float
        ``det J_IK``, ``det J_FK`` and the condition number of ``J_FK`` (dimensionless,
        :mod:`flexkin.analysis.jacobian`).
    boundary_ik, boundary_fk : (ny, nx) bool
        Reached cells with a neighbour not entered because of an IK singularity / an FK
        singularity or instability.
    seeds : tuple of int
        The ids (1-based, as ``flexkin.ik`` numbers them at the seed pose) of the seed
        solutions merged here.
    zrod : (ny, nx, n_rod) float
        Rod chart coordinates.
    boundary_seam : (ny, nx) bool
        Reached cells next to unresolved ones.
    charts : (ny, nx, 3) int
        Rod charts.
    violations : (ny, nx) int8
        Constraints violated at a reached (or, constrained, refused) cell: bits
        :data:`VIOLATION_RANGE`, :data:`VIOLATION_STRAIN`, :data:`VIOLATION_COLLISION`.
    strain : (ny, nx) float
        Peak bending strain over the rods (``NaN`` without rod radii).
    boundary_infeasible : (ny, nx) bool
        Feasible reached cells with an infeasible neighbour (reached or refused).
    boundary_edge : (ny, nx) bool
        Reached cells on the grid's outermost rows/columns: the region is cut by the bounds.
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
    violations: NDArray[np.int8] = field(repr=False, default=None)
    strain: NDArray[np.float64] = field(repr=False, default=None)
    boundary_infeasible: NDArray[np.bool_] = field(repr=False, default=None)
    boundary_edge: NDArray[np.bool_] = field(repr=False, default=None)

    def __post_init__(self) -> None:
        shape = self.status.shape
        defaults = {"violations": np.zeros(shape, np.int8), "strain": np.full(shape, np.nan),
                    "boundary_seam": np.zeros(shape, bool), "boundary_infeasible": np.zeros(shape, bool),
                    "boundary_edge": _ring(self.status == REACHED)}
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)

    @property
    def reached(self) -> NDArray[np.bool_]:
        """Cells reached (stable equilibria of this aspect)."""
        return self.status == REACHED

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """Reached cells that meet every constraint checked."""
        return self.reached & (self.violations == 0)

    @property
    def area_cells(self) -> int:
        """Number of reached cells."""
        return int(np.count_nonzero(self.reached))

    @property
    def feasible_cells(self) -> int:
        """Number of feasible reached cells."""
        return int(np.count_nonzero(self.feasible))

    @property
    def cut_by_grid(self) -> bool:
        """Whether the region reaches the grid's edge (it may continue beyond the bounds)."""
        return bool(np.any(self.boundary_edge))


@dataclass(frozen=True)
class Workspace:
    """Constant-orientation workspace of a mechanism (:mod:`flexkin.solve.workspace`).

    Attributes
    ----------
    mechanism_name : str
        The mechanism's name.
    kinds : tuple of str
        The legs' actuation kinds.
    theta : float
        Platform orientation (rad).
    load : (Fx, Fy, Mz)
        Load wrench at P (N, N, N m).
    x, y : ndarray
        Grid coordinates (m); cell ``[j, i]`` is at ``(x[i], y[j])``.
    seed : (x, y)
        The seed position used (snapped to the grid; with ``seed_search``, where seeds were
        found).
    maps : tuple of WorkspaceMap
        One per aspect (merged seeds), largest first.
    elapsed : float
        Seconds.
    steps : int
        Continuation steps attempted.
    message : str
        Why the maps may be incomplete (empty when they are not).
    complete : bool
        False when the time budget ran out: the maps hold what was reached by then (the
        regions may be larger).
    constraints : tuple of str
        The constraints checked at every cell: ``"ranges"``, ``"strain"``, ``"collisions"``.
    constrained : bool
        Whether the wave stopped at infeasible cells (the maps then hold feasible cells only).
    stability : str
        ``"full"`` or ``"margins"`` (:mod:`flexkin.solve.workspace`).
    grown : int
        How many times the default bounds were grown for the region to close.
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
    constraints: tuple[str, ...] = ()
    constrained: bool = False
    stability: str = "full"
    grown: int = 0
    complete: bool = True

    @property
    def step(self) -> float:
        """Grid step (m)."""
        return float(self.x[1] - self.x[0]) if len(self.x) > 1 else 0.0

    @property
    def region(self) -> str:
        """Which region the maps and every area measure."""
        checks = ", ".join(self.constraints) if self.constraints else "none available"
        if self.constrained:
            return f"feasible only (wave stopped at infeasible cells; checked: {checks})"
        return f"all stable equilibria reached (constraints not applied; checked per cell: {checks})"

    def solution(self, mech: Any, aspect: int, j: int, i: int) -> Solution:
        """The equilibrium mapped at cell ``[j, i]`` of an aspect, with its stability and
        Jacobians.

        Parameters
        ----------
        mech : Mechanism
            The mechanism the workspace was computed for.
        aspect : int
            Index of the aspect (0-based).
        j, i : int
            Row (y) and column (x) of the cell.

        Returns
        -------
        Solution
        """
        mp = self.maps[aspect]
        if mp.status[j, i] != REACHED:
            raise ValueError(f"cell ({j}, {i}) was not reached in aspect {aspect}")
        system = System.from_mechanism(mech)
        x, ch = _cell_unknowns(system, self, mp, np.array([j]), np.array([i]))
        return build_solutions(system, mech, x, ch, np.asarray(self.load))[0]

    def union(self) -> NDArray[np.bool_]:
        """Cells reached by any aspect."""
        out = np.zeros((len(self.y), len(self.x)), bool)
        for m in self.maps:
            out |= m.reached
        return out

    def feasible_union(self) -> NDArray[np.bool_]:
        """Feasible cells reached by any aspect."""
        out = np.zeros((len(self.y), len(self.x)), bool)
        for m in self.maps:
            out |= m.feasible
        return out

    def save(self, path: str) -> None:
        """Save to a ``.npz`` file (:func:`load_workspace` reads it back).

        Parameters
        ----------
        path : str
            File name.
        """
        data: dict[str, Any] = {"mechanism_name": self.mechanism_name, "kinds": np.array(self.kinds),
                                "theta": self.theta, "load": np.array(self.load), "x": self.x, "y": self.y,
                                "seed": np.array(self.seed), "elapsed": self.elapsed, "steps": self.steps,
                                "message": self.message, "n_maps": len(self.maps),
                                "constraints": np.array(self.constraints, dtype=str),
                                "constrained": self.constrained, "stability": self.stability, "grown": self.grown,
                                "complete": self.complete}
        for k, m in enumerate(self.maps):
            for name in _MAP_ARRAYS:
                data[f"map{k}_{name}"] = getattr(m, name)
            data[f"map{k}_seed_ids"] = np.array(m.seeds, dtype=np.int64)  # 1-based solution ids
        np.savez_compressed(path, **data)

    def summary(self) -> str:
        """One line per aspect: cells reached, area, d-mode combinations, boundary cells."""
        h = self.step
        lines = [f"{self.mechanism_name}: workspace at theta = {np.degrees(self.theta):g} deg, grid "
                 f"{len(self.x)} x {len(self.y)} (step {h:g} m), {len(self.maps)} aspect(s), "
                 f"{self.steps} continuation steps in {self.elapsed:.1f} s",
                 f"  region: {self.region}"]
        if self.grown:
            lines.append(f"  bounds grown {self.grown} time(s) for the region to close")
        for k, m in enumerate(self.maps):
            r = m.reached
            combos = sorted({"".join(map(str, q)) for q in m.modes[r]})
            feas = "" if self.constrained or not self.constraints else \
                f" ({m.feasible_cells} feasible, {m.feasible_cells * h * h:.4g} m^2)"
            lines.append(f"  aspect {k + 1} (seed solutions {', '.join(str(s) for s in m.seeds)}): "
                         f"{int(r.sum())} cells, area {r.sum() * h * h:.4g} m^2{feas}, d-modes {', '.join(combos)}; "
                         f"boundary cells: IK {int(m.boundary_ik.sum())}, FK/instability {int(m.boundary_fk.sum())}, "
                         f"infeasible {int(m.boundary_infeasible.sum())}, grid edge {int(m.boundary_edge.sum())}, "
                         f"unresolved (rod straight under tension) {int(m.boundary_seam.sum())}")
        if self.message:
            lines.append(self.message)
        return "\n".join(lines)

    def plot(self, path: str | None = None, **kwargs: Any) -> Any:
        """Figure like the paper's Fig. 17 (see :func:`flexkin.plot.workspace.plot_workspace`).

        Parameters
        ----------
        path : str, optional
            Save the figure (and its further pages) there.
        **kwargs
            Passed to :func:`~flexkin.plot.workspace.plot_workspace`.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ..plot.workspace import plot_workspace

        return plot_workspace([self], path=path, **kwargs)

    def margins(self, mech: Any) -> tuple[NDArray[np.float64], ...]:
        """The stability margin of every reached cell of every aspect (computed where the wave
        left it ``NaN``; the maps are not modified).

        Parameters
        ----------
        mech : Mechanism
            The mechanism the workspace was computed for.

        Returns
        -------
        tuple of (ny, nx) ndarray
            One per aspect, ``NaN`` outside the reached cells.
        """
        system = System.from_mechanism(mech)
        return tuple(_fill_margins(system, self, mp) for mp in self.maps)

    def metrics(self, mech: Any = None) -> dict[str, Any]:
        """Workspace-level metrics at this orientation (issue 15; all areas in m^2 over the
        region named by ``region``).

        Keys: ``theta_deg``, ``step``, ``region``, ``n_aspects``, ``aspect_areas`` (one per
        aspect, largest first), ``aspect_feasible_areas``, ``workspace_area`` (union of the
        aspects), ``feasible_area`` (union of their feasible cells), ``singularity_free_area``
        (the largest aspect: reached from a seed solution without crossing an IK or FK
        singularity), ``cut_by_grid`` (a region reaches the bounds: the areas are lower bounds),
        and over the reached cells of the largest aspect ``{"min", "mean", "max"}`` dicts of
        ``stability_margin`` (all margins computed when ``mech`` is given, else only the
        known ones), ``abs_det_ik``, ``abs_det_fk``, ``cond`` and ``strain``, the ratios
        ``det_ik_ratio`` / ``det_fk_ratio`` (smallest over largest ``|det J|``: 1 for a
        uniform map, near 0 close to a singularity), and ``max_strain`` (over every aspect).
        Undefined values are ``None``.

        Parameters
        ----------
        mech : Mechanism, optional
            Needed for the stability margins that the wave did not compute.

        Returns
        -------
        dict
        """
        h2 = self.step ** 2
        out: dict[str, Any] = {"theta_deg": float(np.degrees(self.theta)), "step": self.step, "region": self.region,
                               "n_aspects": len(self.maps),
                               "aspect_areas": [m.area_cells * h2 for m in self.maps],
                               "aspect_feasible_areas": [m.feasible_cells * h2 for m in self.maps],
                               "workspace_area": float(self.union().sum()) * h2,
                               "feasible_area": float(self.feasible_union().sum()) * h2,
                               "singularity_free_area": (self.maps[0].area_cells * h2) if self.maps else 0.0,
                               "cut_by_grid": any(m.cut_by_grid for m in self.maps)}
        strains = [m.strain[m.reached] for m in self.maps]
        out["max_strain"] = _stats(np.concatenate(strains) if strains else [])["max"]
        mp = self.maps[0] if self.maps else None
        r = mp.reached if mp is not None else None
        margin = (self.margins(mech)[0] if mech is not None else mp.margin) if mp is not None else None
        for key, val in (("stability_margin", margin), ("abs_det_ik", None if mp is None else np.abs(mp.det_ik)),
                         ("abs_det_fk", None if mp is None else np.abs(mp.det_fk)),
                         ("cond", None if mp is None else mp.cond), ("strain", None if mp is None else mp.strain)):
            out[key] = _stats([] if val is None else val[r])
        for key in ("ik", "fk"):
            s = out[f"abs_det_{key}"]
            out[f"det_{key}_ratio"] = s["min"] / s["max"] if s["max"] else None
        return out


def _fill_margins(system: System, ws: "Workspace", mp: WorkspaceMap) -> NDArray[np.float64]:
    """The margins of the reached cells of ``mp`` where they are ``NaN``, computed layer by
    layer outwards from the reached cell nearest the seed, each cell's eigenvector started
    from a computed neighbour's (:class:`~flexkin.analysis.stability.Eigenpairs`)."""
    mg = np.where(mp.reached, mp.margin, np.nan)
    todo = mp.reached & ~np.isfinite(mg)
    if not np.any(todo):
        return mg
    jj, ii = np.nonzero(mp.reached)
    d2 = (ws.x[ii] - ws.seed[0]) ** 2 + (ws.y[jj] - ws.seed[1]) ** 2
    start = (int(jj[np.argmin(d2)]), int(ii[np.argmin(d2)]))
    ny, nx = mp.status.shape
    done = np.zeros((ny, nx), bool)
    pairs: dict[tuple[int, int], tuple] = {}
    layer, parent = [start], [None]
    done[start] = True
    while layer:
        J = np.array([c[0] for c in layer])
        I = np.array([c[1] for c in layer])
        x, ch = _cell_unknowns(system, ws, mp, J, I)
        width = max([pairs[p][1].shape[1] for p in parent if p is not None] + [1])
        G = Eigenpairs(np.zeros((len(layer), 3), np.int64), np.zeros((len(layer), 3, width)),
                       np.zeros((len(layer), 3)), np.zeros(len(layer), bool))
        for k, p in enumerate(parent):
            if p is not None:
                E, R, P, V = pairs[p]
                G.elements[k], G.pose[k], G.valid[k] = E, P, V
                G.rods[k, :, :R.shape[1]] = R
        st = mechanism_stability(system, x, ch, margin=True, guess=G)
        new_pairs = {}
        for k, c in enumerate(layer):
            if todo[c]:
                mg[c] = st.margin[k]
            new_pairs[c] = (st.pairs.elements[k], st.pairs.rods[k], st.pairs.pose[k], st.pairs.valid[k])
        pairs = new_pairs
        nxt, par = [], []
        for c in layer:
            for dj, di in _NEIGHBOURS:
                q = (c[0] + dj, c[1] + di)
                if 0 <= q[0] < ny and 0 <= q[1] < nx and mp.reached[q] and not done[q]:
                    done[q] = True
                    nxt.append(q)
                    par.append(c)
        layer, parent = nxt, par
    return mg


def _cell_unknowns(system: System, ws: Workspace, mp: WorkspaceMap, jj: NDArray, ii: NDArray
                   ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The unknowns and charts of cells ``(jj[k], ii[k])`` of map ``mp``."""
    lay = system.layout
    x = np.zeros((len(jj), lay.n_unknowns))
    x[:, :lay.n_rod] = mp.zrod[jj, ii]
    x[:, lay.pose] = np.stack([ws.x[ii], ws.y[jj], np.full(len(jj), ws.theta)], -1)
    x[:, lay.inputs] = mp.inputs[jj, ii]
    ch = mp.charts[jj, ii] if mp.charts is not None else system.default_charts(len(jj))
    return x, np.asarray(ch, dtype=np.int64)


def load_workspace(path: str) -> Workspace:
    """Read a workspace written by :meth:`Workspace.save`.

    Parameters
    ----------
    path : str
        The ``.npz`` file.

    Returns
    -------
    Workspace
    """
    d = np.load(path, allow_pickle=False)
    maps = []
    for k in range(int(d["n_maps"])):
        g = {name: d[f"map{k}_{name}"] for name in _MAP_ARRAYS if f"map{k}_{name}" in d}
        if f"map{k}_seed_ids" in d:
            ids = tuple(int(s) for s in d[f"map{k}_seed_ids"])
        else:  # files of flexkin <= 0.2 stored 0-based indices as map{k}_seeds
            ids = tuple(int(s) + 1 for s in d[f"map{k}_seeds"])
        maps.append(WorkspaceMap(seeds=ids, **g))
    extra = {}
    if "constraints" in d:
        extra = {"constraints": tuple(str(c) for c in d["constraints"]), "constrained": bool(d["constrained"]),
                 "stability": str(d["stability"]), "grown": int(d["grown"])}
    if "complete" in d:
        extra["complete"] = bool(d["complete"])
    return Workspace(str(d["mechanism_name"]), tuple(str(k) for k in d["kinds"]), float(d["theta"]),
                     tuple(float(v) for v in d["load"]), d["x"], d["y"], tuple(float(v) for v in d["seed"]),
                     tuple(maps), float(d["elapsed"]), int(d["steps"]), str(d["message"]), **extra)


# ---------------------------------------------------------------------------------------------
def singularity_distance_map(ws_map: Any, step: float) -> NDArray[np.float64]:
    """Distance (m) from every reached cell of a workspace map to the nearest singularity found.

    A boundary cell (``boundary_ik | boundary_fk``) has a neighbour across an IK or FK
    singularity (or a loss of stability), which lies between the two cells: its distance is
    ``h/2``.  A reached cell's distance is the Euclidean distance to the nearest boundary cell
    plus ``h/2``.  Cells whose nearest *unknown* cell is closer are ``NaN``: an unknown cell is
    a reached cell on the grid's edge, next to an unresolved (seam) cell or next to an
    unvisited cell (a time budget cut the map short), beyond which a singularity may hide.

    Parameters
    ----------
    ws_map : WorkspaceMap
        One aspect of a :class:`Workspace`.
    step : float
        The grid step ``h`` (m), ``Workspace.step``.

    Returns
    -------
    ndarray (ny, nx)
        Distances (m); ``NaN`` outside the reached cells and where unknown.
    """
    from scipy.ndimage import distance_transform_edt

    h = float(step)
    reached = np.asarray(ws_map.status) == REACHED
    out = np.full(reached.shape, np.nan)
    sing = (np.asarray(ws_map.boundary_ik) | np.asarray(ws_map.boundary_fk)) & reached
    if not np.any(sing) or h <= 0:
        return out
    status = np.pad(np.asarray(ws_map.status), 1, constant_values=-1)   # -1: beyond the grid
    unknown = np.zeros_like(reached)
    for dj, di in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        nb = status[1 + dj:status.shape[0] - 1 + dj, 1 + di:status.shape[1] - 1 + di]
        unknown |= (nb == -1) | (nb == 0) | (nb == SEAM)
    unknown &= reached
    d_s = distance_transform_edt(~sing) * h + 0.5 * h
    d_u = distance_transform_edt(~unknown) * h + 0.5 * h if np.any(unknown) else np.full(reached.shape, np.inf)
    known = reached & (d_s <= d_u)
    out[known] = d_s[known]
    return out
