"""Result objects of the Cosserat refinement (every field always present; no NaN)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

__all__ = ["RefinedRod", "RefinedSolution", "RefineResult"]


def _deg(a: float | None) -> float | None:
    return None if a is None else float(math.degrees(a))


@dataclass(frozen=True)
class RefinedRod:
    """One rod of a refined equilibrium (SI; SPEC §2 conventions).

    ``base_force``/``base_moment`` are n(0), m(0): the force and moment the rod (0, L] exerts
    at its clamp end (the clamp applies their opposites); ``tip_force``/``tip_moment`` are
    n(L), m(L): applied ON the rod tip BY the platform.  ``energy`` is the elastic energy,
    ``load_potential`` the potential ``-int f . p ds`` of the distributed load, ``elongation``
    ``int (v_x - 1) ds``; the strains are maxima of ``|v_x - 1|`` and ``|v_y|``; ``mode`` the
    d-mode (1 + sign changes of the bending moment inside the rod).
    """

    clamp: tuple[float, float]
    clamp_angle: float
    length: float
    base_force: tuple[float, float]
    base_moment: float
    tip: tuple[float, float]
    tip_angle: float
    tip_force: tuple[float, float]
    tip_moment: float
    energy: float
    load_potential: float
    elongation: float
    max_axial_strain: float
    max_shear_strain: float
    mode: int
    steps: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (angles in degrees)."""
        return {
            "clamp": list(self.clamp), "clamp_angle_deg": _deg(self.clamp_angle), "length": self.length,
            "base_force": list(self.base_force), "base_moment": self.base_moment, "tip": list(self.tip),
            "tip_angle_deg": _deg(self.tip_angle), "tip_force": list(self.tip_force),
            "tip_moment": self.tip_moment, "energy": self.energy, "load_potential": self.load_potential,
            "elongation": self.elongation, "max_axial_strain": self.max_axial_strain,
            "max_shear_strain": self.max_shear_strain, "mode": self.mode,
        }


@dataclass(frozen=True)
class RefinedSolution:
    """The Cosserat counterpart of one Kirchhoff solution (or a solution born at a fold).

    Attributes
    ----------
    id : the Kirchhoff solution's id (:attr:`flexkin.Solution.id`, 1-based, the same as in the
        IK/FK table and JSON; its 1-based position in the input when it has none), ``None``
        for a born solution.
    status : ``"refined"`` (branch reached tau = 1), ``"fold"`` (the branch turned back at a
        fold: the solution merged with another one and does not exist in the refined model),
        ``"born"`` (exists only in the refined model: its branch, followed down in tau, turns at
        a fold instead of reaching the Kirchhoff model), ``"unlisted"`` (found by the fold
        multi-start and connected to a Kirchhoff solution that was not in the input) or
        ``"failed"`` (continuation stalled; ``note`` says where).
    reached : the refined solution exists (status refined / born / unlisted).
    tau_end : tau where the branch ended (1 when reached; the fold's tau for ``"fold"``).
    fold_tau : tau of the first fold met (``None`` without fold); for ``"born"`` the birth tau.
    merged_with : id of the input solution this branch met at its fold (``"fold"``); for a born
        solution, the 1-based position in ``born`` of the one forming its pair; ``None`` when
        unknown / not applicable.
    pose, inputs : refined pose (m, m, rad) and inputs (SI); ``None`` unless reached.
    kirchhoff_pose, kirchhoff_inputs : the starting Kirchhoff values (``None`` for born).
    position_shift : |P_refined - P_Kirchhoff| (m); rotation_shift_deg : theta change (deg);
    input_shift : per-leg input change (m, or deg for revolute legs).  ``None`` unless both exist.
    rods : three :class:`RefinedRod` (empty unless reached).
    stable : tri-state stability with the actuators locked in the refined model;
    stability_margin : smallest eigenvalue of the discretised second variation (dimensionless,
    :mod:`flexkin.cosserat.stability`), stability_error its discretisation error,
    stability_index the Morse index, stability_note why ``stable`` is None.
    kirchhoff_stable : the input's Kirchhoff verdict, for comparison.
    residual : scaled max-norm residual of the 12 equations at the solution;
    verification_residual : the same, re-integrated with twice the Runge–Kutta steps;
    verified : ``verification_residual <= 1e-8``.
    energy, load_potential : totals over the rods (J).
    continuation_steps, evaluations : work done on this branch.  note : diagnostics.
    """

    id: int | None
    status: str
    reached: bool
    tau_end: float
    fold_tau: float | None
    merged_with: int | None
    pose: tuple[float, float, float] | None
    inputs: tuple[float, float, float] | None
    kirchhoff_pose: tuple[float, float, float] | None
    kirchhoff_inputs: tuple[float, float, float] | None
    position_shift: float | None
    rotation_shift_deg: float | None
    input_shift: tuple[float, float, float] | None
    rods: tuple[RefinedRod, ...]
    stable: bool | None
    stability_margin: float | None
    stability_error: float | None
    stability_index: int | None
    stability_note: str
    kirchhoff_stable: bool | None
    residual: float | None
    verification_residual: float | None
    verified: bool
    energy: float | None
    load_potential: float | None
    continuation_steps: int
    evaluations: int
    note: str = ""
    position: int | None = field(default=None, repr=False)

    @property
    def index(self) -> int | None:
        """Deprecated (flexkin 0.3): the 0-based position of the Kirchhoff solution in the input;
        use :attr:`id`, the solution's 1-based id."""
        import warnings

        warnings.warn("RefinedSolution.index is deprecated and will be removed in flexkin 0.4: use .id, the "
                      "Kirchhoff solution's 1-based id", FutureWarning, stacklevel=2)
        return self.position

    @property
    def modes(self) -> tuple[int, ...]:
        """d-mode of each rod in the refined model (empty unless reached)."""
        return tuple(r.mode for r in self.rods)

    def to_dict(self, legs: tuple[Any, ...]) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4 units: degrees for angles and revolute inputs).

        Parameters
        ----------
        legs : tuple of Leg
            The mechanism's legs (their ``to_display`` gives the inputs' display units).
        """

        def inputs(u):
            if u is None:
                return None
            return [float(leg.to_display(x)) for x, leg in zip(u, legs)]

        def pose(p):
            return None if p is None else [p[0], p[1], float(math.degrees(p[2]))]

        return {
            "id": self.id, "status": self.status, "reached": self.reached, "tau_end": self.tau_end,
            "fold_tau": self.fold_tau, "merged_with": self.merged_with, "pose": pose(self.pose),
            "inputs": inputs(self.inputs), "kirchhoff_pose": pose(self.kirchhoff_pose),
            "kirchhoff_inputs": inputs(self.kirchhoff_inputs), "position_shift": self.position_shift,
            "rotation_shift_deg": self.rotation_shift_deg, "input_shift": None if self.input_shift is None
            else list(self.input_shift), "modes": list(self.modes), "stable": self.stable,
            "stability_margin": self.stability_margin, "stability_error": self.stability_error,
            "stability_index": self.stability_index, "stability_note": self.stability_note,
            "kirchhoff_stable": self.kirchhoff_stable, "residual": self.residual,
            "verification_residual": self.verification_residual, "verified": self.verified,
            "energy": self.energy, "load_potential": self.load_potential,
            "continuation_steps": self.continuation_steps, "evaluations": self.evaluations,
            "rods": [r.to_dict() for r in self.rods], "note": self.note,
        }


@dataclass(frozen=True)
class RefineResult:
    """All refined solutions: one per input Kirchhoff solution, plus those born at folds.

    Attributes
    ----------
    problem : ``"ik"`` or ``"fk"``.  mechanism : the mechanism.  load : (Fx, Fy, Mz).
    gravity : the gravity vector used (m/s^2) or ``None``.  params : per-leg CosseratParams.
    line_loads : per-leg distributed force (N/m) at tau = 1.
    solutions : one :class:`RefinedSolution` per input solution, in input order.
    born : solutions found by the multi-start around folds (status ``"born"`` / ``"unlisted"``).
    message : one line summary.  elapsed : seconds.  diagnostics : counts.
    """

    problem: str
    mechanism: Any
    load: tuple[float, float, float]
    gravity: tuple[float, float] | None
    params: tuple[Any, ...]
    line_loads: tuple[tuple[float, float], ...]
    solutions: tuple[RefinedSolution, ...]
    born: tuple[RefinedSolution, ...]
    message: str
    elapsed: float
    diagnostics: dict[str, Any] = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return len(self.solutions)

    def __iter__(self):
        return iter(self.solutions)

    @property
    def refined(self) -> tuple[RefinedSolution, ...]:
        """Every solution that exists in the refined model (reached inputs, then born ones)."""
        return tuple(s for s in self.solutions + self.born if s.reached)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        legs = tuple(self.mechanism.legs)
        return {
            "problem": "refine-" + self.problem, "mechanism": getattr(self.mechanism, "name", ""),
            "load": list(self.load), "gravity": None if self.gravity is None else list(self.gravity),
            "params": [{"EA": _fin(p.EA), "GA": _fin(p.GA), "shear_coefficient": p.shear_coefficient,
                        "mass_per_length": p.mass_per_length, "distributed_load": list(p.distributed_load)}
                       for p in self.params],
            "line_loads": [list(f) for f in self.line_loads],
            "solutions": [s.to_dict(legs) for s in self.solutions],
            "born": [s.to_dict(legs) for s in self.born],
            "message": self.message, "elapsed": self.elapsed,
            "diagnostics": dict(self.diagnostics),
        }


def _fin(x: float) -> float | None:
    """JSON has no infinity: an infinite stiffness (rigid) is written as null."""
    return None if math.isinf(x) else x
