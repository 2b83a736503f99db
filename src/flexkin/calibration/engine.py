"""The calibration's model of the measurements: rows matched to branches, branches followed.

Each measurement row is matched ONCE, at the starting parameters, to one equilibrium: the
stable one nearest to the measurement (in standard deviations), unless the row names a
solution.  From then on the row's prediction at other parameters is that equilibrium
followed by continuation in the parameters (tangent predictor from the implicit-function
theorem, :mod:`.sensitivity`; Newton corrector on the one equation system; a corrector that
moves more than half the predicted change is a jump to another branch and the step is
halved), so the fit never changes assembly mode.  A branch that cannot be followed to the
requested parameters (a fold) gives no prediction there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import wrap_to_pi
from ..io.measurements import DEFAULT_SIGMA, MeasurementRow
from ..mechanism.model import Mechanism
from ..solve.continuation import to_working_charts
from ..solve.corrector import newton
from ..solve.corrector import RESIDUAL_TOL
from ..system import System
from .params import Parameter, array_derivatives, with_values
from .sensitivity import parameter_block, prediction_derivative

__all__ = ["Row", "Model", "prepare_rows", "match_rows", "Match"]

#: standardized distance beyond which a row's measurement is "far" from an equilibrium
FAR = 5.0


@dataclass(frozen=True)
class Row:
    """One measurement in internal units.

    ``held`` is what the row imposes (the inputs of an FK row, the pose of an IK row), ``meas``
    what it measured (the pose of an FK row, the inputs of an IK row); ``angular`` marks the
    measured components compared modulo 2 pi (theta; revolute inputs).
    """

    m: MeasurementRow
    fixed: str                      # "inputs" (FK) or "pose" (IK)
    held: NDArray[np.float64]
    meas: NDArray[np.float64]
    sigma: NDArray[np.float64]
    angular: NDArray[np.bool_]
    load: NDArray[np.float64]
    input_angular: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(3, bool))

    @property
    def kind(self) -> str:
        return self.m.kind

    def z(self, pred: NDArray) -> NDArray[np.float64]:
        """Standardized residuals ``(pred - meas) / sigma`` (angles wrapped)."""
        d = np.asarray(pred, dtype=float) - self.meas
        d = np.where(self.angular, wrap_to_pi(d), d)
        return d / self.sigma


def prepare_rows(mech: Mechanism, rows) -> list[Row]:
    """Convert measurement rows to internal units once (the boundary).

    Parameters
    ----------
    mech : Mechanism
    rows : sequence of MeasurementRow

    Returns
    -------
    list of Row
    """
    out = []
    legs = mech.legs
    ang = np.array([leg.actuator.angular for leg in legs])
    for r in rows:
        u = np.array([float(leg.from_display(v)) for leg, v in zip(legs, r.inputs)])
        pose = np.array([r.pose[0], r.pose[1], math.radians(r.pose[2])])
        su = np.array([math.radians(r.sigma_u) if a else r.sigma_u for a in ang]) if r.sigma_u is not None else \
            np.array([math.radians(DEFAULT_SIGMA["u_deg"]) if a else DEFAULT_SIGMA["u_m"] for a in ang])
        sxy = DEFAULT_SIGMA["xy"] if r.sigma_xy is None else r.sigma_xy
        sth = math.radians(DEFAULT_SIGMA["theta_deg"] if r.sigma_theta_deg is None else r.sigma_theta_deg)
        load = np.array(mech.load if r.load is None else r.load, dtype=float)
        if r.kind == "fk":
            out.append(Row(r, "inputs", u, pose, np.array([sxy, sxy, sth]), np.array([False, False, True]), load,
                           ang.copy()))
        else:
            out.append(Row(r, "pose", pose, u, su, ang.copy(), load, ang.copy()))
    return out


@dataclass(frozen=True)
class Match:
    """The equilibrium a row was matched to at the starting parameters (or why none)."""

    ok: bool
    reason: str = ""
    solution: int | None = None
    modes: str = ""
    x: NDArray[np.float64] | None = field(default=None, repr=False)
    charts: NDArray[np.int64] | None = field(default=None, repr=False)
    stable: bool | None = None
    n_solutions: int = 0
    distance: float = math.nan
    note: str = ""


def _what(row: Row) -> str:
    return "for these inputs" if row.fixed == "inputs" else "at this pose"


def _pred_of(row: Row, sol) -> NDArray[np.float64]:
    return np.array(sol.pose if row.fixed == "inputs" else sol.inputs, dtype=float)


@lru_cache(maxsize=256)
def _all_equilibria(mech: Mechanism, fixed: str, held: tuple, load: tuple, max_mode: int):
    """Every equilibrium of a row at the starting parameters (IK or FK), or the ValueError that
    made it impossible; memoized (results are immutable), so refitting the same data with
    other keys or other noise does not repeat the global searches."""
    from ..solve.fk import fk
    from ..solve.ik import ik

    try:
        return (fk if fixed == "inputs" else ik)(mech, np.array(held), np.array(load), max_mode)
    except ValueError as exc:  # e.g. a length leg's free length <= 0
        return exc


def match_rows(mech: Mechanism, rows: list[Row], max_mode: int = 2) -> list[Match]:
    """Match every row to one branch at the starting parameters (see the module docstring).

    Parameters
    ----------
    mech : Mechanism
        The starting mechanism.
    rows : list of Row
    max_mode : int
        Largest d-mode searched by the IK/FK.

    Returns
    -------
    list of Match
    """
    out = []
    for row in rows:
        res = _all_equilibria(mech, row.fixed, tuple(float(v) for v in row.held), tuple(float(v) for v in row.load),
                              int(max_mode))
        if isinstance(res, ValueError):
            out.append(Match(False, f"unreachable: {res}"))
            continue
        sols = list(res.solutions)  # type: ignore[attr-defined]
        if not sols:
            msg = getattr(res, "message", "") or "no equilibrium"
            out.append(Match(False, f"unreachable: no equilibrium {_what(row)} at the starting parameters ({msg})"))
            continue
        dist = [float(np.linalg.norm(row.z(_pred_of(row, s)))) for s in sols]
        if row.m.solution is not None:
            pick = [k for k, s in enumerate(sols) if s.id == row.m.solution]
            if not pick:
                out.append(Match(False, f"named solution {row.m.solution} does not exist: {len(sols)} equilibria "
                                        f"{_what(row)} at the starting parameters", n_solutions=len(sols)))
                continue
            k = pick[0]
            s = sols[k]
            if s.stable is not True:
                out.append(Match(False, f"named solution {s.id} is {'unstable' if s.stable is False else 'of undecided stability'}"
                                        " at the starting parameters: a prototype rests only on stable equilibria",
                                 s.id, s.mode_label, n_solutions=len(sols), distance=dist[k]))
                continue
            out.append(Match(True, "", s.id, s.mode_label, s.x.copy(), np.array(s.charts), s.stable, len(sols), dist[k]))
            continue
        stable = [k for k, s in enumerate(sols) if s.stable is True]
        if not stable:
            out.append(Match(False, f"no stable equilibrium {_what(row)} at the starting parameters (all {len(sols)} "
                                    "are unstable or undecided)", n_solutions=len(sols)))
            continue
        k = min(stable, key=lambda j: dist[j])
        j_all = int(np.argmin(dist))
        if j_all != k and dist[k] > FAR and dist[j_all] < dist[k] / 3.0:
            s2 = sols[j_all]
            out.append(Match(False, f"wrong branch: the measurement lies on equilibrium {s2.id} ({s2.mode_label}, "
                                    f"{'unstable' if s2.stable is False else 'undecided'}; {dist[j_all]:.2g} sigma), far "
                                    f"from every stable one (nearest: {sols[k].id} at {dist[k]:.3g} sigma)",
                             sols[k].id, sols[k].mode_label, n_solutions=len(sols), distance=dist[k]))
            continue
        s = sols[k]
        note = ""
        others = [dist[j] for j in stable if j != k]
        if others and min(others) < 2.0 * dist[k]:
            note = (f"ambiguous: another stable equilibrium is at {min(others):.3g} sigma (this one: {dist[k]:.3g}); "
                    "name the solution in the file's 'solution' column")
        out.append(Match(True, "", s.id, s.mode_label, s.x.copy(), np.array(s.charts), True, len(sols), dist[k], note))
    return out


@dataclass(frozen=True)
class _Equilibrium:
    """The fields of a Solution that the Cosserat refinement reads (pose, inputs, rods)."""

    pose: tuple[float, float, float]
    inputs: tuple[float, float, float]
    rods: tuple


class Model:
    """Predictions of matched rows as functions of the parameters (branch continuation).

    With ``model="cosserat"`` a row's prediction is its Kirchhoff branch refined into the
    Cosserat model with extension, shear and weight (:func:`flexkin.cosserat.refine`, the file's
    ``[environment] gravity`` and rod densities); its derivative is the Kirchhoff one (implicit
    function theorem) plus the central difference of the refinement's correction.

    Parameters
    ----------
    mech : Mechanism
        The starting mechanism.
    params : sequence of Parameter
    theta0 : ndarray
        Starting values (internal units).
    rows : list of Row
    matches : list of Match
    """

    def __init__(self, mech: Mechanism, params, theta0: NDArray, rows: list[Row], matches: list[Match],
                 model: str = "kirchhoff") -> None:
        self.mech0 = mech
        self.model = model
        self.params: tuple[Parameter, ...] = tuple(params)
        self.theta0 = np.asarray(theta0, dtype=float)
        self.rows = rows
        self.matches = matches
        self.scale = np.array([p.typical(mech, v) for p, v in zip(self.params, self.theta0)])
        # points where a row's branch is known: list of (theta, X (n_rows, nu), charts, ok)
        n = len(rows)
        nu = System.from_mechanism(mech).layout.n_unknowns
        X0 = np.zeros((n, nu))
        C0 = np.zeros((n, 3), np.int64)
        ok0 = np.zeros(n, bool)
        for r, m in enumerate(matches):
            if m.ok:
                X0[r], C0[r], ok0[r] = m.x, m.charts, True
        self.known: list[tuple[NDArray, NDArray, NDArray, NDArray]] = [(self.theta0.copy(), X0, C0, ok0)]
        self._mech: dict[bytes, Mechanism] = {}
        self._sys: dict[bytes, System] = {}
        self.follow_failures = 0

    # ---- mechanisms and systems at parameter values (memoized) -------------------------
    def mech_at(self, theta: NDArray) -> Mechanism:
        """The mechanism with the parameters at ``theta`` (internal units)."""
        key = np.asarray(theta, dtype=float).tobytes()
        if key not in self._mech:
            if len(self._mech) > 256:
                self._mech.clear()
                self._sys.clear()
            self._mech[key] = with_values(self.mech0, self.params, theta)
        return self._mech[key]

    def system_at(self, theta: NDArray) -> System:
        """The equation system at ``theta``."""
        key = np.asarray(theta, dtype=float).tobytes()
        if key not in self._sys:
            self._sys[key] = System.from_mechanism(self.mech_at(theta))
        return self._sys[key]

    # ---- one row ----------------------------------------------------------------------
    def tangent(self, theta: NDArray, r: int, X: NDArray, charts: NDArray) -> NDArray[np.float64]:
        """Derivative of row ``r``'s solved columns with respect to the parameters at ``theta``,
        (n_solved, k); its last three rows are the predicted quantities."""
        mech = self.mech_at(theta)
        system = self.system_at(theta)
        row = self.rows[r]
        Gp = parameter_block(system, X[None], charts[None], *array_derivatives(mech, self.params))
        return prediction_derivative(system, X[None], charts[None], row.load, row.fixed, Gp)[0]

    def follow(self, r: int, X: NDArray, charts: NDArray, th0: NDArray, th1: NDArray
               ) -> tuple[NDArray, NDArray] | None:
        """Row ``r``'s equilibrium ``X`` at ``th0`` followed to ``th1`` (None: lost at a fold)."""
        row = self.rows[r]
        cols = self.system_at(th0).layout.columns(row.fixed)
        X, charts = X.copy(), np.array(charts, dtype=np.int64)
        t, h = 0.0, 1.0
        d = th1 - th0
        if not np.any(d):
            return X, charts
        for _ in range(200):
            if t >= 1.0:
                return X, charts
            tn = min(1.0, t + h)
            ta, tb = th0 + t * d, th0 + tn * d
            dY = self.tangent(ta, r, X, charts)
            ok = bool(np.all(np.isfinite(dY)))
            if ok:
                Xp = X.copy()
                Xp[cols] += dY @ (tb - ta)
                sb = self.system_at(tb)
                res = newton(sb, Xp[None], charts[None], row.load, row.fixed, merge_after=None, max_iter=15)
                ok = bool(res.residual[0] <= RESIDUAL_TOL)  # Newton aims at 1e-13; the solvers' own bar
                if ok:
                    sc = sb.unknown_scale()[cols]
                    pred = float(np.max(np.abs((Xp - X)[cols] / sc)))
                    corr = float(np.max(np.abs((res.x[0] - Xp)[cols] / sc)))
                    ok = corr <= 0.5 * pred + 1e-8
            if ok:
                Xw, Cw = to_working_charts(sb, res.x[:1], res.charts[:1])
                X, charts = Xw[0], Cw[0]
                t = tn
                h = min(2.0 * h, 1.0)
            else:
                h *= 0.25
                if h < 1e-5:
                    return None
        return None

    def predict_row(self, r: int, X: NDArray) -> NDArray[np.float64]:
        """The Kirchhoff prediction of row ``r`` at its equilibrium ``X`` (pose or inputs)."""
        lay = self.system_at(self.theta0).layout
        return np.array(X[lay.pose] if self.rows[r].fixed == "inputs" else X[lay.inputs], dtype=float)

    def _equilibrium(self, theta: NDArray, X: NDArray, charts: NDArray) -> _Equilibrium:
        from ..rod.state import RodState
        from ..solve.finish import rod_modes

        mech = self.mech_at(theta)
        system = self.system_at(theta)
        lay = system.layout
        X2, C2 = X[None], np.asarray(charts, dtype=np.int64)[None]
        q, _ = system.unit_rods(X2, C2)
        A, al, L = system.clamps(X2[:, lay.inputs])
        modes = rod_modes(system, X2, C2)
        rods = tuple(RodState.from_unit(q[0, i], int(C2[0, i]), X[lay.rod[i]], L[0, i], system.EI[i], A[0, i],
                                        al[0, i], int(modes[0, i]), mech.legs[i].joint) for i in range(3))
        return _Equilibrium(tuple(float(v) for v in X[lay.pose]), tuple(float(v) for v in X[lay.inputs]), rods)

    def refined(self, theta: NDArray, rows: Sequence[int], Xs: Sequence[NDArray], charts: Sequence[NDArray]
                ) -> list[NDArray[np.float64] | None]:
        """Rows' equilibria ``Xs`` (Kirchhoff, at ``theta``) refined into the Cosserat model: their
        poses (FK rows) or inputs (IK rows); None where the refinement does not reach one (a fold).
        Rows with the same problem and load are refined in one batch."""
        from ..cosserat import refine
        from ..cosserat.params import cosserat_setup

        mech = self.mech_at(theta)
        params, grav = cosserat_setup(mech)
        out: list[NDArray[np.float64] | None] = [None] * len(rows)
        groups: dict[tuple, list[int]] = {}
        for a, r in enumerate(rows):
            row = self.rows[r]
            groups.setdefault((row.fixed, tuple(row.load)), []).append(a)
        for (fixed, load), members in groups.items():
            sols = [self._equilibrium(theta, Xs[a], charts[a]) for a in members]
            ref = refine(mech, sols, params=params, gravity=grav, problem="fk" if fixed == "inputs" else "ik",
                         load=load, stability=False, born_search=False)
            for a, rs in zip(members, ref.solutions[:len(members)]):
                if rs.reached:
                    out[a] = np.array(rs.pose if fixed == "inputs" else rs.inputs, dtype=float)
        return out

    def predictions(self, theta: NDArray, rows: Sequence[int], X: NDArray, C: NDArray
                    ) -> list[NDArray[np.float64] | None]:
        """Rows' predictions at ``theta`` from their (followed) Kirchhoff equilibria ``X[r]``."""
        rows = [int(r) for r in rows]
        if self.model == "cosserat":
            return self.refined(theta, rows, [X[r] for r in rows], [C[r] for r in rows]) if rows else []
        return [self.predict_row(r, X[r]) for r in rows]

    # ---- all rows ---------------------------------------------------------------------
    def _nearest_known(self, theta: NDArray, r: int):
        best, bd = None, math.inf
        for th, X, C, ok in self.known:
            if not ok[r]:
                continue
            dd = float(np.max(np.abs((theta - th) / self.scale))) if len(theta) else 0.0
            if dd < bd:
                best, bd = (th, X[r], C[r]), dd
        return best

    def solve(self, theta: NDArray, which: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Follow the branches of rows ``which`` (bool mask) to ``theta``.

        Returns
        -------
        X : (n_rows, n_unknowns), charts : (n_rows, 3), ok : (n_rows,) bool
        """
        theta = np.asarray(theta, dtype=float)
        for th, X, C, ok in self.known:
            if np.array_equal(th, theta) and np.all(ok[which]):
                return X, C, ok
        n = len(self.rows)
        nu = self.known[0][1].shape[1]
        X = np.zeros((n, nu))
        C = np.zeros((n, 3), np.int64)
        ok = np.zeros(n, bool)
        for r in np.flatnonzero(which):
            base = self._nearest_known(theta, r)
            if base is None:
                continue
            got = self.follow(r, base[1], base[2], base[0], theta)
            if got is None:
                self.follow_failures += 1
                continue
            X[r], C[r], ok[r] = got[0], got[1], True
        self.known.append((theta.copy(), X, C, ok))
        if len(self.known) > 400:
            del self.known[1:101]
        return X, C, ok

    def jacobian(self, theta: NDArray, X: NDArray, C: NDArray, rows: NDArray) -> NDArray[np.float64]:
        """d(prediction)/d(theta) of rows ``rows`` (indices), (len(rows), 3, k)."""
        rows = [int(r) for r in rows]
        out = np.empty((len(rows), 3, len(self.params)))
        for a, r in enumerate(rows):
            out[a] = self.tangent(theta, r, X[r], C[r])[-3:]
        if self.model == "cosserat":  # + d(refined - Kirchhoff)/d(theta), central differences
            for k in range(len(self.params)):
                h = 0.05 * self.scale[k]
                corr = []
                for sg in (1.0, -1.0):
                    th = theta.copy()
                    th[k] += sg * h
                    got = [self.follow(r, X[r], C[r], theta, th) for r in rows]
                    live = [a for a, g in enumerate(got) if g is not None]
                    ref = self.refined(th, [rows[a] for a in live], [got[a][0] for a in live],
                                       [got[a][1] for a in live])
                    d = np.full((len(rows), 3), np.nan)
                    for a, pr in zip(live, ref):
                        if pr is not None:
                            dd = pr - self.predict_row(rows[a], got[a][0])
                            d[a] = np.where(self.rows[rows[a]].angular, wrap_to_pi(dd), dd)
                    corr.append(d)
                dk = (corr[0] - corr[1]) / (2 * h)
                out[:, :, k] += np.where(np.isfinite(dk), dk, 0.0)
        return out
