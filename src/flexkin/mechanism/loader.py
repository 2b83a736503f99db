"""Reading and validating mechanism files (TOML, SPEC §3).

Every user mistake raises :class:`~flexkin.errors.MechanismError` with one message of the
form ``"<file>: <key path>: <problem>"``, e.g.
``examples/x.toml: leg[2].origin: expected a list of two numbers, got 'abc'``.
Legs are numbered from 1 in key paths, as in the paper (``leg[1]`` is the first
``[[leg]]`` table).

Rod properties
--------------
The ``[rod]`` table (optional) gives defaults; a ``[[leg]]`` table may override any rod key
(``length``, ``E``, ``radius``, ``EI``).  The bending stiffness is ``EI`` if given, otherwise
``E * pi * radius**4 / 4``; if both are available they must agree to 1e-9 (relative).  A leg
that overrides ``E`` or ``radius`` (but not ``EI``) gets its ``EI`` recomputed from them
instead of inheriting ``[rod].EI``.  ``length`` is required for prismatic and revolute legs
and ignored for length legs.  ``[limits] max_strain`` requires every leg's ``radius``.

Material keys beyond bending (``G`` or ``poisson``, ``density``, ``shear_coefficient``; used
by the Cosserat refinement) and ``[environment] gravity`` are validated here and resolved per
leg by ``_resolve_material`` (a leg's own value wins; a leg giving ``G`` or ``poisson``
drops the other one inherited from ``[rod]``), and stored on each leg's
:class:`~flexkin.mechanism.model.Rod` and on :attr:`Mechanism.gravity`.

``[[leg]] offset`` (m, or deg for revolute legs; default 0) is the input's zero offset: the leg
behaves as if its input were ``u + offset`` (:mod:`flexkin.mechanism.actuators`).

Angles (``angle``, ``offset`` and ``range`` of revolute legs) are degrees in the file and radians in
the returned :class:`~flexkin.mechanism.model.Mechanism`.

Physically implausible values (a rod radius comparable to its length, ``E = 200`` Pa, a
revolute range in radians, ``angle`` on a revolute leg, ...) are accepted with a
:class:`~flexkin.errors.FlexkinWarning` naming the file, the key, the value and what is
expected (:mod:`flexkin.mechanism.plausibility`).  Full reference: ``docs/mechanism_file.md``.

Unknown keys are errors in every table (never silently ignored), with a ``did you mean``
hint for likely misspellings (:func:`flexkin.core.validation.suggest_key`).

Supported ranges (beyond them squares and fourth powers of the values would overflow or
underflow in double precision): rod ``length`` and ``radius`` in
:data:`~flexkin.mechanism.model.LENGTH_LIMITS` (1e-12 .. 1e12 m), ``E`` and ``EI`` (also the
``EI`` computed from ``E`` and ``radius``) in
:data:`~flexkin.mechanism.model.STIFFNESS_LIMITS` (1e-30 .. 1e30), coordinates (origins,
attach points, strokes of prismatic and length legs) within +-1e12 m, and a platform of at
least 1e-12 m.

Files are read as UTF-8 (a leading byte-order mark is accepted) and at most
:data:`MAX_FILE_BYTES` long; unreadable, binary, oversized and malformed files are
MechanismErrors too.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import warnings
from pathlib import Path
from typing import Any

from flexkin.core.validation import (KeyPathError, check_angle_deg, check_table_keys, file_choice, file_number,
                                     read_text_file, short_text, type_name)
from flexkin.errors import FlexkinWarning, MechanismError
from flexkin.mechanism.joints import JOINTS
from flexkin.mechanism.plausibility import check_mechanism_data
from flexkin.mechanism.model import (
    ACTUATIONS,
    LENGTH_LIMITS,
    STIFFNESS_LIMITS,
    Leg,
    Mechanism,
    Platform,
    Rod,
    circular_EI,
)

__all__ = ["load_mechanism", "mechanism_from_dict", "MATERIAL_KEYS"]

_TOP_KEYS = ("name", "rod", "platform", "leg", "load", "limits", "environment")
_ROD_KEYS = ("length", "E", "radius", "EI")
#: material keys beyond bending, used by the Cosserat refinement (issue 16); per-leg overrides
#: work as for the other rod keys
MATERIAL_KEYS = ("G", "poisson", "density", "shear_coefficient")
_LEG_KEYS = ("actuation", "origin", "angle", "range", "joint", "tip_angle", "offset") + _ROD_KEYS + MATERIAL_KEYS
_ENVIRONMENT_KEYS = ("gravity",)
#: relative tolerance of the agreement of G with E / (2 (1 + poisson)) when all three are given
_G_RTOL = 1e-6
_PLATFORM_KEYS = ("attach",)
_LOAD_KEYS = ("force", "moment")
_LIMITS_KEYS = ("max_strain",)
_EI_RTOL = 1e-9
#: Mechanism files larger than this are refused (protects against /dev/zero and the like).
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Supported range of each numeric rod key, with its unit.
_ROD_LIMITS = {
    "length": (LENGTH_LIMITS, "m"),
    "radius": (LENGTH_LIMITS, "m"),
    "E": (STIFFNESS_LIMITS, "Pa"),
    "EI": (STIFFNESS_LIMITS, "N m^2"),
}


def _show(value: Any) -> str:
    return short_text(value)


def _table(value: Any, path: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise KeyPathError(path, f"expected a table, got {type_name(value)} {_show(value)}")
    return value


def _angle(value: Any, path: str) -> float:
    """An angle in degrees, within the supported range (:data:`~flexkin.core.validation.ANGLE_LIMIT_DEG`)."""
    v = file_number(value, path)
    try:
        return check_angle_deg(v, "")
    except ValueError as e:
        raise KeyPathError(path, str(e)) from None


def _positive(value: Any, path: str, unit: str, limits: tuple[float, float] | None = None) -> float:
    v = file_number(value, path)
    if v <= 0.0:
        raise KeyPathError(path, f"must be > 0 ({unit}), got {v!r}")
    if limits is not None and not limits[0] <= v <= limits[1]:
        raise KeyPathError(path, f"{v:.6g} {unit} is outside the supported range [{limits[0]:g}, {limits[1]:g}] {unit}")
    return v


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _pair(value: Any, path: str, what: str = "a list of two numbers", bound: float | None = None) -> tuple[float, float]:
    """Two finite numbers; with ``bound``, each of magnitude <= bound (m)."""
    if not isinstance(value, list) or len(value) != 2 or not all(_is_number(v) for v in value):
        raise KeyPathError(path, f"expected {what}, got {_show(value)}")
    try:
        a, b = float(value[0]), float(value[1])
    except OverflowError:  # an integer beyond the float range
        raise KeyPathError(path, "expected a finite number, got an integer too large for a float "
                                 f"({_show(value)})") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise KeyPathError(path, f"expected finite numbers, got {_show(value)}")
    if bound is not None and max(abs(a), abs(b)) > bound:
        raise KeyPathError(path, f"values must be within +-{bound:g} m, got {_show(value)}")
    return (a, b)


def _require(table: dict[str, Any], key: str, path: str, what: str) -> Any:
    if key not in table:
        raise KeyPathError(f"{path}.{key}" if path else key, f"missing ({what})")
    return table[key]


# ---- sections ------------------------------------------------------------------------
def _rod_values(table: dict[str, Any], path: str) -> dict[str, float]:
    """Validated numeric rod keys present in ``table``."""
    out: dict[str, float] = {}
    for key in _ROD_KEYS:
        if key in table:
            limits, unit = _ROD_LIMITS[key]
            out[key] = _positive(table[key], f"{path}.{key}", unit, limits)
    return out


def _material_values(table: dict[str, Any], path: str) -> dict[str, float]:
    """Validated material keys (Cosserat refinement) present in ``table``."""
    out: dict[str, float] = {}
    if "G" in table:
        out["G"] = _positive(table["G"], f"{path}.G", "Pa", STIFFNESS_LIMITS)
    if "poisson" in table:
        nu = file_number(table["poisson"], f"{path}.poisson")
        if not -1.0 < nu <= 0.5:
            raise KeyPathError(f"{path}.poisson", f"Poisson's ratio must lie in (-1, 0.5], got {nu!r}")
        out["poisson"] = nu
    if "density" in table:
        rho = file_number(table["density"], f"{path}.density")
        if rho < 0.0:
            raise KeyPathError(f"{path}.density", f"must be >= 0 (kg/m^3), got {rho!r}")
        out["density"] = rho
    if "shear_coefficient" in table:
        out["shear_coefficient"] = _positive(table["shear_coefficient"], f"{path}.shear_coefficient",
                                             "dimensionless", (1e-6, 10.0))
    return out


def _resolve_material(defaults: dict[str, float], overrides: dict[str, float], E: float | None,
                     path: str) -> dict[str, float]:
    """A leg's material keys (``G``, ``poisson``, ``density``, ``shear_coefficient``): the leg's
    own values over the ``[rod]`` defaults.  A leg giving ``G`` or ``poisson`` drops the other
    one inherited from ``[rod]``; ``G`` and ``poisson`` given together must agree with ``E``
    (``G = E / (2 (1 + poisson))`` to 1e-6).  Raises ``KeyPathError`` (loader-internal)."""
    merged = dict(defaults)
    if {"G", "poisson"} & overrides.keys():
        merged.pop("G", None)
        merged.pop("poisson", None)
    merged.update(overrides)
    if "G" in merged and "poisson" in merged and E is not None:
        G_c = E / (2.0 * (1.0 + merged["poisson"]))
        if abs(merged["G"] - G_c) > _G_RTOL * max(merged["G"], G_c):
            where = path if ({"G", "poisson"} & overrides.keys()) else "rod"
            raise KeyPathError(f"{where}.G", f"G = {merged['G']:.6g} Pa disagrees with E / (2 (1 + poisson)) = "
                              f"{G_c:.6g} Pa (E = {E:g} Pa, poisson = {merged['poisson']:g}); give either G or "
                              "poisson, or make them agree")
    return merged


def _environment(value: Any) -> tuple[float, float] | None:
    table = _table(value, "environment")
    check_table_keys(table, _ENVIRONMENT_KEYS, "environment")
    if "gravity" not in table:
        return None
    return _pair(table["gravity"], "environment.gravity", "[gx, gy] in m/s^2")


def _resolve_rod(
    defaults: dict[str, float], overrides: dict[str, float], actuation: str, path: str
) -> Rod:
    merged = dict(defaults)
    merged.update(overrides)
    origin = {k: ("this [[leg]]" if k in overrides else "[rod]") for k in merged}
    if "EI" in merged and "EI" not in overrides and ({"E", "radius"} & overrides.keys()):
        if "E" in merged and "radius" in merged:
            del merged["EI"]  # EI is recomputed from the leg's own E/radius
    EI = merged.get("EI")
    E, radius = merged.get("E"), merged.get("radius")
    if E is not None and radius is not None:
        EI_c = circular_EI(E, radius)
        if EI is None:
            lo, hi = STIFFNESS_LIMITS
            if not lo <= EI_c <= hi:
                where = path if ({"E", "radius"} & overrides.keys()) else "rod"
                raise KeyPathError(
                    f"{where}.radius",
                    f"the bending stiffness E*pi*radius**4/4 = {EI_c:.6g} N m^2 (E = {E:g} Pa from {origin['E']}, "
                    f"radius = {radius:g} m from {origin['radius']}) is outside the supported range "
                    f"[{lo:g}, {hi:g}] N m^2",
                )
            EI = EI_c
        elif abs(EI - EI_c) > _EI_RTOL * max(abs(EI), abs(EI_c)):
            all_rod = not ({"EI", "E", "radius"} & overrides.keys())
            raise KeyPathError(
                "rod.EI" if all_rod else f"{path}.EI",
                f"EI = {EI:.10g} N m^2 (from {origin['EI']}) disagrees with E*pi*radius**4/4 = "
                f"{EI_c:.10g} N m^2 (E from {origin['E']}, radius from {origin['radius']}); "
                "give either EI or E and radius, or make them agree",
            )
    if EI is None:
        missing = "E" if radius is not None else ("radius" if E is not None else "EI")
        raise KeyPathError(
            f"{path}.{missing}",
            "missing: the bending stiffness needs 'EI', or both 'E' and 'radius', "
            "in [rod] or in this [[leg]]",
        )
    if actuation == "length":
        length = None  # the input is the free length; a given length is ignored
    else:
        if "length" not in merged:
            raise KeyPathError(
                f"{path}.length", f"missing (a {actuation} leg needs the rod length in m, in [rod] or in this [[leg]])"
            )
        length = merged["length"]
    return Rod(length=length, EI=EI, radius=radius, E=E)


def _leg(table: Any, i: int, rod_defaults: dict[str, float], material_defaults: dict[str, float] | None = None) -> Leg:
    path = f"leg[{i + 1}]"
    table = _table(table, path)
    check_table_keys(table, _LEG_KEYS, path)
    act = _require(table, "actuation", path, 'one of "prismatic", "revolute", "length"')
    act = file_choice(act, ACTUATIONS, f"{path}.actuation", "actuation")
    origin = _pair(_require(table, "origin", path, "[x, y] in m"), f"{path}.origin", bound=LENGTH_LIMITS[1])
    if act == "revolute":
        angle_deg = _angle(table["angle"], f"{path}.angle") if "angle" in table else 0.0
    else:
        angle_deg = _angle(
            _require(table, "angle", path, f"guide direction in degrees, required for {act} legs"),
            f"{path}.angle",
        )
    rng = None
    if "range" in table:
        lo, hi = _pair(table["range"], f"{path}.range", "[lo, hi]",
                       bound=None if act == "revolute" else LENGTH_LIMITS[1])
        if act == "revolute":
            lo, hi = _angle(lo, f"{path}.range"), _angle(hi, f"{path}.range")
        unit = "deg" if act == "revolute" else "m"
        if not lo < hi:
            raise KeyPathError(f"{path}.range", f"lower bound must be < upper bound, got [{lo:g}, {hi:g}] {unit}")
        if act == "length" and lo <= 0.0:
            raise KeyPathError(
                f"{path}.range", f"a length leg's range is a free rod length and must be > 0, got [{lo:g}, {hi:g}] m"
            )
        rng = (math.radians(lo), math.radians(hi)) if act == "revolute" else (lo, hi)
    offset = 0.0
    if "offset" in table:  # the input's zero offset: m, or deg for revolute legs
        offset = file_number(table["offset"], f"{path}.offset")
        if act != "revolute" and abs(offset) > LENGTH_LIMITS[1]:
            raise KeyPathError(f"{path}.offset", f"must be within +-{LENGTH_LIMITS[1]:g} m, got {offset!r}")
        if act == "revolute":
            offset = math.radians(offset)
    rod = _resolve_rod(rod_defaults, _rod_values(table, path), act, path)
    material = _resolve_material(material_defaults or {}, _material_values(table, path), rod.E, path)
    if material:
        rod = dataclasses.replace(rod, **material)
    joint = table.get("joint", "pinned")
    joint = file_choice(joint, JOINTS, f"{path}.joint", "joint")
    tip_angle = 0.0
    if JOINTS[joint].carries_moment:
        tip_angle = _angle(_require(table, "tip_angle", path, "the rod's tangent at the platform point, in degrees "
                                    "in the platform frame, required for a clamped joint"), f"{path}.tip_angle")
    elif "tip_angle" in table:
        _angle(table["tip_angle"], f"{path}.tip_angle")
        warnings.warn(f"{path}.tip_angle: ignored: a {joint} joint leaves the rod's tip free to turn "
                      f"(tip_angle applies to joint = \"clamped\")", FlexkinWarning, stacklevel=4)
    return Leg(actuation=act, origin=origin, angle=math.radians(angle_deg), rod=rod, range=rng,  # type: ignore[arg-type]
               joint=joint, tip_angle=math.radians(tip_angle), offset=offset)  # type: ignore[arg-type]


def _platform(value: Any) -> Platform:
    table = _table(value, "platform")
    check_table_keys(table, _PLATFORM_KEYS, "platform")
    pts = _require(table, "attach", "platform", "three points [[x1, y1], [x2, y2], [x3, y3]] in m")
    if not isinstance(pts, list) or len(pts) != 3:
        n = f"{len(pts)} entries" if isinstance(pts, list) else _show(pts)
        raise KeyPathError("platform.attach", f"expected exactly three points [[x1, y1], [x2, y2], [x3, y3]], got {n}")
    b = tuple(_pair(p, f"platform.attach[{j + 1}]", "a point [x, y]", bound=LENGTH_LIMITS[1]) for j, p in enumerate(pts))
    try:
        return Platform(attach=b)  # type: ignore[arg-type]
    except MechanismError as exc:  # coincident / collinear points
        msg = str(exc).removeprefix("platform.attach: ")
        raise KeyPathError("platform.attach", msg) from None


def _load(value: Any) -> tuple[float, float, float]:
    table = _table(value, "load")
    check_table_keys(table, _LOAD_KEYS, "load")
    fx, fy = _pair(table["force"], "load.force", "[Fx, Fy] in N") if "force" in table else (0.0, 0.0)
    mz = file_number(table["moment"], "load.moment") if "moment" in table else 0.0
    return (fx, fy, mz)


def _mechanism(data: Any, default_name: str, source: str | None, warn_prefix: str = "") -> Mechanism:
    data = _table(data, "")
    check_table_keys(data, _TOP_KEYS, "")
    name = data.get("name", default_name)
    if not isinstance(name, str):
        raise KeyPathError("name", f"expected a string, got {type_name(name)} {_show(name)}")
    rod_defaults: dict[str, float] = {}
    material_defaults: dict[str, float] = {}
    if "rod" in data:
        rod_table = _table(data["rod"], "rod")
        check_table_keys(rod_table, _ROD_KEYS + MATERIAL_KEYS, "rod")
        rod_defaults = _rod_values(rod_table, "rod")
        material_defaults = _material_values(rod_table, "rod")
    platform = _platform(_require(data, "platform", "", "a [platform] table with 'attach'"))
    legs_raw = _require(data, "leg", "", "three [[leg]] tables")
    if isinstance(legs_raw, dict):
        raise KeyPathError("leg", "expected three [[leg]] tables, got a single [leg] table (write [[leg]])")
    if not isinstance(legs_raw, list):
        raise KeyPathError("leg", f"expected three [[leg]] tables, got {type_name(legs_raw)} {_show(legs_raw)}")
    if len(legs_raw) != 3:
        raise KeyPathError("leg", f"expected exactly three [[leg]] tables, got {len(legs_raw)}")
    legs = tuple(_leg(t, i, rod_defaults, material_defaults) for i, t in enumerate(legs_raw))
    load = _load(data["load"]) if "load" in data else (0.0, 0.0, 0.0)
    gravity = _environment(data["environment"]) if "environment" in data else None
    max_strain = None
    if "limits" in data:
        limits = _table(data["limits"], "limits")
        check_table_keys(limits, _LIMITS_KEYS, "limits")
        if "max_strain" in limits:
            max_strain = _positive(limits["max_strain"], "limits.max_strain", "dimensionless strain")
            for i, leg in enumerate(legs):
                if leg.rod.radius is None:
                    raise KeyPathError(
                        f"leg[{i + 1}].radius",
                        "missing: limits.max_strain needs the rod radius of every leg (in [rod] or in the [[leg]])",
                    )
    try:
        mech = Mechanism(
            name=name, legs=legs, platform=platform, load=load, max_strain=max_strain, source=source, gravity=gravity
        )  # type: ignore[arg-type]
    except MechanismError as exc:  # coincident leg origins etc.; message already has the key path
        raise KeyPathError("", str(exc)) from None
    try:
        notes = check_mechanism_data(data, mech)
    except Exception:  # pragma: no cover - a plausibility check never stops a valid file
        notes = []
    for note in notes:
        warnings.warn(f"{warn_prefix}{note}", FlexkinWarning, stacklevel=4)
    return mech


def _default_name(source: str) -> str:
    if source.startswith("<"):
        return "mechanism"
    return Path(source).stem or "mechanism"


# ---- public API ----------------------------------------------------------------------
def mechanism_from_dict(data: dict[str, Any], source: str = "<dict>") -> Mechanism:
    """Build a :class:`Mechanism` from a parsed mechanism file (SPEC §3).

    Parameters
    ----------
    data : dict
        The file's content as parsed by :func:`tomllib.loads` (degrees for angles).
    source : str, optional
        Name used in error messages (and stored as ``Mechanism.source`` unless it starts
        with ``"<"``); the default name is its stem.

    Returns
    -------
    Mechanism

    Raises
    ------
    MechanismError
        For any invalid content, with a message ``"<source>: <key path>: <problem>"``.
    """
    src = str(source)
    try:
        return _mechanism(data, _default_name(src), None if src.startswith("<") else src,
                          "" if src.startswith("<") else f"{src}: ")
    except KeyPathError as exc:
        raise MechanismError(f"{src}: {exc}") from None
    except MechanismError as exc:
        raise MechanismError(f"{src}: {exc}") from None
    except Exception as exc:  # never a traceback for user mistakes
        raise MechanismError(f"{src}: invalid mechanism description ({type(exc).__name__}: {exc})") from exc


def load_mechanism(path: str | os.PathLike[str]) -> Mechanism:
    """Load and validate a mechanism file (TOML, SPEC §3).

    Parameters
    ----------
    path : str or os.PathLike
        Mechanism file.

    Returns
    -------
    Mechanism
        With angles in radians and ``source`` set to ``str(path)``.

    Raises
    ------
    MechanismError
        If the file cannot be read, is not valid TOML, or describes an invalid mechanism;
        the message names the file and the offending key.
    """
    try:
        src = os.fspath(path)
    except TypeError:
        raise MechanismError(f"{path!r}: expected a file path") from None
    src = src if isinstance(src, str) else os.fsdecode(src)
    if "\0" in src:
        raise MechanismError(f"{src!r}: invalid file name (contains a NUL character)")
    if not src:
        raise MechanismError("'': empty file name")
    src, text = read_text_file(src, "mechanism file", MechanismError, MAX_FILE_BYTES)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MechanismError(f"{src}: malformed TOML: {exc}") from None
    except RecursionError:
        raise MechanismError(f"{src}: malformed TOML: arrays or inline tables nested too deeply") from None
    except ValueError as exc:  # e.g. an integer literal with thousands of digits
        raise MechanismError(f"{src}: malformed TOML: {_show(str(exc))}") from None
    return mechanism_from_dict(data, source=src)
