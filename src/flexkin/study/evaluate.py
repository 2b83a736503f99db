"""The per-(design, orientation) computation of a study: :func:`evaluate_design`.

This is the only module of :mod:`flexkin.study` that calls the workspace and kinematics
API.  :func:`evaluate_design` runs on a Dask worker (or in the calling process): it builds
the design's mechanism, maps its constant-orientation workspace and reduces the maps to one
row of metrics.  To add a metric: declare its column in :data:`METRICS`, compute it in
:func:`evaluate_design`, and bump :data:`ROW_VERSION` (rows stored by earlier versions are
then computed again instead of being reused).

Definitions (``step`` is the workspace grid step; "the largest aspect" is ``ws.maps[0]``,
the largest region reached by continuation from one stable seed solution without crossing an
IK singularity, an FK singularity or a loss of stability):

* ``workspace_area``: area of the cells reached by any aspect (m^2);
* ``singularity_free_area``: area of the largest aspect (m^2);
* ``feasible_area``, ``strain_limited_area``: areas of the reached cells that meet every
  constraint checked, and the strain limit (m^2);
* ``feasible_disc_radius``: the largest disc of feasible cells of one aspect (m);
* every other index is over the reached cells of the largest aspect.

With ``constrained`` the wave stops at infeasible cells, so every area measures the feasible
region reached from the seed.  With ``seed_search`` (the default) a design without a stable
IK solution at the seed pose is seeded elsewhere on the orientation slice
(:func:`flexkin.solve.workspace.workspace`); ``seed_x``, ``seed_y`` say where.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

__all__ = ["METRICS", "ROW_VERSION", "DesignTask", "evaluate_design", "Metric", "INDEX_SUMMARIES"]

#: Version of the row produced by :func:`evaluate_design`; part of every stored row's key.
ROW_VERSION = 3


@dataclass(frozen=True)
class Metric:
    """A metric column: its type (``"float"``, ``"int"``, ``"bool"`` or ``"str"``), unit and
    meaning, and whether a study draws a figure of it (not of a coordinate such as ``seed_x``)."""

    dtype: str
    unit: str
    doc: str
    figure: bool = True


#: Per-equilibrium indices summarised over the largest aspect by ``min_``, ``mean_`` and ``max_``
#: columns: name -> (unit, meaning); see :mod:`flexkin.analysis.indices` for the formulas.
INDEX_SUMMARIES: dict[str, tuple[str, str]] = {
    "stability_margin": ("", "stability margin (smallest eigenvalue of the dimensionless second variation)"),
    "cond": ("", "condition number of the homogenised J_IK (characteristic length: the mean rod length)"),
    "force_stiffness": ("N/m", "stiffness against a force at P in its weakest direction, actuators locked, "
                               "platform free to turn: 1/lambda_max(C[:2, :2])"),
    "moment_stiffness": ("N m/rad", "stiffness against a moment, actuators locked, platform free to translate: "
                                    "1/C[2, 2]"),
    "manipulability": ("", "volume of the velocity ellipsoid, |det J_h|"),
    "velocity_minor": ("m/s", "minor semi-axis of the velocity ellipse of P per unit homogenised input rate"),
    "singularity_distance": ("m", "distance to the nearest IK/FK singularity found by the map (empty where a "
                                  "closer one may lie beyond the grid or an unresolved cell)"),
}
_STAT = {"min": "smallest", "mean": "mean", "max": "largest"}

#: Every metric column, in table order.  A study computes all of them unless it lists some.
METRICS: dict[str, Metric] = {
    "workspace_area": Metric("float", "m^2", "area reached by any aspect (union of the aspects)"),
    "n_aspects": Metric("int", "", "number of aspects (regions mapped from distinct stable seed solutions)"),
    "singularity_free_area": Metric("float", "m^2", "area of the largest aspect (singularity-free and stable, "
                                                    "reached from the seed)"),
    "aspect_areas": Metric("str", "m^2", "area of each aspect, largest first, separated by ';'"),
    "touches_bounds": Metric("bool", "", "a reached cell lies on the edge of the grid: the areas are cut by the bounds"),
    "constraints": Metric("str", "", "the constraints checked at every cell, separated by ';' (ranges, strain, "
                                     "collisions)"),
    "feasible_area": Metric("float", "m^2", "area of the reached cells (any aspect) that meet every constraint "
                                            "checked"),
    "strain_limited_area": Metric("float", "m^2", "area of the reached cells (any aspect) whose peak bending strain "
                                                  "is within [limits] max_strain (empty when the strain is not "
                                                  "checked)"),
    "feasible_disc_radius": Metric("float", "m", "radius of the largest disc whose grid points are all feasible "
                                                 "cells of one aspect (singularity-free, stable); the grid's edge "
                                                 "bounds it"),
    "feasible_disc_x": Metric("float", "m", "x of the centre of that disc", figure=False),
    "feasible_disc_y": Metric("float", "m", "y of the centre of that disc", figure=False),
    "seed_x": Metric("float", "m", "x of the seed pose used (another than the requested one when seed_search moved "
                                   "it)", figure=False),
    "seed_y": Metric("float", "m", "y of the seed pose used", figure=False),
    "inscribed_radius": Metric("float", "m", "distance from the seed to the nearest grid point the largest aspect "
                                             "does not reach"),
    "n_mode_combinations": Metric("int", "", "distinct d-mode combinations in the largest aspect"),
    "fk_boundary_fraction": Metric("float", "", "share of the largest aspect's boundary cells that border an FK "
                                                "singularity or instability (the rest border IK singularities)"),
    **{f"{stat}_{name}": Metric("float", unit, f"{word} {doc} over the largest aspect")
       for name, (unit, doc) in INDEX_SUMMARIES.items() for stat, word in _STAT.items()},
    "input_span_1": Metric("float", "m or deg", "range of actuator input 1 over the largest aspect"),
    "input_span_2": Metric("float", "m or deg", "range of actuator input 2 over the largest aspect"),
    "input_span_3": Metric("float", "m or deg", "range of actuator input 3 over the largest aspect"),
    "in_range_fraction": Metric("float", "", "share of the largest aspect's cells whose inputs lie within every "
                                             "leg's range, revolute angles modulo 360 deg (empty when no leg has "
                                             "a range)"),
    "max_curvature": Metric("float", "1/m", "largest rod curvature over the largest aspect"),
    "max_strain": Metric("float", "", "largest bending strain radius*|curvature| over the largest aspect (empty "
                                      "when no rod has a radius)"),
}
#: metrics computed from the per-cell indices (:func:`flexkin.analysis.indices.index_arrays`)
_INDEX_METRICS = frozenset(f"{s}_{n}" for n in ("cond", "force_stiffness", "moment_stiffness", "manipulability",
                                                 "velocity_minor") for s in _STAT) | {"max_curvature", "max_strain"}


@dataclass(frozen=True)
class DesignTask:
    """One row to compute: a design (its grid values and mechanism dict) at one orientation.

    Built by :meth:`flexkin.study.spec.StudySpec.tasks`, one per (design, orientation), in row
    order.

    Attributes
    ----------
    index : int
        0-based position of the task (the row) in the study.
    design : int
        0-based number of the design on the grid (the first grid key varies slowest).
    params : tuple of (str, float)
        The design's grid values by dotted key (:mod:`flexkin.study.grid`), in the study
        file's units (m, deg, Pa, N m^2, N, N m; dimensionless for scales and strains).
    theta_deg : float
        Platform orientation of the constant-orientation workspace (deg).
    mechanism : mapping
        The design's mechanism file content (the TOML tables as a dict; angles in degrees).
    source : str
        A label naming the design and its base mechanism file, used in error messages.
    workspace : mapping
        The workspace settings (seed, step, bounds, max_mode, ...; lengths in m), already
        scaled for the design.
    metrics : tuple of str
        The metric columns to compute (keys of :data:`METRICS`).
    key : str
        Content hash (24 hex digits) of the row version, mechanism, orientation, workspace
        settings and metrics: identifies the result in the store, so identical rows are
        computed once and reused across runs.
    """

    index: int
    design: int
    params: tuple[tuple[str, float], ...]
    theta_deg: float
    mechanism: Mapping[str, Any]
    source: str
    workspace: Mapping[str, Any]
    metrics: tuple[str, ...]
    key: str


def _f(v: Any) -> float | None:
    """A finite float or None."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split())
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


def _summary(out: dict[str, Any], name: str, values: NDArray[np.float64]) -> None:
    """``min_``, ``mean_`` and ``max_`` of ``name`` over the finite ``values`` (None if none is)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    for stat, f in (("min", np.min), ("mean", np.mean), ("max", np.max)):
        out[f"{stat}_{name}"] = _f(f(v)) if v.size else None


def _cell_states(mp: Any, ws: Any, system: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The unknowns (n, n_unknowns) and charts (n, 3) of the reached cells of map ``mp``, in
    the order of ``np.nonzero(mp.reached)``."""
    jj, ii = np.nonzero(mp.reached)
    lay = system.layout
    Xc = np.zeros((len(jj), lay.n_unknowns))
    Xc[:, :lay.n_rod] = mp.zrod[jj, ii]
    Xc[:, lay.pose] = np.stack([np.asarray(ws.x)[ii], np.asarray(ws.y)[jj], np.full(len(jj), ws.theta)], -1)
    Xc[:, lay.inputs] = mp.inputs[jj, ii]
    return Xc, np.asarray(mp.charts)[jj, ii]


def _feasibility_metrics(out: dict[str, Any], ws: Any) -> None:
    """Feasible and strain-limited areas and the largest feasible disc (see :data:`METRICS`)."""
    from scipy.ndimage import distance_transform_edt

    from ..solve.workspace import VIOLATION_STRAIN

    h = float(ws.step)
    out["constraints"] = ";".join(ws.constraints)
    out["feasible_area"] = float(ws.feasible_union().sum()) * h * h
    if "strain" in ws.constraints:
        ok = np.zeros((len(ws.y), len(ws.x)), bool)
        for mp in ws.maps:
            ok |= mp.reached & ((np.asarray(mp.violations) & VIOLATION_STRAIN) == 0)
        out["strain_limited_area"] = float(ok.sum()) * h * h
    best, centre = 0.0, None
    for mp in ws.maps:
        feas = np.pad(mp.feasible, 1)  # the points beyond the grid are not known to be feasible
        if not feas.any():
            continue
        d = distance_transform_edt(feas) * h  # to the nearest grid point that is not a feasible cell
        k = int(np.argmax(d))
        if d.flat[k] > best:
            best, centre = float(d.flat[k]), np.unravel_index(k, d.shape)
    if centre is not None:
        out["feasible_disc_radius"] = best
        out["feasible_disc_x"] = float(ws.x[centre[1] - 1])
        out["feasible_disc_y"] = float(ws.y[centre[0] - 1])
    else:
        out["feasible_disc_radius"] = 0.0


def _aspect_metrics(out: dict[str, Any], want: set[str], ws: Any, mech: Any) -> None:
    """The metrics of the largest aspect ``ws.maps[0]`` (see :data:`METRICS`)."""
    from ..analysis.indices import index_arrays
    from ..solve.workspace_map import singularity_distance_map
    from ..system import System

    h = float(ws.step)
    X, Y = np.asarray(ws.x, float), np.asarray(ws.y, float)
    mp = ws.maps[0]
    r = mp.reached
    sj = int(np.argmin(np.abs(Y - ws.seed[1])))
    si = int(np.argmin(np.abs(X - ws.seed[0])))
    # inscribed radius: nearest grid point not reached, or the first point beyond the grid
    gx, gy = np.meshgrid(X, Y)
    d_out = np.hypot(gx[~r] - X[si], gy[~r] - Y[sj])
    beyond = min(X[si] - X[0], X[-1] - X[si], Y[sj] - Y[0], Y[-1] - Y[sj]) + h
    out["inscribed_radius"] = float(min(d_out.min() if d_out.size else math.inf, beyond))
    modes = np.asarray(mp.modes)[r]
    out["n_mode_combinations"] = len({tuple(int(q) for q in m) for m in modes})
    nik, nfk = int(np.count_nonzero(mp.boundary_ik)), int(np.count_nonzero(mp.boundary_fk))
    out["fk_boundary_fraction"] = nfk / (nik + nfk) if nik + nfk else None
    if want & {f"{st}_stability_margin" for st in _STAT}:
        # the wave leaves the margin NaN where the sign of det A_FK decided stability: every
        # reached cell's margin, not the subset the wave happened to compute
        _summary(out, "stability_margin", ws.margins(mech)[0][r])
    _summary(out, "singularity_distance", singularity_distance_map(mp, h)[r])
    if want & _INDEX_METRICS:
        system = System.from_mechanism(mech)
        Xc, ch = _cell_states(mp, ws, system)
        ind = index_arrays(mech, Xc, ch, system=system)
        _summary(out, "cond", ind.cond)
        _summary(out, "force_stiffness", ind.force_stiffness)
        _summary(out, "moment_stiffness", ind.moment_stiffness)
        _summary(out, "manipulability", ind.manipulability)
        _summary(out, "velocity_minor", ind.ellipse_axes[:, 1])
        out["max_curvature"] = _f(np.max(ind.curvature)) if len(ind) else None
        strain = ind.max_strain
        strain = strain[np.isfinite(strain)]
        out["max_strain"] = _f(strain.max()) if strain.size else None
    u = np.asarray(mp.inputs)[r]  # internal units (m, rad)
    in_range = np.ones(len(u), bool)
    for k, leg in enumerate(mech.legs):
        span = float(u[:, k].max() - u[:, k].min())
        out[f"input_span_{k + 1}"] = math.degrees(span) if leg.actuation == "revolute" else span
        if leg.range is not None:
            lo, hi = leg.range
            if leg.actuation == "revolute":  # a joint angle is the same modulo 360 deg
                in_range &= np.mod(u[:, k] - lo, 2 * math.pi) <= hi - lo
            else:
                in_range &= (u[:, k] >= lo) & (u[:, k] <= hi)
    if any(leg.range is not None for leg in mech.legs):
        out["in_range_fraction"] = float(in_range.mean())


def evaluate_design(task: DesignTask) -> dict[str, Any]:
    """Compute one row of a study: the design ``task.params`` at orientation ``task.theta_deg``.

    Never raises for a failing design: the exception is recorded as one line in ``error``
    (and the metrics are empty).  The row holds plain Python values (JSON-ready): ``design``,
    the grid parameters, ``theta_deg``, the metrics of ``task.metrics`` (``None`` where
    undefined), ``complete`` (false when a time budget cut the computation short), ``error``,
    ``note`` (the workspace's message, e.g. no stable solution at the seed) and ``elapsed_s``.

    Parameters
    ----------
    task : DesignTask
        The design, orientation, workspace settings and metrics of the row.

    Returns
    -------
    dict
        The row.
    """
    from ..mechanism import mechanism_from_dict
    from ..solve.workspace import workspace

    t0 = time.perf_counter()
    row: dict[str, Any] = {"design": task.design}
    row.update({k: float(v) for k, v in task.params})
    row["theta_deg"] = float(task.theta_deg)
    out: dict[str, Any] = {m: None for m in task.metrics}
    complete, error, note = False, "", ""
    s = task.workspace
    try:
        mech = mechanism_from_dict(dict(task.mechanism), source=task.source)
        ws = workspace(mech, math.radians(task.theta_deg), seed=tuple(s["seed"]), step=s.get("step"),
                       bounds=s.get("bounds"), max_mode=int(s["max_mode"]), all_aspects=bool(s["all_aspects"]),
                       time_budget=s.get("time_budget"), constrained=bool(s.get("constrained", False)),
                       collisions=bool(s.get("collisions", False)), seed_search=bool(s.get("seed_search", True)))
        complete = "time budget" not in ws.message
        note = " ".join(ws.message.split())
        h = float(ws.step)
        union = ws.union()
        out["workspace_area"] = float(union.sum()) * h * h
        out["n_aspects"] = len(ws.maps)
        out["singularity_free_area"] = float(ws.maps[0].area_cells) * h * h if ws.maps else 0.0
        out["aspect_areas"] = ";".join(f"{mp.area_cells * h * h:.6g}" for mp in ws.maps)
        out["touches_bounds"] = bool(union[0].any() or union[-1].any() or union[:, 0].any() or union[:, -1].any())
        out["seed_x"], out["seed_y"] = float(ws.seed[0]), float(ws.seed[1])
        _feasibility_metrics(out, ws)
        if ws.maps:
            _aspect_metrics(out, set(task.metrics), ws, mech)
    except Exception as e:  # a failing design is a row with an error, never a failed study
        error, complete = _one_line(e), False
        out = {m: None for m in task.metrics}
    row.update({m: out.get(m) for m in task.metrics})
    row.update({"complete": bool(complete), "error": error, "note": note,
                "elapsed_s": round(time.perf_counter() - t0, 6)})
    return row
