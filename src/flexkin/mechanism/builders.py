"""Programmatic construction of standard mechanisms (used by tests and examples).

:func:`symmetric_mechanism` builds the C3-symmetric mechanisms of the paper's kind: base
vertices ``V_i = base_radius (cos a_i, sin a_i)`` and platform attach points
``b_i = platform_radius (cos a_i, sin a_i)`` with ``a_i = 210°, 330°, 90°`` (i = 1, 2, 3),
the same ordering as ``examples/prototype_3pfr.toml``.  Rotating the mechanism by 120° about
the origin maps leg i onto leg i+1 (indices mod 3).
"""

from __future__ import annotations

import math

from flexkin.errors import MechanismError
from flexkin.mechanism.model import ACTUATIONS, Actuation, Leg, Mechanism, Platform, Rod

__all__ = ["symmetric_mechanism", "SYMMETRIC_VERTEX_ANGLES_DEG"]

#: Polar angles a_i (deg) of base vertex i and platform attach point i.
SYMMETRIC_VERTEX_ANGLES_DEG: tuple[float, float, float] = (210.0, 330.0, 90.0)

#: Prismatic guide directions (deg): leg i runs along the base-triangle edge V_i -> V_{i+1}.
_PRISMATIC_ANGLES_DEG = (0.0, 120.0, 240.0)

_KIND = {"prismatic": "3-PFR", "revolute": "3-RFR", "length": "3-PFR(length)"}


def _snap(v: float, scale: float) -> float:
    """Exact zero for round-off values such as cos(90°) (keeps files and builders identical).

    The threshold is relative to ``scale`` (the radius the value was computed from), so that
    tiny mechanisms keep their geometry.
    """
    return 0.0 if abs(v) < 1e-15 * scale else v


def symmetric_mechanism(
    actuation: Actuation,
    *,
    base_radius: float = 1.0,
    platform_radius: float = 0.25,
    length: float = 1.0,
    EI: float = 1.0,
    name: str | None = None,
) -> Mechanism:
    """C3-symmetric mechanism with three identical legs of one actuation type.

    Parameters
    ----------
    actuation : {"prismatic", "revolute", "length"}
        Leg type.
        ``"prismatic"``: leg i's guide starts at base vertex ``V_i`` and runs along the base
        triangle edge towards ``V_{i+1}`` (angles 0°, 120°, 240°), as in the prototype file;
        ``"revolute"``: joint at ``V_i`` (file angle 0);
        ``"length"``: guide exit at ``V_i``, pointing from ``V_i`` to the base centroid
        (angles 30°, 150°, 270°), so the rods leave the guides towards the centre.
    base_radius : float, optional
        Circumradius of the base triangle (m).
    platform_radius : float, optional
        Circumradius of the platform triangle (m).
    length : float, optional
        Rod length (m); unused for length legs.
    EI : float, optional
        Bending stiffness (N m^2).
    name : str, optional
        Mechanism name; default ``"unit <kind>"``.

    Returns
    -------
    Mechanism
        With zero load and no ranges or strain limit.
    """
    if actuation not in ACTUATIONS:
        raise MechanismError(
            f"actuation: unknown actuation {actuation!r} (expected one of {', '.join(map(repr, ACTUATIONS))})"
        )
    for what, v in (("base_radius", base_radius), ("platform_radius", platform_radius)):
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0):
            raise MechanismError(f"{what}: must be a finite number > 0, got {v!r}")
    a = [math.radians(d) for d in SYMMETRIC_VERTEX_ANGLES_DEG]
    attach = tuple(
        (_snap(platform_radius * math.cos(t), platform_radius), _snap(platform_radius * math.sin(t), platform_radius))
        for t in a
    )
    rod = Rod(length=None if actuation == "length" else length, EI=EI)
    legs = []
    for i, t in enumerate(a):
        origin = (_snap(base_radius * math.cos(t), base_radius), _snap(base_radius * math.sin(t), base_radius))
        if actuation == "prismatic":
            angle = math.radians(_PRISMATIC_ANGLES_DEG[i])
        elif actuation == "revolute":
            angle = 0.0
        else:  # from V_i towards the centroid (0, 0)
            angle = math.radians((SYMMETRIC_VERTEX_ANGLES_DEG[i] + 180.0) % 360.0)
        legs.append(Leg(actuation=actuation, origin=origin, angle=angle, rod=rod))
    return Mechanism(
        name=name if name is not None else f"unit {_KIND[actuation]}",
        legs=tuple(legs),  # type: ignore[arg-type]
        platform=Platform(attach=attach),  # type: ignore[arg-type]
    )
