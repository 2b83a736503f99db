"""Study files (TOML): parsing and validation.

A study names a base mechanism file, a grid over mechanism parameters (dotted keys, see
:mod:`flexkin.study.grid`), the platform orientations to map and, optionally, the metrics and
the workspace settings.  ``docs/study.md`` describes the format; the minimal form is::

    mechanism = "unit_3rfr.toml"            # relative to the study file
    orientations = [0, 20]                  # deg
    [grid]
    "rod.length" = [0.9, 1.0, 1.1]          # explicit values
    "rod.EI" = {start = 0.5, stop = 2.0, num = 4}

Every mistake raises :class:`StudyError` with one message ``"<file>: <key>: <problem>"``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..core.validation import (MAX_MODE_LIMIT, KeyPathError, check_max_mode, check_table_keys, file_number,
                               read_text_file, short_text, suggest_key, type_name)
from . import grid as _grid
from .evaluate import METRICS, ROW_VERSION, DesignTask

__all__ = ["StudyError", "StudySpec", "GridAxis", "Design", "load_study", "study_from_dict", "WORKSPACE_DEFAULTS"]

_TOP_KEYS = ("name", "mechanism", "orientations", "metrics", "grid", "workspace")
_RANGE_KEYS = ("start", "stop", "num")
#: workspace settings and their defaults (``None``: flexkin's default)
WORKSPACE_DEFAULTS: dict[str, Any] = {"step": None, "bounds": None, "seed": [0.0, 0.0], "max_mode": 2,
                                      "all_aspects": True, "time_budget": None, "constrained": False,
                                      "collisions": False, "seed_search": True}
MAX_TASKS = 1_000_000
MAX_FILE_BYTES = 1024 * 1024


class StudyError(ValueError):
    """A study file or a study argument is invalid, or the study cannot run; the message is
    one line meant for the user."""


@dataclass(frozen=True)
class GridAxis:
    """One grid parameter: its dotted key and its values (in file order)."""

    key: str
    values: tuple[float, ...]


@dataclass(frozen=True)
class Design:
    """One point of the grid: its index (row-major over the axes, the first axis slowest)
    and its parameter values."""

    index: int
    params: tuple[tuple[str, float], ...]

    def as_dict(self) -> dict[str, float]:
        return dict(self.params)


@dataclass(frozen=True)
class StudySpec:
    """A validated study.

    Attributes
    ----------
    name : str
    source : str
        The study file (or ``"<dict>"``).
    mechanism_path : str
        The base mechanism file (absolute).
    mechanism : dict
        The base mechanism file's content (as parsed TOML: degrees).
    grid : tuple of GridAxis
    orientations : tuple of float
        Degrees.
    metrics : tuple of str
        Metric columns to compute (default: every metric of :data:`flexkin.study.METRICS`).
    workspace : dict
        Workspace settings (see :data:`WORKSPACE_DEFAULTS`).
    """

    name: str
    source: str
    mechanism_path: str
    mechanism: dict[str, Any] = field(repr=False)
    grid: tuple[GridAxis, ...]
    orientations: tuple[float, ...]
    metrics: tuple[str, ...]
    workspace: dict[str, Any]

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(a.key for a in self.grid)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a.values) for a in self.grid)

    @property
    def n_designs(self) -> int:
        return math.prod(self.shape)

    @property
    def n_tasks(self) -> int:
        return self.n_designs * len(self.orientations)

    def designs(self) -> list[Design]:
        """Every design, in row order (the first grid key varies slowest)."""
        return [Design(d, tuple(zip(self.keys, vals)))
                for d, vals in enumerate(itertools.product(*(a.values for a in self.grid)))]

    def tasks(self) -> list[DesignTask]:
        """One task per (design, orientation), in row order; each with a content key that
        identifies its result (the same inputs give the same key, whatever the run)."""
        from ..mechanism import mechanism_from_dict

        base_mech = mechanism_from_dict(self.mechanism, source=self.mechanism_path)
        out = []
        for d in self.designs():
            params = d.as_dict()
            data = _grid.apply_design(self.mechanism, base_mech, params)
            ws = _grid.scaled_settings(self.workspace, params)
            for th in self.orientations:
                ident = {"v": ROW_VERSION, "mechanism": data, "theta_deg": th, "workspace": ws,
                         "metrics": list(self.metrics)}
                key = hashlib.sha256(json.dumps(ident, sort_keys=True, allow_nan=False).encode()).hexdigest()[:24]
                label = ", ".join(f"{k} = {v:g}" for k, v in d.params)
                out.append(DesignTask(index=len(out), design=d.index, params=d.params, theta_deg=th,
                                      mechanism=data, source=f"<design {d.index} ({label}) of "
                                      f"{os.path.basename(self.mechanism_path)}>",
                                      workspace=ws, metrics=self.metrics, key=key))
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (written beside the results)."""
        return {"name": self.name, "source": self.source, "mechanism_path": self.mechanism_path,
                "grid": {a.key: list(a.values) for a in self.grid}, "orientations": list(self.orientations),
                "metrics": list(self.metrics), "workspace": dict(self.workspace), "row_version": ROW_VERSION}


# ---- value helpers -------------------------------------------------------------------
def _show(v: Any) -> str:
    return short_text(v)


def _values(v: Any, path: str, what: str = "values") -> tuple[float, ...]:
    """An explicit list of numbers or a ``{start, stop, num}`` range (linspace)."""
    if isinstance(v, list):
        if not v:
            raise KeyPathError(path, "empty list: give at least one value")
        vals = tuple(file_number(x, f"{path}[{j + 1}]") for j, x in enumerate(v))
    elif isinstance(v, dict):
        check_table_keys(v, _RANGE_KEYS, path)
        for k in _RANGE_KEYS:
            if k not in v:
                raise KeyPathError(f"{path}.{k}", "missing (a range is {start = a, stop = b, num = n})")
        a = file_number(v["start"], f"{path}.start")
        b = file_number(v["stop"], f"{path}.stop")
        num = v["num"]
        if isinstance(num, bool) or not isinstance(num, int):
            raise KeyPathError(f"{path}.num", f"expected an integer, got {type_name(num)} {_show(num)}")
        if num < 1:
            raise KeyPathError(f"{path}.num", f"must be >= 1, got {num}")
        if num == 1 and a != b:
            raise KeyPathError(f"{path}.num", "num = 1 with start != stop is ambiguous: give num >= 2 or a list")
        if num > MAX_TASKS:
            raise KeyPathError(f"{path}.num", f"too many values ({num})")
        if num > 1 and a == b:
            raise KeyPathError(path, f"start == stop ({a:g}) with num = {num} gives {num} equal values")
        vals = tuple(float(x) for x in np.linspace(a, b, num))
    else:
        raise KeyPathError(path, f"expected a list of {what} or a range {{start, stop, num}}, got {type_name(v)} {_show(v)}")
    seen: set[float] = set()
    for x in vals:
        if x in seen:
            raise KeyPathError(path, f"duplicate value {x:g}")
        seen.add(x)
    return vals


# ---- sections ------------------------------------------------------------------------
def _read_mechanism(value: Any, base_dir: Path) -> tuple[str, dict[str, Any], Any]:
    from ..errors import MechanismError
    from ..mechanism import load_mechanism

    if not isinstance(value, str):
        raise KeyPathError("mechanism", f"expected a file name (string), got {type_name(value)} {_show(value)}")
    if not value:
        raise KeyPathError("mechanism", "empty file name")
    path = Path(value)
    if not path.is_absolute():
        path = base_dir / path
    path = Path(os.path.normpath(path))
    if not path.exists():
        raise KeyPathError("mechanism", f"file not found: {path}")
    try:
        mech = load_mechanism(path)
    except MechanismError as e:
        raise KeyPathError("mechanism", f"invalid base mechanism: {e}") from None
    with open(path, "rb") as fh:
        data = tomllib.loads(fh.read().decode("utf-8-sig"))
    return str(path), data, mech


def _workspace(value: Any) -> dict[str, Any]:
    out = dict(WORKSPACE_DEFAULTS)
    if value is None:
        return out
    if not isinstance(value, dict):
        raise KeyPathError("workspace", f"expected a table, got {type_name(value)} {_show(value)}")
    check_table_keys(value, tuple(WORKSPACE_DEFAULTS), "workspace")
    if "step" in value:
        s = file_number(value["step"], "workspace.step")
        if s <= 0:
            raise KeyPathError("workspace.step", f"must be > 0 (m), got {s!r}")
        out["step"] = s
    if "bounds" in value:
        b = value["bounds"]
        if not isinstance(b, list) or len(b) != 4:
            raise KeyPathError("workspace.bounds", f"expected [x0, x1, y0, y1] (m), got {_show(b)}")
        bb = [file_number(x, f"workspace.bounds[{j + 1}]") for j, x in enumerate(b)]
        if not (bb[0] < bb[1] and bb[2] < bb[3]):
            raise KeyPathError("workspace.bounds", f"need x0 < x1 and y0 < y1, got {_show(b)}")
        out["bounds"] = bb
    if "seed" in value:
        sd = value["seed"]
        if not isinstance(sd, list) or len(sd) != 2:
            raise KeyPathError("workspace.seed", f"expected [x, y] (m), got {_show(sd)}")
        out["seed"] = [file_number(x, f"workspace.seed[{j + 1}]") for j, x in enumerate(sd)]
    if "max_mode" in value:
        q = value["max_mode"]
        try:
            out["max_mode"] = check_max_mode(q)
        except ValueError:
            raise KeyPathError("workspace.max_mode",
                               f"expected an integer from 1 to {MAX_MODE_LIMIT}, got {_show(q)}") from None
    for key in ("all_aspects", "constrained", "collisions", "seed_search"):
        if key in value:
            flag = value[key]
            if not isinstance(flag, bool):
                raise KeyPathError(f"workspace.{key}", f"expected true or false, got {_show(flag)}")
            out[key] = flag
    if "time_budget" in value:
        t = file_number(value["time_budget"], "workspace.time_budget")
        if t <= 0:
            raise KeyPathError("workspace.time_budget", f"must be > 0 (s), got {t!r}")
        out["time_budget"] = t
    if out["bounds"] is not None and out["seed"] is not None:
        b, s = out["bounds"], out["seed"]
        if not (b[0] <= s[0] <= b[1] and b[2] <= s[1] <= b[3]):
            raise KeyPathError("workspace.seed", f"({s[0]:g}, {s[1]:g}) lies outside the bounds {b}")
    return out


def _check_grid(mech: Any, ws: dict[str, Any]) -> None:
    """The workspace grid of the base design (step and bounds) must be usable: a step no
    design can use is an error of the study file, not a failure of every row."""
    from ..solve.grid import default_grid

    try:
        default_grid(mech, ws["step"], ws["bounds"])
    except ValueError as e:
        raise KeyPathError("workspace.step" if ws["step"] is not None else "workspace.bounds",
                       f"{e} (for the base design)") from None


def _metrics(value: Any) -> tuple[str, ...]:
    if value is None:
        return tuple(METRICS)
    if not isinstance(value, list) or not value:
        raise KeyPathError("metrics", f"expected a non-empty list of metric names, got {_show(value)}")
    out: list[str] = []
    for j, m in enumerate(value):
        if not isinstance(m, str):
            raise KeyPathError(f"metrics[{j + 1}]", f"expected a metric name, got {type_name(m)} {_show(m)}")
        if m not in METRICS:
            close = suggest_key(m, list(METRICS))
            hint = f" (did you mean {close!r}?)" if close else ""
            raise KeyPathError(f"metrics[{j + 1}]", f"unknown metric {m!r}{hint}; metrics: {', '.join(METRICS)}")
        if m in out:
            raise KeyPathError(f"metrics[{j + 1}]", f"duplicate metric {m!r}")
        out.append(m)
    return tuple(m for m in METRICS if m in out)  # the table's column order


def _quoted(key: str) -> str:
    if len(key) > 64:
        return short_text(key)
    return key if key.replace("_", "").isalnum() else json.dumps(key)


def _grid_axes(value: Any, base: dict[str, Any], mech: Any) -> tuple[GridAxis, ...]:
    if value is None:
        raise KeyPathError("grid", "missing: a [grid] table with at least one parameter, e.g. \"rod.length\" = [0.9, 1.0]")
    if not isinstance(value, dict):
        raise KeyPathError("grid", f"expected a table, got {type_name(value)} {_show(value)}")
    if not value:
        raise KeyPathError("grid", "empty: give at least one parameter, e.g. \"rod.length\" = [0.9, 1.0]")
    n = len(mech.legs)
    axes, pks = [], []
    for key, v in value.items():
        path = f"grid.{_quoted(key)}"
        if isinstance(v, dict) and not set(v) & set(_RANGE_KEYS) and v:
            # TOML turns an unquoted dotted key (rod.length = ...) into nested tables
            sub = next(iter(v))
            raise KeyPathError(path, f"write the key in quotes: \"{key}.{sub}\" = ... (a dotted key must be quoted)")
        try:
            pk = _grid.parse_key(key, n)
        except _grid.GridKeyError as e:
            raise KeyPathError(path, str(e)) from None
        vals = _values(v, path)
        for j, x in enumerate(vals):
            try:
                _grid.check_value(pk, x)
            except _grid.GridKeyError as e:
                raise KeyPathError(f"{path}[{j + 1}]" if isinstance(v, list) else path, str(e)) from None
        axes.append(GridAxis(key, vals))
        pks.append(pk)
    try:
        _grid.check_keys(pks, base, mech)
    except _grid.GridKeyError as e:
        raise KeyPathError(f"grid.{_quoted(e.key)}" if e.key else "grid", str(e)) from None
    return tuple(axes)


def study_from_dict(data: Mapping[str, Any], source: str = "<dict>", base_dir: str | os.PathLike[str] | None = None
                    ) -> StudySpec:
    """Validate a parsed study file.

    Parameters
    ----------
    data : dict
        The study file's content (parsed TOML).
    source : str
        Name used in messages.
    base_dir : path, optional
        Directory the mechanism path is relative to (default: the directory of ``source``
        when it is a file, else the current directory).

    Raises
    ------
    StudyError
    """
    if base_dir is None:
        base_dir = Path(source).resolve().parent if not source.startswith("<") else Path.cwd()
    try:
        if not isinstance(data, Mapping):
            raise KeyPathError("", f"expected a table, got {type_name(data)}")
        check_table_keys(data, _TOP_KEYS, "")
        if "mechanism" not in data:
            raise KeyPathError("mechanism", "missing: the base mechanism file, e.g. mechanism = \"unit_3rfr.toml\"")
        mpath, mdata, mech = _read_mechanism(data["mechanism"], Path(base_dir))
        name = data.get("name", Path(source).stem if not source.startswith("<") else "study")
        if not isinstance(name, str):
            raise KeyPathError("name", f"expected a string, got {type_name(name)} {_show(name)}")
        if "orientations" not in data:
            raise KeyPathError("orientations", "missing: the platform orientations to map (deg), e.g. [0, 20]")
        orient = _values(data["orientations"], "orientations", "angles (deg)")
        axes = _grid_axes(data.get("grid"), mdata, mech)
        metrics = _metrics(data.get("metrics"))
        ws = _workspace(data.get("workspace"))
        _check_grid(mech, ws)
        spec = StudySpec(name=name, source=source, mechanism_path=mpath, mechanism=mdata, grid=axes,
                         orientations=orient, metrics=metrics, workspace=ws)
        if spec.n_tasks > MAX_TASKS:
            raise KeyPathError("grid", f"{spec.n_tasks} rows is too many (at most {MAX_TASKS})")
    except KeyPathError as e:
        raise StudyError(f"{source}: {e}") from None
    return spec


def load_study(path: str | os.PathLike[str]) -> StudySpec:
    """Read and validate a study file (TOML).

    Parameters
    ----------
    path : str or path-like
        The study file; its ``mechanism`` is resolved relative to it.

    Returns
    -------
    StudySpec

    Raises
    ------
    StudyError
        With one message naming the file, the key and the problem.
    """
    src, text = read_text_file(path, "study file", StudyError, MAX_FILE_BYTES)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{src}: malformed TOML: {e}") from None
    except (RecursionError, ValueError) as e:
        raise StudyError(f"{src}: malformed TOML: {_show(str(e))}") from None
    return study_from_dict(data, source=src, base_dir=Path(src).resolve().parent)
