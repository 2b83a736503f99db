"""User-facing input/output: rod shapes as CSV / NPZ, measurement files, HTML reports,
progress bars for the command line.

* :mod:`~flexkin.io.shapes` — :func:`write_shapes` (``--shapes FILE.csv|FILE.npz``).
* :mod:`~flexkin.io.measurements` — the calibration's measurement CSV.
* :mod:`~flexkin.io.html_report` — a report's Markdown as one HTML page.
* :mod:`~flexkin.io.progress` — :func:`~flexkin.io.progress.progress_wanted`,
  :class:`~flexkin.io.progress.Ticker`.
"""

from __future__ import annotations

from .shapes import SHAPE_COLUMNS, shape_table, write_shapes

__all__ = ["write_shapes", "shape_table", "SHAPE_COLUMNS"]
