"""The explorer's state and logic, free of any web library (testable without a browser).

:class:`ExplorerState` holds what the user sees and does:

* the *mode*: ``"ik"`` (the user moves the platform pose) or ``"fk"`` (the user moves the
  actuator inputs);
* the last *full solve* (:func:`flexkin.ik` / :func:`flexkin.fk`) and whether it still
  describes the current pose / inputs (``stale``);
* the *selected* equilibrium, followed by a :class:`~flexkin.solve.track.Tracker` while the
  user drags or slides (continuation, never a re-solve), with the tracker's events in a log;
* after a full solve, which new solution is the tracked one (:func:`match_solution`);
* when the tracked branch ends: a notice, and the solutions that remain at that pose.

Solving is split in three steps so that the web layer can run the expensive part in a
background thread while the state is only touched on one thread:
``req = state.request()`` (a snapshot), ``res = solve(state.mech, req)`` (pure, thread-safe),
``state.apply(req, res)`` (ignored if the user has moved on since ``req``).
:meth:`ExplorerState.refresh` does the three at once.

Units: SI and radians inside (``pose``, ``inputs``), display units (m, deg) in the texts.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from flexkin.core.geometry2d import wrap_to_pi
from flexkin.core.validation import check_max_mode
from flexkin.results import fill_margins

__all__ = [
    "EVENT_TITLES", "ExplorerState", "LogEntry", "MoveOutcome", "SolveOutcome", "SolveRequest",
    "default_pose", "input_bounds", "match_solution", "pose_bounds", "solution_distance", "solve",
]

#: Readable names of the tracker's events (``TrackEvent.kind``) and of the explorer's own.
EVENT_TITLES: dict[str, str] = {
    "mode_change": "d-mode change",
    "stability_lost": "stability lost",
    "stability_regained": "stability regained",
    "stability_undecided": "stability undecided",
    "ik_singularity": "IK singularity crossed",
    "fk_singularity": "FK singularity crossed",
    "infeasible": "became infeasible",
    "feasible": "became feasible",
    "branch_end": "branch ended",
    "not_found": "tracked equilibrium not found",
    "no_solution": "no equilibrium here",
}

#: Largest :func:`solution_distance` at which a solution of a full solve is taken to be the
#: tracked one (both are converged to ~1e-10; distinct equilibria differ by far more).
MATCH_TOL = 1e-4
#: The same after a change of load (the selection follows the nearest equilibrium).
MATCH_TOL_LOOSE = 0.2


def _tracker_cls():
    # imported on first use: keeps ``import flexkin.explore.state`` cheap
    from flexkin.solve.track import Tracker

    return Tracker


# ---------------------------------------------------------------------------------------------
# geometry helpers (display ranges)
# ---------------------------------------------------------------------------------------------
def default_pose(mech) -> tuple[float, float, float]:
    """Start pose when none is given: the platform point at the centroid of the legs'
    origins, orientation 0."""
    c = np.asarray(mech.base_centroid, dtype=float)
    return (float(c[0]), float(c[1]), 0.0)


def pose_bounds(mech, pose: Sequence[float] | None = None) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)`` (m): the box of the legs' origins grown by a quarter of the length
    scale (the default workspace box), grown further to contain ``pose``."""
    o = np.array([leg.origin for leg in mech.legs], dtype=float)
    g = 0.25 * float(mech.length_scale)
    x0, y0 = o.min(axis=0) - g
    x1, y1 = o.max(axis=0) + g
    if pose is not None:
        x0, x1 = min(x0, pose[0] - g), max(x1, pose[0] + g)
        y0, y1 = min(y0, pose[1] - g), max(y1, pose[1] + g)
    return (float(x0), float(x1), float(y0), float(y1))


def input_bounds(mech, i: int, value: float | None = None) -> tuple[float, float]:
    """Slider range of leg ``i``'s input in display units (m or deg): the leg's ``range`` when
    the file gives one, else a generous default; widened to contain ``value`` (display units)."""
    leg = mech.legs[i]
    if leg.range is not None:
        lo, hi = (float(leg.to_display(v)) for v in leg.range)
    elif leg.actuation == "revolute":
        lo, hi = -180.0, 180.0
    else:
        L = getattr(getattr(leg, "rod", None), "length", None) or float(mech.length_scale)
        lo, hi = (-0.5 * L, 1.75 * L) if leg.actuation == "prismatic" else (0.05 * L, 2.0 * L)
    if value is not None and np.isfinite(value):
        span = hi - lo
        lo, hi = min(lo, value - 0.05 * span), max(hi, value + 0.05 * span)
    return (float(lo), float(hi))


def _fmt_where(mech, mode: str, where: Sequence[float]) -> str:
    if mode == "ik":
        return f"({where[0]:.4f} m, {where[1]:.4f} m, {where[2]:.2f} deg)"
    return "(" + ", ".join(f"{v:.4g} {leg.input_unit}" for v, leg in zip(where, mech.legs)) + ")"


# ---------------------------------------------------------------------------------------------
# matching solutions across updates
# ---------------------------------------------------------------------------------------------
def solution_distance(a, b, mech) -> float:
    """Dimensionless distance between two equilibria of ``mech``: the largest of the pose
    difference (lengths over the length scale, angle in rad), the input differences (m over the
    length scale, rad) and each rod's tip-force (over EI/L^2) and base-moment (over EI/L)
    differences.  About 1e-9 for the same equilibrium computed twice."""
    L = float(mech.length_scale)
    d = [abs(a.pose[0] - b.pose[0]) / L, abs(a.pose[1] - b.pose[1]) / L, abs(wrap_to_pi(a.pose[2] - b.pose[2]))]
    for ua, ub, leg in zip(a.inputs, b.inputs, mech.legs):
        d.append(abs(wrap_to_pi(ua - ub)) if leg.actuation == "revolute" else abs(ua - ub) / L)
    for ra, rb in zip(a.rods, b.rods):
        f = ra.EI / ra.length**2
        d.append(math.hypot(ra.tip_force[0] - rb.tip_force[0], ra.tip_force[1] - rb.tip_force[1]) / f)
        d.append(abs(ra.base_moment - rb.base_moment) / (ra.EI / ra.length))
        d.append(abs(ra.tip_moment - rb.tip_moment) / (ra.EI / ra.length))
    return float(max(d))


def match_solution(ref, candidates: Sequence[Any], mech, tol: float = MATCH_TOL) -> tuple[Any | None, float]:
    """The candidate that is the same equilibrium as ``ref`` (nearest by
    :func:`solution_distance`, if within ``tol``) and its distance; ``(None, distance)`` when
    none is close enough (``inf`` for no candidate)."""
    best, dbest = None, math.inf
    for c in candidates:
        d = solution_distance(ref, c, mech)
        if d < dbest:
            best, dbest = c, d
    return (best, dbest) if dbest <= tol else (None, dbest)


# ---------------------------------------------------------------------------------------------
# solving (pure, thread-safe)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SolveRequest:
    """A snapshot of what to solve: ``mode``, ``target`` (pose in m, m, rad or inputs in SI),
    ``load``, ``max_mode``; ``serial`` identifies the state it was taken from."""

    mode: str
    target: tuple[float, float, float]
    load: tuple[float, float, float]
    max_mode: int
    serial: int


@dataclass(frozen=True)
class SolveOutcome:
    """A full solve's result (``None`` if the request was invalid, then ``error`` says why)."""

    request: SolveRequest
    result: Any = None
    error: str = ""
    elapsed: float = 0.0


def solve(mech, req: SolveRequest) -> SolveOutcome:
    """Run the full IK (``req.mode == "ik"``) or FK for ``req``; never raises for a bad target
    (the error is returned)."""
    from flexkin.solve.fk import fk   # imported on first use, like the Tracker
    from flexkin.solve.ik import ik

    t0 = time.perf_counter()
    try:
        if req.mode == "ik":
            res = ik(mech, req.target, load=req.load, max_mode=req.max_mode)
        else:
            res = fk(mech, req.target, load=req.load, max_mode=req.max_mode)
    except ValueError as e:
        return SolveOutcome(req, None, str(e), time.perf_counter() - t0)
    return SolveOutcome(req, res, "", time.perf_counter() - t0)


def feasibility_of(mech, solutions: Sequence[Any], cancelled=lambda: False) -> dict[int, Any] | None:
    """Feasibility verdict of each solution, by id (``None`` if ``cancelled()`` turned true)."""
    from flexkin.analysis.feasibility import check_feasibility

    out: dict[int, Any] = {}
    for s in solutions:
        if cancelled():
            return None
        out[s.id] = check_feasibility(mech, s)
    return out


# ---------------------------------------------------------------------------------------------
# the state
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LogEntry:
    """One line of the event log."""

    seq: int
    kind: str
    detail: str
    solution_id: int | None
    mode: str
    where: tuple[float, float, float]  # display units: pose (m, m, deg) or inputs (m / deg)

    @property
    def title(self) -> str:
        return EVENT_TITLES.get(self.kind, self.kind.replace("_", " "))

    def text(self, mech) -> str:
        who = f"#{self.solution_id} " if self.solution_id is not None else ""
        det = f" ({self.detail})" if self.detail else ""
        return f"{who}{self.title}{det} at {_fmt_where(mech, self.mode, self.where)}"


@dataclass(frozen=True)
class MoveOutcome:
    """What :meth:`ExplorerState.move` did: whether the selected equilibrium was tracked and
    reached the target, the new log entries, and whether a full solve is needed now (no
    selection, or the branch ended)."""

    tracked: bool
    reached: bool
    entries: tuple[LogEntry, ...] = ()
    needs_solve: bool = False
    elapsed: float = 0.0


class ExplorerState:
    """State of one explorer session (see the module docstring).

    Parameters
    ----------
    mech : Mechanism
    pose : (x, y, theta), optional
        Start pose (m, m, rad); default :func:`default_pose`.
    load : (Fx, Fy, Mz), optional
        Default: the mechanism file's load.
    max_mode : int
        Largest d-mode of the full solves.
    """

    def __init__(self, mech, pose: Sequence[float] | None = None, *, load: Sequence[float] | None = None,
                 max_mode: int = 2) -> None:
        self.mech = mech
        self.max_mode = check_max_mode(max_mode)
        p = default_pose(mech) if pose is None else pose
        self.pose = np.array([float(v) for v in p])
        if self.pose.shape != (3,) or not np.all(np.isfinite(self.pose)):
            raise ValueError(f"pose must be three finite numbers (x, y, theta), got {pose!r}")
        self.inputs: np.ndarray | None = None
        self.load: tuple[float, float, float] = tuple(float(v) for v in (mech.load if load is None else load))
        self.mode = "ik"
        self.show = "all"  # "all" | "stable" | "feasible" | "selected"
        self.result = None              # last full solve (KinematicsResult) or None
        self.result_request: SolveRequest | None = None  # what it solved
        self.stale = True               # the result does not describe the current pose / inputs
        self.error = ""                 # why the last solve had no result (bad inputs)
        self.feasibility: dict[int, Any] = {}  # id -> Feasibility, for self.result
        self.selected_id: int | None = None
        self._selected = None           # the selected equilibrium, current (tracked or from result)
        self._selected_feas = None
        self.tracker = None
        self.branch_end = None          # the last point of a branch that ended (until the next solve)
        self.notice = ""
        self.log: list[LogEntry] = []
        self._serial = 0
        self._loose = False             # the load changed: match the nearest equilibrium
        self._ended_id: int | None = None

    # ---- small accessors --------------------------------------------------------------------
    @property
    def target(self) -> tuple[float, float, float]:
        """The current pose (IK mode) or inputs (FK mode), SI / rad."""
        v = self.pose if self.mode == "ik" else self.inputs
        return tuple(float(a) for a in v)  # type: ignore[return-value]

    @property
    def serial(self) -> int:
        """Changes whenever the pose, the inputs, the load or the mode change."""
        return self._serial

    @property
    def selected(self):
        """The selected equilibrium as it is now (moved by the tracker during a drag), or None."""
        return self._selected

    @property
    def tracking(self) -> bool:
        """A drag moved the selected equilibrium since the last full solve."""
        return self.stale and self._selected is not None

    @property
    def solutions(self) -> tuple:
        """The full solve's solutions when it describes the current pose / inputs, else ()."""
        if self.stale or self.result is None:
            return ()
        return tuple(self.result.solutions)

    def solution_by_id(self, sid: int):
        for s in self.solutions:
            if s.id == sid:
                return s
        return None

    def where_display(self) -> tuple[float, float, float]:
        """The current pose (m, m, deg) or inputs (display units)."""
        if self.mode == "ik":
            return (float(self.pose[0]), float(self.pose[1]), float(math.degrees(self.pose[2])))
        return tuple(float(leg.to_display(u)) for u, leg in zip(self.inputs, self.mech.legs))  # type: ignore

    def _entry(self, kind: str, detail: str, sid: int | None) -> LogEntry:
        e = LogEntry(len(self.log) + 1, kind, detail, sid, self.mode, self.where_display())
        self.log.append(e)
        return e

    def _bump(self) -> None:
        self._serial += 1
        self.stale = True

    # ---- solving ----------------------------------------------------------------------------
    def request(self) -> SolveRequest:
        """Snapshot of the full solve the current state needs."""
        return SolveRequest(self.mode, self.target, self.load, self.max_mode, self._serial)

    def apply(self, out: SolveOutcome) -> bool:
        """Take a full solve's outcome.  Returns False (and changes nothing) when the state has
        changed since the request was taken.  Matches the selected equilibrium in the new
        solutions (:func:`match_solution`); logs ``not_found`` / ``no_solution``."""
        if out.request.mode != self.mode:
            return False
        if out.request.serial != self._serial:
            # out of date: still shown while the user drags without a selection (each solution
            # is drawn at its own pose), but the state stays stale
            if out.result is not None and self._selected is None and self.branch_end is None:
                self.result, self.result_request, self.feasibility = out.result, out.request, {}
            return False
        res = out.result
        self.result_request = out.request
        self.result, self.error, self.stale = res, out.error, False
        self.feasibility = {}
        self.tracker = None
        self.branch_end = None
        sols = () if res is None else tuple(res.solutions)
        notice = []
        if self._ended_id is not None:
            what = "pose" if self.mode == "ik" else "inputs"
            notice.append(f"The branch of #{self._ended_id} ended. {len(sols)} solution(s) remain at these {what}: "
                          "click one to follow it.")
            self._ended_id = None
        if self._selected is not None:
            tol = MATCH_TOL_LOOSE if self._loose else MATCH_TOL
            m, d = match_solution(self._selected, sols, self.mech, tol=tol)
            if m is not None:
                self.selected_id, self._selected = m.id, m
            else:
                lost = self.selected_id
                self._entry("not_found", f"closest solution differs by {d:.2g}" if math.isfinite(d) else "",
                            lost)
                notice.append(f"The equilibrium #{lost} that was followed is not among the {len(sols)} solution(s) "
                              "of the full solve here; selection cleared.")
                self.selected_id, self._selected = None, None
        self._loose = False
        self._selected_feas = None
        if res is None:
            notice.append(out.error)
        elif not sols:
            self._entry("no_solution", res.message, None)
        self.notice = " ".join(n for n in notice if n)
        return True

    def apply_feasibility(self, serial: int, feas: dict[int, Any] | None) -> bool:
        """Take the feasibility verdicts computed for the solve of state ``serial``."""
        if feas is None or serial != self._serial or self.stale:
            return False
        self.feasibility = dict(feas)
        return True

    def refresh(self) -> SolveOutcome:
        """Full solve at the current pose / inputs, now (synchronous)."""
        out = solve(self.mech, self.request())
        self.apply(out)
        return out

    # ---- interaction ------------------------------------------------------------------------
    def select(self, sid: int | None) -> None:
        """Select the solution ``sid`` of the current full solve (``None`` clears)."""
        if sid is None:
            self.selected_id, self._selected, self.tracker = None, None, None
            return
        if self.stale:
            raise ValueError("no current solution list to select from (a solve is pending)")
        s = self.solution_by_id(int(sid))
        if s is None:
            raise ValueError(f"no solution #{sid} here")
        self.selected_id, self._selected, self.tracker = s.id, s, None
        self._selected_feas = self.feasibility.get(s.id)
        self.notice = ""

    def move(self, target: Sequence[float]) -> MoveOutcome:
        """A live change of the pose (IK mode; m, m, rad) or of the inputs (FK mode; SI) while
        the user drags: the selected equilibrium is moved by the tracker (continuation); without
        a selection, a full solve is needed (``needs_solve``)."""
        t0 = time.perf_counter()
        tgt = np.array([float(v) for v in target])
        if tgt.shape != (3,) or not np.all(np.isfinite(tgt)):
            raise ValueError(f"target must be three finite numbers, got {target!r}")
        if self.mode == "ik":
            self.pose = tgt
        else:
            self.inputs = tgt
        self._bump()
        if self._selected is None:
            return MoveOutcome(False, False, (), True, time.perf_counter() - t0)
        if self.tracker is None:
            self.tracker = _tracker_cls()(self.mech, self._selected, load=self.load, feasibility=True)
        try:
            step = self.tracker.move_to(tgt, kind="pose" if self.mode == "ik" else "inputs")
        except ValueError as e:  # an input the actuator cannot take (e.g. a negative length)
            self.notice = str(e)
            return MoveOutcome(True, False, (), False, time.perf_counter() - t0)
        sid = self.selected_id
        entries = tuple(self._entry(ev.kind, ev.detail, sid) for ev in step.events)
        if step.feasibility is not None:
            self._selected_feas = step.feasibility
        if step.reached:
            self._selected = dataclasses.replace(step.solution, id=sid)
            self.notice = ""
            return MoveOutcome(True, True, entries, False, time.perf_counter() - t0)
        # the branch ends: say so, drop the selection, a full solve offers what remains
        self.branch_end = dataclasses.replace(step.solution, id=sid)
        detail = next((e.detail for e in entries if e.kind == "branch_end"), "")
        self.notice = f"The branch of #{sid} ended: {detail}. Solving for the equilibria that remain..."
        self._ended_id = sid
        self.selected_id, self._selected, self.tracker, self._selected_feas = None, None, None, None
        return MoveOutcome(True, False, entries, True, time.perf_counter() - t0)

    def set_load(self, load: Sequence[float]) -> None:
        """New load wrench (N, N, N m); a full solve is needed; the selection then follows the
        nearest equilibrium."""
        w = tuple(float(v) for v in load)
        if len(w) != 3 or not all(math.isfinite(v) for v in w):
            raise ValueError(f"load must be three finite numbers (Fx, Fy, Mz), got {load!r}")
        if w == self.load:
            return
        self.load = w  # type: ignore[assignment]
        self.tracker = None
        self._loose = self._selected is not None
        self._bump()

    def set_mode(self, mode: str) -> None:
        """Switch between ``"ik"`` and ``"fk"``.  FK starts at the inputs of the selected (else
        the first) solution, IK at the pose of the selected (else the first) solution, so the
        selection carries over."""
        if mode not in ("ik", "fk"):
            raise ValueError(f"mode must be 'ik' or 'fk', got {mode!r}")
        if mode == self.mode:
            return
        ref = self._selected or (self.solutions[0] if self.solutions else None)
        if mode == "fk":
            if ref is not None:
                self.inputs = np.array(ref.inputs, dtype=float)
            elif self.inputs is None:
                self.inputs = np.array([leg.from_display(0.5 * sum(input_bounds(self.mech, i)))
                                        for i, leg in enumerate(self.mech.legs)], dtype=float)
        elif ref is not None:
            self.pose = np.array(ref.pose, dtype=float)
        self.mode = mode
        self.tracker = None
        self.notice = ""
        self._bump()

    def set_show(self, show: str) -> None:
        """Which solutions to draw: ``"all"``, ``"stable"``, ``"feasible"`` or ``"selected"``."""
        if show not in ("all", "stable", "feasible", "selected"):
            raise ValueError(f"show must be all, stable, feasible or selected, got {show!r}")
        self.show = show

    # ---- views ------------------------------------------------------------------------------
    def visible(self) -> list[tuple[Any, bool]]:
        """The equilibria to draw, as ``(solution, is_selected)``: all those of the current
        solve that pass the ``show`` filter, or only the tracked one during a drag."""
        if self.stale:
            if self._selected is not None:
                return [(self._selected, True)]
            if self.branch_end is not None:
                return [(self.branch_end, False)]
            if self.result is not None and self.result_request is not None and self.result_request.mode == self.mode:
                return [(s, False) for s in self.result.solutions]  # out of date, drawn at their own poses
            return []
        out = []
        for s in self.solutions:
            sel = s.id == self.selected_id
            if not sel:
                if self.show == "selected":
                    continue
                if self.show == "stable" and s.stable is not True:
                    continue
                if self.show == "feasible":
                    f = self.feasibility.get(s.id)
                    if f is None or not f.feasible:
                        continue
            out.append((s, sel))
        return out

    def feasibility_for(self, s) -> Any | None:
        if s is self._selected and self._selected_feas is not None:
            return self._selected_feas
        return self.feasibility.get(s.id) if not self.stale else None

    def status(self) -> str:
        """One line: how many equilibria, or why there are none, or what is pending."""
        what = "this pose" if self.mode == "ik" else "these inputs"
        if self.stale:
            if self._selected is not None:
                s = self._selected
                st = {True: "stable", False: "unstable", None: "stability undecided"}[s.stable]
                return (f"Tracking #{self.selected_id} (d-modes {s.mode_label}, {st}); release to solve for "
                        "all equilibria")
            head = f"Solving {'IK' if self.mode == 'ik' else 'FK'}..."
            if self.branch_end is None and self.result is not None and self.result_request is not None \
                    and self.result_request.mode == self.mode:
                rq = self.result_request
                where = (rq.target[0], rq.target[1], math.degrees(rq.target[2])) if rq.mode == "ik" else tuple(
                    float(leg.to_display(u)) for u, leg in zip(rq.target, self.mech.legs))
                head += (f" (showing the {len(self.result.solutions)} equilibria at "
                         f"{_fmt_where(self.mech, rq.mode, where)})")
            return head
        if self.result is None:
            return f"No equilibrium here: {self.error}"
        n = len(self.result.solutions)
        if n == 0:
            return f"No equilibrium here ({self.result.message})" if self.result.message else "No equilibrium here"
        ns = sum(1 for s in self.result.solutions if s.stable is True)
        inc = "" if self.result.complete else " (search incomplete)"
        return f"{n} equilibri{'um' if n == 1 else 'a'} at {what}, {ns} stable{inc}"

    def selection_text(self) -> str:
        """One line on the selected equilibrium (or how to select one)."""
        s = self._selected
        if s is None:
            return "Click a rod or a table row to select an equilibrium and follow it." if self.solutions else ""
        st = {True: "stable", False: "unstable", None: "stability undecided"}[s.stable]
        u = ", ".join(f"{v:.4g} {leg.input_unit}" for v, leg in zip(s.inputs_display(), self.mech.legs))
        j = s.jacobian
        dets = "" if j is None else f"; det J_IK {_num(j.det_ik)}, det J_FK {_num(j.det_fk)}"
        f = self.feasibility_for(s)
        fe = "" if f is None else ("; feasible" if f.feasible else "; infeasible: " + "; ".join(f.reasons))
        where = ""
        if self.mode == "fk":
            where = f" at ({s.pose[0]:.4f} m, {s.pose[1]:.4f} m, {math.degrees(s.pose[2]):.2f} deg)"
        return f"Selected #{self.selected_id}{where}: d-modes {s.mode_label}, {st}; inputs ({u}){dets}{fe}"

    def rows(self) -> dict[str, list]:
        """The solution table, one row per listed equilibrium (the tracked one during a drag)."""
        sols = [self._selected] if (self.stale and self._selected is not None) else list(self.solutions)
        cols: dict[str, list] = {k: [] for k in ("id", "modes", "u1", "u2", "u3", "x", "y", "theta", "stable",
                                                 "margin", "det_ik", "det_fk", "feasible", "selected")}
        fill_margins(sols)  # one batch (they are computed on first use)
        for s in sols:
            u = s.inputs_display()
            cols["id"].append(int(s.id))
            cols["modes"].append(s.mode_label)
            for i in range(3):
                cols[f"u{i + 1}"].append(float(u[i]))
            cols["x"].append(float(s.pose[0]))
            cols["y"].append(float(s.pose[1]))
            cols["theta"].append(float(math.degrees(s.pose[2])))
            cols["stable"].append({True: "stable", False: "unstable", None: "undecided"}[s.stable])
            m = s.stability_margin
            cols["margin"].append(_num(m))
            j = s.jacobian
            cols["det_ik"].append(_num(None if j is None else j.det_ik))
            cols["det_fk"].append(_num(None if j is None else j.det_fk))
            f = self.feasibility_for(s)
            cols["feasible"].append("..." if f is None else ("yes" if f.feasible else "no: " + "; ".join(f.reasons)))
            cols["selected"].append(s.id == self.selected_id)
        return cols

    def pick(self, x: float, y: float, tol: float) -> int | None:
        """Id of the drawn equilibrium whose rods pass nearest to ``(x, y)`` (m), if within
        ``tol`` (m)."""
        best, dbest = None, tol
        p = np.array([x, y], dtype=float)
        for s, _ in self.visible():
            for r in s.rods:
                d = _polyline_distance(p, r.shape(60))
                if d < dbest:
                    best, dbest = s.id, d
        return best


def _num(v) -> str:
    if v is None:
        return "-"
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.4g}"


def _polyline_distance(p: np.ndarray, pts: np.ndarray) -> float:
    a, b = pts[:-1], pts[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    q = a + t[:, None] * ab
    return float(np.min(np.hypot(*(q - p).T)))
