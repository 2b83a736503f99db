"""Full forward kinematics: every equilibrium pose for given inputs and load (paper §5).

With the inputs fixed every clamp is known, and the unknowns are the rods' chart coordinates
and the pose (paper: rigid-body closure Eq. 17 plus equilibrium Eq. 15).  Instead of the
paper's sampled global optimisation, a global search finds every solution region: with all legs
pinned a compiled branch-and-bound over the product of the three rods' atlases
(:mod:`flexkin.solve.fk_search`); with any leg clamped (paper §8: three unknowns per rod,
where interval bounds exclude too little) the legs' rods on a pose lattice
(:mod:`flexkin.solve.fk_lattice`).  The starts are refined by the batched Newton corrector on
the whole equation system with the inputs held.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import as_triple, check_budget, check_max_mode
from ..results import FKDiagnostics, KinematicsResult, Solution
from ..system import System
from .corrector import newton
from .finish import finish_solutions
from .fk_lattice import lattice_starts
from .fk_search import MAX_NODES, fk_starts
from .ik import RESIDUAL_TOL, as_load

__all__ = ["fk"]


def fk(mech, inputs: ArrayLike, load: ArrayLike | None = None, max_mode: int = 2, *, stride: int = 4,
       stable_only: bool = False, time_budget: float | None = None, margin: bool = False) -> KinematicsResult:
    """All equilibrium poses of ``mech`` for actuator ``inputs`` under ``load`` (paper §5).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    inputs : (u1, u2, u3)
        Actuator inputs in SI units: m for prismatic and length legs, **radians** for
        revolute legs.
    load : (Fx, Fy, Mz), optional
        Load wrench on the platform at P; defaults to the mechanism file's ``[load]``.
    max_mode : int
        Largest d-mode of any rod (default 2).
    stride : int
        Coarsening of the atlas cells used by the search (1 = finest, slowest).
    stable_only : bool
        Keep only the stable equilibria (default: all, stable and unstable).
    time_budget : float, optional
        Seconds for the whole FK: the global search stops early enough for its candidates to
        be refined in time; the result then says ``complete = False`` (and so it does when
        the search exhausts its node budget).
    margin : bool
        Compute every solution's stability margin now (default: on first use).

    Returns
    -------
    KinematicsResult
        ``problem == "fk"``; ``solutions`` possibly empty, then ``message`` explains.
    """
    t0 = time.perf_counter()
    max_mode = check_max_mode(max_mode)
    u = as_triple(inputs, "inputs")
    w = as_load(mech, load)
    for i, leg in enumerate(mech.legs):
        leg.actuator.check_input(float(u[i]), i)
    deadline = None if time_budget is None else t0 + check_budget(time_budget)
    system = System.from_mechanism(mech)
    given, wl = tuple(float(v) for v in u), tuple(float(v) for v in w)
    diag: dict[str, Any] = {}
    msg = _assembly_obstruction(system, u)
    if msg:
        return KinematicsResult((), True, msg, time.perf_counter() - t0, FKDiagnostics(), "fk", mech, given, wl,
                                max_mode)
    if np.any(system.clamped):  # 9-D interval bounds exclude too little: the pose lattice
        X, complete, stats = lattice_starts(system, u, w, max_mode, deadline=deadline)
        nodes = stats.combinations
        diag["lattice_h"], diag["lattice_n_theta"] = stats.h, stats.n_theta
    else:
        X, complete, nodes = fk_starts(system, mech, u, w, max_mode, stride=stride, deadline=deadline)
    diag["candidates"] = int(len(X))
    diag["search_complete"] = complete
    diag["nodes"] = int(nodes)
    sols = refine_fk(system, mech, X, system.default_charts(len(X)), w, max_mode, diag, margin)
    msg = "" if sols else "no equilibrium pose found for these inputs and load"
    if diag.get("continuum"):
        msg = ("singular configuration: straight rods carry axial forces freely, a continuum of equilibria; "
               "the least loaded one is reported")
    if not complete:
        why = ("time budget exhausted" if time_budget is not None and (nodes < MAX_NODES or "lattice_h" in diag)
               else f"search budget exhausted ({nodes} node triples examined)")
        msg = f"{why}: the global search did not finish, the solution list may be incomplete" + \
            ("" if sols else "; " + msg)
    res = KinematicsResult(tuple(sols), complete, msg, time.perf_counter() - t0, FKDiagnostics(**diag), "fk", mech,
                           given, wl, max_mode)
    return res.select(stable_only=True) if stable_only else res


def refine_fk(system: System, mech, X: NDArray, charts: NDArray, load: NDArray, max_mode: int,
              diag: dict[str, Any] | None = None, margin: bool = False) -> list[Solution]:
    """Newton-refine FK candidates ``X`` (inputs held) and build the solutions (``margin``: with
    their stability margins)."""
    res = newton(system, X, charts, load, "inputs")
    good = res.residual <= RESIDUAL_TOL
    if diag is not None:
        diag["converged"] = int(np.count_nonzero(good))
    return finish_solutions(system, mech, res.x[good], res.charts[good], res.residual[good], max_mode, load, diag,
                            "inputs", margin)


def _assembly_obstruction(m: System, u: NDArray) -> str:
    """A one-line reason when the rods cannot reach a common platform, else ``""``."""
    A, _, L = m.clamps(u[None])
    A, L = A[0], L[0]
    b = m.attach
    for i in range(3):
        for j in range(i + 1, 3):
            gap = float(np.hypot(*(A[j] - A[i])))
            reach = L[i] + L[j] + float(np.hypot(*(b[j] - b[i])))
            if gap > reach:
                return (f"cannot assemble: clamps {i + 1} and {j + 1} are {gap:.6g} m apart, more than the rods "
                        f"and the platform side can span ({reach:.6g} m)")
    return ""
