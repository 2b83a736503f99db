"""Clamped–pinned Kirchhoff rods in closed form (paper §2) and the single-rod inverse problem."""

from .atlas import Atlas, get_atlas
from .closed_form import (
    ellipe_inc, ellipf, k_from_kr, k_min, kr_from_k, mode_of, phi1_of, rod_shape, rod_tip,
    tip_unit, to_paper, to_unified,
)
from .state import RodState

__all__ = [
    "Atlas", "get_atlas", "ellipe_inc", "ellipf", "k_from_kr", "k_min", "kr_from_k", "mode_of",
    "phi1_of", "rod_shape", "rod_tip", "tip_unit", "to_paper", "to_unified",
    "RodInverseResult", "solve_rod", "RodState",
]


def __getattr__(name: str):
    # the single-rod inverse problem is loaded on first use: the mechanism solvers import this
    # package without needing it
    if name in ("RodInverseResult", "solve_rod"):
        from . import inverse

        return getattr(inverse, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
