"""Rod shapes of equilibria written to CSV or NPZ (``--shapes FILE.csv|FILE.npz``).

Every rod is sampled at ``n_points`` points uniformly spaced in arc length from its clamp
(``s = 0``) to the platform (``s = L``).  Columns (CSV) / arrays (NPZ):

========== ======= ==================================================================
column     unit    meaning
========== ======= ==================================================================
solution   –       :attr:`Solution.id` (the number of the table, the JSON and figures)
sample, t  –       path only: sample index (from 0) and path parameter in [0, 1]
leg        –       leg number, from 1
s_m        m       arc length from the clamp
x_m, y_m   m       centre-line point, world frame
theta_deg  deg     tangent angle of the centre line, world frame, counter-clockwise
moment_Nm  N m     bending moment ``EI theta'(s)`` (counter-clockwise positive)
========== ======= ==================================================================

The CSV starts with ``#`` comment lines (mechanism, problem, units), then a header row
(``pandas.read_csv(..., comment="#")`` reads it with the names, ``numpy.loadtxt(...,
delimiter=",", comments=("#", "solution"))`` the numbers).  The NPZ holds arrays of shape
``(n_solutions, 3, n_points)`` for ``s_m``, ``x_m``, ``y_m``, ``theta_deg``, ``moment_Nm``
and, per solution, ``solution``, ``modes``, ``pose`` (x m, y m, theta deg), ``inputs``
(display units, ``input_units``), ``stable`` (1, 0, or -1 undecided), and ``t`` for a path.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

__all__ = ["write_shapes", "shape_table", "SHAPE_COLUMNS", "SHAPE_FORMATS"]

#: CSV columns of an IK/FK shape file (a path file has ``sample`` and ``t`` after ``solution``)
SHAPE_COLUMNS = ("solution", "leg", "s_m", "x_m", "y_m", "theta_deg", "moment_Nm")
SHAPE_FORMATS = ("csv", "npz")


def _is_path(result: Any) -> bool:
    return hasattr(result, "t") and hasattr(result, "start_solution")


def _solutions_of(result: Any) -> tuple[list[Any], np.ndarray | None]:
    if _is_path(result):
        return result.sample_solutions(), np.asarray(result.t, dtype=float)
    return list(result.solutions), None


def shape_table(solutions: Sequence[Any], n_points: int = 101) -> dict[str, np.ndarray]:
    """Arrays ``(n, 3, n_points)`` ``s_m``, ``x_m``, ``y_m``, ``theta_deg``, ``moment_Nm`` of the rods
    of ``solutions``, with per-solution ``solution``, ``modes``, ``pose``, ``inputs``, ``stable``.

    Parameters
    ----------
    solutions : sequence of Solution
        The equilibria.
    n_points : int
        Points per rod, uniformly spaced in arc length (>= 2).

    Returns
    -------
    dict of str to ndarray
    """
    if int(n_points) < 2:
        raise ValueError(f"n_points must be >= 2, got {n_points!r}")
    n = len(solutions)
    out = {k: np.zeros((n, 3, n_points)) for k in ("s_m", "x_m", "y_m", "theta_deg", "moment_Nm")}
    for a, s in enumerate(solutions):
        for i, rod in enumerate(s.rods):
            p = rod.profile(n_points)
            out["s_m"][a, i], out["x_m"][a, i], out["y_m"][a, i] = p["s"], p["x"], p["y"]
            out["theta_deg"][a, i] = np.degrees(p["theta"])
            out["moment_Nm"][a, i] = p["moment"]
    out["solution"] = np.array([int(s.id) for s in solutions], dtype=np.int64)
    out["modes"] = np.array([list(s.modes) for s in solutions], dtype=np.int64).reshape(n, 3)
    out["pose"] = np.array([[s.pose[0], s.pose[1], np.degrees(s.pose[2])] for s in solutions],
                           dtype=float).reshape(n, 3)
    out["inputs"] = np.array([s.inputs_display() for s in solutions], dtype=float).reshape(n, 3)
    out["stable"] = np.array([-1 if s.stable is None else int(bool(s.stable)) for s in solutions], dtype=np.int64)
    return out


def _header(result: Any, mech: Any, n_points: int) -> list[str]:
    units = ", ".join(f"u{i + 1} in {leg.input_unit}" for i, leg in enumerate(mech.legs))
    if _is_path(result):
        a, b = result.start, result.end
        what = (f"path from ({a[0]:g} m, {a[1]:g} m, {np.degrees(a[2]):g} deg) to ({b[0]:g} m, {b[1]:g} m, "
                f"{np.degrees(b[2]):g} deg), solution {getattr(result.start_solution, 'id', '?')} followed; "
                "one block per sample (sample, t)")
    elif getattr(result, "problem", "") == "ik":
        g = result.given
        what = f"ik at pose ({g[0]:g} m, {g[1]:g} m, {np.degrees(g[2]):g} deg)"
    else:
        g = [float(leg.to_display(u)) for u, leg in zip(result.given, mech.legs)]
        what = "fk at inputs (" + ", ".join(f"{v:g} {leg.input_unit}" for v, leg in zip(g, mech.legs)) + ")"
    return [f"flexkin rod shapes: mechanism {mech.name!r}, {what}",
            f"{n_points} points per rod from the clamp (s = 0) to the platform (s = L); "
            "solution = the solution's id (as in the table, the JSON and the figures); leg from 1",
            "units: s_m, x_m, y_m in m (world frame); theta_deg = tangent angle in DEGREES (world frame, "
            f"counter-clockwise); moment_Nm = bending moment EI theta' in N m; inputs: {units}"]


def write_shapes(path: str | os.PathLike[str], result: Any, n_points: int = 101) -> Path:
    """Write the rod shapes of every solution of ``result`` (a
    :class:`~flexkin.results.KinematicsResult`, or a :class:`~flexkin.solve.path.PathResult`:
    every sample) to ``path``; the format follows the extension (``.csv`` or ``.npz``).

    Parameters
    ----------
    path : str or path-like
        Output file, ``.csv`` or ``.npz``.
    result : KinematicsResult or PathResult
        The solutions (or path samples) whose rods are written.
    n_points : int
        Points per rod, uniformly spaced in arc length.

    Returns
    -------
    Path
        The file written.
    """
    out = Path(path)
    ext = out.suffix.lower().lstrip(".")
    if ext not in SHAPE_FORMATS:
        raise ValueError(f"shapes file {str(out)!r}: unknown file type {out.suffix or '(no extension)'}; "
                         "use .csv or .npz")
    mech = result.mechanism
    sols, t = _solutions_of(result)
    tab = shape_table(sols, n_points)
    header = _header(result, mech, n_points)
    if ext == "npz":
        extra: dict[str, Any] = {}
        if t is not None:
            extra["t"] = t
            extra["sample"] = np.arange(len(t))
        np.savez_compressed(out, **tab, **extra, mechanism=np.array(mech.name), problem=np.array(
            "path" if t is not None else getattr(result, "problem", "")),
            input_units=np.array([leg.input_unit for leg in mech.legs]), description=np.array("\n".join(header)))
        return out
    cols = list(SHAPE_COLUMNS)
    if t is not None:
        cols[1:1] = ["sample", "t"]
    with open(out, "w", newline="", encoding="utf-8") as fh:
        for line in header:
            fh.write(f"# {line}\n")
        w = csv.writer(fh)
        w.writerow(cols)
        for a in range(len(sols)):
            sid = int(tab["solution"][a])
            lead: list[Any] = [sid] if t is None else [sid, a, f"{t[a]:.10g}"]
            for i in range(3):
                for k in range(n_points):
                    w.writerow(lead + [i + 1] + [f"{tab[c][a, i, k]:.10g}"
                                                 for c in ("s_m", "x_m", "y_m", "theta_deg", "moment_Nm")])
    return out
