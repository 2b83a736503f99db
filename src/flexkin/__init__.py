"""flexkin: complete kinematic analysis of planar parallel continuum mechanisms.

Kirchhoff rods in closed form (elliptic integrals), every inverse- and forward-kinematics
solution over all d-mode combinations, stability, Jacobians and workspaces.

Quick start
-----------
>>> import numpy as np, flexkin
>>> mech = flexkin.load_mechanism("examples/prototype_3pfr.toml")      # doctest: +SKIP
>>> res = flexkin.ik(mech, (0.0, 0.0, np.radians(90)))                 # doctest: +SKIP
>>> print(res.table())                                                 # doctest: +SKIP
"""

from .errors import FlexkinWarning, MechanismError
from .kinematics import KinematicsResult, Solution, fk, ik
from .mechanism import Leg, Mechanism, Platform, Rod, load_mechanism
from .rod import RodInverseResult, RodState, solve_rod

__version__ = "0.1.0"

__all__ = [
    "FlexkinWarning", "MechanismError", "KinematicsResult", "Solution", "fk", "ik", "Leg", "Mechanism",
    "Platform", "Rod", "load_mechanism", "RodInverseResult", "RodState", "solve_rod", "__version__",
]
