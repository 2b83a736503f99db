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

from ..core.budget import Deadline
from ..core.validation import as_load, as_triple, check_max_mode, check_max_winding
from ..io.progress import Progress, substage
from ..results import FKDiagnostics, KinematicsResult
from ..system import System
from ..rod.wrench_atlas import lambda_max
from .finish import SCOPE_MESSAGE, force_limit_message, refine
from .fk_lattice import lattice_starts
from .fk_search import fk_starts

__all__ = ["fk"]


def fk(mech, inputs: ArrayLike, load: ArrayLike | None = None, max_mode: int = 2, *, max_winding: int = 1,
       stride: int = 4,
       stable_only: bool = False, time_budget: float | Deadline | None = None,
       progress: Progress | None = None, margin: bool = False) -> KinematicsResult:
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
        Largest d-mode of any rod (default 2; a clamped rod's d-mode counts its inflections
        strictly inside).
    max_winding : int
        Largest ``|winding|`` of a clamped rod (SPEC §2; default 1).
    stride : int
        Coarsening of the atlas cells used by the search (1 = finest, slowest).
    stable_only : bool
        Keep only the stable equilibria (default: all, stable and unstable).
    time_budget : float or Deadline, optional
        Seconds for the whole FK (start-up excluded; see :mod:`flexkin.core.budget`): the
        global search stops early enough for its candidates to be refined and analysed in
        time; when the time runs out the result holds what was finished and says
        ``complete = False`` (and so it does when the search exhausts its node budget).  A
        :class:`~flexkin.core.budget.Deadline` shares a caller's clock.
    progress : callable, optional
        Called as ``progress(fraction, stage)`` as the work advances (``fraction`` from 0 to 1,
        during the search the share of the search space resolved;
        :class:`flexkin.io.progress.ProgressBar` draws it).
    margin : bool
        Compute every solution's stability margin now (default: on first use -- the verdict
        and the index come from the closed form and need no margin).

    Returns
    -------
    KinematicsResult
        ``problem == "fk"``; ``solutions`` possibly empty, then ``message`` explains.
        ``complete`` is ``False`` when the search stopped early, when it reached equilibria
        with a rod near straight under tension beyond the numerical scope (not reported), or
        when a clamped leg's rods reached the search's force limit where the other legs reach.
    """
    t0 = time.perf_counter()
    max_mode = check_max_mode(max_mode)
    max_winding = check_max_winding(max_winding)
    u = as_triple(inputs, "inputs")
    w = as_load(mech, load)
    for i, leg in enumerate(mech.legs):
        leg.actuator.check_input(float(u[i]), i)
    dl = Deadline.of(time_budget)
    system = System.from_mechanism(mech)
    given, wl = tuple(float(v) for v in u), tuple(float(v) for v in w)
    diag: dict[str, Any] = {}
    msg = _assembly_obstruction(system, u)
    if msg:
        return KinematicsResult((), True, msg, time.perf_counter() - t0, FKDiagnostics(), "fk", mech, given, wl,
                                max_mode, max_winding=max_winding)
    if np.any(system.clamped):  # 9-D interval bounds exclude too little: the pose lattice
        X, complete, stats = lattice_starts(system, u, w, max_mode, max_winding=max_winding,
                                            deadline=dl.end if dl.limited else None,
                                            progress=substage(progress, 0.0, 0.6, "pose lattice"))
        charts = system.default_charts(len(X))
        nodes = stats.combinations
        diag["lattice_h"], diag["lattice_n_theta"] = stats.h, stats.n_theta
        diag["force_limit"] = int(stats.force_limit)
    else:
        X, charts, complete, nodes = fk_starts(system, u, w, max_mode, stride=stride, deadline=dl.for_search(),
                                               progress=substage(progress, 0.0, 0.6, "branch-and-bound"))
    diag["candidates"] = int(len(X))
    diag["search_complete"] = complete
    diag["nodes"] = int(nodes)
    if progress is not None:
        progress(0.6, f"Newton on {len(X)} candidates")
    sols = refine(system, mech, X, charts, w, max_mode, "inputs", diag, deadline=dl,
                  progress=substage(progress, 0.7, 1.0, "equilibria"), margin=margin, max_winding=max_winding)
    if dl.limited and not complete and "lattice_h" in diag:
        dl.hit = True  # the lattice search stops only at the deadline
    complete = complete and not dl.hit
    msg = "" if sols else "no equilibrium pose found for these inputs and load"
    if diag.get("continuum"):
        msg = ("singular configuration: straight rods carry axial forces freely, a continuum of equilibria; "
               "the least loaded one is reported")
    if diag.get("out_of_scope_taut"):
        complete = False
        msg = SCOPE_MESSAGE
    if diag.get("force_limit"):
        complete = False
        msg = force_limit_message(lambda_max(max_mode))
    if not diag["search_complete"] or dl.hit:
        why = dl.message() if dl.hit else f"search budget exhausted ({nodes} node triples examined)"
        msg = f"{why}: the global search did not finish, the solution list may be incomplete" + \
            ("" if sols else "; " + msg)
    res = KinematicsResult(tuple(sols), complete, msg, time.perf_counter() - t0, FKDiagnostics(**diag), "fk", mech,
                           given, wl, max_mode, max_winding=max_winding)
    return res.select(stable_only=True) if stable_only else res


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
