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
* every other index is over the reached cells of the largest aspect.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

__all__ = ["METRICS", "ROW_VERSION", "DesignTask", "evaluate_design", "Metric"]

#: Version of the row produced by :func:`evaluate_design`; part of every stored row's key.
ROW_VERSION = 1


@dataclass(frozen=True)
class Metric:
    """A metric column: its type (``"float"``, ``"int"`` or ``"bool"``), unit and meaning."""

    dtype: str
    unit: str
    doc: str


#: Every metric column, in table order.  A study computes all of them unless it lists some.
METRICS: dict[str, Metric] = {
    "workspace_area": Metric("float", "m^2", "area reached by any aspect (union of the aspects)"),
    "n_aspects": Metric("int", "", "number of aspects (regions mapped from distinct stable seed solutions)"),
    "singularity_free_area": Metric("float", "m^2", "area of the largest aspect"),
    "touches_bounds": Metric("bool", "", "a reached cell lies on the edge of the grid: the areas are cut by the bounds"),
    "inscribed_radius": Metric("float", "m", "distance from the seed to the nearest grid point the largest aspect "
                                             "does not reach"),
    "n_mode_combinations": Metric("int", "", "distinct d-mode combinations in the largest aspect"),
    "fk_boundary_fraction": Metric("float", "", "share of the largest aspect's boundary cells that border an FK "
                                                "singularity or instability (the rest border IK singularities)"),
    "min_stability_margin": Metric("float", "", "smallest stability margin in the largest aspect"),
    "mean_stability_margin": Metric("float", "", "mean stability margin over the largest aspect"),
    "cond_min": Metric("float", "", "smallest Jacobian condition number in the largest aspect"),
    "cond_mean": Metric("float", "", "mean Jacobian condition number over the largest aspect"),
    "cond_max": Metric("float", "", "largest Jacobian condition number in the largest aspect"),
    "input_span_1": Metric("float", "m or deg", "range of actuator input 1 over the largest aspect"),
    "input_span_2": Metric("float", "m or deg", "range of actuator input 2 over the largest aspect"),
    "input_span_3": Metric("float", "m or deg", "range of actuator input 3 over the largest aspect"),
    "in_range_fraction": Metric("float", "", "share of the largest aspect's cells whose inputs lie within every "
                                             "leg's range, revolute angles modulo 360 deg (empty when no leg has "
                                             "a range)"),
    "max_curvature": Metric("float", "1/m", "largest rod curvature at the sampled cells of the largest aspect"),
    "max_strain": Metric("float", "", "largest bending strain radius*|curvature| at the sampled cells (empty "
                                      "when no rod has a radius)"),
    "strain_samples": Metric("int", "", "cells of the largest aspect where the strain was evaluated (its extreme "
                                        "cells in [workspace] strain_samples directions)"),
}
_STRAIN_METRICS = ("max_curvature", "max_strain", "strain_samples")
#: Seconds of global search for each IK of the strain sampling (see :func:`flexkin.ik`).
IK_BUDGET = 1.0


@dataclass(frozen=True)
class DesignTask:
    """One row to compute: a design (its grid values and mechanism dict) at one orientation.

    ``mechanism`` is the design's mechanism file content (degrees), ``workspace`` the
    workspace settings (already scaled for the design), ``key`` identifies the result.
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


def evaluate_design(task: DesignTask) -> dict[str, Any]:
    """Compute one row of a study: the design ``task.params`` at orientation ``task.theta_deg``.

    Never raises for a failing design: the exception is recorded as one line in ``error``
    (and the metrics are empty).  The row holds plain Python values (JSON-ready): ``design``,
    the grid parameters, ``theta_deg``, the metrics of ``task.metrics`` (``None`` where
    undefined), ``complete`` (false when a time budget cut the computation short), ``error``,
    ``note`` (the workspace's message, e.g. no stable solution at the seed) and ``elapsed_s``.
    """
    from .. import ik
    from ..mechanism import mechanism_from_dict
    from ..solve.workspace import workspace

    t0 = time.perf_counter()
    row: dict[str, Any] = {"design": task.design}
    row.update({k: float(v) for k, v in task.params})
    row["theta_deg"] = float(task.theta_deg)
    out: dict[str, Any] = {m: None for m in task.metrics}
    want = set(task.metrics)
    complete, error, note = False, "", ""
    s = task.workspace
    try:
        mech = mechanism_from_dict(dict(task.mechanism), source=task.source)
        budget = s.get("time_budget")
        ws = workspace(mech, math.radians(task.theta_deg), seed=tuple(s["seed"]), step=s.get("step"),
                       bounds=s.get("bounds"), max_mode=int(s["max_mode"]), all_aspects=bool(s["all_aspects"]),
                       time_budget=budget)
        complete = "time budget" not in ws.message
        note = " ".join(ws.message.split())
        h = float(ws.step)
        X, Y = np.asarray(ws.x, float), np.asarray(ws.y, float)
        union = np.zeros((len(Y), len(X)), bool)
        for mp in ws.maps:
            union |= mp.reached
        out["workspace_area"] = float(union.sum()) * h * h
        out["n_aspects"] = len(ws.maps)
        out["singularity_free_area"] = float(ws.maps[0].area_cells) * h * h if ws.maps else 0.0
        out["touches_bounds"] = bool(union[0].any() or union[-1].any() or union[:, 0].any() or union[:, -1].any())
        if ws.maps:
            mp = ws.maps[0]
            r = mp.reached
            jj, ii = np.nonzero(r)
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
            margin = np.asarray(mp.margin)[r]
            out["min_stability_margin"] = _f(margin.min())
            out["mean_stability_margin"] = _f(margin.mean())
            cond = np.asarray(mp.cond)[r]
            cond = cond[np.isfinite(cond)]
            if cond.size:
                out["cond_min"], out["cond_mean"], out["cond_max"] = (_f(cond.min()), _f(cond.mean()),
                                                                      _f(cond.max()))
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
            # strain: full IK at a few cells, the solution of this aspect picked by its inputs
            n_samples = int(s.get("strain_samples", 0))
            if want & set(_STRAIN_METRICS) and n_samples > 0:
                coords = np.stack([X[ii], Y[jj]], -1)
                cells = []  # the extreme cells of the aspect in n_samples directions
                for a in np.arange(n_samples) * (2 * math.pi / n_samples):
                    k = int(np.argmax(coords @ np.array([math.cos(a), math.sin(a)])))
                    cells.append((int(jj[k]), int(ii[k])))
                cells = list(dict.fromkeys(cells))
                revolute = np.array([leg.actuation == "revolute" for leg in mech.legs])
                scale = np.where(revolute, 1.0, float(mech.length_scale))
                kmax, smax, used = 0.0, None, 0
                for c, (j, i) in enumerate(cells):
                    left = None if budget is None else budget - (time.perf_counter() - t0)
                    if left is not None and left <= 0:
                        complete = False
                        break
                    ik_budget = IK_BUDGET if left is None else min(IK_BUDGET, left / (len(cells) - c))
                    try:
                        res = ik(mech, (float(X[i]), float(Y[j]), math.radians(task.theta_deg)),
                                 max_mode=int(s["max_mode"]), time_budget=ik_budget)
                    except Exception:  # noqa: BLE001 - a sample without IK is skipped (strain_samples says so)
                        continue
                    sols = list(res.solutions)
                    if not sols:
                        continue
                    du = np.array([np.asarray(q.inputs, float) for q in sols]) - mp.inputs[j, i]
                    du = np.where(revolute, (du + math.pi) % (2 * math.pi) - math.pi, du)  # angles modulo 2 pi
                    dist = np.max(np.abs(du) / scale, axis=1)
                    best = int(np.argmin(dist))
                    if dist[best] > 1e-5:
                        continue
                    used += 1
                    for leg, rod in zip(mech.legs, sols[best].rods):
                        kap = float(np.max(np.abs(rod.curvature())))
                        kmax = max(kmax, kap)
                        if leg.rod.radius is not None:
                            smax = max(smax or 0.0, leg.rod.radius * kap)
                out["strain_samples"] = used
                if used:
                    out["max_curvature"] = _f(kmax)
                    out["max_strain"] = _f(smax)
    except Exception as e:  # a failing design is a row with an error, never a failed study
        error, complete = _one_line(e), False
        out = {m: None for m in task.metrics}
    row.update({m: out.get(m) for m in task.metrics})
    row.update({"complete": bool(complete), "error": error, "note": note,
                "elapsed_s": round(time.perf_counter() - t0, 6)})
    return row
