"""``flexkin.calibrate``: weighted nonlinear least squares of a mechanism's parameters.

Method (``docs/calibration.md``):

1. every row is matched to one stable equilibrium at the starting parameters
   (:func:`~flexkin.calibration.engine.match_rows`); rows no stable branch reaches are outliers
   with their reason;
2. the weighted residuals ``(predicted - measured) / sigma`` of the matched rows are minimised
   by :func:`scipy.optimize.least_squares` (trust-region reflective, bounds: lengths and
   stiffnesses stay above 1e-3 of their start; optional robust loss) over the parameters
   scaled by typical changes; the predictions follow each row's branch by continuation
   (:class:`~flexkin.calibration.engine.Model`) and the Jacobian is analytic
   (:mod:`~flexkin.calibration.sensitivity`);
3. rows whose branch turns unstable at the estimate, or whose residual is grossly out of line
   (above :data:`GROSS` times the robust scale of all residuals, and above :data:`GROSS`
   standard deviations), are flagged as outliers and the fit is repeated without them;
4. statistics at the estimate: covariance ``s^2 (J^T J)^-1`` (``s^2`` the reduced chi-square,
   or 1 with ``absolute_sigma``), 95 % intervals (Student t with the residual degrees of
   freedom, or normal with ``absolute_sigma``), the correlation matrix, the singular values of
   the column-scaled Jacobian and the combinations it cannot see;
5. leave-one-out: each fitted row is predicted from a refit without it.
"""

from __future__ import annotations

import math
import os
import time
import tomllib
from typing import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from ..core.geometry2d import wrap_to_pi
from ..io.measurements import Measurements, measurements_from_rows, read_measurements
from ..mechanism.loader import load_mechanism
from ..mechanism.model import Mechanism
from ..analysis.stability import mechanism_stability
from .engine import Model, Row, match_rows, prepare_rows
from .params import Parameter, parse_fit_keys, values_of
from .result import CalibrationDiagnostics, CalibrationResult, Combination, ParameterEstimate, RowFit

__all__ = ["calibrate", "LOSSES", "GROSS", "NOT_IDENTIFIABLE", "WEAK"]

#: robust losses of scipy.optimize.least_squares
LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
#: a residual above GROSS times max(1, robust scale) standard deviations is a gross error
GROSS = 6.0
#: relative singular value below which a combination is not identifiable at all
NOT_IDENTIFIABLE = 1e-7
#: relative singular value below which a combination is reported as weakly identified
WEAK = 1e-3


def _load_inputs(mech, data) -> tuple[Mechanism, dict | None, Measurements]:
    raw = None
    if isinstance(mech, (str, os.PathLike)):
        path = os.fspath(mech)
        m = load_mechanism(path)
        with open(path, "rb") as fh:
            raw = tomllib.load(fh)
    elif isinstance(mech, Mechanism):
        m = mech
        if m.source:
            try:
                with open(m.source, "rb") as fh:
                    raw = tomllib.load(fh)
            except (OSError, tomllib.TOMLDecodeError):
                raw = None
    else:
        raise ValueError(f"mech: expected a Mechanism or a mechanism file, got {type(mech).__name__}")
    if isinstance(data, Measurements):
        meas = data
    elif isinstance(data, (str, os.PathLike)):
        meas = read_measurements(data)
    else:
        meas = measurements_from_rows(data)
    return m, raw, meas


def _display(row: Row, mech: Mechanism, v: NDArray, held: bool = False) -> tuple[float, float, float]:
    """A row's measured quantity (or a difference; with ``held`` its held quantity) in display
    units: a pose in m, m, deg; inputs in m or deg."""
    v = np.asarray(v, dtype=float)
    pose = (row.fixed == "inputs") != held
    if pose:
        return float(v[0]), float(v[1]), float(math.degrees(v[2]))
    return tuple(float(np.degrees(x)) if a else float(x) for x, a in zip(v, row.input_angular))  # type: ignore[return-value]


def _diff(row: Row, pred: NDArray) -> NDArray:
    d = np.asarray(pred, dtype=float) - row.meas
    return np.where(row.angular, wrap_to_pi(d), d)


class _Fit:
    """The least-squares problem over the rows ``active`` of a :class:`Model`.

    The variables are ``eta`` with ``theta = theta0 + scale * (B @ eta)``: ``B`` is the identity,
    or (when the data cannot see some combinations of the parameters at all) a basis of the
    identifiable subspace, so that an unseen combination stays at its starting value instead of
    drifting on rounding noise.
    """

    def __init__(self, model: Model, active: NDArray, lower: NDArray, upper: NDArray,
                 basis: NDArray | None = None) -> None:
        self.model = model
        self.active = np.asarray(active, dtype=bool)
        self.idx = np.flatnonzero(self.active)
        self.lower, self.upper = lower, upper
        self.B = np.eye(len(model.params)) if basis is None else basis
        self.base_r: NDArray | None = None

    def theta(self, eta: NDArray) -> NDArray:
        return self.model.theta0 + (self.B @ np.asarray(eta)) * self.model.scale

    def fun(self, eta: NDArray) -> NDArray:
        m = self.model
        th = self.theta(eta)
        if np.any(th < self.lower) or np.any(th > self.upper):  # outside the physical bounds (subspace runs)
            b = self.base_r if self.base_r is not None else np.zeros((len(self.idx), 3))
            return (10.0 * b + np.where(b >= 0, 1.0, -1.0) * 1e3).ravel()
        X, C, ok = m.solve(th, self.active)
        r = np.empty((len(self.idx), 3))
        live = [k for k in self.idx if ok[k]]
        got = dict(zip(live, m.predictions(th, live, X, C)))
        for a, k in enumerate(self.idx):
            pred = got.get(k)
            if pred is not None:
                r[a] = m.rows[k].z(pred)
            else:  # the branch is lost before th: a large residual makes the trust region shrink
                b = self.base_r[a] if self.base_r is not None else np.zeros(3)
                r[a] = 10.0 * b + np.where(b >= 0, 1.0, -1.0) * 1e3
        out = r.ravel()
        if self.base_r is None:
            self.base_r = r.copy()
        return out

    def jac_theta(self, th: NDArray) -> NDArray:
        """d(weighted residual)/d(theta / scale) at ``th`` (rows of lost branches are zero)."""
        m = self.model
        X, C, ok = m.solve(th, self.active)
        J = np.zeros((len(self.idx), 3, len(th)))
        good = [k for k in self.idx if ok[k]]
        if good:
            Jg = m.jacobian(th, X, C, np.array(good))
            pos = {k: a for a, k in enumerate(self.idx)}
            for b, k in enumerate(good):
                J[pos[k]] = Jg[b] / m.rows[k].sigma[:, None]
        J = J.reshape(-1, len(th)) * m.scale[None, :]
        return np.where(np.isfinite(J), J, 0.0)

    def jac(self, eta: NDArray) -> NDArray:
        return self.jac_theta(self.theta(eta)) @ self.B

    def run(self, theta_start: NDArray, loss: str, f_scale: float, max_nfev: int):
        """Fit from ``theta_start``; returns (least_squares result, theta)."""
        m = self.model
        xi0 = (theta_start - m.theta0) / m.scale
        Js = self.jac_theta(theta_start)
        _, S, Vt = np.linalg.svd(Js, full_matrices=False) if Js.size else (None, np.zeros(0), np.eye(len(xi0)))
        smax = float(S[0]) if S.size and S[0] > 0 else 1.0
        seen = S / smax > NOT_IDENTIFIABLE
        if S.size == len(xi0) and np.all(seen):
            self.B = np.eye(len(xi0))
            lo = (self.lower - m.theta0) / m.scale
            hi = (self.upper - m.theta0) / m.scale
            with np.errstate(invalid="ignore"):
                eta0 = np.clip(xi0, np.where(np.isfinite(lo), lo + 1e-9 * (1 + np.abs(lo)), -np.inf),
                               np.where(np.isfinite(hi), hi - 1e-9 * (1 + np.abs(hi)), np.inf))
            bounds = (lo, hi)
        else:  # restrict to the identifiable subspace through the start (no bounds there)
            self.B = Vt[:S.size][seen].T
            eta0 = self.B.T @ xi0
            self.anchor = xi0 - self.B @ eta0
            bounds = (-np.inf, np.inf)
        anchor = getattr(self, "anchor", np.zeros(len(xi0)))
        if np.any(anchor):
            base = m.theta0 + anchor * m.scale
            self.theta = lambda eta: base + (self.B @ np.asarray(eta)) * m.scale  # type: ignore[method-assign]
        self.base_r = None
        self.fun(eta0)
        if self.B.shape[1] == 0:
            res = optimize.OptimizeResult(x=eta0, nfev=1, njev=0, status=1, message="nothing identifiable to fit")
        else:
            res = optimize.least_squares(self.fun, eta0, jac=self.jac, bounds=bounds, method="trf", loss=loss,
                                         f_scale=f_scale, x_scale=1.0, max_nfev=max_nfev, xtol=1e-10, ftol=1e-10,
                                         gtol=1e-10, tr_solver="exact")
        return res, self.theta(res.x)


def _combination_text(params: Sequence[Parameter], coef: NDArray) -> str:
    terms = []
    for p, c in zip(params, coef):
        if abs(c) >= 0.05:
            terms.append(f"{'+' if c >= 0 else '-'} {abs(c):.3g} {p.name}")
    s = " ".join(terms).lstrip("+ ").strip()
    return s if s else "(none)"


def _rms(rows: Sequence[RowFit], which: str) -> dict[str, float | None]:
    xy, th, um, ud = [], [], [], []
    for r in rows:
        v = {"before": r.residual_before, "after": r.residual_after, "loo": r.loo}[which]
        if r.outlier or v is None:
            continue
        if r.kind == "fk":
            xy.append(v[0] ** 2 + v[1] ** 2)
            th.append(v[2] ** 2)
        else:
            for x, unit in zip(v, r.units):
                (ud if unit == "deg" else um).append(x ** 2)

    def f(a):
        return float(math.sqrt(np.mean(a))) if a else None

    return {"xy": f(xy), "theta_deg": f(th), "u": f(um), "u_deg": f(ud)}


def calibrate(mech: Mechanism | str | os.PathLike[str], data: Measurements | str | os.PathLike[str] | Sequence[dict],
              fit: Sequence[str], *, loss: str = "linear", f_scale: float = 1.0, absolute_sigma: bool = False,
              max_mode: int = 2, loo: bool = True, max_nfev: int = 200, model: str = "kirchhoff") -> CalibrationResult:
    """Identify a mechanism's parameters from measured (inputs, pose) rows.

    Parameters
    ----------
    mech : Mechanism or path
        The starting (nominal) mechanism, or its TOML file.
    data : Measurements, path or sequence of dict
        The measurements (``docs/calibration.md``; :func:`flexkin.io.measurements.read_measurements`).
    fit : sequence of str
        The parameters to fit, by dotted keys (``"leg[*].offset"``, ``"rod.E"``,
        ``"leg[2].origin"``, ``"platform.attach"``, ...; :mod:`flexkin.calibration.params`).
    loss : str
        ``"linear"`` (default) or a robust loss of :func:`scipy.optimize.least_squares`
        (``"soft_l1"``, ``"huber"``, ``"cauchy"``, ``"arctan"``).
    f_scale : float
        Soft margin of the robust loss, in standard deviations.
    absolute_sigma : bool
        Take the rows' standard deviations as exact (covariance ``(J^T J)^-1``); by default
        the covariance is scaled by the reduced chi-square (for default or guessed sigmas).
    max_mode : int
        Largest d-mode of the IK/FK that matches the rows.
    loo : bool
        Compute the leave-one-out prediction errors.
    max_nfev : int
        Residual evaluations allowed to the optimizer.
    model : {"kirchhoff", "cosserat"}
        ``"cosserat"``: each row's Kirchhoff branch is refined into the Cosserat model with
        extension, shear and weight (``[rod] density``, ``[environment] gravity``) before it is
        compared with the measurement, so that a vertical prototype's sag is not absorbed into
        wrong geometry; needs ``E`` and ``radius`` (fit ``E``, not ``EI``).  Slower: one
        refinement per row and evaluation, and central differences of the refinement's
        correction in the Jacobian.

    Returns
    -------
    CalibrationResult
        ``complete`` is False when the optimizer stopped without converging.

    Raises
    ------
    ValueError
        Bad arguments, a bad key (:class:`~flexkin.calibration.params.FitKeyError`) or a bad
        measurement file (:class:`~flexkin.io.measurements.MeasurementError`).
    """
    t0 = time.perf_counter()
    if loss not in LOSSES:
        raise ValueError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}")
    if not (isinstance(f_scale, (int, float)) and math.isfinite(f_scale) and f_scale > 0):
        raise ValueError(f"f_scale: expected a positive number, got {f_scale!r}")
    if model not in ("kirchhoff", "cosserat"):
        raise ValueError(f"model: expected 'kirchhoff' or 'cosserat', got {model!r}")
    if isinstance(fit, str):
        fit = [fit]
    m0, raw, meas = _load_inputs(mech, data)
    params = parse_fit_keys(list(fit), m0, raw)
    if model == "cosserat":
        from ..cosserat.params import cosserat_setup

        cosserat_setup(m0)  # E and radius on every rod, else a ValueError naming the leg
        bad = [p.name for p in params if p.prop == "EI"]
        if bad:
            raise ValueError(f"--fit {bad[0]}: the Cosserat model's stiffnesses come from E and radius; fit E")
    theta0 = values_of(m0, params)
    rows = prepare_rows(m0, meas.rows)
    matches = match_rows(m0, rows, max_mode)
    t_match = time.perf_counter() - t0
    model = Model(m0, params, theta0, rows, matches, model=model)
    lower = np.where([p.positive for p in params], 1e-3 * theta0, -np.inf)
    upper = np.full(len(params), np.inf)
    n = len(rows)
    reasons = [m.reason for m in matches]
    active = np.array([m.ok for m in matches])
    theta = theta0.copy()
    res = None
    passes = 0
    nfev = njev = 0
    t1 = time.perf_counter()
    stab_final: dict[int, bool | None] = {}
    while True:
        passes += 1
        if np.count_nonzero(active) == 0:
            break
        f = _Fit(model, active, lower, upper)
        res, theta = f.run(theta, loss, f_scale, max_nfev)
        nfev += int(res.nfev)
        njev += int(res.njev or 0)
        th = theta
        X, C, ok = model.solve(th, active)
        # stability of the followed branches at the estimate
        sysf = model.system_at(th)
        idx = np.flatnonzero(active & ok)
        st = mechanism_stability(sysf, X[idx], C[idx]) if idx.size else None
        new_out = False
        for a, k in enumerate(idx):
            v = int(st.stable[a])  # type: ignore[union-attr]
            stab_final[k] = None if v < 0 else bool(v)
            if v == 0:
                reasons[k] = ("its branch is unstable at the fitted parameters (no stable equilibrium of the fitted "
                              "mechanism is where the row was matched)")
                active[k] = False
                new_out = True
        for k in np.flatnonzero(active & ~ok):
            reasons[k] = "its branch could not be followed to the fitted parameters (a fold)"
            active[k] = False
            new_out = True
        # gross errors: compared with the robust scale of the fitted residuals
        zs = {}
        act_k = list(np.flatnonzero(active))
        for k, pred in zip(act_k, model.predictions(th, act_k, X, C)):
            if pred is None:
                reasons[k] = "its branch could not be refined into the Cosserat model at the fitted parameters (a fold)"
                active[k] = False
                new_out = True
            else:
                zs[k] = model.rows[k].z(pred)
        if len(zs) >= 3:
            allz = np.concatenate(list(zs.values()))
            s_rob = 1.4826 * float(np.median(np.abs(allz)))
            gate = GROSS * max(1.0, s_rob)
            worst = max(zs, key=lambda k: float(np.max(np.abs(zs[k]))))
            zmax = float(np.max(np.abs(zs[worst])))
            if zmax > gate:
                reasons[worst] = (f"gross error: residual {zmax:.3g} sigma at the fitted parameters, beyond "
                                  f"{GROSS:g} x the robust residual scale ({max(1.0, s_rob):.3g} sigma); "
                                  "a wrong branch or a bad measurement")
                active[worst] = False
                new_out = True
        if not new_out or passes >= 6:
            break
    t_fit = time.perf_counter() - t1
    p = len(params)
    # ---- statistics at the estimate -----------------------------------------------------
    f = _Fit(model, active, lower, upper)
    k_act = np.flatnonzero(active)
    if k_act.size:
        r_w = f.fun((theta - theta0) / model.scale)
        Jt = f.jac_theta(theta)          # d(weighted residual) per typical change of each parameter
    else:
        r_w = np.zeros(0)
        Jt = np.zeros((0, p))
    mres = len(r_w)
    dof = mres - p
    chi2 = float(np.sum(r_w ** 2))
    s2 = chi2 / dof if dof > 0 else math.nan
    scale2 = 1.0 if absolute_sigma else (s2 if dof > 0 else math.nan)
    if Jt.size:
        _, S, Vt = np.linalg.svd(Jt, full_matrices=True)
    else:
        S, Vt = np.zeros(0), np.eye(p)
    smax = float(S[0]) if S.size and S[0] > 0 else 1.0
    rel = np.zeros(p)
    rel[:S.size] = S / smax
    seen = rel > NOT_IDENTIFIABLE
    cov_t = np.zeros((p, p))         # covariance in typical-change units
    for j in range(min(p, S.size)):
        if seen[j]:
            cov_t += np.outer(Vt[j], Vt[j]) / S[j] ** 2
    cov = cov_t * np.outer(model.scale, model.scale) * scale2
    unidentified = np.zeros(p, bool)
    for j in range(p):
        if not seen[j]:
            unidentified |= np.abs(Vt[j]) > 1e-3
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    se = np.where(unidentified | ~np.isfinite(se), np.nan, se)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    corr = np.where(np.isfinite(corr), corr, np.nan)
    np.fill_diagonal(corr, np.where(np.isfinite(se), 1.0, np.nan))
    q = float(stats.norm.ppf(0.975)) if absolute_sigma or dof <= 0 else float(stats.t.ppf(0.975, dof))
    estimates = []
    for a, prm in enumerate(params):
        v, s = theta[a] * prm.display, se[a] * prm.display
        ok_s = math.isfinite(s)
        estimates.append(ParameterEstimate(prm.name, prm.key, prm.unit, float(theta0[a] * prm.display), float(v),
                                           float(s) if ok_s else None,
                                           (float(v - q * s), float(v + q * s)) if ok_s else None))
    combos = []
    disp = np.array([prm.display for prm in params])
    for j in range(p):
        if rel[j] < WEAK:
            c = Vt[j] * model.scale * disp   # the direction in display units
            c = c / np.max(np.abs(c)) if np.max(np.abs(c)) > 0 else c
            combos.append(Combination(float(rel[j]), tuple(float(x) for x in c), _combination_text(params, c),
                                      bool(seen[j])))
    identifiable = not any(not c.identifiable for c in combos) and k_act.size > 0
    # ---- rows before / after -------------------------------------------------------------
    calibrated = model.mech_at(theta)
    Xa, Ca, oka = model.solve(theta, np.array([m.ok for m in matches]))
    t2 = time.perf_counter()
    loo_err: dict[int, NDArray] = {}
    if loo and k_act.size > 1:
        for k in k_act:
            act = active.copy()
            act[k] = False
            fk_ = _Fit(model, act, lower, upper)
            try:
                rk, thk = fk_.run(theta, loss, f_scale, max(30, max_nfev // 4))
            except (ValueError, np.linalg.LinAlgError):
                continue
            Xk, Ck, okk = model.solve(thk, np.eye(n, dtype=bool)[k])
            pk = model.predictions(thk, [k], Xk, Ck)[0] if okk[k] else None
            if pk is not None:
                loo_err[int(k)] = _diff(rows[k], pk)
    t_loo = time.perf_counter() - t2
    out_rows = []
    matched = [k for k, mt in enumerate(matches) if mt.ok]
    X0 = np.array([mt.x if mt.ok else Xa[k] for k, mt in enumerate(matches)])
    C0 = np.array([mt.charts if mt.ok else Ca[k] for k, mt in enumerate(matches)])
    pbs = dict(zip(matched, model.predictions(theta0, matched, X0, C0)))
    reached = [k for k in range(n) if oka[k]]
    pas = dict(zip(reached, model.predictions(theta, reached, Xa, Ca)))
    for k, (row, mt) in enumerate(zip(rows, matches)):
        pb = pbs.get(k)
        pa = pas.get(k)
        rb = None if pb is None else _diff(row, pb)
        ra = None if pa is None else _diff(row, pa)
        units = ("m", "m", "deg") if row.fixed == "inputs" else tuple(
            "deg" if a else "m" for a in row.angular)
        out_rows.append(RowFit(
            index=row.m.index, line=row.m.line, kind=row.kind, label=row.m.label,
            held=_display(row, m0, row.held, held=True), measured=_display(row, m0, row.meas),
            solution=mt.solution, modes=mt.modes,
            predicted_before=None if pb is None else _display(row, m0, pb),
            predicted_after=None if pa is None else _display(row, m0, pa),
            residual_before=None if rb is None else _display(row, m0, rb),
            residual_after=None if ra is None else _display(row, m0, ra),
            z_before=None if rb is None else tuple(float(v) for v in rb / row.sigma),
            z_after=None if ra is None else tuple(float(v) for v in ra / row.sigma),
            loo=None if k not in loo_err else _display(row, m0, loo_err[k]),
            outlier=not bool(active[k]), reason=reasons[k] if not active[k] else "", note=mt.note,
            stable_after=stab_final.get(k), units=units, sigma=_display(row, m0, row.sigma)))  # type: ignore[arg-type]
    out_rows_t = tuple(out_rows)
    complete = res is not None and int(res.status) > 0
    msgs = []
    if k_act.size == 0:
        msgs.append("no row could be matched to a stable equilibrium: nothing was fitted")
    elif res is not None and int(res.status) <= 0:
        msgs.append(f"the optimizer stopped without converging: {res.message}")
    if dof <= 0 and k_act.size:
        msgs.append(f"{mres} residuals for {p} parameters: no degrees of freedom left, no standard errors")
    if not identifiable and k_act.size:
        msgs.append("not identifiable from these data: " + "; ".join(c.text for c in combos if not c.identifiable))
    if model.model == "kirchhoff" and m0.gravity is not None and any(m0.gravity):
        msgs.append("the mechanism file's [environment] gravity is ignored: the fit uses the weightless Kirchhoff "
                    "model (model='cosserat' / --model cosserat includes the rods' weight)")
    n_out = sum(r.outlier for r in out_rows_t)
    if n_out:
        msgs.append(f"{n_out} outlier row{'s' if n_out > 1 else ''} not fitted")
    diag = CalibrationDiagnostics(nfev, njev, 0 if res is None else int(res.status),
                                  "" if res is None else str(res.message), passes, model.follow_failures,
                                  t_match, t_fit, t_loo)
    return CalibrationResult(
        solutions=out_rows_t, complete=complete, message="; ".join(msgs), elapsed=time.perf_counter() - t0,
        diagnostics=diag, mechanism=m0, calibrated=calibrated, parameters=tuple(estimates),
        correlation=corr, singular_values=tuple(float(v) for v in rel), combinations=tuple(combos),
        identifiable=identifiable, rms_before=_rms(out_rows_t, "before"), rms_after=_rms(out_rows_t, "after"),
        loo_rms=_rms(out_rows_t, "loo"), chi2=chi2, dof=int(dof), scale=float(math.sqrt(s2)) if dof > 0 else math.nan,
        absolute_sigma=absolute_sigma, loss=loss, model=model.model, source=meas.source)

