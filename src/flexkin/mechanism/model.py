"""Mechanism data model: :class:`Rod`, :class:`Leg`, :class:`Platform`, :class:`Mechanism`.

Conventions (SPEC §2)
---------------------
SI units and **radians** everywhere in this module; degrees only appear in files, on the
command line and through :meth:`Leg.to_display` / :meth:`Leg.from_display`.

A leg's actuator input ``u`` and its clamp (the rod's base, where the rod is clamped):

* ``"prismatic"``: ``u = rho`` (m); clamp point ``A = origin + rho (cos angle, sin angle)``,
  clamp tangent angle ``alpha = angle``, free rod length ``L = rod.length``;
* ``"revolute"``: ``u = phi`` (rad); ``A = origin``, ``alpha = phi``, ``L = rod.length``;
* ``"length"``: ``u = s`` (m); ``A = origin`` (the fixed guide's exit), ``alpha = angle``,
  ``L = s``.

The platform pose is ``(x, y, theta)`` of its reference point P; the attach points are
``B_i = P + Rot(theta) b_i``.

All classes are frozen dataclasses holding plain floats and tuples (hashable); they are
validated on construction and raise :class:`~flexkin.errors.MechanismError` for invalid
parameters.  The file loader (:mod:`flexkin.mechanism.loader`) checks everything first and
gives messages naming the file and key; the checks here are the safety net for mechanisms
built in code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flexkin.core.geometry2d import platform_points
from flexkin.errors import MechanismError
from flexkin.mechanism.actuators import ACTUATORS, Actuator
from flexkin.mechanism.joints import JOINTS, Joint

__all__ = [
    "Actuation",
    "ACTUATIONS",
    "Rod",
    "Leg",
    "Platform",
    "Mechanism",
    "circular_EI",
    "LENGTH_LIMITS",
    "STIFFNESS_LIMITS",
]

Actuation = Literal["prismatic", "revolute", "length"]
ACTUATIONS: tuple[str, ...] = tuple(ACTUATORS)
JointName = Literal["pinned", "clamped"]


def circular_EI(E: float, radius: float) -> float:
    """Bending stiffness of a circular cross-section.

    Parameters
    ----------
    E : float
        Young's modulus (Pa).
    radius : float
        Section radius (m).

    Returns
    -------
    float
        ``E * pi * radius**4 / 4`` (N m^2); ``inf`` if that overflows.
    """
    try:
        return float(E) * math.pi * float(radius) ** 4 / 4.0
    except OverflowError:
        return math.inf


#: Supported range of every length-like quantity (m): rod lengths and radii, the platform size,
#: and the largest coordinate magnitude (origins, attach points, prismatic/length strokes).
#: Far beyond any real mechanism, and narrow enough that squares and fourth powers (EI/L^2,
#: E pi r^4 / 4, ...) never overflow or underflow in double precision.
LENGTH_LIMITS: tuple[float, float] = (1e-12, 1e12)

#: Supported range of the bending stiffness EI (N m^2) and of Young's modulus E (Pa).
STIFFNESS_LIMITS: tuple[float, float] = (1e-30, 1e30)


def _short(value: object) -> str:
    try:
        s = repr(value)
    except (ValueError, RecursionError):  # integers with thousands of digits, deep nesting
        return f"<{type(value).__name__} too large to show>"
    return s if len(s) <= 60 else s[:57] + "..."


def _finite(value: object, what: str) -> float:
    """Return ``value`` as a finite float or raise :class:`MechanismError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise MechanismError(f"{what}: expected a number, got {_short(value)}")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond the float range
        raise MechanismError(f"{what}: expected a finite number, got an integer too large for a float") from None
    if not math.isfinite(v):
        raise MechanismError(f"{what}: expected a finite number, got {v!r}")
    return v


def _positive(value: object, what: str) -> float:
    v = _finite(value, what)
    if v <= 0.0:
        raise MechanismError(f"{what}: must be > 0, got {v!r}")
    return v


def _within(v: float, limits: tuple[float, float], what: str, unit: str) -> float:
    """``v`` (> 0) if it lies in ``limits``, else a MechanismError naming the supported range."""
    lo, hi = limits
    if not lo <= v <= hi:
        raise MechanismError(f"{what}: {v:.6g} {unit} is outside the supported range [{lo:g}, {hi:g}] {unit}")
    return v


def _bounded_point(value: object, what: str) -> tuple[float, float]:
    """:func:`_point` whose coordinates are within +-LENGTH_LIMITS[1] (m)."""
    p = _point(value, what)
    hi = LENGTH_LIMITS[1]
    if max(abs(p[0]), abs(p[1])) > hi:
        raise MechanismError(f"{what}: coordinates must be within +-{hi:g} m, got ({p[0]:.6g}, {p[1]:.6g})")
    return p


def _point(value: object, what: str) -> tuple[float, float]:
    try:
        seq = tuple(value)  # type: ignore[arg-type]
    except TypeError:
        raise MechanismError(f"{what}: expected two numbers (x, y), got {_short(value)}") from None
    if len(seq) != 2:
        raise MechanismError(f"{what}: expected two numbers (x, y), got {_short(value)}")
    return (_finite(seq[0], what), _finite(seq[1], what))


# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rod:
    """Elastic rod properties.

    Parameters
    ----------
    length : float or None
        Rod length (m).  ``None`` for length-actuated legs, whose input *is* the free length.
    EI : float
        Bending stiffness (N m^2), > 0.
    radius : float, optional
        Radius of the circular cross-section (m); needed only for strain checks.
    E : float, optional
        Young's modulus (Pa); informative only (``EI`` is what the mechanics use).
    G : float, optional
        Shear modulus (Pa), for the Cosserat refinement (:mod:`flexkin.cosserat`).
    poisson : float, optional
        Poisson's ratio, in (-1, 0.5]; gives ``G = E / (2 (1 + poisson))`` when ``G`` is absent.
    density : float, optional
        Mass density (kg/m^3), for the rods' self-weight in the Cosserat refinement.
    shear_coefficient : float, optional
        Timoshenko shear coefficient of the section (default: the circular section's).
    """

    length: float | None
    EI: float
    radius: float | None = None
    E: float | None = None
    G: float | None = None
    poisson: float | None = None
    density: float | None = None
    shear_coefficient: float | None = None

    def __post_init__(self) -> None:
        if self.length is not None:
            v = _positive(self.length, "rod.length")
            object.__setattr__(self, "length", _within(v, LENGTH_LIMITS, "rod.length", "m"))
        v = _positive(self.EI, "rod.EI")
        object.__setattr__(self, "EI", _within(v, STIFFNESS_LIMITS, "rod.EI", "N m^2"))
        if self.radius is not None:
            v = _positive(self.radius, "rod.radius")
            object.__setattr__(self, "radius", _within(v, LENGTH_LIMITS, "rod.radius", "m"))
        if self.E is not None:
            v = _positive(self.E, "rod.E")
            object.__setattr__(self, "E", _within(v, STIFFNESS_LIMITS, "rod.E", "Pa"))

    @classmethod
    def circular(cls, length: float | None, E: float, radius: float) -> Rod:
        """Rod of circular section, ``EI = E pi radius**4 / 4``.

        Parameters
        ----------
        length : float or None
            Rod length (m), ``None`` for length-actuated legs.
        E : float
            Young's modulus (Pa).
        radius : float
            Section radius (m).

        Returns
        -------
        Rod
        """
        E = _within(_positive(E, "rod.E"), STIFFNESS_LIMITS, "rod.E", "Pa")
        radius = _within(_positive(radius, "rod.radius"), LENGTH_LIMITS, "rod.radius", "m")
        return cls(length=length, EI=circular_EI(E, radius), radius=radius, E=E)

    def strain(self, curvature: ArrayLike) -> NDArray[np.float64]:
        """Maximum bending strain ``radius * |curvature|`` of the section.

        Parameters
        ----------
        curvature : array_like
            Curvature (1/m).

        Returns
        -------
        ndarray
            Strain (dimensionless), same shape as ``curvature``.

        Raises
        ------
        MechanismError
            If the rod has no ``radius``.
        """
        if self.radius is None:
            raise MechanismError("rod.radius: needed for strain checks but not given")
        return self.radius * np.abs(np.asarray(curvature, dtype=float))


# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Leg:
    """One leg = an actuator + an elastic rod + a platform joint (paper §3, Fig. 3; §8).

    The fields are the plain data of the mechanism file; the behaviour is composed from the
    registries: :attr:`actuator` (:data:`~flexkin.mechanism.actuators.ACTUATORS`) maps the
    input to the rod's clamp, :attr:`platform_joint` (:data:`~flexkin.mechanism.joints.JOINTS`)
    sets the rod's conditions at ``B_i``.

    Parameters
    ----------
    actuation : {"prismatic", "revolute", "length"}
        Actuator kind (SPEC §2).
    origin : tuple of float
        Base point (m, world frame): start of the prismatic guide, revolute joint centre,
        or exit of the length-actuation guide.
    angle : float
        Guide direction (rad) for prismatic legs, guide exit direction for length legs;
        for revolute legs the optional file value (default 0), unused by the kinematics.
    rod : Rod
        The leg's rod (``rod.length`` is ignored for length legs).
    range : tuple of float, optional
        Actuator stroke ``(lo, hi)`` in internal units (m, or rad for revolute legs).
    joint : {"pinned", "clamped"}
        Rod-platform joint (default ``"pinned"``).
    tip_angle : float
        Clamped joints: the rod's tangent at ``B_i`` in the platform frame (rad).
    offset : float
        Input zero offset in internal units (m, or rad for revolute legs): the leg behaves as
        if its input were ``u + offset`` (SPEC §4; applied by the actuator only).
    """

    actuation: Actuation
    origin: tuple[float, float]
    angle: float
    rod: Rod
    range: tuple[float, float] | None = None
    joint: JointName = "pinned"
    tip_angle: float = 0.0
    offset: float = 0.0
    actuator: Actuator = field(init=False, repr=False, compare=False)
    platform_joint: Joint = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.actuation not in ACTUATIONS:
            raise MechanismError(
                f"leg.actuation: unknown actuation {self.actuation!r} "
                f"(expected one of {', '.join(map(repr, ACTUATIONS))})"
            )
        if self.joint not in JOINTS:
            raise MechanismError(
                f"leg.joint: unknown joint {self.joint!r} (expected one of {', '.join(map(repr, JOINTS))})"
            )
        object.__setattr__(self, "origin", _bounded_point(self.origin, "leg.origin"))
        object.__setattr__(self, "angle", _finite(self.angle, "leg.angle"))
        object.__setattr__(self, "tip_angle", _finite(self.tip_angle, "leg.tip_angle"))
        object.__setattr__(self, "offset", _finite(self.offset, "leg.offset"))
        if self.actuation != "revolute" and abs(self.offset) > LENGTH_LIMITS[1]:
            raise MechanismError(f"leg.offset: must be within +-{LENGTH_LIMITS[1]:g} m, got {self.offset:.6g}")
        if not isinstance(self.rod, Rod):
            raise MechanismError(f"leg.rod: expected a Rod, got {self.rod!r}")
        if self.actuation != "length" and self.rod.length is None:
            raise MechanismError(f"leg.rod.length: a {self.actuation} leg needs a rod length")
        if self.range is not None:
            lo, hi = _point(self.range, "leg.range")
            if self.actuation != "revolute":
                _bounded_point((lo, hi), "leg.range")
            if not lo < hi:
                raise MechanismError(f"leg.range: lower bound must be < upper bound, got {self.range!r}")
            if self.actuation == "length" and lo <= 0.0:
                raise MechanismError(
                    f"leg.range: a length leg's range is a free rod length and must be > 0, got {self.range!r}"
                )
            object.__setattr__(self, "range", (lo, hi))
        length = None if self.actuation == "length" else self.rod.length
        object.__setattr__(self, "actuator",
                           ACTUATORS[self.actuation](self.origin, self.angle, length, self.range, self.offset))
        object.__setattr__(self, "platform_joint", JOINTS[self.joint](self.tip_angle))

    # ---- delegation to the actuator --------------------------------------------------------
    @property
    def direction(self) -> NDArray[np.float64]:
        """Unit vector ``(cos angle, sin angle)``."""
        return np.array([math.cos(self.angle), math.sin(self.angle)])

    def clamp(self, u: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Clamp of the rod for actuator input(s) ``u`` (vectorised).

        Parameters
        ----------
        u : array_like
            Actuator input(s) in internal units: m for prismatic and length legs, rad for
            revolute legs.

        Returns
        -------
        A : ndarray, shape ``u.shape + (2,)``
            Clamp point (m, world frame).
        alpha : ndarray, shape ``u.shape``
            Clamp tangent angle (rad).
        L : ndarray, shape ``u.shape``
            Free rod length (m).
        """
        return self.actuator.clamp(u)

    def in_range(self, u: ArrayLike) -> NDArray[np.bool_]:
        """Whether input(s) ``u`` (internal units) lie in the leg's range (always true without
        one); revolute inputs are compared modulo 360 degrees.

        Parameters
        ----------
        u : array_like
            Actuator input(s), m or rad.

        Returns
        -------
        ndarray of bool
            Same shape as ``u``.
        """
        return self.actuator.in_range(u)

    @property
    def input_unit(self) -> str:
        """Display unit of the input: ``"deg"`` for revolute legs, ``"m"`` otherwise."""
        return self.actuator.input_unit

    def to_display(self, u: ArrayLike) -> NDArray[np.float64] | float:
        """Internal input (m or rad) to display units (m or deg).

        Parameters
        ----------
        u : array_like
            Input(s) in internal units.

        Returns
        -------
        float or ndarray
            A float for scalar input, an array otherwise.
        """
        return self.actuator.to_display(u)

    def from_display(self, v: ArrayLike) -> NDArray[np.float64] | float:
        """Display input (m or deg) to internal units (m or rad).

        Parameters
        ----------
        v : array_like
            Input(s) in display units.

        Returns
        -------
        float or ndarray
            A float for scalar input, an array otherwise.
        """
        return self.actuator.from_display(v)


# --------------------------------------------------------------------------------------
def _triangle_check(points: tuple[tuple[float, float], ...], what: str) -> None:
    """Raise if two points coincide or the triangle is degenerate."""
    p = np.asarray(points, dtype=float)
    size = max(float(np.hypot(*(p[i] - p[j]))) for i in range(3) for j in range(i + 1, 3))
    for i in range(3):
        for j in range(i + 1, 3):
            d = float(np.hypot(*(p[i] - p[j])))
            if d <= 1e-12 * max(size, 1e-300) or d == 0.0:
                raise MechanismError(
                    f"{what}: attach points {i + 1} and {j + 1} coincide "
                    f"(({p[i][0]:.6g}, {p[i][1]:.6g}) and ({p[j][0]:.6g}, {p[j][1]:.6g}))"
                )
    if size < LENGTH_LIMITS[0]:
        raise MechanismError(
            f"{what}: the platform is too small (largest distance between attach points {size:.3g} m, "
            f"supported >= {LENGTH_LIMITS[0]:g} m)"
        )
    e1, e2 = p[1] - p[0], p[2] - p[0]
    area = 0.5 * abs(float(e1[0] * e2[1] - e1[1] * e2[0]))
    if area < 1e-9 * size**2:
        raise MechanismError(
            f"{what}: the three attach points are collinear (triangle area {area:.3g} m^2); "
            "the platform must be a proper triangle"
        )


@dataclass(frozen=True)
class Platform:
    """Rigid triangular platform.

    Parameters
    ----------
    attach : tuple of three (x, y) tuples
        Attach points ``b_i`` of the rods in the platform frame (m), relative to the
        platform's reference point P.
    """

    attach: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]

    def __post_init__(self) -> None:
        try:
            pts = tuple(self.attach)
        except TypeError:
            raise MechanismError(f"platform.attach: expected three points, got {self.attach!r}") from None
        if len(pts) != 3:
            raise MechanismError(f"platform.attach: expected exactly three points, got {len(pts)}")
        pts = tuple(_bounded_point(p, f"platform.attach[{i + 1}]") for i, p in enumerate(pts))
        _triangle_check(pts, "platform.attach")
        object.__setattr__(self, "attach", pts)

    @property
    def b(self) -> NDArray[np.float64]:
        """Attach points as an array of shape (3, 2)."""
        return np.asarray(self.attach, dtype=float)

    @property
    def size(self) -> float:
        """Characteristic length: the largest distance between two attach points (m)."""
        b = self.b
        return max(float(np.hypot(*(b[i] - b[j]))) for i in range(3) for j in range(i + 1, 3))

    def world(self, pose: ArrayLike) -> NDArray[np.float64]:
        """World coordinates of the attach points, ``B_i = P + Rot(theta) b_i``.

        Parameters
        ----------
        pose : array_like, shape (..., 3)
            Platform pose(s) ``(x, y, theta)``, theta in rad.

        Returns
        -------
        ndarray, shape (..., 3, 2)
            ``B_i`` for i = 1, 2, 3 along the second-last axis.
        """
        return platform_points(self.b, pose)


# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Mechanism:
    """A planar parallel continuum mechanism: three legs and a platform.

    Parameters
    ----------
    name : str
        Human-readable name.
    legs : tuple of three Leg
        The legs, in order (leg i attaches to ``platform.attach[i]``).
    platform : Platform
        The platform.
    load : tuple of float
        Load wrench ``(Fx, Fy, Mz)`` acting on the platform at P (N, N, N m).
    max_strain : float, optional
        Allowable bending strain for feasibility checks.
    source : str, optional
        Path of the file the mechanism was loaded from.
    gravity : tuple of float, optional
        In-plane gravity ``(gx, gy)`` (m/s^2) of the file's ``[environment]``; used only by the
        Cosserat refinement (the Kirchhoff rods are weightless).
    """

    name: str
    legs: tuple[Leg, Leg, Leg]
    platform: Platform
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_strain: float | None = None
    source: str | None = field(default=None, compare=False)
    gravity: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise MechanismError(f"name: expected a string, got {self.name!r}")
        legs = tuple(self.legs)
        if len(legs) != 3:
            raise MechanismError(f"legs: expected exactly three legs, got {len(legs)}")
        for i, leg in enumerate(legs):
            if not isinstance(leg, Leg):
                raise MechanismError(f"leg[{i + 1}]: expected a Leg, got {leg!r}")
        object.__setattr__(self, "legs", legs)
        if not isinstance(self.platform, Platform):
            raise MechanismError(f"platform: expected a Platform, got {self.platform!r}")
        load = tuple(self.load)
        if len(load) != 3:
            raise MechanismError(f"load: expected (Fx, Fy, Mz), got {self.load!r}")
        object.__setattr__(self, "load", tuple(_finite(v, "load") for v in load))
        if self.max_strain is not None:
            object.__setattr__(self, "max_strain", _positive(self.max_strain, "limits.max_strain"))
            for i, leg in enumerate(legs):
                if leg.rod.radius is None:
                    raise MechanismError(
                        f"leg[{i + 1}].radius: limits.max_strain needs the rod radius of every leg"
                    )
        msg = _coincident_fixed_origins(legs)
        if msg is not None:
            raise MechanismError(msg)

    # ---- scales --------------------------------------------------------------------
    @property
    def base_centroid(self) -> NDArray[np.float64]:
        """Centroid of the three leg origins (m)."""
        return np.mean([leg.origin for leg in self.legs], axis=0)

    @property
    def length_scale(self) -> float:
        """Characteristic length (m): mean rod length.

        A length leg (no fixed rod length) contributes the distance from its origin to the
        base centroid instead.  Falls back to the platform size if that mean is zero.
        """
        c = self.base_centroid
        vals = [
            float(leg.rod.length)
            if (leg.actuation != "length" and leg.rod.length is not None)
            else float(np.hypot(*(np.asarray(leg.origin) - c)))
            for leg in self.legs
        ]
        m = float(np.mean(vals))
        return m if m > 0.0 else self.platform.size

    @property
    def EI_scale(self) -> float:
        """Mean bending stiffness of the three rods (N m^2)."""
        return float(np.mean([leg.rod.EI for leg in self.legs]))

    @property
    def actuations(self) -> tuple[str, str, str]:
        """Actuation type of each leg."""
        return tuple(leg.actuation for leg in self.legs)  # type: ignore[return-value]

    @property
    def joints(self) -> tuple[str, str, str]:
        """Rod-platform joint of each leg (``"pinned"`` or ``"clamped"``)."""
        return tuple(leg.joint for leg in self.legs)  # type: ignore[return-value]

    @property
    def kind(self) -> str:
        """Human label: ``"3-PFR"``, ``"3-RFR"``, ``"3-PFR(length)"``, ``"3-PF"`` (clamped tips)
        or e.g. ``"mixed (P,R,L)"`` / ``"mixed (PF,RFR,LFR)"``."""
        acts = set(self.actuations)
        joints = set(self.joints)
        tail = "FR" if joints == {"pinned"} else ("F" if joints == {"clamped"} else None)
        if len(acts) == 1 and tail is not None:
            base = {"prismatic": "3-P", "revolute": "3-R", "length": "3-P"}[self.actuations[0]]
            return base + tail + ("(length)" if acts == {"length"} else "")
        if joints == {"pinned"}:
            return "mixed (" + ",".join(leg.actuator.letter for leg in self.legs) + ")"
        return "mixed (" + ",".join(leg.actuator.letter + ("F" if leg.joint == "clamped" else "FR")
                                    for leg in self.legs) + ")"

    @property
    def is_symmetric_rods(self) -> bool:
        """Whether the three rods are identical."""
        return self.legs[0].rod == self.legs[1].rod == self.legs[2].rod

    # ---- description ---------------------------------------------------------------
    def summary(self) -> str:
        """Multi-line human-readable description of the mechanism.

        Returns
        -------
        str
            Name, kind, a legs table (actuation, origin, guide angle, range, rod, platform joint
            and a clamped joint's tip angle), the platform, the rods, load and limits.
        """
        lines = [f"{self.name}  [{self.kind}]"]
        if self.source:
            lines.append(f"  file: {self.source}")
        lines.append("  legs:")
        lines.append(
            f"    {'#':>2}  {'actuation':<10} {'origin x [m]':>13} {'origin y [m]':>13} "
            f"{'angle [deg]':>11}  {'range':<24} {'L [m]':>8} {'EI [N m^2]':>11} {'radius [m]':>11}  "
            f"{'joint':<8} {'tip angle [deg]':>15}"
        )
        for i, leg in enumerate(self.legs):
            if leg.range is None:
                rng = "-"
            else:
                lo, hi = (leg.to_display(v) for v in leg.range)
                rng = f"[{lo:.6g}, {hi:.6g}] {leg.input_unit}"
            ang = "-" if leg.actuation == "revolute" and leg.angle == 0.0 else f"{math.degrees(leg.angle):.6g}"
            L = "input" if leg.actuation == "length" else f"{leg.rod.length:.6g}"
            rad = "-" if leg.rod.radius is None else f"{leg.rod.radius:.4g}"
            tip = f"{math.degrees(leg.tip_angle):.6g}" if leg.joint == "clamped" else "-"
            lines.append(
                f"    {i + 1:>2}  {leg.actuation:<10} {leg.origin[0]:>13.6g} {leg.origin[1]:>13.6g} "
                f"{ang:>11}  {rng:<24} {L:>8} {leg.rod.EI:>11.6g} {rad:>11}  {leg.joint:<8} {tip:>15}"
            )
        if any(leg.offset for leg in self.legs):
            lines.append("  input zero offsets (the leg acts as if its input were u + offset): " + ", ".join(
                f"leg {i + 1} = {float(leg.to_display(leg.offset)):.6g} {leg.input_unit}" for i, leg in enumerate(self.legs)))
        lines.append("  platform attach points b_i (platform frame) [m]:")
        for i, b in enumerate(self.platform.attach):
            lines.append(f"    b{i + 1} = ({b[0]:.6g}, {b[1]:.6g})")
        lines.append(f"    size (largest attach distance) = {self.platform.size:.6g} m")
        rods = {leg.rod for leg in self.legs}
        if len(rods) == 1 and self.legs[0].rod.E is not None:
            r = self.legs[0].rod
            lines.append(f"  rods: E = {r.E:.6g} Pa, radius = {r.radius:.6g} m, EI = {r.EI:.6g} N m^2")
        lines.append(
            f"  scales: length = {self.length_scale:.6g} m, EI = {self.EI_scale:.6g} N m^2, "
            f"force EI/L^2 = {self.EI_scale / self.length_scale**2:.6g} N"
        )
        fx, fy, mz = self.load
        lines.append(f"  load at P: Fx = {fx:.6g} N, Fy = {fy:.6g} N, Mz = {mz:.6g} N m")
        if self.max_strain is not None:
            lines.append(f"  max strain: {self.max_strain:.6g}")
        return "\n".join(lines)


def _coincident_fixed_origins(legs: tuple[Leg, ...]) -> str | None:
    """Message if two revolute/length legs share their origin, else None."""
    pts = np.array([leg.origin for leg in legs], dtype=float)
    spread = max(float(np.hypot(*(pts[i] - pts[j]))) for i in range(3) for j in range(i + 1, 3))
    # relative to the base's own size (the rods' lengths do not make distinct points coincide)
    tol = 1e-9 * spread
    for i in range(3):
        for j in range(i + 1, 3):
            if legs[i].actuation == "prismatic" or legs[j].actuation == "prismatic":
                continue
            if float(np.hypot(*(pts[i] - pts[j]))) <= tol:
                return (
                    f"leg[{j + 1}].origin: coincides with leg[{i + 1}].origin "
                    f"({pts[i][0]:.6g}, {pts[i][1]:.6g}); a {legs[i].actuation} and a "
                    f"{legs[j].actuation} leg cannot share a base point"
                )
    return None
