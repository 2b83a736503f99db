"""Cosserat material data of a mechanism: per-leg ``G``/``poisson``, ``density``,
``shear_coefficient`` and the ``[environment] gravity`` of its file (issue 16).

The values are validated by the loader (``flexkin.mechanism.loader``)
and carried by ``Rod.G``, ``Rod.poisson``, ``Rod.density``, ``Rod.shear_coefficient`` and
``Mechanism.gravity``.
"""

from __future__ import annotations

from typing import Any, Sequence

__all__ = ["leg_materials", "cosserat_setup"]

_KEYS = ("G", "poisson", "density", "shear_coefficient")


def leg_materials(mech: Any) -> list[dict[str, float]]:
    """Per leg, the material keys given for it (``[rod]`` defaults and the leg's overrides).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.

    Returns
    -------
    list of dict
        Per leg, ``G``, ``poisson``, ``density``, ``shear_coefficient`` where given.
    """
    return [{k: getattr(leg.rod, k) for k in _KEYS if getattr(leg.rod, k) is not None} for leg in mech.legs]


def cosserat_setup(mech: Any, gravity: Sequence[float] | None = None) -> tuple[tuple[Any, ...], tuple[float, float] | None]:
    """Per-leg :class:`~flexkin.cosserat.CosseratParams` from each rod's ``E``, ``radius`` and
    material keys, and the gravity vector (``gravity`` if given, else the file's).

    Parameters
    ----------
    mech : Mechanism
        The mechanism; every rod needs ``E`` and ``radius``.
    gravity : (gx, gy), optional
        In-plane gravity (m/s^2); default :attr:`Mechanism.gravity`.

    Returns
    -------
    params : tuple of CosseratParams
        One per leg.
    gravity : (gx, gy) or None

    Raises
    ------
    ValueError
        Naming the leg, when a rod lacks ``E`` or ``radius``.
    """
    from ..cosserat import CosseratParams

    mats = leg_materials(mech)
    params = []
    for i, (leg, m) in enumerate(zip(mech.legs, mats)):
        if leg.rod.E is None or leg.rod.radius is None:
            raise ValueError(f"leg[{i + 1}]: the Cosserat refinement needs E and radius for every rod (give them in "
                             "[rod] or the [[leg]]; EI alone has no extension or shear stiffness)")
        params.append(CosseratParams.from_material(leg.rod.E, leg.rod.radius, G=m.get("G"), poisson=m.get("poisson"),
                                                   density=m.get("density", 0.0),
                                                   shear_coefficient=m.get("shear_coefficient")))
    g = mech.gravity if gravity is None else (float(gravity[0]), float(gravity[1]))
    return tuple(params), g
