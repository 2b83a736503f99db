"""Clamped–pinned Kirchhoff rods in closed form (paper §2) and the single-rod inverse problem."""

from .atlas import Atlas, get_atlas
from .closed_form import (
    ellipe_inc, ellipf, k_from_kr, k_min, kr_from_k, mode_of, phi1_of, rod_shape, rod_tip,
    tip_unit, to_paper, to_unified,
)
from .inverse import RodInverseResult, solve_rod
from .state import RodState

__all__ = [
    "Atlas", "get_atlas", "ellipe_inc", "ellipf", "k_from_kr", "k_min", "kr_from_k", "mode_of",
    "phi1_of", "rod_shape", "rod_tip", "tip_unit", "to_paper", "to_unified",
    "RodInverseResult", "solve_rod", "RodState",
]
