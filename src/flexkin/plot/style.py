"""Shared figure conventions: one colour per d-mode combination, figure creation."""

from __future__ import annotations

import itertools
from typing import Any

__all__ = ["mode_color", "new_figure", "save"]

_PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
            "#bcbd22", "#7f7f7f"]
_SINGLE = {1: "#1f77b4", 2: "#d62728", 3: "#2ca02c", 4: "#9467bd"}


def _labels(max_mode: int = 3) -> list[str]:
    return ["".join(map(str, c)) for c in itertools.product(range(1, max_mode + 1), repeat=3)]


def mode_color(label: str | int) -> str:
    """Colour of a d-mode combination (``"112"``) or of a single rod's d-mode (``2``).

    The combinations of modes 1–2 get eight distinct colours in a fixed order, so that
    every figure colours the same combination alike.
    """
    if isinstance(label, (int,)) or (isinstance(label, str) and len(label) == 1):
        return _SINGLE.get(int(label), "#7f7f7f")
    labels = _labels(2)
    if label in labels:
        return _PALETTE[labels.index(label)]
    return _PALETTE[8 + (hash(label) % 2)]


def new_figure(**kwargs: Any):
    """A matplotlib Figure not attached to pyplot (safe in libraries and with Agg)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def save(fig, path, tight: bool = True) -> None:
    """Save a figure with the house settings.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or path-like
        Output file; the format follows the extension.
    tight : bool
        Crop to the drawn content (one more drawing pass; figures laid out on a fixed grid
        do without).
    """
    fig.savefig(path, dpi=150, bbox_inches="tight" if tight else None)
