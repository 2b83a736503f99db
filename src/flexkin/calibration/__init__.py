"""Calibration: identify a built prototype's parameters from measured (inputs, pose) rows.

``flexkin.calibrate(mech, data, fit=[...])`` (:func:`.fit.calibrate`) returns a
:class:`~.result.CalibrationResult`.  Modules: :mod:`.params` (the fitted keys),
:mod:`.sensitivity` (the parameter Jacobian by the implicit-function theorem), :mod:`.engine`
(rows matched to branches, branches followed by continuation), :mod:`.fit` (weighted least
squares, statistics, leave-one-out), :mod:`.text` (tables), :mod:`.toml_edit` (the calibrated
mechanism file), :mod:`.report` (the ``--report`` page).  Method and file format:
``docs/calibration.md``.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["calibrate", "CalibrationResult", "FitKeyError"]

# Loaded on first use: the command line builds the ``calibrate`` sub-parser from
# :mod:`.cli` on every call, and :mod:`.fit` imports scipy.optimize and scipy.stats, which an IK
# or FK command must not pay for (tests/test_startup.py).
_LAZY = {"calibrate": ".fit", "CalibrationResult": ".result", "FitKeyError": ".params"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
