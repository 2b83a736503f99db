"""Following one equilibrium continuously while the pose or the inputs change (interactive use).

A :class:`Tracker` holds one solution and moves it by continuation
(:func:`~flexkin.solve.continuation.continue_ik`), never by re-solving from scratch, so the
same physical branch is followed through d-mode changes.  Each move reports what happened
on the way as :class:`TrackEvent` s, from quantities computed at the two ends of the move:

* ``"mode_change"``: a rod's d-mode changed (followed; not a failure);
* ``"stability_lost"`` / ``"stability_regained"`` / ``"stability_undecided"`` (the closed-form
  verdict at the end of the move; its margin is computed from the previous move's eigenvector);
* ``"ik_singularity"`` / ``"fk_singularity"``: the smooth singularity function ``det A_IK``
  / ``det A_FK`` changed sign;
* ``"infeasible"`` / ``"feasible"``: the feasibility verdict changed (only with ``feasibility=True``);
* ``"branch_end"``: the move failed even in small sub-steps: the branch ends (an IK
  singularity when tracking poses, an FK singularity when tracking inputs); the tracker stays
  at the last point reached.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.validation import as_load, as_triple
from ..results import Solution
from ..system import System
from .continuation import continue_ik
from ..analysis.stability import mechanism_stability
from .finish import build_solutions, rod_modes

__all__ = ["Tracker", "TrackStep", "TrackEvent"]


@dataclass(frozen=True)
class TrackEvent:
    """Something that happened during one move (see the module docstring)."""

    kind: str
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {"kind": self.kind, "detail": self.detail}


@dataclass(frozen=True)
class TrackStep:
    """The outcome of :meth:`Tracker.move_to`.

    Attributes
    ----------
    solution : Solution
        Where the tracker is now (the target, or the last point reached).
    reached : bool
        Whether the target was reached.
    fraction : float
        Fraction of the move achieved (1 when reached).
    events : tuple of TrackEvent
    elapsed : float
        Seconds.
    """

    solution: Solution
    reached: bool
    fraction: float
    events: tuple[TrackEvent, ...] = ()
    elapsed: float = 0.0
    feasibility: Any = field(default=None, repr=False)


class Tracker:
    """Follow one solution of ``mech`` (an IK or FK solution) as its pose or inputs move.

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    solution : Solution
        The equilibrium to follow.
    load : (Fx, Fy, Mz), optional
        Defaults to the mechanism file's load.
    feasibility : bool
        Also check feasibility after every move (``"infeasible"`` / ``"feasible"`` events).
    max_halvings : int
        How many times a failing move is split in two before the branch is declared ended.
    """

    def __init__(self, mech, solution: Solution, load: ArrayLike | None = None, *, feasibility: bool = False,
                 max_halvings: int = 6) -> None:
        self.mech = mech
        self.system = System.from_mechanism(mech)
        self.load = as_load(mech, load)
        self.solution = solution
        self.feasibility = feasibility
        self.max_halvings = int(max_halvings)
        self._pairs = None   # the current solution's lowest eigenvector (its margin's start)
        self._feas = self._check(solution) if feasibility else None

    def _check(self, sol: Solution):
        from ..analysis.feasibility import check_feasibility

        return check_feasibility(self.mech, sol)

    def move_to(self, target: ArrayLike, *, kind: str = "pose") -> TrackStep:
        """Move to a new pose ``(x, y, theta)`` (m, m, rad; ``kind="pose"``) or new inputs (SI;
        ``kind="inputs"``) by continuation, halving the step where it fails."""
        if kind not in ("pose", "inputs"):
            raise ValueError(f"kind must be 'pose' or 'inputs', got {kind!r}")
        t0 = time.perf_counter()
        target = as_triple(target, "target pose" if kind == "pose" else "target inputs")
        lay = self.system.layout
        sl = lay.pose if kind == "pose" else lay.inputs
        x = np.asarray(self.solution.x, dtype=float)[None].copy()
        ch = np.asarray(self.solution.charts, dtype=np.int64)[None].copy()
        start = x[0, sl].copy()
        if kind == "inputs":
            for i, leg in enumerate(self.mech.legs):
                leg.actuator.check_input(float(target[i]), i)
        t, dt, halvings = 0.0, 1.0, 0
        while t < 1.0 - 1e-12:
            dt = min(dt, 1.0 - t)
            x1, c1, ok = continue_ik(self.system, x, ch, (start + (t + dt) * (target - start))[None], self.load,
                                     fixed=kind)
            if ok[0]:
                x, ch, t = x1, c1, t + dt
                dt *= 2.0
            elif halvings < self.max_halvings:
                dt *= 0.5
                halvings += 1
            else:
                break
        # the stability: the closed form, and the margin from the previous eigenvector (afresh at
        # a d-mode change; the discretisation restarts by itself when the carried one fails)
        same = np.array_equal(rod_modes(self.system, x, ch)[0], np.asarray(self.solution.modes))
        st = mechanism_stability(self.system, x, ch, margin=True, guess=self._pairs if same else None)
        self._pairs = st.pairs
        new = build_solutions(self.system, self.mech, x, ch, self.load, stability=st)[0]
        events = self._events(self.solution, new)
        reached = t >= 1.0 - 1e-12
        if not reached:
            what = "an IK singularity" if kind == "pose" else "an FK singularity"
            events.append(TrackEvent("branch_end", f"the tracked branch ends near {what} after {t:.0%} of the move"))
        feas = None
        if self.feasibility:
            feas = self._check(new)
            if self._feas is not None and feas.feasible != self._feas.feasible:
                events.append(TrackEvent("feasible" if feas.feasible else "infeasible",
                                         "; ".join(feas.reasons)))
            self._feas = feas
        self.solution = new
        return TrackStep(new, reached, float(t), tuple(events), time.perf_counter() - t0, feas)

    @staticmethod
    def _events(a: Solution, b: Solution) -> list[TrackEvent]:
        ev: list[TrackEvent] = []
        if a.modes != b.modes:
            ev.append(TrackEvent("mode_change", f"d-modes {a.mode_label} -> {b.mode_label}"))
        if a.stable is True and b.stable is False:
            ev.append(TrackEvent("stability_lost", f"margin {b.stability_margin:.3g}"))
        elif a.stable is False and b.stable is True:
            ev.append(TrackEvent("stability_regained", f"margin {b.stability_margin:.3g}"))
        elif b.stable is None and a.stable is not None:
            ev.append(TrackEvent("stability_undecided", b.stability.note if b.stability else ""))
        if a.jacobian is not None and b.jacobian is not None:
            if np.sign(a.jacobian.sing_ik) != np.sign(b.jacobian.sing_ik):
                ev.append(TrackEvent("ik_singularity", "det J_IK changed sign"))
            if np.sign(a.jacobian.sing_fk) != np.sign(b.jacobian.sing_fk):
                ev.append(TrackEvent("fk_singularity", "det J_FK changed sign"))
        return ev
