"""Result objects shared by the inverse and forward kinematics."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np


from ..rod.state import RodState

__all__ = ["Solution", "KinematicsResult"]


@dataclass(frozen=True)
class Solution:
    """One equilibrium of the mechanism.

    Attributes
    ----------
    pose : (x, y, theta) of the platform reference point P (m, m, rad).
    inputs : actuator inputs (SI: m for prismatic and length legs, rad for revolute legs).
    modes : d-mode of each rod.
    rods : the three :class:`~flexkin.rod.state.RodState`.
    residual : infinity norm of the scaled residual of the 9 equations after refinement.
    stable : stability verdict with the actuators locked (:mod:`flexkin.kinematics.stability`).
    stability_margin : positive iff stable: the smallest eigenvalue of the dimensionless reduced
        Hessian of the potential over the pose when every rod is stable with its tip pinned,
        otherwise ``sigma/L - 1 < 0`` for the first conjugate point ``sigma`` of a buckled rod.
    stability_index : number of independent unstable directions (Morse index; 0 iff stable).
    jacobian : dict with ``det_ik``, ``det_fk``, ``cond`` and the matrices ``J_IK``, ``J_FK``
        of Eq. (16) (dimensionless, :mod:`flexkin.kinematics.jacobian`); ``None`` entries at
        singularities.
    """

    pose: tuple[float, float, float]
    inputs: tuple[float, float, float]
    modes: tuple[int, int, int]
    rods: tuple[RodState, RodState, RodState]
    residual: float
    zrod: tuple[float, ...] = field(repr=False, default=())
    stable: bool | None = None
    stability_margin: float | None = None
    stability_index: int | None = None
    jacobian: dict[str, Any] | None = None

    @property
    def energy(self) -> float:
        """Total bending energy of the three rods (J)."""
        return float(sum(r.energy for r in self.rods))

    @property
    def mode_label(self) -> str:
        """d-modes as a string, e.g. ``"112"``."""
        return "".join(str(q) for q in self.modes)

    def inputs_display(self, kinds: tuple[str, ...]) -> list[float]:
        """Inputs in display units (m, or degrees for revolute legs)."""
        return [float(np.degrees(u)) if k == "revolute" else float(u) for u, k in zip(self.inputs, kinds)]

    def to_dict(self, kinds: tuple[str, ...]) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4)."""
        return {
            "pose": [self.pose[0], self.pose[1], float(np.degrees(self.pose[2]))],
            "inputs": self.inputs_display(kinds),
            "modes": list(self.modes),
            "stable": self.stable,
            "stability_margin": self.stability_margin,
            "stability_index": self.stability_index,
            "residual": self.residual,
            "energy": self.energy,
            "rods": [r.to_dict() for r in self.rods],
            "jacobian": self.jacobian,
        }


@dataclass(frozen=True)
class KinematicsResult:
    """All equilibria found by an inverse or forward kinematics call.

    Attributes
    ----------
    problem : ``"ik"`` or ``"fk"``.
    mechanism : the :class:`~flexkin.mechanism.Mechanism`.
    given : the pose (IK; rad) or the inputs (FK; SI) that were imposed.
    load : (Fx, Fy, Mz).
    max_mode : largest d-mode searched.
    solutions : tuple of :class:`Solution`, sorted by (modes, energy, inputs/pose).
    complete : ``False`` when the search was cut short (time budget).
    message : one line explaining an empty result.
    elapsed : seconds.
    diagnostics : counts of candidates, Newton failures, etc.
    """

    problem: str
    mechanism: Any
    given: tuple[float, float, float]
    load: tuple[float, float, float]
    max_mode: int
    solutions: tuple[Solution, ...]
    complete: bool = True
    message: str = ""
    elapsed: float = 0.0
    diagnostics: dict[str, Any] = field(default_factory=dict, repr=False)
    curves: Any = field(default=None, repr=False)
    _cache: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def __len__(self) -> int:
        return len(self.solutions)

    def __iter__(self):
        return iter(self.solutions)

    @property
    def kinds(self) -> tuple[str, ...]:
        """Actuation of each leg."""
        return tuple(leg.actuation for leg in self.mechanism.legs)

    def by_modes(self) -> dict[str, int]:
        """Number of solutions per d-mode combination, e.g. ``{"111": 5, "222": 2}``."""
        out: dict[str, int] = {}
        for s in self.solutions:
            out[s.mode_label] = out.get(s.mode_label, 0) + 1
        return out

    def feasibility(self) -> tuple[Any, ...]:
        """Feasibility of every solution (:func:`~flexkin.kinematics.feasibility.check_feasibility`:
        collisions, self-intersection, bending strain, input ranges), computed once."""
        if "feasibility" not in self._cache:
            from .feasibility import check_solutions

            self._cache["feasibility"] = check_solutions(self.mechanism, self.solutions)
        return self._cache["feasibility"]

    def select(self, stable_only: bool = False, feasible_only: bool = False) -> "KinematicsResult":
        """A copy keeping only the stable and/or feasible solutions (order preserved)."""
        keep = [True] * len(self.solutions)
        if stable_only:
            keep = [k and bool(s.stable) for k, s in zip(keep, self.solutions)]
        if feasible_only:
            keep = [k and f.feasible for k, f in zip(keep, self.feasibility())]
        sols = tuple(s for k, s in zip(keep, self.solutions) if k)
        out = dataclasses.replace(self, solutions=sols, _cache={})
        if "feasibility" in self._cache:
            out._cache["feasibility"] = tuple(f for k, f in zip(keep, self._cache["feasibility"]) if k)
        if not sols and self.solutions:
            what = " and ".join(w for w, on in (("stable", stable_only), ("feasible", feasible_only)) if on)
            out = dataclasses.replace(out, message=f"none of the {len(self.solutions)} equilibria is {what}")
        return out

    def to_dict(self) -> dict[str, Any]:
        """The SPEC §4 JSON object (with each solution's ``feasible`` verdict and reasons)."""
        d: dict[str, Any] = {
            "problem": self.problem,
            "mechanism": self.mechanism.name,
            "load": list(self.load),
            "max_mode": self.max_mode,
        }
        if self.problem == "ik":
            d["pose"] = [self.given[0], self.given[1], float(np.degrees(self.given[2]))]
        else:
            d["inputs"] = [float(np.degrees(u)) if k == "revolute" else float(u)
                           for u, k in zip(self.given, self.kinds)]
        d["complete"] = self.complete
        d["message"] = self.message
        sols = []
        for s, f in zip(self.solutions, self.feasibility()):
            e = s.to_dict(self.kinds)
            e["feasible"] = f.feasible
            e["feasibility"] = f.to_dict()
            sols.append(e)
        d["solutions"] = sols
        return d

    def table(self) -> str:
        """Human-readable table of the solutions."""
        units = ["deg" if k == "revolute" else "m" for k in self.kinds]
        head = (f"{'#':>3} {'modes':>5} {'x [m]':>10} {'y [m]':>10} {'th [deg]':>9} "
                + " ".join(f"{'u' + str(i + 1) + ' [' + u + ']':>11}" for i, u in enumerate(units))
                + f" {'energy [J]':>11} {'stable':>6} {'residual':>9}")
        lines = [head, "-" * len(head)]
        for i, s in enumerate(self.solutions, 1):
            u = s.inputs_display(self.kinds)
            st = "-" if s.stable is None else ("yes" if s.stable else "no")
            lines.append(
                f"{i:>3} {s.mode_label:>5} {s.pose[0]:>10.5f} {s.pose[1]:>10.5f} {np.degrees(s.pose[2]):>9.3f} "
                + " ".join(f"{v:>11.5f}" for v in u)
                + f" {s.energy:>11.4e} {st:>6} {s.residual:>9.1e}"
            )
        return "\n".join(lines)

    def plot(self, path: str | None = None, **kwargs: Any):
        """One panel per solution with the deformed rods (paper Figs. 10–16)."""
        from ..plot.solutions import plot_solutions

        return plot_solutions(self, path=path, **kwargs)
