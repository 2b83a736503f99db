"""The result of a calibration: estimates, uncertainty, identifiability, rows, leave-one-out."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.jsonable import finite_or_none
from ..results import Result

__all__ = ["ParameterEstimate", "Combination", "RowFit", "CalibrationDiagnostics", "CalibrationResult"]


@dataclass(frozen=True)
class ParameterEstimate:
    """One fitted scalar parameter, in display units (m, deg, Pa, N m^2).

    ``stderr`` and ``ci95`` are ``None`` where the data do not identify the parameter.
    """

    key: str
    fit_key: str
    unit: str
    initial: float
    value: float
    stderr: float | None
    ci95: tuple[float, float] | None

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "fit_key": self.fit_key, "unit": self.unit, "initial": self.initial,
                "value": self.value, "stderr": finite_or_none(self.stderr),
                "ci95": None if self.ci95 is None else [finite_or_none(v) for v in self.ci95]}


@dataclass(frozen=True)
class Combination:
    """A direction of the scaled parameter space the data (nearly) cannot see.

    ``singular_value`` is relative to the largest one; ``coefficients`` are per parameter in
    display units (largest magnitude 1): moving the parameters along them changes no
    prediction (to first order, relative to ``singular_value``).
    """

    singular_value: float
    coefficients: tuple[float, ...]
    text: str
    identifiable: bool

    def to_dict(self) -> dict[str, Any]:
        return {"singular_value": finite_or_none(self.singular_value), "coefficients": list(self.coefficients),
                "combination": self.text, "identifiable": self.identifiable}


@dataclass(frozen=True)
class RowFit:
    """One measurement row before and after the fit (display units: m, m, deg for poses; m or
    deg for inputs).

    ``residual_*`` are predicted minus measured; ``z_*`` the same over the standard deviations.
    ``loo`` is the leave-one-out prediction error (the row's prediction with the parameters
    fitted without it, minus the measurement).  ``outlier`` rows were not fitted; ``reason``
    says why.
    """

    index: int
    line: int
    kind: str
    label: str
    held: tuple[float, float, float]
    measured: tuple[float, float, float]
    solution: int | None
    modes: str
    predicted_before: tuple[float, float, float] | None
    predicted_after: tuple[float, float, float] | None
    residual_before: tuple[float, float, float] | None
    residual_after: tuple[float, float, float] | None
    z_before: tuple[float, float, float] | None
    z_after: tuple[float, float, float] | None
    loo: tuple[float, float, float] | None
    outlier: bool
    reason: str = ""
    note: str = ""
    stable_after: bool | None = None
    units: tuple[str, str, str] = ("m", "m", "deg")
    sigma: tuple[float, float, float] | None = None

    def error_summary(self, which: str = "after") -> tuple[float, float] | None:
        """FK rows: (position error in m, angle error in deg); IK rows: (largest input error,
        0) in the legs' units -- of ``"before"``, ``"after"`` or ``"loo"``."""
        r = {"before": self.residual_before, "after": self.residual_after, "loo": self.loo}[which]
        if r is None:
            return None
        if self.kind == "fk":
            return float(math.hypot(r[0], r[1])), float(abs(r[2]))
        return float(max(abs(v) for v in r)), 0.0

    def to_dict(self) -> dict[str, Any]:
        def tup(t):
            return None if t is None else [finite_or_none(v) for v in t]

        return {"row": self.index, "line": self.line, "kind": self.kind, "label": self.label,
                "held": tup(self.held), "measured": tup(self.measured), "units": list(self.units),
                "solution": self.solution, "modes": self.modes,
                "predicted_before": tup(self.predicted_before), "predicted_after": tup(self.predicted_after),
                "residual_before": tup(self.residual_before), "residual_after": tup(self.residual_after),
                "z_before": tup(self.z_before), "z_after": tup(self.z_after), "loo_error": tup(self.loo),
                "outlier": self.outlier, "reason": self.reason, "note": self.note, "stable_after": self.stable_after,
                "sigma": tup(self.sigma)}


@dataclass(frozen=True)
class CalibrationDiagnostics:
    """What the fit did: residual and Jacobian evaluations, optimizer status, outlier passes,
    branches that could not be followed to a trial point, and the time of each stage (s)."""

    nfev: int = 0
    njev: int = 0
    status: int = 0
    optimizer_message: str = ""
    passes: int = 0
    follow_failures: int = 0
    time_match: float = 0.0
    time_fit: float = 0.0
    time_loo: float = 0.0


@dataclass(frozen=True)
class CalibrationResult(Result):
    """Result of :func:`flexkin.calibrate`.

    ``solutions`` are the :class:`RowFit` of every measurement row (also :attr:`rows`),
    outliers included (flagged); ``complete`` is ``False`` when the optimizer stopped without
    converging; ``message``, ``elapsed`` and ``diagnostics`` (:class:`CalibrationDiagnostics`)
    are as in :class:`~flexkin.results.Result`.

    Attributes
    ----------
    mechanism : Mechanism
        The mechanism as given (the nominal parameters).
    calibrated : Mechanism
        The mechanism with the estimates.
    parameters : tuple of ParameterEstimate
        The estimates, one per fitted scalar parameter, in display units (m, deg, Pa, N m^2).
    correlation : ndarray (p, p) or None
        Correlation matrix of the estimates (dimensionless); ``NaN`` rows and columns for the
        parameters the data do not identify.
    singular_values : tuple of float
        Singular values of the scaled parameter Jacobian (of the weighted residuals per typical
        change of each parameter), relative to the largest (dimensionless).
    combinations : tuple of Combination
        The weakest directions of the scaled parameter space (relative singular value below
        :data:`flexkin.calibration.fit.WEAK`).
    identifiable : bool
        ``False`` when one combination is not seen by the data at all (relative singular value
        below :data:`flexkin.calibration.fit.NOT_IDENTIFIABLE`), or when no row was fitted.
    rms_before, rms_after, loo_rms : dict
        RMS errors over the fitted rows at the nominal parameters, at the estimates, and in
        leave-one-out: ``xy`` (position, m), ``theta_deg`` (orientation, deg), ``u`` (inputs
        of prismatic and length legs, m) and ``u_deg`` (inputs of revolute legs, deg);
        ``None`` where no row measures that quantity.
    chi2 : float
        Sum of the squared residuals over their standard deviations at the estimates
        (dimensionless).
    dof : int
        Degrees of freedom: number of fitted residuals minus number of parameters.
    scale : float
        ``sqrt(chi2 / dof)`` (dimensionless; ``NaN`` when ``dof <= 0``): the factor by which
        the rows' standard deviations are scaled in the covariance unless ``absolute_sigma``.
    absolute_sigma : bool
        The rows' standard deviations were taken as exact (covariance not scaled).
    loss : str
        The least-squares loss used (``"linear"`` or a robust loss of
        :func:`scipy.optimize.least_squares`).
    model : {"kirchhoff", "cosserat"}
        The rod model the predictions were made with.
    source : str
        Where the measurements came from (the measurement file's path, or ``"<rows>"``).
    """

    mechanism: Any = field(default=None, repr=False)
    calibrated: Any = field(default=None, repr=False)
    parameters: tuple[ParameterEstimate, ...] = ()
    correlation: NDArray[np.float64] | None = field(default=None, repr=False)
    singular_values: tuple[float, ...] = ()
    combinations: tuple[Combination, ...] = ()
    identifiable: bool = True
    rms_before: dict[str, float | None] = field(default_factory=dict)
    rms_after: dict[str, float | None] = field(default_factory=dict)
    loo_rms: dict[str, float | None] = field(default_factory=dict)
    chi2: float = 0.0
    dof: int = 0
    scale: float = 1.0
    absolute_sigma: bool = False
    loss: str = "linear"
    model: str = "kirchhoff"
    source: str = ""

    @property
    def rows(self) -> tuple[RowFit, ...]:
        """The measurement rows (the same as ``solutions``)."""
        return self.solutions

    @property
    def outliers(self) -> tuple[RowFit, ...]:
        """The rows that were not fitted, with their reasons."""
        return tuple(r for r in self.solutions if r.outlier)

    def estimate(self, key: str) -> ParameterEstimate:
        """The estimate of one scalar parameter by its key (e.g. ``"leg[1].offset"``).

        Parameters
        ----------
        key : str

        Returns
        -------
        ParameterEstimate
        """
        for p in self.parameters:
            if p.key == key:
                return p
        raise KeyError(key)

    def to_dict(self) -> dict[str, Any]:
        """The SPEC §4 calibration JSON (finite numbers or null)."""
        def rms(d):
            return {k: finite_or_none(v) for k, v in d.items()}

        corr = None if self.correlation is None else [[finite_or_none(v) for v in row] for row in self.correlation]
        diag = self.diagnostics or CalibrationDiagnostics()
        return {"problem": "calibrate", "mechanism": getattr(self.mechanism, "name", ""), "data": self.source,
                "model": self.model, "loss": self.loss, "absolute_sigma": self.absolute_sigma,
                "complete": self.complete, "message": self.message,
                "parameters": [p.to_dict() for p in self.parameters],
                "correlation": corr, "singular_values": [finite_or_none(v) for v in self.singular_values],
                "identifiable": self.identifiable,
                "combinations": [c.to_dict() for c in self.combinations],
                "rms_before": rms(self.rms_before), "rms_after": rms(self.rms_after), "loo_rms": rms(self.loo_rms),
                "chi2": finite_or_none(self.chi2), "dof": self.dof, "scale": finite_or_none(self.scale),
                "rows": [r.to_dict() for r in self.solutions],
                "elapsed": self.elapsed,
                "diagnostics": {"nfev": diag.nfev, "njev": diag.njev, "status": diag.status,
                                "optimizer_message": diag.optimizer_message, "passes": diag.passes,
                                "follow_failures": diag.follow_failures, "time_match": diag.time_match,
                                "time_fit": diag.time_fit, "time_loo": diag.time_loo}}

    def table(self) -> str:
        """The human-readable report: parameters, identifiability, rows, RMS before/after and
        leave-one-out."""
        from .text import result_table

        return result_table(self)

    def plot(self, path: str | None = None, **kwargs: Any):
        """Measured vs predicted (before and after) and residual bars per row."""
        from ..plot.calibration import plot_calibration

        return plot_calibration(self, path=path, **kwargs)
