"""Result objects of every solver: one base class, one :class:`Solution`.

Every solver returns a frozen :class:`Result` with ``solutions``, ``complete``, ``message``,
``elapsed``, typed ``diagnostics``, ``to_dict()`` (the SPEC §4 JSON contract) and
``plot()``.  "No solution" is an empty result with a ``message``; solvers never print.

A :class:`Solution` holds arrays and knows its mechanism, so ``to_dict()`` needs no
arguments.  Units inside are SI and radians; ``to_dict`` converts angles to degrees.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterator

import numpy as np
from numpy.typing import NDArray

from .core.jsonable import finite_or_none

if TYPE_CHECKING:
    from .analysis.jacobian import Jacobians
    from .analysis.stability import Stability
    from .analysis.indices import Indices
    from .rod.state import RodState

__all__ = ["Stability", "Jacobians", "Solution", "Result", "KinematicsResult", "IKDiagnostics",
           "FKDiagnostics", "finite_or_none", "fill_margins"]

#: names defined in a lower layer and re-exported here for users, imported on first use (PEP 562)
#: so that ``import flexkin.results`` stays cheap (the analysis modules load the compiled kernels)
_REEXPORTED = {"Stability": "flexkin.analysis.stability", "Jacobians": "flexkin.analysis.jacobian"}


def __getattr__(name: str) -> Any:
    if name in _REEXPORTED:
        import importlib

        value = getattr(importlib.import_module(_REEXPORTED[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'flexkin.results' has no attribute {name!r}")


@dataclass(frozen=True, eq=False)
class Solution:
    """One equilibrium of the mechanism.

    Attributes
    ----------
    mechanism : Mechanism
        The mechanism this is an equilibrium of.
    pose : tuple of 3 floats
        ``(x, y, theta)`` of the platform reference point P (m, m, rad).
    inputs : tuple of 3 floats
        Actuator inputs (SI: m for prismatic and length legs, rad for revolute legs).
    modes : tuple of int
        d-mode of each rod (SPEC §2).
    rods : tuple of RodState
        The three rods in the world frame.
    x : ndarray
        The equation system's unknowns at this solution (:class:`flexkin.system.Layout`).
    charts : ndarray (3,)
        The rods' charts (:mod:`flexkin.rod.kernels`).
    residual : float
        Infinity norm of the scaled residual after refinement (dimensionless: the equations
        scaled to O(1) as in :mod:`flexkin.system`).
    stability : Stability or None
        Stability with the actuators locked (paper §4.3); ``None`` if not computed.
    jacobian : Jacobians or None
        Kinematic Jacobians and singularity measures at the solution (Eq. 16); ``None`` if not
        computed.
    verified : bool or None
        Independent a-posteriori check (:mod:`flexkin.analysis.verify`); ``None`` if not run.
    condition : float or None
        Estimated condition number of the Newton system at the solution.
    verify_error : float or None
        The largest scaled residual of that check (dimensionless: positions in ``L_ref``,
        angles in rad, forces in ``F_ref``, moments in ``F_ref L_ref``; ``inf`` when an
        integration failed); ``verified`` requires it at most
        :data:`flexkin.analysis.verify.VERIFY_TOL`.  ``None`` if not run.
    id : int
        1-based number of the solution in its result, the same in tables, JSON, figures and
        the ``path --solution`` option.
    """

    mechanism: Any = field(repr=False)
    pose: tuple[float, float, float]
    inputs: tuple[float, float, float]
    modes: tuple[int, ...]
    rods: tuple[RodState, ...]
    x: NDArray[np.float64] = field(repr=False)
    charts: NDArray[np.int64] = field(repr=False)
    residual: float = 0.0
    stability: Stability | None = None
    jacobian: Jacobians | None = field(default=None, repr=False)
    verified: bool | None = None
    condition: float | None = None
    verify_error: float | None = field(default=None, repr=False)
    id: int = 0

    # ---- conveniences --------------------------------------------------------------------
    @property
    def stable(self) -> bool | None:
        """Stability verdict (``None``: undecided)."""
        return None if self.stability is None else self.stability.stable

    @property
    def stability_margin(self) -> float | None:
        """Smallest eigenvalue of the dimensionless second variation (computed on first use)."""
        if self.stability is None:
            return None
        if np.isnan(self.stability.margin):
            fill_margins([self])
        return self.stability.margin

    @property
    def stability_index(self) -> int | None:
        """Number of unstable directions, where resolved."""
        return None if self.stability is None else self.stability.index

    @property
    def zrod(self) -> NDArray[np.float64]:
        """The rods' chart coordinates (the leading columns of :attr:`x`)."""
        return self.x[: len(self.x) - 6]

    @property
    def energy(self) -> float:
        """Total bending energy of the three rods (J)."""
        return float(sum(r.energy for r in self.rods))

    @property
    def mode_label(self) -> str:
        """d-modes as a string, e.g. ``"112"``."""
        return "".join(str(q) for q in self.modes)

    @functools.cached_property
    def indices(self) -> "Indices":
        """Performance indices (output stiffness and compliance, velocity ellipse, condition
        number, peak strain; :mod:`flexkin.analysis.indices`), computed once, on demand."""
        from .analysis.indices import performance_indices

        return performance_indices([self])[0]

    def inputs_display(self) -> list[float]:
        """Inputs in display units (m, or degrees for revolute legs)."""
        return [float(leg.to_display(u)) for u, leg in zip(self.inputs, self.mechanism.legs)]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4)."""
        st = self.stability
        d: dict[str, Any] = {
            "id": self.id,
            "pose": [float(self.pose[0]), float(self.pose[1]), float(np.degrees(self.pose[2]))],
            "inputs": self.inputs_display(),
            "modes": list(self.modes),
            "stable": None if st is None else st.stable,
            "stability_margin": None if st is None else finite_or_none(self.stability_margin),
            "stability_index": None if st is None else st.index,
        }
        if st is not None and st.note:
            d["stability_note"] = st.note
        d.update({
            "residual": float(self.residual),
            "verified": self.verified,
            "condition": finite_or_none(self.condition),
            "energy": self.energy,
            "rods": [r.to_dict() for r in self.rods],
            "jacobian": None if self.jacobian is None else self.jacobian.to_dict(),
            "indices": self.indices.to_dict(),
        })
        return d


def fill_margins(solutions: Any) -> None:
    """Compute the stability margins the solutions do not have yet, in one batch per
    mechanism (the discretised second variation, :mod:`flexkin.analysis.stability`), into their
    :class:`Stability` (a cache: the margin of an equilibrium was always defined, it is only
    computed on demand).

    Parameters
    ----------
    solutions : sequence of Solution
        Solutions, possibly of several mechanisms.
    """
    todo = [s for s in solutions if s.stability is not None and np.isnan(s.stability.margin)
            and s.mechanism is not None]
    if not todo:
        return
    from .analysis.stability import solution_margins
    from .system import System

    groups: dict[int, list[Solution]] = {}
    for s in todo:
        groups.setdefault(id(s.mechanism), []).append(s)
    for group in groups.values():
        system = System.from_mechanism(group[0].mechanism)
        index = np.array([-1 if s.stability.index is None else s.stability.index for s in group])
        mu, res = solution_margins(system, np.array([s.x for s in group]), np.array([s.charts for s in group]), index)
        for s, m, r in zip(group, mu, res):
            object.__setattr__(s, "stability", dataclasses.replace(s.stability, margin=float(m), resolution=float(r)))


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class IKDiagnostics:
    """What the inverse kinematics did: curve branches per leg, equilibrium candidates, Newton
    convergences, whether the global search completed, the size of a singular continuum
    (0 when none) and the equilibria found beyond the numerical scope and not reported (with a
    pinned rod beyond it; among them, with a rod near straight under tension beyond it, which
    makes the result incomplete), and ``force_limit``: the curve polylines of clamped legs
    stopped at the search's force limit, which makes the result incomplete."""

    branches: tuple[int, ...] = ()
    candidates: int = 0
    converged: int = 0
    search_complete: bool = True
    continuum: int = 0
    out_of_scope: int = 0
    out_of_scope_taut: int = 0
    force_limit: int = 0


@dataclass(frozen=True)
class FKDiagnostics:
    """What the forward kinematics did: starting points from the global search, Newton
    convergences, whether the search completed, node triples (branch-and-bound, all legs
    pinned) or rod combinations (pose lattice, any leg clamped) examined, singular continuum,
    the pose lattice's spacing (``lattice_h`` in m and ``lattice_n_theta`` orientations per
    turn; 0 for the branch-and-bound) and the equilibria found beyond the numerical scope and not
    reported (as in :class:`IKDiagnostics`); ``force_limit`` is 1 when a clamped leg's rods
    reach the search's force limit at poses the other legs reach (the result is then
    incomplete)."""

    candidates: int = 0
    converged: int = 0
    search_complete: bool = True
    nodes: int = 0
    continuum: int = 0
    lattice_h: float = 0.0
    lattice_n_theta: int = 0
    out_of_scope: int = 0
    out_of_scope_taut: int = 0
    force_limit: int = 0


@dataclass(frozen=True)
class Result:
    """Base of every solver result.

    Attributes
    ----------
    solutions : tuple
        The solutions (possibly empty: then ``message`` explains).
    complete : bool
        ``False`` when a search or a budget was cut short.
    message : str
        One line explaining an empty or incomplete result.
    elapsed : float
        Wall-clock time of the call, s.
    diagnostics : dataclass
        Typed counters of the solver (e.g. :class:`IKDiagnostics`, :class:`FKDiagnostics`).
    """

    solutions: tuple = ()
    complete: bool = True
    message: str = ""
    elapsed: float = 0.0
    diagnostics: Any = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.solutions)

    def __iter__(self) -> Iterator:
        return iter(self.solutions)

    def to_dict(self) -> dict[str, Any]:  # pragma: no cover - every subclass overrides
        """JSON-ready dict."""
        raise NotImplementedError

    def plot(self, path: str | None = None, **kwargs: Any):  # pragma: no cover
        """A figure of the result (matplotlib, imported lazily); saved when ``path`` is given."""
        raise NotImplementedError


@dataclass(frozen=True)
class KinematicsResult(Result):
    """All equilibria found by an inverse or forward kinematics call.

    The fields ``solutions``, ``complete``, ``message``, ``elapsed`` and ``diagnostics`` are
    those of :class:`Result`.

    Attributes
    ----------
    problem : {"ik", "fk"}
        Inverse or forward kinematics.
    mechanism : Mechanism
        The :class:`~flexkin.mechanism.Mechanism` solved.
    given : tuple of 3 floats
        What was imposed: the pose ``(x, y, theta)`` (IK; m, m, rad) or the inputs (FK; SI: m
        for prismatic and length legs, rad for revolute legs).
    load : tuple of 3 floats
        Load wrench ``(Fx, Fy, Mz)`` on the platform at P (N, N, N m).
    max_mode : int
        Largest d-mode of any rod searched.
    curves : list of LegCurve or None
        The geometric-condition curves of each leg (IK, :func:`flexkin.solve.curves.leg_curves`),
        else ``None``.
    max_winding : int
        Largest ``|winding|`` of a clamped rod searched (SPEC §2).
    """

    problem: str = "ik"
    mechanism: Any = field(default=None, repr=False)
    given: tuple[float, float, float] = (0.0, 0.0, 0.0)
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_mode: int = 2
    curves: Any = field(default=None, repr=False)
    max_winding: int = 1
    _cache: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

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
        """Feasibility of every solution (:func:`~flexkin.analysis.feasibility.check_feasibility`:
        collisions, self-intersection, bending strain, input ranges), computed once, on demand."""
        if "feasibility" not in self._cache:
            from .analysis.feasibility import check_solutions

            self._cache["feasibility"] = check_solutions(self.mechanism, self.solutions)
        return self._cache["feasibility"]

    def select(self, stable_only: bool = False, feasible_only: bool = False) -> "KinematicsResult":
        """A copy keeping only the stable (``stable is True``) and/or feasible solutions; every
        solution keeps its :attr:`Solution.id`."""
        keep = [True] * len(self.solutions)
        if stable_only:
            keep = [k and s.stable is True for k, s in zip(keep, self.solutions)]
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

    def to_dict(self, feasibility: bool = False) -> dict[str, Any]:
        """The SPEC §4 JSON object; with ``feasibility`` (only when asked: about 5 ms per
        solution) each solution carries its ``feasible`` verdict and reasons."""
        d: dict[str, Any] = {
            "problem": self.problem,
            "mechanism": self.mechanism.name,
            "load": list(self.load),
            "max_mode": self.max_mode,
            "max_winding": self.max_winding,
        }
        if self.problem == "ik":
            d["pose"] = [self.given[0], self.given[1], float(np.degrees(self.given[2]))]
        else:
            d["inputs"] = [float(leg.to_display(u)) for u, leg in zip(self.given, self.mechanism.legs)]
        d["complete"] = self.complete
        d["message"] = self.message
        feas = self.feasibility() if feasibility else (None,) * len(self.solutions)
        fill_margins(self.solutions)
        self._batch_indices()
        sols = []
        for s, f in zip(self.solutions, feas):
            e = s.to_dict()
            if f is not None:
                e["feasible"] = f.feasible
                e["feasibility"] = f.to_dict()
            sols.append(e)
        d["solutions"] = sols
        return d

    def _batch_indices(self) -> None:
        """Compute the solutions' performance indices in one batch (one assembly of the
        Jacobians and stiffnesses for all, ~8x faster than one by one) into their caches."""
        todo = [s for s in self.solutions if "indices" not in s.__dict__]
        if todo:
            from .analysis.indices import performance_indices

            for s, ix in zip(todo, performance_indices(todo)):
                s.__dict__["indices"] = ix  # the functools.cached_property slot

    def table(self, feasibility: bool = False) -> str:
        """Human-readable table of the solutions (with a ``margin`` column when the margins were
        computed, e.g. ``ik(..., margin=True)``, and a ``windings`` column -- SPEC §2, ``-`` for a
        pinned rod -- when a leg is clamped).

        Parameters
        ----------
        feasibility : bool
            Add a ``feasible`` column (``yes``/``no``) followed by the reasons
            (:meth:`feasibility`, computed on demand).

        Returns
        -------
        str
        """
        units = [leg.input_unit for leg in self.mechanism.legs]
        clamped = [leg.joint == "clamped" for leg in self.mechanism.legs]
        with_winding = any(clamped)
        with_margin = bool(self.solutions) and all(s.stability is not None and not np.isnan(s.stability.margin)
                                                   for s in self.solutions)
        head = (f"{'#':>3} {'modes':>5}" + (f" {'windings':>8}" if with_winding else "") + f" {'x [m]':>10} {'y [m]':>10} {'th [deg]':>9} "
                + " ".join(f"{'u' + str(i + 1) + ' [' + u + ']':>11}" for i, u in enumerate(units))
                + f" {'energy [J]':>11} {'stable':>6}" + (f" {'margin':>9}" if with_margin else "")
                + f" {'residual':>9}")
        if feasibility:
            head += f" {'feasible':>8}  reasons"
        lines = [head, "-" * len(head)]
        feas = self.feasibility() if feasibility else (None,) * len(self.solutions)
        for s, f in zip(self.solutions, feas):
            u = s.inputs_display()
            st = "?" if s.stable is None else ("yes" if s.stable else "no")
            mg = f" {s.stability.margin:>9.3g}" if with_margin else ""
            wd = (" " + " ".join("-" if r.winding is None else f"{r.winding:+d}" for r in s.rods).rjust(8)
                  if with_winding else "")
            row = (f"{s.id:>3} {s.mode_label:>5}{wd} {s.pose[0]:>10.5f} {s.pose[1]:>10.5f} {np.degrees(s.pose[2]):>9.3f} "
                   + " ".join(f"{v:>11.5f}" for v in u)
                   + f" {s.energy:>11.4e} {st:>6}{mg} {s.residual:>9.1e}")
            if f is not None:
                row += f" {'yes' if f.feasible else 'no':>8}  {'; '.join(f.reasons)}".rstrip()
            lines.append(row)
        return "\n".join(lines)

    def plot(self, path: str | None = None, **kwargs: Any):
        """One panel per solution with the deformed rods (paper Figs. 10-16)."""
        from .plot.solutions import plot_solutions

        return plot_solutions(self, path=path, **kwargs)
