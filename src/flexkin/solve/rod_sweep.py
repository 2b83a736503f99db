"""Sweeps of the single-rod inverse problem (paper §7, Fig. 19).

The paper's rod experiment clamps a Nitinol rod on a linear actuator and pins its tip on
a dynamometer at a fixed height; the tip force is recorded while the tip abscissa changes.
:func:`rod_sweep` solves every equilibrium at each abscissa and links them into
continuous branches.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rod_inverse import RodInverseResult, refine_rod, solve_rod
from ..core.geometry2d import rot2

__all__ = ["RodSweep", "rod_sweep", "FIG19"]

#: The paper's Fig. 19 set-up: Nitinol rod, L = 0.908 m, r = 1.5 mm, E = 68 GPa, tip
#: height -0.2125 m, tip abscissa from 0.86 m to 0.51 m.
FIG19 = {"length": 0.908, "E": 68e9, "radius": 1.5e-3, "tip_y": -0.2125, "x_start": 0.86, "x_end": 0.51}


@dataclass(frozen=True)
class RodSweep:
    """All equilibria along a sweep of the tip abscissa.

    Attributes
    ----------
    x : (n,) tip abscissae (m).
    results : per abscissa, the :class:`RodInverseResult`.
    branches : list of branches; each is a dict of arrays ``x``, ``fx``, ``fy``, ``k``,
        ``psi``, ``mode``, ``energy``, ``base_moment`` (one entry per abscissa on the branch).
    """

    x: NDArray[np.float64]
    tip_y: float
    results: tuple[RodInverseResult, ...]
    branches: list[dict[str, NDArray[np.float64]]] = field(repr=False)

    def table(self) -> str:
        """Plain-text table: one row per (abscissa, solution)."""
        head = f"{'x [m]':>8} {'branch':>6} {'mode':>4} {'k':>9} {'psi [deg]':>9} {'Fx [N]':>10} {'Fy [N]':>10} {'m0 [N m]':>10} {'energy [J]':>10}"
        lines = [head, "-" * len(head)]
        for b_id, b in enumerate(self.branches, 1):
            for j in range(len(b["x"])):
                lines.append(
                    f"{b['x'][j]:>8.4f} {b_id:>6d} {int(b['mode'][j]):>4d} {b['k'][j]:>9.5f} "
                    f"{np.degrees(b['psi'][j]):>9.3f} {b['fx'][j]:>10.5f} {b['fy'][j]:>10.5f} "
                    f"{b['base_moment'][j]:>10.5f} {b['energy'][j]:>10.5f}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "problem": "rod-sweep",
            "tip_y": self.tip_y,
            "x": self.x.tolist(),
            "branches": [{k: np.asarray(v).tolist() for k, v in b.items()} for b in self.branches],
        }

    def plot(self, path: str | None = None):
        """Tip-force components against the tip abscissa, one line per branch."""
        from ..plot.rod import plot_rod_sweep

        return plot_rod_sweep(self, path)


def rod_sweep(xs: ArrayLike, tip_y: float, length: float, EI: float, *, clamp_angle: float = 0.0,
              max_mode: int = 2) -> RodSweep:
    """Solve the pinned-tip rod at ``(x, tip_y)`` for every ``x`` and link the branches."""
    xs = np.asarray(xs, dtype=float)
    results = tuple(solve_rod((x, tip_y), length, EI, clamp_angle=clamp_angle, max_mode=max_mode) for x in xs)
    branches: list[dict[str, list]] = []
    last: list[tuple[float, float]] = []  # chart coordinates (v, phis) of each open branch's end
    open_idx: list[int] = []
    for x, res in zip(xs, results):
        sols = list(res.solutions)
        chart = np.array([[s.v, s.phis] for s in sols]).reshape(-1, 2)
        taken: set[int] = set()
        still_open = []
        if open_idx and len(sols):
            # continue every open branch by Newton from its previous state (d-mode changes are
            # continuous in the chart) and attach it to the solution it lands on
            local = rot2(-clamp_angle) @ np.array([x, tip_y]) / length
            cont = refine_rod(np.array([last[bi] for bi in open_idx]), local)
            for bi, z, ok in zip(open_idx, cont.z, cont.converged):
                if not ok:
                    continue
                d = np.max(np.abs(chart - z), axis=1)
                j = int(np.argmin(d))
                if d[j] < 1e-6 and j not in taken:
                    taken.add(j)
                    _append(branches[bi], x, sols[j])
                    last[bi] = (sols[j].v, sols[j].phis)
                    still_open.append(bi)
        for j, s in enumerate(sols):
            if j not in taken:
                b = {k: [] for k in ("x", "fx", "fy", "k", "psi", "mode", "energy", "base_moment")}
                _append(b, x, s)
                branches.append(b)
                last.append((s.v, s.phis))
                still_open.append(len(branches) - 1)
        open_idx = still_open
    out = [{k: np.asarray(v, dtype=float) for k, v in b.items()} for b in branches]
    return RodSweep(xs, float(tip_y), results, out)


def _append(b: dict[str, list], x: float, s) -> None:
    b["x"].append(x)
    b["fx"].append(s.tip_force[0])
    b["fy"].append(s.tip_force[1])
    b["k"].append(s.k)
    b["psi"].append(s.psi)
    b["mode"].append(s.mode)
    b["energy"].append(s.energy)
    b["base_moment"].append(s.base_moment)
