"""The fitted parameters of a calibration: dotted keys -> scalar parameters.

The keys are those of ``flexkin study`` (``docs/study.md``) with the forms a calibration needs:

=================================  =================================================================
key                                scalar parameters (internal units)
=================================  =================================================================
``leg[i].offset``                  the input's zero offset of leg i (m, or rad for revolute legs)
``leg[i].origin``                  ``leg[i].origin_x`` and ``leg[i].origin_y`` (m)
``leg[i].origin_x``, ``_y``        one coordinate of leg i's origin (m)
``leg[i].angle``                   guide direction (rad; prismatic and length legs)
``leg[i].length``                  rod length (m; not for length legs)
``leg[i].EI``, ``leg[i].E``        bending stiffness (N m^2) / Young's modulus (Pa; needs radius)
``leg[*].KEY``                     one parameter per leg (legs KEY does not apply to are skipped)
``leg.KEY``                        ONE parameter shared by every leg (offset, angle, length, EI, E)
``rod.KEY``                        ONE parameter: the ``[rod]`` default (length, EI, E), acting on
                                   every leg that does not set KEY in its own ``[[leg]]`` table
``platform.attach``                the six coordinates of the attach points b_j (m)
``platform.attach[j]``             ``platform.attach[j].x`` and ``.y`` (m)
=================================  =================================================================

Each scalar parameter knows how to read its value from a mechanism, how to set it
(:func:`with_values`) and the exact derivative of the equation system's arrays (clamp maps
``c0, c1``, ``EI``, attach points) with respect to it (:func:`array_derivatives`), which the
implicit-function Jacobian of :mod:`flexkin.calibration.sensitivity` uses.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ..mechanism.model import Leg, Mechanism, Platform, circular_EI

__all__ = ["Parameter", "FitKeyError", "parse_fit_keys", "values_of", "with_values", "array_derivatives",
           "FIT_KEYS"]

_LEG_PROPS = ("offset", "origin", "origin_x", "origin_y", "angle", "length", "EI", "E")
_SHARED_PROPS = ("offset", "angle", "length", "EI", "E")
_ROD_PROPS = ("length", "EI", "E")
FIT_KEYS = ("leg[i].{offset,origin,origin_x,origin_y,angle,length,EI,E}", "leg[*].KEY",
            "leg.{offset,angle,length,EI,E}", "rod.{length,EI,E}", "platform.attach", "platform.attach[j]")
_LEG_RE = re.compile(r"^leg(?:\[(\d+|\*)\])?\.([A-Za-z_]+)$")
_ATTACH_RE = re.compile(r"^platform\.attach(?:\[(\d+)\])?(?:\.([xy]))?$")


class FitKeyError(ValueError):
    """A ``--fit`` key is unknown or does not apply to the mechanism (one-line message)."""


@dataclass(frozen=True)
class Parameter:
    """One scalar fitted parameter.

    Attributes
    ----------
    name : str
        Its own dotted key, e.g. ``"leg[2].origin_x"``, ``"rod.E"``, ``"platform.attach[1].x"``.
    key : str
        The ``--fit`` key it came from.
    prop : str
        ``offset``, ``origin_x``, ``origin_y``, ``angle``, ``length``, ``EI``, ``E``,
        ``attach_x`` or ``attach_y``.
    targets : tuple of int
        The legs it acts on (0-based); for ``attach_*`` the attach point.
    unit : str
        Display unit (``m``, ``deg``, ``Pa``, ``N m^2``).
    display : float
        Factor from internal to display units (``180/pi`` for angles, else 1).
    positive : bool
        Physically > 0 (lengths and stiffnesses).
    """

    name: str
    key: str
    prop: str
    targets: tuple[int, ...]
    unit: str
    display: float = 1.0
    positive: bool = False

    def typical(self, mech: Mechanism, value: float) -> float:
        """A typical change of the parameter (internal units), for scaling the fit: 1 % of
        the length scale for lengths, 1 degree for angles, 10 % for stiffnesses."""
        if self.prop in ("EI", "E"):
            return 0.1 * abs(value)
        if self.unit == "deg":
            return math.radians(1.0)
        return 0.01 * float(mech.length_scale)


def _leg_has(raw_legs: Sequence[Mapping[str, Any]], i: int, prop: str) -> bool:
    return i < len(raw_legs) and prop in raw_legs[i]


def _check_leg_prop(mech: Mechanism, i: int, prop: str, key: str, strict: bool) -> bool:
    """Whether ``prop`` acts on leg ``i``; raise (strict) or return False when it does not."""
    leg = mech.legs[i]
    why = ""
    if prop == "angle" and leg.actuation == "revolute":
        why = f"leg {i + 1} is revolute (its angle is unused; its input is the clamp angle)"
    elif prop == "length" and leg.actuation == "length":
        why = f"leg {i + 1} is length-actuated (its input is the free rod length)"
    elif prop == "E" and leg.rod.radius is None:
        why = f"leg {i + 1} has no rod radius, so E does not set its bending stiffness (fit EI)"
    elif prop == "EI" and leg.rod.E is not None and leg.rod.radius is not None:
        why = f"leg {i + 1}'s bending stiffness comes from E and radius (fit E)"
    if why and strict:
        raise FitKeyError(f"--fit {key}: {why}")
    return not why


def _unit(mech: Mechanism, prop: str, legs: Sequence[int], key: str) -> tuple[str, float]:
    if prop == "offset":
        units = {mech.legs[i].input_unit for i in legs}
        if len(units) > 1:
            raise FitKeyError(f"--fit {key}: the legs mix units (m and deg); fit their offsets per leg (leg[*].offset)")
        u = units.pop()
        return u, (180.0 / math.pi if u == "deg" else 1.0)
    if prop == "angle":
        return "deg", 180.0 / math.pi
    return {"E": "Pa", "EI": "N m^2"}.get(prop, "m"), 1.0


def _make(mech: Mechanism, name: str, key: str, prop: str, legs: Sequence[int]) -> Parameter:
    unit, disp = _unit(mech, prop, legs, key)
    return Parameter(name, key, prop, tuple(legs), unit, disp, prop in ("length", "EI", "E"))


def parse_fit_keys(keys: Sequence[str], mech: Mechanism, raw: Mapping[str, Any] | None = None) -> tuple[Parameter, ...]:
    """The scalar parameters named by ``--fit`` keys (see the module docstring).

    Parameters
    ----------
    keys : sequence of str
        The keys, in order.
    mech : Mechanism
        The starting mechanism.
    raw : mapping, optional
        The mechanism file's content (to know which legs override a ``[rod]`` key); without
        it ``rod.KEY`` acts on every leg.

    Returns
    -------
    tuple of Parameter

    Raises
    ------
    FitKeyError
        For an unknown key, a key that does not apply, or a parameter named twice.
    """
    if not keys:
        raise FitKeyError("--fit: give at least one parameter to fit (e.g. --fit 'leg[*].offset')")
    raw_legs = [t if isinstance(t, dict) else {} for t in (raw or {}).get("leg", [])]
    out: list[Parameter] = []
    for key in keys:
        key = str(key).strip()
        out.extend(_parse_one(key, mech, raw_legs, raw is not None))
    seen: dict[str, str] = {}
    per_leg: dict[tuple[int, str], str] = {}
    for p in out:
        if p.name in seen:
            raise FitKeyError(f"--fit {p.key}: {p.name} is already fitted (by --fit {seen[p.name]})")
        seen[p.name] = p.key
        if p.prop in ("EI", "E", "length", "offset", "angle") and not p.prop.startswith("attach"):
            for i in p.targets:
                group = "stiffness" if p.prop in ("EI", "E") else p.prop
                if (i, group) in per_leg:
                    raise FitKeyError(f"--fit {p.key}: leg {i + 1}'s {group} is already fitted by --fit {per_leg[(i, group)]}")
                per_leg[(i, group)] = p.key
    return tuple(out)


def _parse_one(key: str, mech: Mechanism, raw_legs: list, have_raw: bool) -> list[Parameter]:
    n = len(mech.legs)
    m = _ATTACH_RE.match(key)
    if m:
        idx, comp = m.group(1), m.group(2)
        if idx is None and comp is not None:
            raise FitKeyError(f"--fit {key}: name the attach point, e.g. platform.attach[1].{comp}")
        js = range(n) if idx is None else [int(idx) - 1]
        if idx is not None and not 1 <= int(idx) <= n:
            raise FitKeyError(f"--fit {key}: no attach point {idx}: they are numbered 1 to {n}")
        comps = ("x", "y") if comp is None else (comp,)
        return [Parameter(f"platform.attach[{j + 1}].{c}", key, f"attach_{c}", (j,), "m") for j in js for c in comps]
    head, _, prop = key.partition(".")
    if head == "rod":
        if prop not in _ROD_PROPS:
            raise _unknown(key)
        legs = [i for i in range(n) if not (have_raw and _leg_has(raw_legs, i, prop))]
        legs = [i for i in legs if _check_leg_prop(mech, i, prop, key, strict=False)]
        if not legs:
            raise FitKeyError(f"--fit {key}: acts on no leg (every [[leg]] sets its own {prop!r}, or it does not "
                              "apply to the legs; use leg[i]." + prop + ")")
        for i in legs:
            _check_leg_prop(mech, i, prop, key, strict=True)
        return [_make(mech, key, key, prop, legs)]
    m = _LEG_RE.match(key)
    if not m:
        raise _unknown(key)
    idx, prop = m.group(1), m.group(2)
    if prop not in _LEG_PROPS:
        raise _unknown(key)
    if idx is None:  # one shared parameter
        if prop not in _SHARED_PROPS:
            raise FitKeyError(f"--fit {key}: {prop!r} cannot be shared by the legs; use leg[*].{prop} or leg[i].{prop}")
        legs = [i for i in range(n) if _check_leg_prop(mech, i, prop, key, strict=False)]
        if not legs:
            raise FitKeyError(f"--fit {key}: applies to no leg of this mechanism")
        return [_make(mech, key, key, prop, legs)]
    if idx == "*":
        legs = [i for i in range(n) if _check_leg_prop(mech, i, prop, key, strict=False)]
        if not legs:
            raise FitKeyError(f"--fit {key}: applies to no leg of this mechanism")
    else:
        i = int(idx)
        if not 1 <= i <= n:
            raise FitKeyError(f"--fit {key}: no leg {i}: legs are numbered 1 to {n} in file order")
        legs = [i - 1]
        _check_leg_prop(mech, i - 1, prop, key, strict=True)
    props = ("origin_x", "origin_y") if prop == "origin" else (prop,)
    return [_make(mech, f"leg[{i + 1}].{p}", key, p, [i]) for i in legs for p in props]


def _unknown(key: str) -> FitKeyError:
    return FitKeyError(f"--fit {key}: unknown parameter; parameters are {', '.join(FIT_KEYS)} "
                       "(see docs/calibration.md)")


# ---- values ---------------------------------------------------------------------------
def _get(mech: Mechanism, p: Parameter) -> float:
    if p.prop.startswith("attach"):
        j = p.targets[0]
        return float(mech.platform.attach[j][0 if p.prop == "attach_x" else 1])
    leg = mech.legs[p.targets[0]]
    if p.prop == "offset":
        return float(leg.offset)
    if p.prop == "origin_x":
        return float(leg.origin[0])
    if p.prop == "origin_y":
        return float(leg.origin[1])
    if p.prop == "angle":
        return float(leg.angle)
    if p.prop == "length":
        return float(leg.rod.length)  # type: ignore[arg-type]
    if p.prop == "EI":
        return float(leg.rod.EI)
    return float(leg.rod.E)  # type: ignore[arg-type]


def values_of(mech: Mechanism, params: Sequence[Parameter]) -> NDArray[np.float64]:
    """The parameters' values in ``mech`` (internal units; a shared parameter: its first leg's).

    Parameters
    ----------
    mech : Mechanism
    params : sequence of Parameter

    Returns
    -------
    ndarray (n_params,)
    """
    return np.array([_get(mech, p) for p in params], dtype=float)


def with_values(mech: Mechanism, params: Sequence[Parameter], values: Sequence[float]) -> Mechanism:
    """A copy of ``mech`` with the parameters set to ``values`` (internal units).

    Parameters
    ----------
    mech : Mechanism
    params : sequence of Parameter
    values : sequence of float

    Returns
    -------
    Mechanism
    """
    legs = [dict(actuation=lg.actuation, origin=list(lg.origin), angle=lg.angle, rod=lg.rod, range=lg.range,
                 joint=lg.joint, tip_angle=lg.tip_angle, offset=lg.offset) for lg in mech.legs]
    attach = [list(b) for b in mech.platform.attach]
    for p, v in zip(params, values):
        v = float(v)
        if p.prop.startswith("attach"):
            attach[p.targets[0]][0 if p.prop == "attach_x" else 1] = v
            continue
        for i in p.targets:
            t = legs[i]
            if p.prop == "offset":
                t["offset"] = v
            elif p.prop == "origin_x":
                t["origin"][0] = v
            elif p.prop == "origin_y":
                t["origin"][1] = v
            elif p.prop == "angle":
                t["angle"] = v
            elif p.prop == "length":
                t["rod"] = dataclasses.replace(t["rod"], length=v)
            elif p.prop == "EI":
                t["rod"] = dataclasses.replace(t["rod"], EI=v)
            elif p.prop == "E":
                t["rod"] = dataclasses.replace(t["rod"], E=v, EI=circular_EI(v, t["rod"].radius))
    new_legs = tuple(Leg(**{**t, "origin": tuple(t["origin"])}) for t in legs)
    plat = Platform(tuple(tuple(b) for b in attach)) if any(p.prop.startswith("attach") for p in params) \
        else mech.platform
    return dataclasses.replace(mech, legs=new_legs, platform=plat)  # type: ignore[arg-type]


def array_derivatives(mech: Mechanism, params: Sequence[Parameter]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Exact derivatives of the equation system's arrays (:class:`flexkin.system.System`) with
    respect to each parameter.

    Parameters
    ----------
    mech : Mechanism
        The mechanism at the current parameter values.
    params : sequence of Parameter

    Returns
    -------
    dc0, dc1 : ndarray (n_params, 3, 4)
        Of the legs' affine clamp maps ``(A_x, A_y, alpha, L) = c0 + c1 u``.
    dEI : ndarray (n_params, 3)
    dattach : ndarray (n_params, 3, 2)
    """
    k = len(params)
    dc0 = np.zeros((k, 3, 4))
    dc1 = np.zeros((k, 3, 4))
    dEI = np.zeros((k, 3))
    dat = np.zeros((k, 3, 2))
    for a, p in enumerate(params):
        if p.prop.startswith("attach"):
            dat[a, p.targets[0], 0 if p.prop == "attach_x" else 1] = 1.0
            continue
        for i in p.targets:
            leg = mech.legs[i]
            if p.prop == "EI":
                dEI[a, i] = 1.0
            elif p.prop == "E":
                dEI[a, i] = circular_EI(1.0, leg.rod.radius)  # type: ignore[arg-type]
            else:
                d0, d1 = leg.actuator.affine_derivative(p.prop)
                dc0[a, i] += d0
                dc1[a, i] += d1
    return dc0, dc1, dEI, dat
