"""Design parameters of a study: the dotted keys, their validation and their application.

A study's ``[grid]`` names mechanism parameters by dotted keys (see ``docs/study.md``):

=============================  ===========================================================
key                            meaning (unit)
=============================  ===========================================================
``scale``                      every length of the mechanism and of the workspace grid
                               multiplied by this factor (> 0); applied last
``rod.KEY``                    rod property KEY of every leg that does not set KEY in its
                               own ``[[leg]]`` table (the file's ``[rod]`` default)
``leg.KEY``                    KEY of every leg
``leg[i].KEY``                 KEY of leg i (1, 2 or 3, in file order)
  KEY = ``length``             rod length (m, > 0; not for length-actuated legs)
  KEY = ``EI``                 bending stiffness (N m^2, > 0); drops ``E``
  KEY = ``E``                  Young's modulus (Pa, > 0); needs ``radius``; EI = E pi r^4/4
  KEY = ``radius``             section radius (m, > 0); EI = E pi r^4/4 when ``E`` is known,
                               otherwise EI is kept (the radius then only sets strains)
  KEY = ``angle``              guide direction (deg; prismatic and length legs only)
  KEY = ``origin_radius``      distance of the origin from the world origin O (m, > 0),
                               keeping the origin's polar angle
  KEY = ``origin_angle``       polar angle of the origin about O (deg), keeping its
                               distance (``leg[i]`` only)
  KEY = ``origin_x``/``_y``    a coordinate of the origin (m; ``leg[i]`` only)
  KEY = ``offset``             the input's zero offset (m, or deg for revolute legs)
``platform.scale``             attach points b_i multiplied by this factor (> 0)
``platform.radius``            every attach point at this distance from P (m, > 0), keeping
                               its polar angle in the platform frame
``load.force_x``, ``_y``       load force at P (N)
``load.moment``                load moment (N m)
``limits.max_strain``          allowable bending strain (> 0)
=============================  ===========================================================

A more specific key wins: ``leg[i].KEY`` over ``leg.KEY`` over ``rod.KEY``.  Rod properties
are first resolved per leg from the base file (as the mechanism loader resolves them), so in a
design's mechanism dict each ``[[leg]]`` carries its own ``length``, ``EI``, ``radius`` and
``E``, and ``[rod]`` keeps only other keys, if any.

Everything here is pure dictionary manipulation; problems are raised as
:class:`GridKeyError` (turned into one-line study-file messages by :mod:`.spec`).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from ..core.validation import suggest_key

__all__ = ["ParamKey", "GridKeyError", "parse_key", "valid_keys", "check_keys", "apply_design",
           "scaled_settings"]

_ROD_PROPS = ("length", "EI", "E", "radius")
_LEG_ALL_PROPS = _ROD_PROPS + ("angle", "origin_radius", "offset")
_LEG_ONE_PROPS = _LEG_ALL_PROPS + ("origin_angle", "origin_x", "origin_y")
_PLATFORM_PROPS = ("scale", "radius")
_LOAD_PROPS = ("force_x", "force_y", "moment")
_LIMITS_PROPS = ("max_strain",)
#: properties whose values must be > 0
_POSITIVE = {"length", "EI", "E", "radius", "origin_radius", "scale", "max_strain"}
_UNITS = {"length": "m", "EI": "N m^2", "E": "Pa", "radius": "m", "angle": "deg", "origin_radius": "m",
          "origin_angle": "deg", "origin_x": "m", "origin_y": "m", "scale": "", "force_x": "N",
          "force_y": "N", "moment": "N m", "max_strain": "", "offset": "m or deg"}
_LEG_RE = re.compile(r"^leg(?:\[(\d+)\])?\.([A-Za-z_]+)$")
#: order in which the properties of one leg are applied (EI last: it wins over E/radius)
_ORDER = {"origin_radius": 0, "origin_angle": 1, "origin_x": 2, "origin_y": 3, "angle": 4, "length": 5,
          "radius": 6, "E": 7, "EI": 8, "offset": 9}
_SPECIFICITY = {"rod": 0, "leg": 1, "legi": 2}


class GridKeyError(ValueError):
    """A grid key is unknown, does not apply to the base mechanism, or has a bad value;
    ``key`` names the grid key at fault when the problem is not about one key's text."""

    def __init__(self, message: str, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class ParamKey:
    """A parsed grid key.

    ``section`` is ``"scale"``, ``"rod"``, ``"leg"`` (every leg), ``"legi"`` (one leg:
    ``leg`` is its 0-based index), ``"platform"``, ``"load"`` or ``"limits"``; ``prop`` the
    property name (``""`` for ``scale``).
    """

    key: str
    section: str
    prop: str
    leg: int | None = None

    @property
    def unit(self) -> str:
        return _UNITS.get(self.prop or "scale", "")

    @property
    def positive(self) -> bool:
        return (self.prop or "scale") in _POSITIVE


def valid_keys(n_legs: int = 3) -> list[str]:
    """Every valid grid key for a mechanism with ``n_legs`` legs."""
    keys = ["scale"] + [f"rod.{p}" for p in _ROD_PROPS] + [f"leg.{p}" for p in _LEG_ALL_PROPS]
    keys += [f"leg[{i}].{p}" for i in range(1, n_legs + 1) for p in _LEG_ONE_PROPS]
    keys += [f"platform.{p}" for p in _PLATFORM_PROPS] + [f"load.{p}" for p in _LOAD_PROPS]
    keys += [f"limits.{p}" for p in _LIMITS_PROPS]
    return keys


def _unknown(key: str, n_legs: int, detail: str = "unknown parameter") -> GridKeyError:
    keys = valid_keys(n_legs)
    close = suggest_key(key, keys)
    hint = f" (did you mean {close!r}?)" if close else ""
    return GridKeyError(f"{detail}{hint}; parameters are scale, rod.{{{','.join(_ROD_PROPS)}}}, "
                        f"leg.{{{','.join(_LEG_ALL_PROPS)}}}, leg[i].{{...,origin_angle,origin_x,origin_y}}, "
                        f"platform.{{scale,radius}}, load.{{force_x,force_y,moment}}, limits.max_strain "
                        "(see docs/study.md)")


def parse_key(key: str, n_legs: int = 3) -> ParamKey:
    """Parse one dotted grid key; raise :class:`GridKeyError` for an unknown one."""
    if key == "scale":
        return ParamKey(key, "scale", "")
    head, _, prop = key.partition(".")
    if head == "rod" and prop in _ROD_PROPS:
        return ParamKey(key, "rod", prop)
    if head == "platform" and prop in _PLATFORM_PROPS:
        return ParamKey(key, "platform", prop)
    if head == "load" and prop in _LOAD_PROPS:
        return ParamKey(key, "load", prop)
    if head == "limits" and prop in _LIMITS_PROPS:
        return ParamKey(key, "limits", prop)
    m = _LEG_RE.match(key)
    if m:
        idx, prop = m.group(1), m.group(2)
        if idx is None:
            if prop in _LEG_ALL_PROPS:
                return ParamKey(key, "leg", prop)
            if prop in _LEG_ONE_PROPS:
                raise GridKeyError(f"'{prop}' can only be set per leg: use leg[1].{prop}, leg[2].{prop}, ...")
        elif prop in _LEG_ONE_PROPS:
            i = int(idx)
            if not 1 <= i <= n_legs:
                raise GridKeyError(f"no leg {i}: legs are numbered 1 to {n_legs} in file order")
            return ParamKey(key, "legi", prop, i - 1)
    raise _unknown(key, n_legs)


def _targets(pk: ParamKey, n_legs: int, raw_legs: Sequence[Mapping[str, Any]]) -> list[int]:
    """Legs (0-based) whose property ``pk.prop`` the key sets."""
    if pk.section == "legi":
        return [int(pk.leg)]  # type: ignore[arg-type]
    if pk.section == "leg":
        return list(range(n_legs))
    if pk.section == "rod":
        return [i for i in range(n_legs) if pk.prop not in raw_legs[i]]
    return []


def check_keys(keys: Sequence[ParamKey], base: Mapping[str, Any], mech: Any) -> None:
    """Check that every key applies to the base mechanism (raw dict ``base``, built ``mech``)
    and that no two keys conflict; raise :class:`GridKeyError` naming the key."""
    legs = mech.legs
    n = len(legs)
    raw_legs = [t if isinstance(t, dict) else {} for t in base.get("leg", [])]
    owner: dict[tuple[int, str], ParamKey] = {}
    for pk in sorted(keys, key=lambda k: _SPECIFICITY.get(k.section, -1)):
        tg = _targets(pk, n, raw_legs)
        if pk.section == "rod" and not tg:
            raise GridKeyError(f"has no effect: every [[leg]] sets its own '{pk.prop}' "
                               f"(use leg.{pk.prop} or leg[i].{pk.prop})", pk.key)
        for i in tg:
            owner[(i, pk.prop)] = pk  # the most specific key wins
    for pk in keys:
        tg = _targets(pk, n, raw_legs)
        if not tg:
            continue
        live = [i for i in tg if owner[(i, pk.prop)] is pk]
        if not live:
            other = owner[(tg[0], pk.prop)]
            raise GridKeyError(f"has no effect: {other.key} sets '{pk.prop}' of "
                               f"{'every leg it applies to' if len(tg) > 1 else f'leg {tg[0] + 1}'}", pk.key)
        for i in live:
            leg = legs[i]
            if pk.prop == "length" and leg.actuation == "length":
                if pk.section == "legi" or all(legs[j].actuation == "length" for j in live):
                    raise GridKeyError(f"has no effect: leg {i + 1} is length-actuated "
                                       "(its input is the free rod length)", pk.key)
            if pk.prop == "angle" and leg.actuation == "revolute":
                if pk.section == "legi" or all(legs[j].actuation == "revolute" for j in live):
                    raise GridKeyError(f"has no effect: leg {i + 1} is revolute "
                                       "(a revolute leg's angle is unused; its input is the clamp angle)", pk.key)
            if pk.prop == "E" and leg.rod.radius is None and (i, "radius") not in owner:
                raise GridKeyError(f"leg {i + 1} has no rod radius, so E cannot set its bending "
                                   "stiffness (give 'radius' in the mechanism file or use EI)", pk.key)
            if pk.prop in ("origin_radius", "origin_angle") and math.hypot(*leg.origin) == 0.0:
                raise GridKeyError(f"leg {i + 1}'s origin is at the world origin O, "
                                   "so it has no polar angle", pk.key)
    for i in range(n):
        mine = {p: owner[(i, p)].key for p in _LEG_ONE_PROPS if (i, p) in owner}
        if "E" in mine and "EI" in mine:
            raise GridKeyError(f"conflicts with {mine['E']}: both set the bending stiffness "
                               f"of leg {i + 1}", mine["EI"])
        polar = [mine[p] for p in ("origin_radius", "origin_angle") if p in mine]
        cart = [mine[p] for p in ("origin_x", "origin_y") if p in mine]
        if polar and cart:
            raise GridKeyError(f"conflicts with {polar[0]}: give leg {i + 1}'s origin either "
                               "in polar (origin_radius, origin_angle) or in cartesian (origin_x, origin_y) form",
                               cart[0])
    plat = [pk.key for pk in keys if pk.section == "platform"]
    if len(plat) > 1:
        raise GridKeyError(f"conflicts with {plat[0]}: both set the platform size", plat[1])
    if any(pk.section == "platform" and pk.prop == "radius" for pk in keys):
        for j, b in enumerate(mech.platform.attach):
            if math.hypot(*b) == 0.0:
                raise GridKeyError(f"attach point {j + 1} is at P, so it has no polar angle", "platform.radius")
    if any(pk.section == "limits" for pk in keys):
        for i, leg in enumerate(legs):
            if leg.rod.radius is None and (i, "radius") not in owner:
                raise GridKeyError(f"leg {i + 1} has no rod radius (strains need it)", "limits.max_strain")


def check_value(pk: ParamKey, value: Any) -> float:
    """The value as a float; raise :class:`GridKeyError` if it is not a finite number
    (> 0 for lengths, stiffnesses and factors)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise GridKeyError(f"expected a number, got {type(value).__name__} {value!r}")
    try:
        v = float(value)
    except OverflowError:
        raise GridKeyError(f"{value!r} is too large") from None
    if not math.isfinite(v):
        raise GridKeyError(f"expected a finite number, got {v!r}")
    if pk.positive and v <= 0.0:
        raise GridKeyError(f"must be > 0{(' (' + pk.unit + ')') if pk.unit else ''}, got {v!r}")
    return v


# ---- application ---------------------------------------------------------------------
def _normalised(base: Mapping[str, Any], mech: Any) -> dict[str, Any]:
    """Deep copy of the base dict with each leg carrying its own resolved rod properties
    (length, EI, radius, E); any other [rod] key stays in [rod]."""
    data = copy.deepcopy(dict(base))
    rod = {k: v for k, v in data.pop("rod", {}).items() if k not in _ROD_PROPS}
    if rod:
        data["rod"] = rod
    legs = []
    for raw, leg in zip(base["leg"], mech.legs):
        t = {k: copy.deepcopy(v) for k, v in raw.items() if k not in _ROD_PROPS}
        r = leg.rod
        if leg.actuation != "length" and r.length is not None:
            t["length"] = float(r.length)
        t["EI"] = float(r.EI)
        if r.radius is not None:
            t["radius"] = float(r.radius)
        if getattr(r, "E", None) is not None and r.radius is not None:
            t["E"] = float(r.E)
        legs.append(t)
    data["leg"] = legs
    return data


def _set_rod(t: dict[str, Any], prop: str, v: float) -> None:
    if prop == "length":
        if t.get("actuation") != "length":
            t["length"] = v
    elif prop == "EI":
        t["EI"] = v
        t.pop("E", None)
    elif prop == "E":
        t["E"] = v
        t.pop("EI", None)
    elif prop == "radius":
        t["radius"] = v
        if "E" in t:
            t.pop("EI", None)


def _polar(p: Sequence[float]) -> tuple[float, float]:
    return math.hypot(p[0], p[1]), math.atan2(p[1], p[0])


def apply_design(base: Mapping[str, Any], mech: Any, params: Mapping[str, float]) -> dict[str, Any]:
    """The mechanism dict of one design: the base dict (raw TOML, degrees) with the grid
    values ``params`` (key -> value) applied.  ``mech`` is the base mechanism built from
    ``base`` (it supplies the resolved rod properties).  Keys must have passed
    :func:`check_keys`."""
    n = len(mech.legs)
    data = _normalised(base, mech)
    raw_legs = [t if isinstance(t, dict) else {} for t in base["leg"]]
    keys = [parse_key(k, n) for k in params]
    per_leg: dict[tuple[int, str], tuple[int, float]] = {}
    for pk in keys:
        for i in _targets(pk, n, raw_legs):
            spec = _SPECIFICITY[pk.section]
            if (i, pk.prop) not in per_leg or per_leg[(i, pk.prop)][0] < spec:
                per_leg[(i, pk.prop)] = (spec, float(params[pk.key]))
    for (i, prop), (_, v) in sorted(per_leg.items(), key=lambda kv: (kv[0][0], _ORDER[kv[0][1]])):
        t = data["leg"][i]
        if prop in _ROD_PROPS:
            _set_rod(t, prop, v)
        elif prop in ("angle", "offset"):
            t[prop] = v
        elif prop in ("origin_radius", "origin_angle"):
            r, a = _polar(t["origin"])
            if prop == "origin_radius":
                r = v
            else:
                a = math.radians(v)
            t["origin"] = [r * math.cos(a), r * math.sin(a)]
        elif prop == "origin_x":
            t["origin"] = [v, float(t["origin"][1])]
        elif prop == "origin_y":
            t["origin"] = [float(t["origin"][0]), v]
    for pk in keys:
        v = float(params[pk.key])
        if pk.section == "platform":
            pts = data["platform"]["attach"]
            if pk.prop == "scale":
                data["platform"]["attach"] = [[v * float(p[0]), v * float(p[1])] for p in pts]
            else:
                data["platform"]["attach"] = [[v * math.cos(a), v * math.sin(a)]
                                              for a in (_polar(p)[1] for p in pts)]
        elif pk.section == "load":
            load = data.setdefault("load", {})
            if pk.prop == "moment":
                load["moment"] = v
            else:
                f = [float(c) for c in load.get("force", [0.0, 0.0])]
                f[0 if pk.prop == "force_x" else 1] = v
                load["force"] = f
        elif pk.section == "limits":
            data.setdefault("limits", {})["max_strain"] = v
    if "scale" in params:
        _scale_all(data, float(params["scale"]))
    return data


def _scale_all(data: dict[str, Any], s: float) -> None:
    """Multiply every length of a normalised mechanism dict by ``s``."""
    data["platform"]["attach"] = [[s * float(p[0]), s * float(p[1])] for p in data["platform"]["attach"]]
    for t in data["leg"]:
        t["origin"] = [s * float(t["origin"][0]), s * float(t["origin"][1])]
        if "length" in t:
            t["length"] = s * float(t["length"])
        if "radius" in t:
            _set_rod(t, "radius", s * float(t["radius"]))
        if "range" in t and t.get("actuation") != "revolute":
            t["range"] = [s * float(t["range"][0]), s * float(t["range"][1])]
        if "offset" in t and t.get("actuation") != "revolute":
            t["offset"] = s * float(t["offset"])


def scaled_settings(settings: Mapping[str, Any], params: Mapping[str, float]) -> dict[str, Any]:
    """Workspace settings of one design: ``step``, ``bounds`` and ``seed`` multiplied by the
    design's ``scale`` (if the grid has that key)."""
    out = dict(settings)
    s = float(params.get("scale", 1.0))
    if s != 1.0:
        if out.get("step") is not None:
            out["step"] = s * float(out["step"])
        if out.get("bounds") is not None:
            out["bounds"] = [s * float(b) for b in out["bounds"]]
        if out.get("seed") is not None:
            out["seed"] = [s * float(c) for c in out["seed"]]
    return out
