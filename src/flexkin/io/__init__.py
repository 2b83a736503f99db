"""User-facing input/output: rod shapes as CSV / NPZ, Cosserat material data read from
mechanism files, progress bars for the command line.

* :mod:`~flexkin.io.shapes` — :func:`write_shapes` (``--shapes FILE.csv|FILE.npz``).
* :mod:`~flexkin.io.material` — :func:`~flexkin.io.material.cosserat_setup` (Cosserat
  parameters and gravity of a mechanism).
* :mod:`~flexkin.io.progress` — :func:`~flexkin.io.progress.progress_wanted`,
  :class:`~flexkin.io.progress.Ticker`.
"""

from __future__ import annotations

from .shapes import SHAPE_COLUMNS, shape_table, write_shapes

__all__ = ["write_shapes", "shape_table", "SHAPE_COLUMNS"]
