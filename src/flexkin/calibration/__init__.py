"""Calibration: identify a built prototype's parameters from measured (inputs, pose) rows.

``flexkin.calibrate(mech, data, fit=[...])`` (:func:`.fit.calibrate`) returns a
:class:`~.result.CalibrationResult`.  Modules: :mod:`.params` (the fitted keys),
:mod:`.sensitivity` (the parameter Jacobian by the implicit-function theorem), :mod:`.engine`
(rows matched to branches, branches followed by continuation), :mod:`.fit` (weighted least
squares, statistics, leave-one-out), :mod:`.text` (tables), :mod:`.toml_edit` (the calibrated
mechanism file), :mod:`.report` (the ``--report`` page).  Method and file format:
``docs/calibration.md``.
"""

from .fit import calibrate
from .params import FitKeyError
from .result import CalibrationResult

__all__ = ["calibrate", "CalibrationResult", "FitKeyError"]
