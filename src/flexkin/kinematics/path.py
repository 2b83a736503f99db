"""Following one IK solution along a straight path of poses; singularities and stability on the way.

The path ``x(t) = (1 - t) x_from + t x_to``, ``t`` in [0, 1], is sampled at ``steps + 1``
points; between samples the solution is continued (:func:`continue_ik`) with steps halved
on failure, down to 1/64 of the sample spacing.  Where even those fail the branch ends:
an **IK singularity** (the solution folds back; typically the workspace boundary).  Along
the branch, sign changes of the smooth singularity functions ``det A_IK``, ``det A_FK``
(:mod:`flexkin.kinematics.jacobian`) and changes of the stability verdict are reported as
events located between two samples.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..rod.closed_form import mode_of
from .continuation import continue_ik
from .ik import _as_load, _as_triple, _check_budget, _check_mode, ik
from .jacobian import kinematic_jacobians
from .results import Solution
from .stability import mechanism_stability
from .system import MechArrays

__all__ = ["follow_path", "PathResult", "PathEvent"]

#: smallest sub-step, as a fraction of the sample spacing
MIN_SUBSTEP = 1.0 / 64


@dataclass(frozen=True)
class PathEvent:
    """Something that happens between two samples ``t_lo < t <= t_hi`` of the path.

    ``kind`` is one of ``"ik_singularity"`` (det J_IK changes sign), ``"fk_singularity"``
    (det J_FK changes sign), ``"stability_lost"``, ``"stability_regained"``,
    ``"mode_change"`` (followed, not a failure) and ``"continuation_failed"`` (the branch
    ends: IK singularity).
    """

    kind: str
    t_lo: float
    t_hi: float
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "t_lo": self.t_lo, "t_hi": self.t_hi, "detail": self.detail}


@dataclass(frozen=True)
class PathResult:
    """One IK solution followed along a straight path of poses.

    Array attributes have one row per reached sample: ``t`` (k,), ``poses`` (k, 3) (rad),
    ``inputs`` (k, 3) (SI, continuous), ``modes`` (k, 3), ``stable`` (k,), ``margin`` (k,),
    ``det_ik``, ``det_fk``, ``cond`` (k,) (Eq. 16, dimensionless; non-finite at
    singularities), ``sing_ik``, ``sing_fk`` (k,) the smooth singularity functions.
    ``complete`` is ``True`` when the end of the path was reached.
    """

    mechanism: Any
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    load: tuple[float, float, float]
    t: NDArray[np.float64]
    poses: NDArray[np.float64]
    inputs: NDArray[np.float64]
    modes: NDArray[np.int64]
    stable: NDArray[np.bool_]
    margin: NDArray[np.float64]
    det_ik: NDArray[np.float64]
    det_fk: NDArray[np.float64]
    cond: NDArray[np.float64]
    sing_ik: NDArray[np.float64]
    sing_fk: NDArray[np.float64]
    events: tuple[PathEvent, ...]
    complete: bool
    message: str = ""
    start_solution: Solution | None = field(default=None, repr=False)
    elapsed: float = 0.0

    @property
    def kinds(self) -> tuple[str, ...]:
        return tuple(leg.actuation for leg in self.mechanism.legs)

    def inputs_display(self) -> NDArray[np.float64]:
        """Inputs in display units (m, degrees for revolute legs)."""
        out = self.inputs.copy()
        for i, k in enumerate(self.kinds):
            if k == "revolute":
                out[:, i] = np.degrees(out[:, i])
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict; non-finite numbers are ``None``."""
        def num(v):
            return float(v) if np.isfinite(v) else None

        pts = []
        u = self.inputs_display()
        for j in range(len(self.t)):
            pts.append({"t": float(self.t[j]),
                        "pose": [float(self.poses[j, 0]), float(self.poses[j, 1]), float(np.degrees(self.poses[j, 2]))],
                        "inputs": [float(v) for v in u[j]], "modes": [int(q) for q in self.modes[j]],
                        "stable": bool(self.stable[j]), "stability_margin": float(self.margin[j]),
                        "jacobian": {"det_ik": num(self.det_ik[j]), "det_fk": num(self.det_fk[j]),
                                     "cond": num(self.cond[j]), "sing_ik": float(self.sing_ik[j]),
                                     "sing_fk": float(self.sing_fk[j])}})
        return {"problem": "path", "mechanism": self.mechanism.name, "load": list(self.load),
                "from": [self.start[0], self.start[1], float(np.degrees(self.start[2]))],
                "to": [self.end[0], self.end[1], float(np.degrees(self.end[2]))],
                "complete": self.complete, "message": self.message,
                "events": [e.to_dict() for e in self.events], "points": pts}

    def table(self) -> str:
        """Human-readable table of the samples, then the events."""
        units = ["deg" if k == "revolute" else "m" for k in self.kinds]
        head = (f"{'t':>6} {'modes':>5} " + " ".join(f"{'u' + str(i + 1) + ' [' + un + ']':>11}" for i, un in enumerate(units))
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
        """Inputs, Jacobian determinants and stability margin against the path parameter."""
        from ..plot.path import plot_path

        return plot_path(self, path=path, **kwargs)


def _pose_at(a: NDArray, b: NDArray, t: float) -> NDArray:
    return (1.0 - t) * a + t * b


def follow_path(mech, start: ArrayLike, end: ArrayLike, steps: int = 50, load: ArrayLike | None = None,
                solution: int | Solution | None = None, max_mode: int = 2,
                time_budget: float | None = None) -> PathResult:
    """Follow one IK solution from pose ``start`` to pose ``end`` (m, m, rad).

    Parameters
    ----------
    mech : Mechanism
    start, end : (x, y, theta)
        End poses of the straight path (theta in radians).
    steps : int
        Number of path intervals (samples at ``t = j / steps``).
    load : (Fx, Fy, Mz), optional
        Defaults to the mechanism file's load.
    solution : int or Solution, optional
        The IK solution at ``start`` to follow: an index into ``ik(mech, start)`` or a
        :class:`Solution`.  Default: the first stable one (else the first one).
    max_mode : int
        Passed to the IK at ``start`` when ``solution`` is not a :class:`Solution`.
    time_budget : float, optional
        Seconds; when they run out the samples reached so far are returned with
        ``complete = False`` and a message.

    Returns
    -------
    PathResult
        ``complete`` is ``False`` when the branch ended before ``end`` (then the last event
        is ``"continuation_failed"``).
    """
    t0 = time.perf_counter()
    deadline = None if time_budget is None else t0 + _check_budget(time_budget)
    a = _as_triple(start, "start pose (x, y, theta)")
    b = _as_triple(end, "end pose (x, y, theta)")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 1 <= steps <= 100000:
        raise ValueError(f"steps must be an integer between 1 and 100000, got {steps!r}")
    w = _as_load(mech, load)
    m = MechArrays.from_mechanism(mech)
    if isinstance(solution, Solution):
        sol = solution
    else:
        res = ik(mech, a, load=w, max_mode=_check_mode(max_mode))
        if not res.solutions:
            return _empty(mech, a, b, w, f"no IK solution at the start pose: {res.message}", t0)
        if solution is None:
            sol = next((s for s in res.solutions if s.stable), res.solutions[0])
        else:
            if not 0 <= int(solution) < len(res.solutions):
                raise ValueError(f"solution index {solution} out of range: the start pose has "
                                 f"{len(res.solutions)} IK solutions (0..{len(res.solutions) - 1})")
            sol = res.solutions[int(solution)]
    x = np.concatenate([sol.zrod, sol.inputs])[None]
    ts, xs = [0.0], [x[0]]
    t, h = 0.0, 1.0 / steps
    failed_at = None
    bridged: list[PathEvent] = []
    j = 0
    timed_out = False
    while j < steps:
        if deadline is not None and time.perf_counter() > deadline:
            timed_out = True
            break
        j += 1
        if j / steps <= t + 1e-15:
            continue
        target = j / steps
        dt = target - t
        while t < target - 1e-15:
            dt = min(dt, target - t)
            x1, ok = continue_ik(m, x, _pose_at(a, b, t)[None], _pose_at(a, b, t + dt)[None], w)
            if ok[0]:
                x, t = x1, t + dt
                dt = min(2 * dt, h)
            elif dt > MIN_SUBSTEP * h * 1.0001:
                dt *= 0.5
            else:
                failed_at = t
                break
        if failed_at is not None:
            # a rod passing straight under tension sits on the seam of the elliptic chart
            # (|k| -> 1): bridge it with the full IK at the next samples, if a solution there
            # continues the branch (see _bridge); otherwise the branch has really ended
            jump = _bridge(mech, m, x[0], _pose_at(a, b, t), a, b, j, steps, w, max_mode)
            if jump is None:
                break
            j_new, x_new = jump
            bridged.append(PathEvent("chart_seam", float(ts[-1]), j_new / steps,
                                     "a rod passes straight under tension (|k| = 1): samples inside were "
                                     "bridged by the full IK"))
            x, t, failed_at = x_new[None], j_new / steps, None
            ts.append(t)
            xs.append(x[0].copy())
            continue
        ts.append(target)
        xs.append(x[0].copy())
    X = np.array(xs)
    T = np.array(ts)
    P = np.array([_pose_at(a, b, tt) for tt in T])
    st = mechanism_stability(m, X[:, :6], P, X[:, 6:])
    jac = kinematic_jacobians(m, X[:, :6], P, X[:, 6:])
    modes = mode_of(X[:, 1:6:2])
    events = sorted(_events(T, modes, st.stable, jac.sing_ik, jac.sing_fk) + bridged, key=lambda e: e.t_lo)
    msg = ""
    if failed_at is not None:
        t_hi = min(T[-1] + h, 1.0)
        events.append(PathEvent("continuation_failed", float(T[-1]), float(t_hi),
                                f"the branch ends near t = {failed_at:.4f} (IK singularity: no nearby solution "
                                f"beyond it)"))
        msg = f"continuation failed near t = {failed_at:.4f}: IK singularity (the solution branch folds back)"
    if timed_out:
        msg = f"time budget exhausted at t = {T[-1]:.4f}"
    return PathResult(mech, tuple(map(float, a)), tuple(map(float, b)), tuple(map(float, w)), T, P, X[:, 6:],
                      modes, st.stable, st.margin, jac.det_ik, jac.det_fk, jac.cond, jac.sing_ik, jac.sing_fk,
                      tuple(events), failed_at is None and not timed_out, msg, sol, time.perf_counter() - t0)


def _near_seam(x: NDArray) -> bool:
    """Whether a rod is close to the straight-under-tension seam of the chart (|v| large)."""
    return bool(np.any(np.abs(x[0:6:2]) > 4.0))


def _bridge(mech, m: MechArrays, x: NDArray, pose: NDArray, a: NDArray, b: NDArray, j: int, steps: int,
            w: NDArray, max_mode: int) -> tuple[int, NDArray] | None:
    """Continue the branch across the chart seam by the full IK at the next samples.

    The candidate at sample ``j'`` (up to 3 samples ahead) must have the same d-modes and
    inputs within a quarter of the predicted change (linear extrapolation with J_FK) of the
    prediction, so a bridge never lands on another branch.
    """
    if not _near_seam(x):
        return None
    jac = kinematic_jacobians(m, x[None, :6], pose[None], x[None, 6:])
    if not np.all(np.isfinite(jac.J_FK)):
        return None
    su = np.array([1.0 if k == 1 else m.L_ref for k in m.kind])
    sx = np.array([m.L_ref, m.L_ref, 1.0])
    modes0 = mode_of(x[1:6:2])
    for jj in range(j, min(j + 3, steps) + 1):
        p1 = _pose_at(a, b, jj / steps)
        du = jac.J_FK[0] @ ((p1 - pose) / sx)
        pred = x[6:] / su + du
        res = ik(mech, p1, load=w, max_mode=max(max_mode, int(modes0.max())))
        best, dist = None, np.inf
        for s in res.solutions:
            if tuple(s.modes) != tuple(modes0):
                continue
            d = np.max(np.abs(_unwrap(np.array(s.inputs), x[6:], m) / su - pred))
            if d < dist:
                best, dist = s, d
        if best is not None and dist <= 0.25 * np.max(np.abs(du)) + 1e-6:
            u = _unwrap(np.array(best.inputs), x[6:], m)
            return jj, np.concatenate([best.zrod, u])
    return None


def _unwrap(u: NDArray, ref: NDArray, m: MechArrays) -> NDArray:
    """Revolute inputs shifted by multiples of 2 pi to be closest to ``ref``."""
    out = u.copy()
    rev = m.kind == 1
    out[rev] = ref[rev] + (u[rev] - ref[rev] + np.pi) % (2 * np.pi) - np.pi
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


def _empty(mech, a, b, w, msg, t0) -> PathResult:
    e3 = np.zeros((0, 3))
    e = np.zeros(0)
    return PathResult(mech, tuple(map(float, a)), tuple(map(float, b)), tuple(map(float, w)), e, e3, e3,
                      np.zeros((0, 3), np.int64), np.zeros(0, bool), e, e, e, e, e, e, (), False, msg, None,
                      time.perf_counter() - t0)




