"""flexkin: complete kinematic analysis of planar parallel continuum mechanisms.

Kirchhoff rods in closed form (elliptic integrals), every inverse- and forward-kinematics
solution over all d-mode combinations, stability, Jacobians, paths and workspaces.

Quick start
-----------
>>> import numpy as np, flexkin
>>> mech = flexkin.load_mechanism("examples/prototype_3pfr.toml")      # doctest: +SKIP
>>> res = flexkin.ik(mech, (0.0, 0.0, np.radians(90)))                 # doctest: +SKIP
>>> print(res.table())                                                 # doctest: +SKIP

The solvers are imported on first use, so ``import flexkin`` stays cheap.
"""

from __future__ import annotations

from typing import Any

from . import _moved
from .core.version import __version__
from .errors import FlexkinWarning, MechanismError
from .mechanism import Leg, Mechanism, Platform, Rod, load_mechanism, mechanism_from_dict

_moved.install()  # import paths of earlier releases keep working for one release (CHANGELOG.md)


__all__ = [
    "FlexkinWarning", "MechanismError", "Leg", "Mechanism", "Platform", "Rod", "load_mechanism",
    "mechanism_from_dict", "ik", "fk", "follow_path", "workspace", "check_feasibility", "solve_rod",
    "RodState", "RodInverseResult", "KinematicsResult", "Solution", "PathResult", "Workspace", "__version__",
    "calibrate", "CalibrationResult",
]

#: public name -> (module, attribute), resolved lazily (PEP 562)
_LAZY = {
    "ik": ("flexkin.solve.ik", "ik"),
    "fk": ("flexkin.solve.fk", "fk"),
    "follow_path": ("flexkin.solve.path", "follow_path"),
    "workspace": ("flexkin.solve.workspace", "workspace"),
    "check_feasibility": ("flexkin.analysis.feasibility", "check_feasibility"),
    "solve_rod": ("flexkin.solve.rod_inverse", "solve_rod"),
    "RodState": ("flexkin.rod.state", "RodState"),
    "RodInverseResult": ("flexkin.solve.rod_inverse", "RodInverseResult"),
    "KinematicsResult": ("flexkin.results", "KinematicsResult"),
    "Solution": ("flexkin.results", "Solution"),
    "PathResult": ("flexkin.solve.path", "PathResult"),
    "Workspace": ("flexkin.solve.workspace", "Workspace"),
    "calibrate": ("flexkin.calibration.fit", "calibrate"),
    "CalibrationResult": ("flexkin.calibration.result", "CalibrationResult"),
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        mod, attr = _LAZY[name]
        value = getattr(importlib.import_module(mod), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'flexkin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
