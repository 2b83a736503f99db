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

    Attributes
    ----------
    clamp : tuple of 2 floats
        Clamp point, world frame (m).
    clamp_angle : float
        Tangent angle at the clamp, world frame (rad).
    length : float
        Free (undeformed) length of the rod (m).
    base_force : tuple of 2 floats
        n(0): the force the rod (0, L] exerts at its clamp end, world frame (N); the clamp
        applies its opposite.
    base_moment : float
        m(0): the moment the rod exerts at its clamp end (N m), counter-clockwise positive.
    tip : tuple of 2 floats
        Tip position, world frame (m).
    tip_angle : float
        Tangent angle at the tip, world frame (rad).
    tip_force : tuple of 2 floats
        n(L): the force applied ON the rod tip BY the platform, world frame (N).
    tip_moment : float
        m(L): the moment applied on the rod tip by the platform (N m; 0 for a pinned tip).
    energy : float
        Elastic energy (bending, extension and shear) of the rod (J).
    load_potential : float
        Potential ``-int f . p ds`` of the distributed load (J).
    elongation : float
        ``int (v_x - 1) ds``: the change of length by axial strain (m).
    max_axial_strain : float
        Largest ``|v_x - 1|`` along the rod (dimensionless).
    max_shear_strain : float
        Largest ``|v_y|`` along the rod (dimensionless).
    mode : int
        d-mode: inflection points on (0, L] (SPEC §2): sign changes of the bending moment
        strictly inside the rod, plus 1 for a pinned tip.
    steps : int
        Runge–Kutta steps the rod was integrated with (:mod:`flexkin.cosserat.rod`).
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
    id : int or None
        The Kirchhoff solution's id (:attr:`flexkin.Solution.id`, 1-based, the same as in the
        IK/FK table and JSON; its 1-based position in the input when it has none), ``None``
        for a born solution.
    status : {"refined", "fold", "born", "unlisted", "failed"}
        ``"refined"`` (branch reached tau = 1), ``"fold"`` (the branch turned back at a
        fold: the solution merged with another one and does not exist in the refined model),
        ``"born"`` (exists only in the refined model: its branch, followed down in tau, turns at
        a fold instead of reaching the Kirchhoff model), ``"unlisted"`` (found by the fold
        multi-start and connected to a Kirchhoff solution that was not in the input) or
        ``"failed"`` (continuation stalled; ``note`` says where).
    reached : bool
        The refined solution exists (status refined / born / unlisted).
    tau_end : float
        Homotopy parameter tau where the branch ended (dimensionless; 1 when reached, the
        fold's tau for ``"fold"``).
    fold_tau : float or None
        tau of the first fold met (``None`` without fold); for ``"born"`` the birth tau.
    merged_with : int or None
        Id of the input solution this branch met at its fold (``"fold"``); for a born
        solution, the 1-based position in ``born`` of the one forming its pair; ``None`` when
        unknown / not applicable.
    pose : tuple of 3 floats or None
        Refined pose ``(x, y, theta)`` (m, m, rad); ``None`` unless reached.
    inputs : tuple of 3 floats or None
        Refined inputs (SI: m, or rad for revolute legs); ``None`` unless reached.
    kirchhoff_pose, kirchhoff_inputs : tuple of 3 floats or None
        The starting Kirchhoff pose and inputs, same units (``None`` for born).
    position_shift : float or None
        ``|P_refined - P_Kirchhoff|`` (m); ``None`` unless both exist.
    rotation_shift_deg : float or None
        Change of the platform angle theta, refined minus Kirchhoff (deg); ``None`` unless
        both exist.
    input_shift : tuple of 3 floats or None
        Per-leg input change, refined minus Kirchhoff (m, or deg for revolute legs); ``None``
        unless both exist.
    rods : tuple of RefinedRod
        The three rods (empty unless reached).
    stable : bool or None
        Stability with the actuators locked in the refined model; ``None`` when not resolved
        or not computed (``stability_note`` says why).
    stability_margin : float or None
        Smallest eigenvalue of the discretised second variation, Richardson-extrapolated from
        two meshes (dimensionless, :mod:`flexkin.cosserat.stability`).
    stability_error : float or None
        Estimated discretisation error of ``stability_margin`` (same scale).
    stability_index : int or None
        Morse index: the number of negative eigenvalues on the finer mesh.
    stability_note : str
        Why ``stable`` is ``None`` (empty otherwise).
    kirchhoff_stable : bool or None
        The input's Kirchhoff verdict, for comparison.
    residual : float or None
        Scaled max-norm residual of the shooting equations (platform equilibrium, tips on
        the platform, segment matching; dimensionless) at the solution.
    verification_residual : float or None
        The same, re-integrated with twice the Runge–Kutta steps.
    verified : bool
        ``verification_residual <= 1e-8``.
    energy : float or None
        Elastic energy of the three rods (J).
    load_potential : float or None
        Potential of the distributed loads summed over the rods (J).
    continuation_steps : int
        Predictor–corrector steps taken on this branch.
    evaluations : int
        Evaluations of the shooting residual with its Jacobian spent on this branch.
    note : str
        Diagnostics of the branch (a possible branch jump, folds passed, why it failed).
    position : int or None
        0-based position of the Kirchhoff solution in the input (``None`` for born ones);
        backs the deprecated :attr:`index`.
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
    problem : {"ik", "fk"}
        The kinematics problem of the input solutions (pose or inputs held).
    mechanism : Mechanism
        The mechanism.
    load : tuple of 3 floats
        Load wrench ``(Fx, Fy, Mz)`` on the platform at P (N, N, N m).
    gravity : tuple of 2 floats or None
        The gravity vector used, world frame (m/s^2), or ``None``.
    params : tuple of CosseratParams
        Per-leg extension, shear and distributed-load data (SI).
    line_loads : tuple of (float, float)
        Per-leg distributed force at tau = 1, world frame (N/m): weight plus the
        ``distributed_load`` of the params and of the call.
    solutions : tuple of RefinedSolution
        One per input solution, in input order.
    born : tuple of RefinedSolution
        Solutions found by the multi-start around folds (status ``"born"`` / ``"unlisted"``).
    message : str
        One-line summary.
    elapsed : float
        Wall-clock time of the call, s.
    diagnostics : dict
        Counts: ``evaluations`` and ``batched_rounds`` of the shooting kernel,
        ``reruns_for_jumping`` (branches re-run with small steps), ``multistart_starts``, and
        per input solution the Runge–Kutta steps ``rk_steps`` and shooting ``segments`` of
        each rod.
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
