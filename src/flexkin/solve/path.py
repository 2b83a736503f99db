"""Following one IK solution along a straight path of poses; singularities and stability on the way.

The path ``x(t) = (1 - t) x_from + t x_to``, ``t`` in [0, 1], is sampled at ``steps + 1``
points; between samples the solution is continued (:func:`~flexkin.solve.continuation.continue_ik`)
with steps halved on failure, down to :data:`MIN_SUBSTEP` of the sample spacing.  Along the
branch, sign changes of the singularity measures ``sing_ik`` and ``sing_fk``
(:mod:`flexkin.analysis.jacobian`; they change sign with ``det A_IK``, ``det A_FK``), changes of
the stability verdict (the closed-form index of :mod:`flexkin.analysis.stability` at every
sample) and of the d-modes are reported as events located between two samples.  The stability
margin of every sample is computed with the eigenvector of the previous sample as the start (a
full computation at a d-mode change).

Where the continuation fails even at the smallest sub-step, the branch ends, and the reason
given follows from what was computed there: an **IK singularity** (the branch folds back,
typically the workspace boundary) when the IK singularity measure ``sing_ik``
(:mod:`flexkin.analysis.jacobian`: dimensionless, scale-free, 0 at an IK singularity) is
below :data:`FOLD_SING` at the last point reached, or when, extrapolated from the last two
points reached with the square-root law of a fold (``sing_ik^2`` linear in ``t``), it
vanishes within the step that failed; otherwise "the corrector failed to converge" with the
step size and what was measured.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..analysis.jacobian import kinematic_jacobians, singularity_measures, system_blocks
from ..analysis.stability import StabilityArrays, mechanism_stability
from ..core.budget import Deadline, Rate
from ..core.geometry2d import wrap_to_pi
from ..core.validation import as_load, as_triple, check_count, check_max_mode
from ..io.progress import Progress, substage
from ..core.jsonable import finite_or_none
from ..results import Result, Solution
from ..system import System
from .continuation import SEAM_V, continue_ik
from .finish import rod_modes
from .ik import ik

__all__ = ["follow_path", "PathResult", "PathEvent", "MIN_SUBSTEP", "FOLD_SING"]

#: smallest sub-step, as a fraction of the sample spacing
MIN_SUBSTEP = 1.0 / 64
#: IK singularity measure |sing_ik| below which a failed step is an IK singularity
FOLD_SING = 1e-6
#: seconds to analyse one sample (stability, Jacobians) before anything is measured; with
#: feasibility (the sample's solution and its collision checks) about ten times more
SAMPLE_COST = 1e-3


@dataclass(frozen=True)
class PathEvent:
    """Something that happens between two samples ``t_lo < t <= t_hi`` of the path.

    ``kind`` is one of ``"ik_singularity"`` (det J_IK changes sign), ``"fk_singularity"``
    (det J_FK changes sign), ``"stability_lost"``, ``"stability_regained"``,
    ``"mode_change"`` (followed, not a failure), ``"chart_seam"`` (bridged) and
    ``"continuation_failed"`` (the branch ends; ``detail`` says why).
    """

    kind: str
    t_lo: float
    t_hi: float
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {"kind": self.kind, "t_lo": self.t_lo, "t_hi": self.t_hi, "detail": self.detail}


@dataclass(frozen=True)
class PathResult(Result):
    """One IK solution followed along a straight path of poses.

    The array attributes have one row per reached sample (``k`` rows).  ``complete`` is
    ``True`` when the end of the path was reached (never when a time budget ran out); the
    other fields ``solutions`` (empty), ``message``, ``elapsed`` and ``diagnostics`` are those
    of :class:`~flexkin.results.Result`.

    Attributes
    ----------
    mechanism : Mechanism
        The mechanism followed.
    start, end : tuple of 3 floats
        The end poses ``(x, y, theta)`` of the straight path (m, m, rad).
    load : tuple of 3 floats
        Load wrench ``(Fx, Fy, Mz)`` on the platform at P (N, N, N m).
    t : ndarray (k,)
        Path parameter of each sample, in [0, 1] (dimensionless; pose ``(1 - t) start + t end``).
    poses : ndarray (k, 3)
        Platform pose ``(x, y, theta)`` of each sample (m, m, rad).
    inputs : ndarray (k, 3)
        Actuator inputs (SI: m for prismatic and length legs, rad for revolute legs),
        continuous along the branch (revolute inputs are not wrapped).
    modes : ndarray (k, 3) of int
        d-mode of each rod at each sample (SPEC §2).
    stable : ndarray (k,) of bool
        Closed-form stability verdict (:mod:`flexkin.analysis.stability`); samples whose
        stability is undecided count as not stable.
    margin : ndarray (k,)
        Stability margin: smallest eigenvalue of the dimensionless second variation (positive
        iff stable).
    det_ik, det_fk : ndarray (k,)
        Determinants of ``J_IK`` and ``J_FK`` (Eq. 16; dimensionless: lengths in ``L_ref``,
        angles in rad); ``inf`` where the Jacobian does not exist.
    cond : ndarray (k,)
        2-norm condition number of ``J_FK`` (dimensionless); ``inf`` where it does not exist.
    sing_ik, sing_fk : ndarray (k,)
        The singularity measures (:mod:`flexkin.analysis.jacobian`: dimensionless,
        scale-free, in [-1, 1], smooth along the branch, zero at IK / FK singularities).
    x : ndarray (k, n_unknowns)
        The equation system's unknowns at each sample (:class:`flexkin.system.Layout`).
    charts : ndarray (k, 3) of int
        The rods' charts at each sample (:mod:`flexkin.rod.kernels`).
    events : tuple of PathEvent
        Singularities, stability changes, d-mode changes, bridged chart seams and the end of
        the branch, in order of ``t``.
    start_solution : Solution or None
        The IK solution at ``start`` that was followed (``None`` when none was found).
    feasibility : tuple of Feasibility
        One :class:`~flexkin.analysis.feasibility.Feasibility` per sample when
        :func:`follow_path` computed them (``feasibility=True``), else empty.
    """

    mechanism: Any = field(default=None, repr=False)
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    end: tuple[float, float, float] = (0.0, 0.0, 0.0)
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)
    t: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    poses: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    inputs: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    modes: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    stable: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    margin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    det_ik: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    det_fk: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    cond: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    sing_ik: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    sing_fk: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    x: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    charts: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64), repr=False)
    events: tuple[PathEvent, ...] = ()
    start_solution: Solution | None = field(default=None, repr=False)
    feasibility: tuple[Any, ...] = field(default=(), repr=False)

    @property
    def kinds(self) -> tuple[str, ...]:
        """Actuation of each leg."""
        return tuple(leg.actuation for leg in self.mechanism.legs)

    def inputs_display(self) -> NDArray[np.float64]:
        """Inputs in display units (m, degrees for revolute legs)."""
        out = self.inputs.copy()
        for i, leg in enumerate(self.mechanism.legs):
            out[:, i] = leg.to_display(out[:, i])
        return out

    def sample_solutions(self) -> list[Solution]:
        """One :class:`~flexkin.results.Solution` per reached sample (rods, stability,
        Jacobians), in sample order, each carrying the id of the followed start solution;
        rebuilt from the samples' unknowns ``x`` and charts ``charts``."""
        import dataclasses

        from .finish import build_solutions

        if len(self.t) == 0:
            return []
        mech = self.mechanism
        sols = build_solutions(System.from_mechanism(mech), mech, np.asarray(self.x), np.asarray(self.charts),
                               np.asarray(self.load, dtype=float))
        sid = 0 if self.start_solution is None else int(self.start_solution.id)
        return [s if s.id == sid else dataclasses.replace(s, id=sid) for s in sols]

    def to_dict(self, feasibility: bool = False, solutions: list[Solution] | None = None) -> dict[str, Any]:
        """JSON-ready dict; non-finite numbers are ``None``.

        Parameters
        ----------
        feasibility : bool
            Add per sample the bending strain of each rod (``strains``; ``None`` without a
            radius), the largest one (``max_strain``), the verdict of
            :func:`~flexkin.analysis.feasibility.check_feasibility` (``feasibility``:
            collisions, self-intersection, strain above ``[limits] max_strain``, inputs outside
            a leg's ``range``) and ``feasible``; and ``feasible_samples`` at the top.
        solutions : list of Solution, optional
            The samples as solutions, if already built (:meth:`sample_solutions`).
        """
        pts = []
        u = self.inputs_display()
        for j in range(len(self.t)):
            pts.append({"t": float(self.t[j]),
                        "pose": [float(self.poses[j, 0]), float(self.poses[j, 1]), float(np.degrees(self.poses[j, 2]))],
                        "inputs": [float(v) for v in u[j]], "modes": [int(q) for q in self.modes[j]],
                        "stable": bool(self.stable[j]), "stability_margin": finite_or_none(self.margin[j]),
                        "jacobian": {"det_ik": finite_or_none(self.det_ik[j]), "det_fk": finite_or_none(self.det_fk[j]),
                                     "cond": finite_or_none(self.cond[j]), "sing_ik": finite_or_none(self.sing_ik[j]),
                                     "sing_fk": finite_or_none(self.sing_fk[j])}})
        d = {"problem": "path", "mechanism": self.mechanism.name, "load": list(self.load),
             "from": [self.start[0], self.start[1], float(np.degrees(self.start[2]))],
             "to": [self.end[0], self.end[1], float(np.degrees(self.end[2]))],
             "solution": None if self.start_solution is None else self.start_solution.id,
             "complete": self.complete, "message": self.message,
             "jacobian_units": f"dimensionless: lengths in L_ref = {self.mechanism.length_scale:.6g} m (the "
                               "mechanism's length scale), angles in rad",
             "events": [e.to_dict() for e in self.events], "points": pts}
        if feasibility and pts:
            from ..analysis.feasibility import check_feasibility

            verdicts = self.feasibility
            if len(verdicts) != len(pts):
                sols = self.sample_solutions() if solutions is None else solutions
                verdicts = tuple(check_feasibility(self.mechanism, sol) for sol in sols)
            for p, f in zip(pts, verdicts):
                p.update(feasible=f.feasible, max_strain=f.max_strain, strains=list(f.strains),
                         feasibility=f.to_dict())
            d["feasible_samples"] = sum(bool(p["feasible"]) for p in pts)
        return d

    def table(self) -> str:
        """Human-readable table of the samples, then the events."""
        units = [leg.input_unit for leg in self.mechanism.legs]
        head = (f"{'t':>6} {'modes':>5} " + " ".join(f"{'u' + str(i + 1) + ' [' + un + ']':>11}"
                                                      for i, un in enumerate(units))
                + f" {'stable':>6} {'margin':>9} {'det J_IK':>10} {'det J_FK':>10}")
        lines = [head, "-" * len(head)]
        u = self.inputs_display()
        for j in range(len(self.t)):
            lines.append(f"{self.t[j]:>6.3f} {''.join(map(str, self.modes[j])):>5} "
                         + " ".join(f"{v:>11.5f}" for v in u[j])
                         + f" {'yes' if self.stable[j] else 'no':>6} {self.margin[j]:>9.3g}"
                         + f" {self.det_ik[j]:>10.3g} {self.det_fk[j]:>10.3g}")
        if self.events:
            lines.append("")
            lines.append("events:")
            for e in self.events:
                lines.append(f"  {e.kind:<20} t in ({e.t_lo:.4f}, {e.t_hi:.4f}]  {e.detail}")
        if self.message:
            lines.append(self.message)
        return "\n".join(lines)

    def plot(self, path: str | None = None, **kwargs: Any):
        """Inputs, singularity functions, Jacobian determinants and stability margin against the
        path parameter (:func:`~flexkin.plot.path.plot_path`).

        Parameters
        ----------
        path : str, optional
            Save the figure there.
        **kwargs
            Passed to :func:`~flexkin.plot.path.plot_path`.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ..plot.path import plot_path

        return plot_path(self, path=path, **kwargs)


def _pose_at(a: NDArray, b: NDArray, t: float) -> NDArray:
    return (1.0 - t) * a + t * b


def follow_path(mech, start: ArrayLike, end: ArrayLike, steps: int = 50, load: ArrayLike | None = None,
                solution: int | Solution | None = None, max_mode: int = 2,
                time_budget: float | Deadline | None = None, *, feasibility: bool = False,
                progress: Progress | None = None) -> PathResult:
    """Follow one IK solution from pose ``start`` to pose ``end`` (m, m, rad).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    start, end : (x, y, theta)
        End poses of the straight path (theta in radians).
    steps : int
        Number of path intervals (samples at ``t = j / steps``).
    load : (Fx, Fy, Mz), optional
        Defaults to the mechanism file's load.
    solution : int or Solution, optional
        The IK solution at ``start`` to follow: its id (1-based, as in ``ik(mech, start)``'s
        table and JSON) or a :class:`Solution`.  Default: the first stable one (else the first).
    max_mode : int
        Passed to the IK at ``start`` when ``solution`` is not a :class:`Solution`.
    time_budget : float or Deadline, optional
        Seconds for the whole path (start-up excluded; see :mod:`flexkin.core.budget`): the
        IK at ``start``, the continuation, and the analysis of every sample (stability,
        Jacobians, and feasibility when asked for).  When they run out, the samples reached
        and analysed so far are returned with ``complete = False`` and a message.
    feasibility : bool
        Also check every sample's feasibility (:func:`~flexkin.analysis.feasibility.check_feasibility`,
        a few ms per sample; within the budget) into :attr:`PathResult.feasibility`.
    progress : callable, optional
        Called as ``progress(fraction, stage)``: the IK at the start pose (when ``solution`` is
        not a :class:`Solution`), the path parameter reached, then the analysis of the
        remaining samples (:class:`flexkin.io.progress.ProgressBar` draws it).

    Returns
    -------
    PathResult
        ``complete`` is ``False`` when the branch ended before ``end`` (then the last event
        is ``"continuation_failed"`` and its detail says why).
    """
    t0 = time.perf_counter()
    dl = Deadline.of(time_budget)
    a = as_triple(start, "start pose (x, y, theta)")
    b = as_triple(end, "end pose (x, y, theta)")
    steps = check_count(steps, "steps")
    max_mode = check_max_mode(max_mode)
    w = as_load(mech, load)
    system = System.from_mechanism(mech)
    base = dict(mechanism=mech, start=tuple(map(float, a)), end=tuple(map(float, b)), load=tuple(map(float, w)))
    if isinstance(solution, Solution):
        sol = solution
    else:
        res = ik(mech, a, load=w, max_mode=max_mode, time_budget=dl if dl.limited else None,
                 progress=substage(progress, 0.0, 0.1, "IK at the start pose"))
        if dl.hit:  # the solution to follow is not known for sure
            return PathResult(complete=False, message=dl.message("in the IK at the start pose"),
                              elapsed=time.perf_counter() - t0, **base)
        if not res.solutions:
            return PathResult(complete=False, message=f"no IK solution at the start pose: {res.message}",
                              elapsed=time.perf_counter() - t0, **base)
        if solution is None:
            sol = next((s for s in res.solutions if s.stable), res.solutions[0])
        else:
            ids = [s.id for s in res.solutions]
            if isinstance(solution, bool) or not isinstance(solution, (int, np.integer)) or int(solution) not in ids:
                raise ValueError(f"solution {solution!r} does not exist: the start pose has {len(ids)} IK solutions "
                                 f"(ids 1..{len(ids)})")
            sol = res.solutions[ids.index(int(solution))]
    x = np.asarray(sol.x, dtype=float)[None].copy()
    ch = np.asarray(sol.charts, dtype=np.int64)[None].copy()
    x[0, system.layout.pose] = a
    xs, cs, ts = [x[0].copy()], [ch[0].copy()], [0.0]
    t, h = 0.0, 1.0 / steps
    failed: tuple[float, float] | None = None
    last = [(0.0, x.copy(), ch.copy())]  # the last accepted points (also between samples)
    bridged: list[PathEvent] = []
    j = 0
    timed_out = False
    # the samples are analysed in slices as they come (part of the budget, so that the time
    # left always covers the samples not analysed yet)
    ana = _Analysis(system, mech, w, feasibility)
    cost = Rate(SAMPLE_COST * (10 if feasibility else 1))
    while j < steps:
        if dl.expired(cost.cost(len(xs) - ana.n)):
            timed_out = True
            break
        if dl.limited and len(xs) - ana.n >= cost.units_for(dl.slice_seconds(), 1):
            ana.run(xs, cs, cost)
        j += 1
        if j / steps <= t + 1e-15:
            continue
        target = j / steps
        dt = target - t
        while t < target - 1e-15:
            dt = min(dt, target - t)
            x1, c1, ok = continue_ik(system, x, ch, _pose_at(a, b, t + dt)[None], w)
            if ok[0]:
                x, ch, t = x1, c1, t + dt
                last = (last + [(t, x.copy(), ch.copy())])[-2:]
                dt = min(2 * dt, h)
            elif dt > MIN_SUBSTEP * h * 1.0001:
                dt *= 0.5
            else:
                failed = (t, dt)
                break
        if failed is not None:
            # a rod passing straight under tension sits on the seam of the elliptic chart
            # (|k| -> 1): bridge it with the full IK at the next samples, if a solution there
            # continues the branch (see _bridge); otherwise the branch has really ended
            jump = _bridge(mech, system, x[0], ch[0], a, b, j, steps, w, max_mode, dl)
            if dl.hit:
                timed_out, failed = True, None
                break
            if jump is None:
                break
            j_new, x_new, c_new = jump
            bridged.append(PathEvent("chart_seam", float(ts[-1]), j_new / steps,
                                     "a rod passes straight under tension (|k| = 1): samples inside were "
                                     "bridged by the full IK"))
            x, ch, t, failed = x_new[None], c_new[None], j_new / steps, None
            last = [(t, x.copy(), ch.copy())]
            ts.append(t)
            xs.append(x[0].copy())
            cs.append(ch[0].copy())
            continue
        ts.append(target)
        xs.append(x[0].copy())
        cs.append(ch[0].copy())
        if progress is not None:
            progress(0.1 + 0.8 * target, f"t = {target:.3f}")
    if progress is not None:
        progress(0.9, f"analysis of {len(xs) - ana.n} remaining samples")
    ana.run(xs, cs, cost)
    X, C, T = np.array(xs), np.array(cs), np.array(ts)
    P = X[:, system.layout.pose]
    an = ana.arrays()
    modes = rod_modes(system, X, C)
    stable = an["stable"]
    events = sorted(_events(T, modes, stable, an["sing_ik"], an["sing_fk"]) + bridged, key=lambda e: e.t_lo)
    msg = ""
    if failed is not None:
        t_end, dt_end = failed
        why = _stop_reason(system, last, w, t_end, dt_end, float(np.linalg.norm((b - a)[:2])))
        events.append(PathEvent("continuation_failed", float(T[-1]), float(min(T[-1] + h, 1.0)), why))
        msg = f"continuation stopped: {why}"
    if timed_out:
        msg = dl.message(f"the path was followed to t = {T[-1]:.4f}")
    return PathResult(complete=failed is None and not timed_out and not dl.hit, message=msg,
                      elapsed=time.perf_counter() - t0, t=T, poses=P, inputs=X[:, system.layout.inputs], modes=modes,
                      stable=stable, margin=an["margin"], det_ik=an["det_ik"], det_fk=an["det_fk"], cond=an["cond"],
                      sing_ik=an["sing_ik"], sing_fk=an["sing_fk"], x=X, charts=C, events=tuple(events),
                      start_solution=sol, feasibility=tuple(ana.feasibility) if feasibility else (), **base)


class _Analysis:
    """Stability, Jacobians (and feasibility) of the path's samples, computed slice by slice."""

    _KEYS = ("margin", "det_ik", "det_fk", "cond", "sing_ik", "sing_fk")

    def __init__(self, system: System, mech, w: NDArray, feasibility: bool) -> None:
        self.system, self.mech, self.w, self.with_feasibility = system, mech, w, feasibility
        self.n = 0
        self.parts: dict[str, list[NDArray]] = {k: [] for k in self._KEYS + ("stable",)}
        self.feasibility: list[Any] = []
        self._pairs: Any = None               # eigenvectors of the last sample analysed
        self._modes: NDArray | None = None    # and its d-modes

    def run(self, xs: list[NDArray], cs: list[NDArray], rate: Rate) -> None:
        """Analyse the samples ``xs[self.n:]``."""
        if len(xs) <= self.n:
            return
        t = time.perf_counter()
        X, C = np.array(xs[self.n:]), np.array(cs[self.n:])
        st = self._stability(X, C)
        jac = kinematic_jacobians(self.system, X, C, self.w)
        self.parts["stable"].append(st.stable == 1)
        self.parts["margin"].append(st.margin)
        for k in self._KEYS[1:]:
            self.parts[k].append(getattr(jac, k))
        if self.with_feasibility:
            from ..analysis.feasibility import check_feasibility
            from .finish import build_solutions

            self.feasibility += [check_feasibility(self.mech, s)
                                 for s in build_solutions(self.system, self.mech, X, C, self.w)]
        rate.add(len(X), time.perf_counter() - t)
        self.n = len(xs)

    def arrays(self) -> dict[str, NDArray]:
        return {k: np.concatenate(v) for k, v in self.parts.items()}

    def _stability(self, X: NDArray, C: NDArray) -> StabilityArrays:
        """Stability of the next samples of the branch: the closed-form verdict of each, and its
        margin with the eigenvector carried from the previous sample (computed afresh at a
        d-mode change; the discretisation restarts by itself when the carried one fails,
        :mod:`flexkin.analysis.second_variation`)."""
        modes = rod_modes(self.system, X, C)
        rows = []
        for j in range(len(X)):
            same = self._modes is not None and np.array_equal(modes[j], self._modes)
            st = mechanism_stability(self.system, X[j:j + 1], C[j:j + 1], margin=True,
                                     guess=self._pairs if same else None)
            self._pairs, self._modes = st.pairs, modes[j]
            rows.append(st)
        return StabilityArrays(*(np.concatenate([getattr(r, f) for r in rows]) for f in
                               ("stable", "margin", "resolution", "index", "method", "flags", "gap", "sign")))


def _stop_reason(system: System, last: list, w: NDArray, t_end: float, dt_end: float, span: float) -> str:
    """Why the branch ended at ``t_end`` (see the module docstring)."""
    X = np.array([p[1][0] for p in last])
    C = np.array([p[2][0] for p in last])
    T = np.array([p[0] for p in last])
    d, _ = singularity_measures(*system_blocks(system, X, C, w))
    s_end = float(abs(d[-1]))
    t_fold = None
    if len(T) == 2 and T[1] > T[0] and d[0] ** 2 > d[1] ** 2 and np.sign(d[0]) == np.sign(d[1]):
        t_fold = T[1] + d[1] ** 2 * (T[1] - T[0]) / (d[0] ** 2 - d[1] ** 2)
    if not np.isfinite(s_end) or s_end < FOLD_SING:
        return (f"IK singularity: the branch folds back near t = {t_end:.4f} (sing_ik = {s_end:.2g} there: "
                "the IK Newton matrix is singular)")
    if t_fold is not None and t_fold <= t_end + dt_end:
        return (f"IK singularity: the branch folds back at t = {t_fold:.4f} (sing_ik -> 0, extrapolated from "
                f"the last points; sing_ik = {s_end:.2g} at t = {t_end:.4f})")
    where = "" if t_fold is None else f", extrapolating to zero only at t = {t_fold:.3f}"
    return (f"the corrector failed to converge at step size h = {dt_end * span:.3g} m (dt = {dt_end:.2g}) near "
            f"t = {t_end:.4f}; no singularity detected there (sing_ik = {s_end:.2g}{where})")


def _near_seam(system: System, x: NDArray, ch: NDArray) -> bool:
    """Whether a pinned rod is close to the straight-under-tension seam of the chart."""
    for i in range(3):
        c = system.layout.rod[i].start
        if ch[i] == 1 or (ch[i] == 0 and abs(x[c]) > SEAM_V):
            return True
    return False


def _bridge(mech, system: System, x: NDArray, ch: NDArray, a: NDArray, b: NDArray, j: int, steps: int,
            w: NDArray, max_mode: int, deadline: Deadline) -> tuple[int, NDArray, NDArray] | None:
    """Continue the branch across the chart seam by the full IK at the next samples.

    The candidate at sample ``j'`` (up to 3 samples ahead) must have the same d-modes and
    inputs within a quarter of the predicted change (linear extrapolation with J_FK) of the
    prediction, so a bridge never lands on another branch.  The IKs run on the path's
    ``deadline``; when it is hit the bridge gives up (None) and the caller sees the hit.
    """
    if not _near_seam(system, x, ch):
        return None
    lay = system.layout
    pose = x[lay.pose]
    jac = kinematic_jacobians(system, x[None], ch[None], w)
    if not np.all(np.isfinite(jac.J_FK)):
        return None
    su = system.input_scale()
    sx = np.array([system.L_ref, system.L_ref, 1.0])
    modes0 = rod_modes(system, x[None], ch[None])[0]
    for jj in range(j, min(j + 3, steps) + 1):
        p1 = _pose_at(a, b, jj / steps)
        du = jac.J_FK[0] @ ((p1 - pose) / sx)
        pred = x[lay.inputs] / su + du
        res = ik(mech, p1, load=w, max_mode=max(max_mode, int(modes0.max())),
                 time_budget=deadline if deadline.limited else None)
        if deadline.hit:
            return None
        best, dist = None, np.inf
        for s in res.solutions:
            if tuple(s.modes) != tuple(modes0):
                continue
            d = np.max(np.abs(_unwrap(s.inputs, x[lay.inputs], system) / su - pred))
            if d < dist:
                best, dist = s, d
        if best is not None and dist <= 0.25 * np.max(np.abs(du)) + 1e-6:
            xn = np.array(best.x, dtype=float)
            xn[lay.inputs] = _unwrap(best.inputs, x[lay.inputs], system)
            return jj, xn, np.array(best.charts)
    return None


def _unwrap(u: NDArray, ref: NDArray, system: System) -> NDArray:
    """Angular inputs shifted by multiples of 2 pi to be closest to ``ref``."""
    out = np.array(u, dtype=float)
    rev = system.angular
    out[rev] = ref[rev] + wrap_to_pi(out[rev] - ref[rev])
    return out


def _events(T, modes, stable, sing_ik, sing_fk) -> list[PathEvent]:
    ev: list[PathEvent] = []
    for j in range(1, len(T)):
        lo, hi = float(T[j - 1]), float(T[j])
        if np.sign(sing_ik[j]) != np.sign(sing_ik[j - 1]):
            ev.append(PathEvent("ik_singularity", lo, hi, "det J_IK changes sign"))
        if np.sign(sing_fk[j]) != np.sign(sing_fk[j - 1]):
            ev.append(PathEvent("fk_singularity", lo, hi, "det J_FK changes sign"))
        if stable[j - 1] and not stable[j]:
            ev.append(PathEvent("stability_lost", lo, hi))
        elif stable[j] and not stable[j - 1]:
            ev.append(PathEvent("stability_regained", lo, hi))
        if np.any(modes[j] != modes[j - 1]):
            ev.append(PathEvent("mode_change", lo, hi,
                                f"d-modes {''.join(map(str, modes[j - 1]))} -> {''.join(map(str, modes[j]))}"))
    return ev
