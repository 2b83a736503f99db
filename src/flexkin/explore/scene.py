"""Drawing data for the explorer: plain dicts of lists / arrays, one per drawn layer, ready to
become the browser's data sources (no web import here).

Colours follow the library's figures: the selected equilibrium's rods in the leg colours
(:data:`flexkin.plot.mechanism.LEG_COLORS`), the other equilibria in the colour of their d-mode
combination (:func:`flexkin.plot.style.mode_color`), solid when stable and dashed otherwise.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from flexkin.plot.mechanism import LEG_COLORS
from flexkin.plot.style import mode_color
from flexkin.rod.state import centre_lines

from .state import ExplorerState, input_bounds

__all__ = ["LEG_COLORS", "ROD_POINTS", "SELECTED_POINTS", "base_layers", "scene", "ShapeCache", "empty_scene"]

#: Points per rod polyline for the other equilibria and for the selected one.
ROD_POINTS = 40
SELECTED_POINTS = 90
PLATFORM_FILL = "#c6dbef"
PLATFORM_LINE = "#08519c"
GUIDE_COLOR = "#8c8c8c"
BASE_COLOR = "#404040"


class ShapeCache:
    """Rod polylines of solutions, computed once per solution object (solutions are immutable),
    many at a time (:func:`flexkin.rod.state.centre_lines`)."""

    def __init__(self, limit: int = 600) -> None:
        self._d: dict[tuple[int, int], tuple[Any, list[np.ndarray]]] = {}
        self.limit = limit

    def _hit(self, sol, n: int) -> list[np.ndarray] | None:
        hit = self._d.get((id(sol), n))
        return hit[1] if hit is not None and hit[0] is sol else None

    def fill(self, sols, n: int) -> None:
        """Compute the polylines (``n`` points per rod) of those of ``sols`` not cached yet."""
        todo = [s for s in sols if self._hit(s, n) is None]
        if not todo:
            return
        if len(self._d) + len(todo) > self.limit:
            self._d.clear()
        lines = centre_lines([r for s in todo for r in s.rods], n)
        k = 0
        for s in todo:
            self._d[(id(s), n)] = (s, list(lines[k:k + len(s.rods)]))
            k += len(s.rods)

    def shapes(self, sol, n: int) -> list[np.ndarray]:
        hit = self._hit(sol, n)
        if hit is None:
            self.fill((sol,), n)
            hit = self._hit(sol, n)
        return hit


def _layers() -> dict[str, dict[str, list]]:
    return {
        "rods_solid": {"xs": [], "ys": [], "color": [], "sid": [], "leg": []},
        "rods_dashed": {"xs": [], "ys": [], "color": [], "sid": [], "leg": []},
        "rods_selected": {"xs": [], "ys": [], "color": [], "sid": [], "leg": []},
        "clamps": {"x": [], "y": [], "color": []},
        "platforms": {"xs": [], "ys": [], "fill_alpha": [], "line_alpha": [], "sid": []},
        "handle": {"xs": [], "ys": [], "px": [], "py": []},
        "joints": {"x": [], "y": []},
    }


def empty_scene() -> dict[str, dict[str, list]]:
    """All layers, empty."""
    return _layers()


def scene(state: ExplorerState, cache: ShapeCache | None = None) -> dict[str, dict[str, list]]:
    """The drawing of the current state: the visible equilibria's rods (``rods_solid``,
    ``rods_dashed``, ``rods_selected``), the selected rods' clamps, the platforms of the drawn
    equilibria (``platforms``; in IK mode they coincide with the handle), the platform the user
    drags (``handle``, at the current pose in IK mode, else at the selected solution's pose) and
    its joints."""
    cache = cache or ShapeCache()
    out = _layers()
    mech = state.mech
    handle_pose = None
    if state.mode == "ik":
        handle_pose = tuple(float(v) for v in state.pose)
    elif state.selected is not None:
        handle_pose = tuple(float(v) for v in state.selected.pose)
    visible = state.visible()
    cache.fill([sol for sol, sel in visible if sel], SELECTED_POINTS)
    cache.fill([sol for sol, sel in visible if not sel], ROD_POINTS)
    for sol, sel in visible:
        label = sol.mode_label
        if sel:
            for i, xy in enumerate(cache.shapes(sol, SELECTED_POINTS)):
                lay = out["rods_selected"]
                lay["xs"].append(xy[:, 0].tolist())
                lay["ys"].append(xy[:, 1].tolist())
                lay["color"].append(LEG_COLORS[i])
                lay["sid"].append(int(sol.id))
                lay["leg"].append(i + 1)
                out["clamps"]["x"].append(float(xy[0, 0]))
                out["clamps"]["y"].append(float(xy[0, 1]))
                out["clamps"]["color"].append(LEG_COLORS[i])
        else:
            lay = out["rods_solid"] if sol.stable is True else out["rods_dashed"]
            col = mode_color(label)
            for i, xy in enumerate(cache.shapes(sol, ROD_POINTS)):
                lay["xs"].append(xy[:, 0].tolist())
                lay["ys"].append(xy[:, 1].tolist())
                lay["color"].append(col)
                lay["sid"].append(int(sol.id))
                lay["leg"].append(i + 1)
        same = handle_pose is not None and max(abs(a - b) for a, b in zip(sol.pose, handle_pose)) < 1e-9
        if not same:  # platforms of equilibria elsewhere (FK mode, or out-of-date IK results)
            B = np.asarray(mech.platform.world(sol.pose), dtype=float)
            out["platforms"]["xs"].append(B[:, 0].tolist())
            out["platforms"]["ys"].append(B[:, 1].tolist())
            out["platforms"]["fill_alpha"].append(0.5 if sel else 0.08)
            out["platforms"]["line_alpha"].append(1.0 if sel else 0.35)
            out["platforms"]["sid"].append(int(sol.id))
    if handle_pose is not None:
        B = np.asarray(mech.platform.world(handle_pose), dtype=float)
        out["handle"]["xs"].append(B[:, 0].tolist())
        out["handle"]["ys"].append(B[:, 1].tolist())
        out["handle"]["px"].append(handle_pose[0])
        out["handle"]["py"].append(handle_pose[1])
        out["joints"]["x"].extend(B[:, 0].tolist())
        out["joints"]["y"].extend(B[:, 1].tolist())
    return out


def base_layers(mech) -> dict[str, dict[str, list]]:
    """The fixed parts: each leg's guide (prismatic: the whole slider stroke; length: the
    sleeve; revolute: a short ground bar) and its origin, with the leg number."""
    guides: dict[str, list] = {"xs": [], "ys": [], "color": []}
    origins: dict[str, list] = {"x": [], "y": [], "color": [], "label": [], "lx": [], "ly": []}
    scale = float(mech.length_scale)
    centroid = np.asarray(mech.base_centroid, dtype=float)
    for i, leg in enumerate(mech.legs):
        o = np.asarray(leg.origin, dtype=float)
        d = np.array([math.cos(leg.angle), math.sin(leg.angle)])
        if leg.actuation == "prismatic":
            lo, hi = input_bounds(mech, i)  # of the input u; the slider sits at u + offset
            a, b = o + (lo + leg.offset) * d, o + (hi + leg.offset) * d
        elif leg.actuation == "length":
            a, b = o - 0.1 * scale * d, o
        else:
            n = np.array([-d[1], d[0]]) if leg.actuation == "revolute" else d
            a, b = o - 0.04 * scale * n, o + 0.04 * scale * n
        guides["xs"].append([float(a[0]), float(b[0])])
        guides["ys"].append([float(a[1]), float(b[1])])
        guides["color"].append(GUIDE_COLOR)
        away = o - centroid
        nrm = float(np.hypot(*away))
        away = away / nrm if nrm > 0 else np.array([0.0, -1.0])
        lab = o + 0.08 * scale * away
        origins["x"].append(float(o[0]))
        origins["y"].append(float(o[1]))
        origins["color"].append(LEG_COLORS[i])
        origins["label"].append(str(i + 1))
        origins["lx"].append(float(lab[0]))
        origins["ly"].append(float(lab[1]))
    return {"guides": guides, "origins": origins}
