"""Planar Cosserat rods (extension, shear, distributed load) and the refinement of Kirchhoff solutions.

The paper's next design stage (§4.2, §8): every Kirchhoff equilibrium found by :func:`flexkin.ik`
/ :func:`flexkin.fk` is followed, by continuation in a homotopy parameter tau, into a planar
Cosserat model with axial extension, shear and self-weight (paper Eqs. 1–7).

* :mod:`~flexkin.cosserat.params` — :class:`CosseratParams` (EA, GA, shear coefficient, weight).
* :mod:`~flexkin.cosserat.rod` — one rod: compiled shooting with analytic Jacobians, shapes.
* :mod:`~flexkin.cosserat.system` — the 12 mechanism equations, batched.
* :mod:`~flexkin.cosserat.continuation` — batched pseudo-arclength continuation with folds.
* :mod:`~flexkin.cosserat.stability` — discretised second variation, smallest eigenvalue.
* :mod:`~flexkin.cosserat.refinement` — :func:`refine`, the mechanism-level refinement.
"""

from .continuation import ContinuationOptions
from .params import CosseratParams, circular_shear_coefficient, params_for_mechanism
from .refinement import refine
from .results import RefinedRod, RefinedSolution, RefineResult
from .rod import RodShape, ShootResult, auto_steps, rod_shape, shoot

__all__ = [
    "CosseratParams", "circular_shear_coefficient", "params_for_mechanism", "refine", "RefineResult",
    "RefinedSolution", "RefinedRod", "ContinuationOptions", "shoot", "rod_shape", "auto_steps",
    "ShootResult", "RodShape",
]
