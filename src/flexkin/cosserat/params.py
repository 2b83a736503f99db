"""Material parameters of a planar Cosserat rod beyond bending: extension, shear, weight.

The bending stiffness ``EI`` is not repeated here: it always comes from the Kirchhoff model
(``leg.rod.EI`` / ``RodState.EI``), so that tau = 0 of the homotopy is exactly the Kirchhoff
problem flexkin solved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..mechanism.loader import MATERIAL_KEYS  # the rods' material keys beyond E and radius

__all__ = ["CosseratParams", "circular_shear_coefficient", "params_for_mechanism", "cosserat_setup", "leg_materials",
           "line_loads"]


def circular_shear_coefficient(poisson: float | None) -> float:
    """Timoshenko shear coefficient of a solid circular section.

    ``6 (1 + nu) / (7 + 6 nu)`` (Cowper 1966, J. Appl. Mech. 33:335); ``0.9`` when the
    Poisson ratio is unknown (``None``).

    Parameters
    ----------
    poisson : float or None
        Poisson's ratio nu of the material, or ``None`` if unknown.

    Returns
    -------
    float
        The shear coefficient kappa.
    """
    if poisson is None:
        return 0.9
    nu = float(poisson)
    return 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)


def _nonneg_or_inf(value: Any, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a number, got {value!r}") from None
    if math.isnan(v) or v <= 0.0:
        raise ValueError(f"{what}: must be > 0 (inf allowed for a rigid section), got {value!r}")
    return v


def _vec2(value: Any, what: str) -> tuple[float, float]:
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected two numbers (x, y), got {value!r}") from None
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected two finite numbers (x, y), got {value!r}")
    return float(a[0]), float(a[1])


@dataclass(frozen=True)
class CosseratParams:
    """Extension, shear and distributed-load data of one rod (SI units).

    Parameters
    ----------
    EA : float
        Axial stiffness (N); ``inf`` for an inextensible rod.
    GA : float
        Shear modulus times section area (N), *before* the shear coefficient; ``inf`` for an
        unshearable rod.
    shear_coefficient : float
        Timoshenko shear coefficient kappa (the effective shear stiffness is ``kappa GA``);
        default 0.9.
    mass_per_length : float
        rho A (kg/m); with the gravity vector given to :func:`~flexkin.cosserat.refine` this
        is the self-weight ``rho A g`` (N/m).
    distributed_load : (fx, fy)
        Further uniform distributed force per unit length (N/m), world frame (dead load).
    """

    EA: float = math.inf
    GA: float = math.inf
    shear_coefficient: float = 0.9
    mass_per_length: float = 0.0
    distributed_load: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "EA", _nonneg_or_inf(self.EA, "EA"))
        object.__setattr__(self, "GA", _nonneg_or_inf(self.GA, "GA"))
        k = _nonneg_or_inf(self.shear_coefficient, "shear_coefficient")
        if not math.isfinite(k):
            raise ValueError(f"shear_coefficient: must be finite, got {self.shear_coefficient!r}")
        object.__setattr__(self, "shear_coefficient", k)
        try:
            mpl = float(self.mass_per_length)
        except (TypeError, ValueError):
            raise ValueError(f"mass_per_length: expected a number, got {self.mass_per_length!r}") from None
        if not math.isfinite(mpl) or mpl < 0.0:
            raise ValueError(f"mass_per_length: must be finite and >= 0, got {self.mass_per_length!r}")
        object.__setattr__(self, "mass_per_length", mpl)
        object.__setattr__(self, "distributed_load", _vec2(self.distributed_load, "distributed_load"))

    # ---- constructors ---------------------------------------------------------------
    @classmethod
    def from_material(cls, E: float, radius: float, *, G: float | None = None, poisson: float | None = None,
                      density: float = 0.0, shear_coefficient: float | None = None,
                      distributed_load: Sequence[float] = (0.0, 0.0)) -> "CosseratParams":
        """Solid circular section: ``A = pi r^2``, ``EA = E A``, ``GA = G A``.

        ``G`` defaults to ``E / (2 (1 + poisson))``; with ``G`` given and ``poisson`` not,
        ``poisson = E / (2 G) - 1`` is used for the shear coefficient (Cowper's
        ``6 (1 + nu) / (7 + 6 nu)``), unless ``shear_coefficient`` is given.  Without ``G``
        and ``poisson`` the rod is unshearable (``GA = inf``).  ``density`` (kg/m^3) gives
        ``mass_per_length = density A``.
        """
        E = _nonneg_or_inf(E, "E")
        r = _nonneg_or_inf(radius, "radius")
        if not (math.isfinite(E) and math.isfinite(r)):
            raise ValueError("E and radius must be finite")
        area = math.pi * r * r
        nu = None if poisson is None else float(poisson)
        if nu is not None and not (-1.0 < nu < 0.5 + 1e-12):
            raise ValueError(f"poisson: must lie in (-1, 0.5], got {poisson!r}")
        if G is None:
            Gv = math.inf if nu is None else E / (2.0 * (1.0 + nu))
        else:
            Gv = _nonneg_or_inf(G, "G")
            if nu is None and math.isfinite(Gv):
                nu = E / (2.0 * Gv) - 1.0
                if not -1.0 < nu <= 0.5 + 1e-12:
                    nu = None  # G not isotropic-consistent: fall back to kappa = 0.9
        kappa = circular_shear_coefficient(nu) if shear_coefficient is None else shear_coefficient
        try:
            rho = float(density)
        except (TypeError, ValueError):
            raise ValueError(f"density: expected a number, got {density!r}") from None
        if not math.isfinite(rho) or rho < 0.0:
            raise ValueError(f"density: must be finite and >= 0, got {density!r}")
        return cls(EA=E * area, GA=Gv * area, shear_coefficient=kappa, mass_per_length=rho * area,
                   distributed_load=tuple(distributed_load))

    @classmethod
    def kirchhoff(cls) -> "CosseratParams":
        """Inextensible, unshearable, weightless: the Kirchhoff rod (refinement is the identity)."""
        return cls()

    # ---- derived ----------------------------------------------------------------------
    @property
    def axial_compliance(self) -> float:
        """``1 / EA`` (1/N), 0 for an inextensible rod."""
        return 0.0 if math.isinf(self.EA) else 1.0 / self.EA

    @property
    def shear_compliance(self) -> float:
        """``1 / (kappa GA)`` (1/N), 0 for an unshearable rod."""
        return 0.0 if math.isinf(self.GA) else 1.0 / (self.shear_coefficient * self.GA)

    def line_load(self, gravity: Sequence[float] | None = None) -> tuple[float, float]:
        """Total distributed force per unit length (N/m): ``rho A g + distributed_load``."""
        g = (0.0, 0.0) if gravity is None else _vec2(gravity, "gravity")
        return (self.mass_per_length * g[0] + self.distributed_load[0],
                self.mass_per_length * g[1] + self.distributed_load[1])


def leg_materials(mech: Any) -> list[dict[str, float]]:
    """Per leg, the material keys its file gives (``[rod]`` defaults and the leg's overrides,
    resolved by the loader into ``Rod.G``, ``Rod.poisson``, ``Rod.density``,
    ``Rod.shear_coefficient``).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.

    Returns
    -------
    list of dict
        Per leg, ``G``, ``poisson``, ``density``, ``shear_coefficient`` where given.
    """
    return [{k: getattr(leg.rod, k) for k in MATERIAL_KEYS if getattr(leg.rod, k, None) is not None}
            for leg in mech.legs]


def params_for_mechanism(mech: Any, *, G: float | None = None, poisson: float | None = None,
                         density: float | None = None, shear_coefficient: float | None = None,
                         distributed_load: Sequence[float] = (0.0, 0.0)) -> tuple[CosseratParams, ...]:
    """One :class:`CosseratParams` per leg from each rod's ``E``, ``radius`` and the material
    keys of the mechanism file (:func:`leg_materials`); an argument given here overrides the
    file's value for every rod.

    Parameters
    ----------
    mech : Mechanism
        The mechanism; every rod needs ``E`` and ``radius``.
    G : float, optional
        Shear modulus (Pa) for every rod; default the file's, else from ``poisson``.
    poisson : float, optional
        Poisson's ratio, used for ``G = E / (2 (1 + nu))`` and the shear coefficient; default
        the file's.
    density : float, optional
        Mass density (kg/m^3) for every rod; default the file's, else 0 (weightless).
    shear_coefficient : float, optional
        Timoshenko shear coefficient kappa; default the file's, else
        :func:`circular_shear_coefficient`.
    distributed_load : (2,) float, optional
        Extra dead load per unit length (N/m, world frame) on every rod.

    Returns
    -------
    tuple of CosseratParams
        One per leg.

    Raises
    ------
    ValueError
        Naming the leg if a rod lacks ``E`` or ``radius``.
    """
    given = {"G": G, "poisson": poisson, "density": density, "shear_coefficient": shear_coefficient}
    out = []
    for i, (leg, mat) in enumerate(zip(mech.legs, leg_materials(mech))):
        if leg.rod.E is None or leg.rod.radius is None:
            raise ValueError(f"leg[{i + 1}]: the Cosserat model needs E and radius for every rod (give them in "
                             "[rod] or the [[leg]]; EI alone has no extension or shear stiffness)")
        if G is not None or poisson is not None:  # the caller's shear data replace the file's
            mat = {k: v for k, v in mat.items() if k not in ("G", "poisson")}
        m = {**mat, **{k: v for k, v in given.items() if v is not None}}
        out.append(CosseratParams.from_material(leg.rod.E, leg.rod.radius, G=m.get("G"), poisson=m.get("poisson"),
                                                density=m.get("density", 0.0),
                                                shear_coefficient=m.get("shear_coefficient"),
                                                distributed_load=distributed_load))
    return tuple(out)


def cosserat_setup(mech: Any, gravity: Sequence[float] | None = None
                   ) -> tuple[tuple[CosseratParams, ...], tuple[float, float] | None]:
    """The Cosserat parameters of a mechanism file (:func:`params_for_mechanism`) and its gravity
    (``gravity`` if given, else the file's ``[environment] gravity``).

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
    """
    g = mech.gravity if gravity is None else (float(gravity[0]), float(gravity[1]))
    return params_for_mechanism(mech), g


def line_loads(params: Sequence[CosseratParams], gravity: Sequence[float] | None,
               extra: Sequence[float] | Sequence[Sequence[float]] | None) -> np.ndarray:
    """Per-leg distributed force (N/m), shape ``(len(params), 2)``: weight + params' load + ``extra``.

    ``extra`` is one (fx, fy) for every leg or one pair per leg.
    """
    f = np.array([p.line_load(gravity) for p in params], dtype=float).reshape(-1, 2)
    if extra is not None:
        e = np.asarray(extra, dtype=float)
        if e.shape == (2,):
            e = np.broadcast_to(e, f.shape)
        if e.shape != f.shape or not np.all(np.isfinite(e)):
            raise ValueError(f"distributed_load: expected (fx, fy) or one pair per leg, got {extra!r}")
        f = f + e
    return f
