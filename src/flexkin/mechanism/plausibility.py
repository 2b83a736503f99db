"""Plausibility checks of a mechanism file: values that are possible but physically unlikely.

The loader (:mod:`flexkin.mechanism.loader`) rejects what is impossible (a negative length,
coincident platform points, ...) with a :class:`~flexkin.errors.MechanismError`.  What is
possible but almost certainly a unit mistake is accepted with a
:class:`~flexkin.errors.FlexkinWarning` that names the key, the value and what is expected:

* a ``radius`` that is not small compared with the rod length (not a slender rod: the
  Kirchhoff model does not apply; typically metres written for millimetres);
* a Young's modulus ``E`` (or a shear modulus ``G``) far below or above any engineering
  material (``E = 200``: GPa or MPa forgotten);
* a ``density`` far from any solid (``7.85``: g/cm^3 written for kg/m^3);
* a revolute leg's ``range`` whose bounds all lie within +-2 pi (radians written for degrees);
* an ``angle`` key on a revolute leg (it has no effect there);
* an ``angle`` or ``tip_angle`` of more than a full turn;
* leg origins too far apart for the rods and the platform to meet anywhere, or spread over
  far more than the rods can span (millimetres written for metres);
* rods many orders of magnitude longer than the base and the platform (the platform is then a
  point to the solvers' resolution);
* revolute actuator inputs on the command line that look like radians
  (:func:`revolute_inputs_look_like_radians`).

Every check returns plain ``"<key path>: <problem>"`` strings; the caller decides how to
report them (the loader warns, prefixing the file name).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from flexkin.core.validation import angle_note

__all__ = [
    "check_mechanism_data",
    "revolute_inputs_look_like_radians",
    "SLENDER_RATIO",
    "E_RANGE",
    "G_RANGE",
    "DENSITY_RANGE",
    "SPREAD_RATIO",
    "PROPORTION_RATIO",
]

#: largest plausible radius / length of a rod modelled as a Kirchhoff rod (length/diameter >= 10)
SLENDER_RATIO = 0.05
#: plausible Young's modulus (Pa): from soft elastomers (~1e5 Pa) to diamond (~1.2e12 Pa)
E_RANGE = (1e5, 1.5e12)
#: plausible shear modulus (Pa)
G_RANGE = (3e4, 6e11)
#: plausible density of a solid rod (kg/m^3): from foams/wood (~100) to osmium (~22600)
DENSITY_RANGE = (100.0, 25000.0)
_TWO_PI = 2.0 * math.pi
#: leg origins spread over more than this many times what the rods and the platform can span
#: are implausible (a unit mistake: millimetres for metres gives 1000)
SPREAD_RATIO = 100.0
#: rods longer than this many times the base and the platform are implausible
PROPORTION_RATIO = 1e6


def _num(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        f = float(v)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def _where(data: dict[str, Any], i: int, key: str) -> str | None:
    """Key path a leg's rod value comes from: ``leg[i].key``, ``rod.key`` or None."""
    legs = data.get("leg")
    if isinstance(legs, list) and i < len(legs) and isinstance(legs[i], dict) and key in legs[i]:
        return f"leg[{i + 1}].{key}"
    rod = data.get("rod")
    if isinstance(rod, dict) and key in rod:
        return f"rod.{key}"
    return None


def _value(data: dict[str, Any], where: str) -> float | None:
    table, key = where.split(".", 1)
    if table == "rod":
        return _num(data["rod"][key])
    i = int(table[4:-1]) - 1
    return _num(data["leg"][i][key])


def _leg_length(mech: Any, i: int) -> tuple[float | None, str]:
    leg = mech.legs[i]
    if leg.actuation != "length" and leg.rod.length is not None:
        return float(leg.rod.length), "the rod length"
    if leg.range is not None:
        return float(leg.range[1]), "the longest free length of the leg's range"
    return None, ""


def _material(data: dict[str, Any], mech: Any, key: str, bounds: tuple[float, float], unit: str,
              low_hint: str, high_hint: str, out: list[str], noun: str = "engineering material") -> None:
    seen: set[str] = set()
    for i in range(len(mech.legs)):
        where = _where(data, i, key)
        if where is None or where in seen:
            continue
        seen.add(where)
        v = _value(data, where)
        if v is None or v <= 0:
            continue
        if v < bounds[0]:
            out.append(f"{where}: {key} = {v:g} {unit} is far below any {noun} "
                       f"(expected {bounds[0]:g} .. {bounds[1]:g} {unit}; {low_hint})")
        elif v > bounds[1]:
            out.append(f"{where}: {key} = {v:g} {unit} is above any {noun} "
                       f"(expected {bounds[0]:g} .. {bounds[1]:g} {unit}; {high_hint})")


def check_mechanism_data(data: dict[str, Any], mech: Any) -> list[str]:
    """Plausibility problems of a mechanism file (see the module docstring).

    Parameters
    ----------
    data : dict
        The file's content as parsed (degrees, display units), already validated.
    mech : Mechanism
        The mechanism the loader built from ``data``.

    Returns
    -------
    list of str
        ``"<key path>: <problem>"`` messages, one per implausible value (a value in ``[rod]``
        is reported once, not per leg).
    """
    out: list[str] = []
    legs_raw = data.get("leg") if isinstance(data.get("leg"), list) else []
    # radius vs length: a slender rod
    seen: set[str] = set()
    for i, leg in enumerate(mech.legs):
        r = leg.rod.radius
        where = _where(data, i, "radius")
        if r is None or where is None:
            continue
        L, what = _leg_length(mech, i)
        if L is None or L <= 0 or r <= SLENDER_RATIO * L:
            continue
        key = f"{where}@{L!r}"
        if key in seen:
            continue
        seen.add(key)
        out.append(f"{where}: radius = {r:g} m is not small compared with {what} {L:g} m "
                   f"(radius/length = {r / L:.3g}, a slender rod needs below {SLENDER_RATIO:g}); "
                   f"the radius is in m: a 3 mm rod is radius = 1.5e-3")
    # materials
    _material(data, mech, "E", E_RANGE, "Pa",
              "E is in Pa: steel is 2e11, Nitinol 6.8e10, PEEK 3.6e9; was GPa or MPa meant?",
              "E is in Pa; was kPa or MPa used by mistake?", out)
    _material(data, mech, "G", G_RANGE, "Pa",
              "G is in Pa: steel is 8e10, Nitinol 2.6e10; was GPa or MPa meant?",
              "G is in Pa", out)
    _material(data, mech, "density", DENSITY_RANGE, "kg/m^3",
              "density is in kg/m^3: steel is 7850, Nitinol 6450; was g/cm^3 meant?",
              "density is in kg/m^3", out, noun="solid")
    # revolute legs: range in radians, angle without effect
    for i, leg in enumerate(mech.legs):
        if leg.actuation != "revolute":
            continue
        raw = legs_raw[i] if i < len(legs_raw) and isinstance(legs_raw[i], dict) else {}
        rng = raw.get("range")
        if isinstance(rng, list) and len(rng) == 2:
            lo, hi = _num(rng[0]), _num(rng[1])
            if lo is not None and hi is not None and max(abs(lo), abs(hi)) <= _TWO_PI:
                out.append(f"leg[{i + 1}].range: [{lo:g}, {hi:g}] looks like radians: a revolute leg's range "
                           f"is in degrees (this one spans only {hi - lo:.3g} deg); in degrees it would be "
                           f"[{math.degrees(lo):.4g}, {math.degrees(hi):.4g}]")
        if "angle" in raw:
            out.append(f"leg[{i + 1}].angle: has no effect on a revolute leg (its input is the clamp angle); "
                       "remove the key")
    # angles of more than a full turn
    for i, raw in enumerate(legs_raw):
        if not isinstance(raw, dict):
            continue
        for key in ("angle", "tip_angle"):
            v = _num(raw.get(key))
            note = None if v is None else angle_note(v, key)
            if note:
                out.append(f"leg[{i + 1}].{key}: {note}")
    note = _origins_too_far(mech)
    if note:
        out.append(note)
    note = _proportions(mech)
    if note:
        out.append(note)
    return out


def _clamp_set(leg: Any) -> tuple[tuple[float, float], tuple[float, float], float] | None:
    """Where a leg's clamp can be and how far its rod reaches: ``(A0, A1, reach)`` with the clamp
    on the segment ``A0 A1`` (a point for revolute and length legs); None when unbounded (a
    prismatic leg without a range, a length leg without one)."""
    o = (float(leg.origin[0]), float(leg.origin[1]))
    if leg.actuation == "revolute":
        return o, o, float(leg.rod.length)
    if leg.actuation == "length":
        return (o, o, float(leg.range[1])) if leg.range is not None else None
    if leg.range is None:
        return None
    d = (math.cos(leg.angle), math.sin(leg.angle))
    lo, hi = leg.range
    return (o[0] + lo * d[0], o[1] + lo * d[1]), (o[0] + hi * d[0], o[1] + hi * d[1]), float(leg.rod.length)


def _point_segment(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = dx * dx + dy * dy
    t = 0.0 if n == 0.0 else min(max(((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n, 0.0), 1.0)
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def _segments(a0, a1, b0, b1) -> float:
    """Distance between the segments ``a0 a1`` and ``b0 b1`` (0 when they cross)."""
    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    if a0 != a1 and b0 != b1:
        d1, d2 = orient(a0, a1, b0), orient(a0, a1, b1)
        d3, d4 = orient(b0, b1, a0), orient(b0, b1, a1)
        if d1 * d2 < 0 and d3 * d4 < 0:
            return 0.0
    return min(_point_segment(a0, b0, b1), _point_segment(a1, b0, b1), _point_segment(b0, a0, a1),
               _point_segment(b1, a0, a1))


def _origins_too_far(mech: Any) -> str | None:
    """A note when the legs' clamps are too far apart for the rods and the platform to meet
    (no pose can be assembled), or the origins spread over far more than they can span."""
    b = mech.platform.b
    sets = [_clamp_set(leg) for leg in mech.legs]
    unit = "the coordinates are in m: were they given in mm?"
    for i in range(3):
        for j in range(i + 1, 3):
            if sets[i] is None or sets[j] is None:
                continue
            gap = _segments(sets[i][0], sets[i][1], sets[j][0], sets[j][1])
            span = sets[i][2] + sets[j][2] + math.hypot(*(b[i] - b[j]))
            if gap > span:
                return (f"leg[{i + 1}].origin, leg[{j + 1}].origin: the clamps of legs {i + 1} and {j + 1} are at "
                        f"least {gap:.4g} m apart, more than their rods and the platform side can span "
                        f"({span:.4g} m): no pose can be assembled" + (f"; {unit}" if gap > 10 * span else ""))
    o = [(float(leg.origin[0]), float(leg.origin[1])) for leg in mech.legs]
    spread = max(math.hypot(o[i][0] - o[j][0], o[i][1] - o[j][1]) for i in range(3) for j in range(i + 1, 3))
    reach = [s[2] for s in sets if s is not None] + [float(leg.rod.length) for leg in mech.legs
                                                     if leg.actuation == "prismatic"]
    if not reach:
        return None
    span = 2.0 * max(reach) + mech.platform.size
    if spread > SPREAD_RATIO * span:
        return (f"leg[*].origin: the leg origins are spread over {spread:.4g} m, {spread / span:.3g} times what "
                f"two rods and the platform can span ({span:.4g} m); {unit}")
    return None


def _proportions(mech: Any) -> str | None:
    """A note when the rods are many orders of magnitude longer than the base and the platform."""
    L = max([float(leg.rod.length) for leg in mech.legs if leg.rod.length is not None]
            + [float(leg.range[1]) for leg in mech.legs if leg.actuation == "length" and leg.range is not None]
            + [0.0])
    o = [(float(leg.origin[0]), float(leg.origin[1])) for leg in mech.legs]
    spread = max(math.hypot(o[i][0] - o[j][0], o[i][1] - o[j][1]) for i in range(3) for j in range(i + 1, 3))
    size = max(spread, mech.platform.size)
    if L > PROPORTION_RATIO * size:
        return (f"rod.length: the rods ({L:.4g} m) are {L / size:.3g} times longer than the base and the platform "
                f"({size:.4g} m): the platform is a point to the solvers' resolution (was the length meant in "
                "another unit?)")
    return None


def revolute_inputs_look_like_radians(mech: Any, inputs_display: Sequence[float]) -> str | None:
    """A warning text if revolute inputs given in degrees look like radians, else None.

    They do when every revolute input lies within +-2 pi (at least one of them non-zero) and,
    for the legs with a ``range``, at least one input is outside its range in degrees while
    its radian reading lies inside it (without any range, the magnitudes alone decide).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    inputs_display : sequence of float
        The three inputs as typed (m, or deg for revolute legs).

    Returns
    -------
    str or None
    """
    rev = [(i, float(v), leg) for i, (v, leg) in enumerate(zip(inputs_display, mech.legs))
           if leg.actuation == "revolute"]
    if not rev or not all(abs(v) <= _TWO_PI for _, v, _ in rev) or all(v == 0.0 for _, v, _ in rev):
        return None
    ranged = [(i, v, leg) for i, v, leg in rev if leg.range is not None]
    if ranged:
        hint = [i for i, v, leg in ranged
                if not bool(leg.in_range(math.radians(v))) and bool(leg.in_range(v))]
        if not hint:
            return None
    shown = ", ".join(f"{v:g}" for _, v, _ in rev)
    as_deg = ", ".join(f"{math.degrees(v):.4g}" for _, v, _ in rev)
    legs = ", ".join(str(i + 1) for i, _, _ in rev)
    return (f"--inputs: the revolute inputs ({shown}) of leg(s) {legs} look like radians; revolute inputs are "
            f"in degrees (in degrees these radians would be {as_deg})")
