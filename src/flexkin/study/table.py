"""Study results on disk: the per-row store (resumability) and the Parquet/CSV table.

Layout of a study's output directory::

    DIR/study.json        the validated study (provenance)
    DIR/rows/KEY.json     one finished row per file, written atomically as it completes
    DIR/results.parquet   the table, assembled at the end (row order: design, then orientation)
    DIR/results.csv       the same table as CSV
    DIR/fig_*.png         figures

``KEY`` is a hash of everything that determines a row (the design's mechanism, the
orientation, the workspace settings, the metrics and the row version), so a re-run with the
same ``DIR`` reuses every stored row whose inputs did not change, whatever the grid around it.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

__all__ = ["RowStore", "table_columns", "write_table", "read_table", "rows_to_arrow"]

_TYPES = {"float", "int", "bool", "str"}


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


class RowStore:
    """Finished rows of a study, one JSON file per row under ``DIR/rows``."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.dir = Path(out) / "rows"
        self.dir.mkdir(parents=True, exist_ok=True)

    def path(self, key: str) -> Path:
        return self.dir / f"{key}.json"

    def get(self, key: str) -> dict[str, Any] | None:
        """The stored row of ``key``, or None (also for an unreadable file)."""
        try:
            with open(self.path(key), "rb") as fh:
                doc = json.loads(fh.read())
        except (OSError, ValueError):
            return None
        if not isinstance(doc, dict) or doc.get("key") != key or not isinstance(doc.get("row"), dict):
            return None
        return doc["row"]

    def put(self, key: str, row: Mapping[str, Any]) -> None:
        """Store a finished row (atomically: a killed writer leaves no partial file)."""
        doc = {"key": key, "row": {k: _clean(v) for k, v in row.items()}}
        _atomic_write(self.path(key), json.dumps(doc, allow_nan=False, sort_keys=False).encode())

    def keys(self) -> set[str]:
        return {p.stem for p in self.dir.glob("*.json")}


def table_columns(params: Sequence[str], metrics: Mapping[str, str]) -> list[tuple[str, str]]:
    """Columns ``(name, type)`` of a study's table: ``design``, the grid parameters,
    ``theta_deg``, the metrics (name -> type), ``complete``, ``error``, ``note``, ``elapsed_s``."""
    cols = [("design", "int")] + [(p, "float") for p in params] + [("theta_deg", "float")]
    cols += list(metrics.items())
    cols += [("complete", "bool"), ("error", "str"), ("note", "str"), ("elapsed_s", "float")]
    for name, t in cols:
        if t not in _TYPES:
            raise ValueError(f"column {name!r}: unknown type {t!r}")
    return cols


def rows_to_arrow(rows: Iterable[Mapping[str, Any]], columns: Sequence[tuple[str, str]]):
    """A :class:`pyarrow.Table` of ``rows`` with the given columns (missing values are nulls)."""
    import pyarrow as pa

    types = {"float": pa.float64(), "int": pa.int64(), "bool": pa.bool_(), "str": pa.string()}
    rows = list(rows)
    arrays = []
    for name, t in columns:
        vals = []
        for r in rows:
            v = _clean(r.get(name))
            if v is not None:
                v = {"float": float, "int": int, "bool": bool, "str": str}[t](v)
            vals.append(v)
        arrays.append(pa.array(vals, type=types[t]))
    return pa.Table.from_arrays(arrays, names=[n for n, _ in columns])


def write_table(rows: Iterable[Mapping[str, Any]], columns: Sequence[tuple[str, str]],
                out: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write ``DIR/results.parquet`` and ``DIR/results.csv`` (atomically); return their paths."""
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    out = Path(out)
    table = rows_to_arrow(rows, columns)
    pq_path, csv_path = out / "results.parquet", out / "results.csv"
    for path, writer in ((pq_path, pq.write_table), (csv_path, pcsv.write_csv)):
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=out)
        os.close(fd)
        try:
            writer(table, tmp)
            os.replace(tmp, path)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
    return pq_path, csv_path


def read_table(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The rows of a ``results.parquet`` (or of the directory holding it) as dicts.

    Parameters
    ----------
    path : str or path-like
        ``results.parquet`` or the study's output directory.

    Returns
    -------
    list of dict
        One per (design, orientation) row.
    """
    import pyarrow.parquet as pq

    p = Path(path)
    if p.is_dir():
        p = p / "results.parquet"
    return pq.read_table(p).to_pylist()
