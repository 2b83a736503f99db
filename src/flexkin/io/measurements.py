"""Measurement files of ``flexkin calibrate`` (CSV, SPEC §4; format in ``docs/calibration.md``).

One row per measurement, a header row, ``#`` comments and blank lines ignored::

    kind,u1,u2,u3,x,y,theta_deg
    fk,0.025,0.025,0.025,-0.002,-0.002,99.0     # inputs set, pose measured
    ik,-0.017,-0.013,-0.018,0.0,0.0,60.0        # pose commanded, inputs measured

Units as on the command line: inputs in m (prismatic and length legs) or deg (revolute legs),
the pose in m, m, deg.  Optional columns: ``fx, fy, mz`` (the load on the platform, N, N, N m;
default the mechanism file's ``[load]``), ``solution`` (the id of the equilibrium at the starting
parameters the row belongs to; default: the stable one nearest to the measurement),
``sigma_u, sigma_xy, sigma_theta_deg`` (standard deviations of the measured quantities; defaults
:data:`DEFAULT_SIGMA`), ``label`` (free text shown in tables).  An empty optional cell takes the
default.

Values stay in display units here (this module sits below the mechanism layer and does not know
which legs are revolute); :mod:`flexkin.calibration` converts them once.  Every problem raises
:class:`MeasurementError` with one line ``"<file>: row N (line L): <column>: <problem>"``.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from ..core.validation import read_text_file, short_text, suggest_key

__all__ = ["MeasurementError", "MeasurementRow", "Measurements", "read_measurements", "measurements_from_rows",
           "DEFAULT_SIGMA", "COLUMNS"]

#: default standard deviations: position (m), orientation (deg), prismatic/length input (m),
#: revolute input (deg).  A column ``sigma_u`` gives the input's in each leg's own unit.
DEFAULT_SIGMA = {"xy": 1e-3, "theta_deg": 1.0, "u_m": 1e-3, "u_deg": 0.5}
_REQUIRED = ("kind", "u1", "u2", "u3", "x", "y", "theta_deg")
_OPTIONAL = ("fx", "fy", "mz", "solution", "sigma_u", "sigma_xy", "sigma_theta_deg", "label")
COLUMNS = _REQUIRED + _OPTIONAL
MAX_FILE_BYTES = 16 * 1024 * 1024


class MeasurementError(ValueError):
    """A measurement file or row is invalid; the message is one line naming the row."""


@dataclass(frozen=True)
class MeasurementRow:
    """One measurement (display units).

    Attributes
    ----------
    index : int
        1-based number of the row among the data rows.
    line : int
        Line of the file (1-based), 0 for rows not read from a file.
    kind : {"fk", "ik"}
        ``fk``: ``inputs`` were set and ``pose`` measured; ``ik``: ``pose`` commanded and
        ``inputs`` measured.
    inputs : (u1, u2, u3)
        m, or deg for revolute legs.
    pose : (x, y, theta_deg)
        m, m, deg.
    load : (fx, fy, mz) or None
        None: the mechanism's load.
    solution : int or None
        Id of the equilibrium (at the starting parameters) the row belongs to.
    sigma_u, sigma_xy, sigma_theta_deg : float or None
        Standard deviations (None: the defaults).
    label : str
    """

    index: int
    line: int
    kind: str
    inputs: tuple[float, float, float]
    pose: tuple[float, float, float]
    load: tuple[float, float, float] | None = None
    solution: int | None = None
    sigma_u: float | None = None
    sigma_xy: float | None = None
    sigma_theta_deg: float | None = None
    label: str = ""

    @property
    def where(self) -> str:
        """``"row N (line L)"`` or ``"row N"``."""
        return f"row {self.index} (line {self.line})" if self.line else f"row {self.index}"


@dataclass(frozen=True)
class Measurements:
    """The rows of a measurement file and where they came from."""

    rows: tuple[MeasurementRow, ...]
    source: str = "<rows>"

    def __len__(self) -> int:
        return len(self.rows)


def _number(text: Any, col: str, where: str, src: str, positive: bool = False) -> float:
    if isinstance(text, bool):
        raise MeasurementError(f"{src}: {where}: {col}: expected a number, got {text!r}")
    try:
        v = float(text)
    except (TypeError, ValueError, OverflowError):
        raise MeasurementError(f"{src}: {where}: {col}: expected a number, got {str(text)!r}") from None
    if not math.isfinite(v):
        raise MeasurementError(f"{src}: {where}: {col}: expected a finite number, got {str(text)!r}")
    if positive and v <= 0.0:
        raise MeasurementError(f"{src}: {where}: {col}: must be > 0, got {str(text)!r}")
    return v


def _blank(v: Any) -> bool:
    return v is None or (isinstance(v, str) and not v.strip())


def _row(rec: Mapping[str, Any], index: int, line: int, src: str) -> MeasurementRow:
    where = f"row {index} (line {line})" if line else f"row {index}"
    for c in _REQUIRED:
        if _blank(rec.get(c)):
            raise MeasurementError(f"{src}: {where}: {c}: missing")
    kind = str(rec["kind"]).strip().lower()
    if kind not in ("fk", "ik"):
        raise MeasurementError(f"{src}: {where}: kind: expected 'fk' (inputs set, pose measured) or 'ik' "
                               f"(pose commanded, inputs measured), got {str(rec['kind'])!r}")
    u = tuple(_number(rec[c], c, where, src) for c in ("u1", "u2", "u3"))
    pose = tuple(_number(rec[c], c, where, src) for c in ("x", "y", "theta_deg"))
    load = None
    given = [c for c in ("fx", "fy", "mz") if not _blank(rec.get(c))]
    if given:
        load = tuple(0.0 if _blank(rec.get(c)) else _number(rec[c], c, where, src) for c in ("fx", "fy", "mz"))
    sol = None
    if not _blank(rec.get("solution")):
        v = _number(rec["solution"], "solution", where, src)
        if v != int(v) or v < 1:
            raise MeasurementError(f"{src}: {where}: solution: expected a solution id (an integer >= 1), "
                                   f"got {str(rec['solution'])!r}")
        sol = int(v)
    sig = {c: (None if _blank(rec.get(c)) else _number(rec[c], c, where, src, positive=True))
           for c in ("sigma_u", "sigma_xy", "sigma_theta_deg")}
    label = "" if _blank(rec.get("label")) else str(rec["label"]).strip()
    return MeasurementRow(index, line, kind, u, pose, load, sol, sig["sigma_u"], sig["sigma_xy"],  # type: ignore[arg-type]
                          sig["sigma_theta_deg"], label)


def _check_header(header: Iterable[str], src: str) -> list[str]:
    cols = [str(h).strip() for h in header]
    for c in cols:
        if c not in COLUMNS:
            close = suggest_key(c, COLUMNS)
            hint = f" (did you mean {close!r}?)" if close else ""
            raise MeasurementError(f"{src}: header: unknown column {short_text(c)}{hint}; columns are "
                                   f"{', '.join(_REQUIRED)} and optionally {', '.join(_OPTIONAL)}")
    dup = {c for c in cols if cols.count(c) > 1}
    if dup:
        raise MeasurementError(f"{src}: header: column {sorted(dup)[0]!r} appears twice")
    missing = [c for c in _REQUIRED if c not in cols]
    if missing:
        raise MeasurementError(f"{src}: header: missing column{'s' if len(missing) > 1 else ''} "
                               f"{', '.join(missing)} (required: {', '.join(_REQUIRED)})")
    return cols


def _strip_comment(line: str) -> str:
    return line.split("#", 1)[0]


def parse_measurements(text: str, source: str = "<text>") -> Measurements:
    """Parse the CSV text of a measurement file.

    Parameters
    ----------
    text : str
        File content.
    source : str
        Name used in error messages.

    Returns
    -------
    Measurements

    Raises
    ------
    MeasurementError
        One line naming the file, the row and the column.
    """
    lines = [(n, _strip_comment(raw)) for n, raw in enumerate(text.splitlines(), start=1)]
    lines = [(n, s) for n, s in lines if s.strip()]
    if not lines:
        raise MeasurementError(f"{source}: no header row (expected {','.join(_REQUIRED)})")
    header_line, header_text = lines[0]
    cols = _check_header(next(csv.reader(io.StringIO(header_text))), source)
    rows = []
    for k, (n, s) in enumerate(lines[1:], start=1):
        cells = next(csv.reader(io.StringIO(s)))
        cells = [c.strip() for c in cells]
        while len(cells) > len(cols) and not cells[-1]:
            cells.pop()
        if len(cells) > len(cols):
            raise MeasurementError(f"{source}: row {k} (line {n}): {len(cells)} values for {len(cols)} columns")
        rec = dict(zip(cols, cells + [""] * (len(cols) - len(cells))))
        rows.append(_row(rec, k, n, source))
    if not rows:
        raise MeasurementError(f"{source}: no measurement rows after the header (line {header_line})")
    return Measurements(tuple(rows), source)


def read_measurements(path: str | os.PathLike[str]) -> Measurements:
    """Read a measurement file (CSV, UTF-8; see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    Measurements

    Raises
    ------
    MeasurementError
        For an unreadable file or any bad row (one line naming the row and the column).
    """
    src, text = read_text_file(path, "measurement file", MeasurementError, MAX_FILE_BYTES)
    return parse_measurements(text, src)


def measurements_from_rows(rows: Iterable[Mapping[str, Any]], source: str = "<rows>") -> Measurements:
    """Measurements from dicts with the file's column names (display units).

    Parameters
    ----------
    rows : iterable of mapping
        One mapping per row, keys as the CSV columns.
    source : str
        Name used in error messages.

    Returns
    -------
    Measurements
    """
    out = []
    for k, rec in enumerate(rows, start=1):
        for c in rec:
            if c not in COLUMNS:
                close = suggest_key(str(c), COLUMNS)
                hint = f" (did you mean {close!r}?)" if close else ""
                raise MeasurementError(f"{source}: row {k}: unknown column {short_text(c)}{hint}")
        out.append(_row(rec, k, 0, source))
    if not out:
        raise MeasurementError(f"{source}: no measurement rows")
    return Measurements(tuple(out), source)
