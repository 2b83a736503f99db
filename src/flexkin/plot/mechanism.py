"""Drawing a mechanism: base guides/joints, platform, rods.

matplotlib is imported lazily inside the functions; figures are created with
:class:`matplotlib.figure.Figure` (no pyplot state, safe with the Agg backend).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from flexkin.mechanism.model import Leg, Mechanism

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

__all__ = ["plot_mechanism", "plot_mechanism_file", "LEG_COLORS"]

#: Colour of leg i's rod (matplotlib tab10 blue, orange, green).
LEG_COLORS: tuple[str, str, str] = ("#1f77b4", "#ff7f0e", "#2ca02c")
_GUIDE = "0.55"
_BASE = "0.25"


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _draw_ground(ax: Axes, p: np.ndarray, size: float, zorder: float = 2.0) -> None:
    """Ground symbol (a bar with hatch ticks) just below point ``p``."""
    y = p[1] - 0.9 * size
    ax.plot([p[0] - size, p[0] + size], [y, y], color=_BASE, lw=1.5, zorder=zorder, solid_capstyle="butt")
    for t in np.linspace(-size, size * 0.6, 5):
        ax.plot([p[0] + t, p[0] + t + 0.4 * size], [y, y - 0.5 * size], color=_BASE, lw=0.8, zorder=zorder)
    ax.plot([p[0], p[0]], [p[1], y], color=_BASE, lw=1.2, zorder=zorder)


def _draw_leg_base(ax: Axes, leg: Leg, scale: float, u: float | None) -> None:
    """Fixed parts of a leg (and the actuated clamp if the input ``u`` is given)."""
    o = np.asarray(leg.origin, dtype=float)
    d = _unit(leg.angle)
    mark = 0.03 * scale
    if leg.actuation == "prismatic":
        L = float(leg.rod.length)  # type: ignore[arg-type]
        lo, hi = 0.0, 0.5 * L
        if leg.range is not None:  # a range of the input u; the slider sits at u + offset
            lo, hi = min(lo, leg.range[0] + leg.offset), max(hi, leg.range[1] + leg.offset)
        if u is not None:
            lo, hi = min(lo, u + leg.offset), max(hi, u + leg.offset)
        a, b = o + lo * d, o + hi * d
        ax.plot([a[0], b[0]], [a[1], b[1]], color=_GUIDE, lw=6, alpha=0.6, solid_capstyle="butt", zorder=1)
        ax.plot(*o, marker="o", ms=5, mfc="white", mec=_BASE, zorder=3)
        if u is not None:  # the slider carrying the clamp (at u + offset)
            c = np.asarray(leg.clamp(u)[0], dtype=float)
            ax.plot(*c, marker="s", ms=9, mfc="0.8", mec=_BASE, zorder=3)
    elif leg.actuation == "revolute":
        _draw_ground(ax, o, mark, zorder=2)
        ax.plot(*o, marker="o", ms=9, mfc="white", mec=_BASE, mew=1.5, zorder=3)
        if u is not None:  # clamp tangent direction (input + offset)
            t = o + 2.5 * mark * _unit(u + leg.offset)
            ax.plot([o[0], t[0]], [o[1], t[1]], color=_BASE, lw=1.5, zorder=3)
    else:  # length: a sleeve behind the exit point
        back = o - 3.0 * mark * d
        ax.plot([back[0], o[0]], [back[1], o[1]], color=_GUIDE, lw=9, solid_capstyle="butt", zorder=1)
        ax.plot([back[0], o[0]], [back[1], o[1]], color="white", lw=2.5, solid_capstyle="butt", zorder=1.5)
        ax.plot(*o, marker="o", ms=4, mfc=_BASE, mec=_BASE, zorder=3)


def plot_mechanism(
    mech: Mechanism,
    pose: ArrayLike | None = None,
    rods: Sequence[ArrayLike] | None = None,
    ax: Axes | None = None,
    title: str | None = None,
    inputs: ArrayLike | None = None,
) -> Axes:
    """Draw a mechanism at a platform pose, optionally with its rods.

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    pose : array_like, optional
        Platform pose ``(x, y, theta)`` (m, m, rad); default ``(0, 0, 0)``.
    rods : sequence of three array_like, optional
        World-frame rod polylines, each of shape (n, 2), drawn in the leg colours with the
        clamp (first point) as a filled square.
    ax : matplotlib.axes.Axes, optional
        Axes to draw into; default a new figure (not registered with pyplot).
    title : str, optional
        Title; default the mechanism's name and kind.
    inputs : array_like, optional
        Actuator inputs (internal units: m, or rad for revolute legs); draws the prismatic
        sliders / revolute clamp directions at these inputs.

    Returns
    -------
    matplotlib.axes.Axes
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    if ax is None:
        fig = Figure(figsize=(6.4, 6.0), layout="constrained")
        ax = fig.add_subplot()
    pose_a = np.zeros(3) if pose is None else np.asarray(pose, dtype=float).reshape(3)
    u_all: list[float | None] = [None, None, None]
    if inputs is not None:
        u_arr = np.asarray(inputs, dtype=float).reshape(3)
        u_all = [float(v) for v in u_arr]
    scale = mech.length_scale
    centroid = mech.base_centroid
    label_pts: list[np.ndarray] = []

    for i, leg in enumerate(mech.legs):
        _draw_leg_base(ax, leg, scale, u_all[i])
        o = np.asarray(leg.origin, dtype=float)
        away = o - centroid
        n = float(np.hypot(*away))
        away = away / n if n > 0 else np.array([0.0, -1.0])
        if leg.actuation == "length":  # the sleeve points away from the centre: label beside it
            d = _unit(leg.angle)
            side = np.array([-d[1], d[0]])
            lab = o + 0.08 * scale * side - 0.05 * scale * d
        else:
            lab = o + 0.08 * scale * away
        label_pts.append(lab)
        ax.annotate(  # leg number, offset from the origin away from the base centroid
            str(i + 1),
            xy=lab,
            ha="center",
            va="center",
            fontsize=11,
            fontweight="bold",
            color=LEG_COLORS[i],
            zorder=6,
        )

    # rods
    if rods is not None:
        rods_l = list(rods)
        if len(rods_l) != 3:
            raise ValueError(f"rods must be a sequence of three (n, 2) arrays, got {len(rods_l)}")
        for i, r in enumerate(rods_l):
            xy = np.asarray(r, dtype=float)
            if xy.ndim != 2 or xy.shape[1] != 2:
                raise ValueError(f"rods[{i}] must have shape (n, 2), got {xy.shape}")
            ax.plot(xy[:, 0], xy[:, 1], color=LEG_COLORS[i], lw=2.0, zorder=4, label=f"rod {i + 1}")
            ax.plot(*xy[0], marker="s", ms=7, color=LEG_COLORS[i], mec="black", mew=0.6, zorder=5)

    # platform
    B = mech.platform.world(pose_a)
    ax.add_patch(Polygon(B, closed=True, fc="#c6dbef", ec="#08519c", lw=1.5, alpha=0.9, zorder=4.5))
    ax.plot(B[:, 0], B[:, 1], ls="none", marker="o", ms=6, mfc="white", mec="#08519c", mew=1.3, zorder=5.5)
    ax.plot(pose_a[0], pose_a[1], marker="x", ms=8, mew=2, color="#08519c", zorder=5.5)

    ax.update_datalim(np.asarray(label_pts))  # annotations do not take part in autoscaling
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.autoscale_view()
    ax.margins(0.08)
    if title is None:
        title = f"{mech.name} [{mech.kind}]"
    ax.set_title(title)
    return ax


def plot_mechanism_file(mech: Mechanism, path: str | os.PathLike[str], **kwargs: Any) -> Path:
    """Draw a mechanism and save the figure (dpi 150).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    path : str or os.PathLike
        Output file; the format follows the extension (png, pdf, svg, ...).
    **kwargs
        Passed to :func:`plot_mechanism` (``pose``, ``rods``, ``title``, ``inputs``).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    ax = plot_mechanism(mech, **kwargs)
    out = Path(path)
    ax.figure.savefig(out, dpi=150)
    return out
