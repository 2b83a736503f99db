"""Feasibility checks of an equilibrium (paper §4, last step; SPEC §1 "feasibility checks").

The kinematics report *every* equilibrium; this module says which of them a real device can
actually take, and why not.  :func:`check_feasibility` runs five independent checks on one
:class:`~flexkin.results.Solution` and returns a frozen :class:`Feasibility`:

1. **rod–rod contact** (different rods).  The centre lines, sampled at ``n_samples`` points
   uniformly in arc length (:meth:`RodState.shape`), are polylines.  Two rods collide if
   their polylines cross, or if they come closer than ``r_i + r_j + clearance``: with known
   radii the rods are *capsules* (the Minkowski sum of the centre line and a disc of the
   section radius), without a radius a rod has zero thickness.
2. **self-intersection** (loops, typical of d-mode 2).  Non-adjacent segments of the same
   polyline crossing.  With a radius (or a clearance), also *self-contact*: two points of the
   rod further apart than ``pi r_eff`` in arc length closer than ``2 r_eff``, with
   ``r_eff = r + clearance/2`` (points nearer along the rod are always that close in a bent
   rod whose radius of curvature is >= r, so they are not compared).
3. **rod–platform contact**.  The platform is the triangle ``B_1 B_2 B_3`` at the
   solution's pose (:meth:`Platform.world`).  A rod collides if its centre line enters the
   triangle's interior, or (capsule) comes closer than ``r_i + clearance`` to it.  The rod's
   own last portion near its pin ``B_i``, of arc length ``tip_exclusion`` (default
   ``r_i + clearance + 0.05 * shortest platform edge``), is exempt: a rod ending on the
   boundary is fine, and so is a rod whose pin fitting reaches a little over the plate.
4. **bending strain**.  ``max |theta'| * r`` per rod, against ``max_strain`` (argument) or
   else the mechanism's ``[limits] max_strain`` (:attr:`Mechanism.max_strain`).  The peak
   curvature is computed in closed form (below), not from the samples.  Without a radius
   the rod's strain is ``None``; without a limit the strains are reported but not judged.
   Both cases are listed in :attr:`Feasibility.skipped`, never in the reasons.
5. **actuator strokes**: inputs outside a leg's ``range`` (:meth:`Leg.in_range`).

Peak curvature in closed form
-----------------------------
In the unified chart of :mod:`flexkin.rod.closed_form`, ``theta'(s) = 2 lambda ku cos(phi(s))``
with ``lambda = sqrt(R/EI)`` and the amplitude ``phi`` increasing from ``phis`` at the clamp
to ``pi/2`` at the pinned tip.  So ``max |theta'| = 2 lambda |ku|`` if ``[phis, pi/2]``
contains a multiple of pi (``phis <= 0``: every d-mode >= 2 rod and mode-1 rods whose
curvature peaks inside), else ``2 lambda |ku| cos(phis) = |m0|/EI`` (peak at the clamp).
This is exact (no sampling error), unlike the maximum of sampled curvatures, which misses
an interior peak by O(h^2); :func:`rod_max_curvature` can add the sampled maximum as a
safety net.

Tolerances and sampling
-----------------------
The polylines are chords of the true curves: a chord deviates from the arc by at most
``h^2 kappa / 8`` (``h = L/(n_samples - 1)``), 6e-5 L for a tight loop (kappa L = 20) at
the default 200 samples.  A transversal crossing is therefore detected; only grazing
contacts (overlaps shallower than that deviation) are uncertain, and distances carry that
error.  Two segments "touch" (zero distance without a proper crossing: T-contacts, collinear
overlaps) when their distance is below ``1e-12`` times the mechanism's length scale
(:data:`TOUCH_RTOL`).  The platform tests use the same absolute tolerance: a point is
inside only if it is further than that from every edge, and a segment crosses an edge only
if its end points are further than that from the edge's line, so a rod tip lying on the
boundary (to the solver's residual) is never "inside" or "crossing".

The polyline geometry (distances, crossings with a two-level bounding-box prefilter that
equals brute force) is :mod:`flexkin.core.polyline`.  At 200 samples one solution takes
~10 ms, mostly sampling the three rods.

Rods, legs and inputs are numbered from 1 in reasons and in the index tuples of
:class:`Feasibility`, like the SPEC's ``B_1, B_2, B_3``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.polyline import polyline_crossings, polyline_platform, self_crossings, truncate

__all__ = [
    "Feasibility",
    "check_feasibility",
    "check_solutions",
    "inputs_out_of_range",
    "rod_max_curvature",
]

#: default exempt length near a rod's own pin, as a fraction of the shortest platform edge
TIP_EXCLUSION_FRACTION = 0.05

#: relative tolerance (times the mechanism's length scale) for "touching" and "inside"
TOUCH_RTOL = 1e-12

#: the rod pairs, numbered from 1, in the order of :attr:`Feasibility.rod_distances`
_PAIRS1 = ((1, 2), (1, 3), (2, 3))


# --------------------------------------------------------------------------------------
# result object
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Feasibility:
    """Verdict of the feasibility checks on one equilibrium.

    Attributes
    ----------
    feasible : bool
        ``True`` iff ``reasons`` is empty.
    reasons : tuple of str
        One short line per violation, e.g. ``"rods 1 and 3 intersect"``,
        ``"rod 2 self-intersects"``, ``"rod 2 crosses the platform"``,
        ``"strain 0.052 > 0.04 on rod 2"``, ``"input 1 = 0.35 m outside range [-0.1, 0.3]"``.
    max_strain : float or None
        Largest bending strain over the rods whose radius is known (``None`` if none is).
    min_rod_distance : float
        Smallest distance between the centre lines of two different rods (m); 0 if two rods
        cross.  Compare with ``r_i + r_j`` for the surface gap.
    strains : tuple of (float or None)
        Bending strain ``max |curvature| * radius`` of each rod (``None`` without radius).
    max_curvatures : tuple of float
        Peak ``|theta'|`` of each rod (1/m).
    strain_limit : float or None
        Allowable strain used (argument, else the mechanism's), ``None`` if there is none.
    rod_collisions : tuple of (int, int)
        Pairs of rods (1-based, ``i < j``) that cross or are closer than allowed.
    rod_distances : tuple of float
        Centre-line distance (m) of the pairs (1, 2), (1, 3), (2, 3), in that order (0 for
        a crossing).
    self_intersecting : tuple of int
        Rods (1-based) that cross or touch themselves.
    self_crossings : tuple of int
        Number of crossing pairs of non-adjacent segments of each rod (a simple loop: 1).
    platform_collisions : tuple of int
        Rods (1-based) that enter the platform or come closer than allowed.
    platform_distances : tuple of float
        Distance (m) from each rod, without its exempt tail, to the platform triangle; 0 if
        it enters it.
    inputs_out_of_range : tuple of int
        Legs (1-based) whose input lies outside their ``range``.
    skipped : tuple of str
        Checks that could not be made, e.g. ``"strain: no allowable strain given"``.
    n_samples : int
        Points per rod used for the geometric checks.
    clearance : float
        Extra gap (m) that was required between bodies.
    """

    feasible: bool
    reasons: tuple[str, ...]
    max_strain: float | None
    min_rod_distance: float
    strains: tuple[float | None, ...] = ()
    max_curvatures: tuple[float, ...] = ()
    strain_limit: float | None = None
    rod_collisions: tuple[tuple[int, int], ...] = ()
    rod_distances: tuple[float, ...] = ()
    self_intersecting: tuple[int, ...] = ()
    self_crossings: tuple[int, ...] = ()
    platform_collisions: tuple[int, ...] = ()
    platform_distances: tuple[float, ...] = ()
    inputs_out_of_range: tuple[int, ...] = ()
    skipped: tuple[str, ...] = ()
    n_samples: int = 200
    clearance: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (plain floats, lists and strings; rods numbered from 1)."""
        return {
            "feasible": self.feasible,
            "reasons": list(self.reasons),
            "max_strain": self.max_strain,
            "strain_limit": self.strain_limit,
            "strains": list(self.strains),
            "max_curvatures": list(self.max_curvatures),
            "min_rod_distance": self.min_rod_distance,
            "rod_distances": {f"{i}-{j}": d for (i, j), d in zip(_PAIRS1, self.rod_distances)},
            "rod_collisions": [list(p) for p in self.rod_collisions],
            "self_intersecting": list(self.self_intersecting),
            "self_crossings": list(self.self_crossings),
            "platform_collisions": list(self.platform_collisions),
            "platform_distances": list(self.platform_distances),
            "inputs_out_of_range": list(self.inputs_out_of_range),
            "skipped": list(self.skipped),
            "n_samples": self.n_samples,
            "clearance": self.clearance,
        }


# --------------------------------------------------------------------------------------
# strain and inputs
# --------------------------------------------------------------------------------------
def rod_max_curvature(rod: Any, n_samples: int = 0) -> float:
    """Peak ``|theta'(s)|`` of a rod (1/m), exact.

    A pinned rod in the unified chart (module docstring): ``2 |ku| sqrt(R/EI)`` if the clamp
    amplitude ``phis <= 0`` (the curvature has an interior extremum), else the clamp value
    ``2 |ku| sqrt(R/EI) cos(phis) = |m0|/EI``.

    A rod in the wrench chart (every clamped-tip rod): the first integral of the elastica
    with the tip force ``F`` on the rod, ``EI theta'^2 / 2 + F . t(theta) = const`` (``t`` the
    unit tangent; from ``EI theta'' = -(t x F)``), makes ``theta'^2`` a function of ``theta``
    alone, largest where ``t = -F/|F|``.  The peak is therefore the larger end moment over EI,
    or ``sqrt(theta'(0)^2 + 2 (F . t(0) + |F|) / EI)`` if the tangent passes through
    ``-F/|F|`` along the rod -- found by bracketing on the sampled tangent angle, which is
    exact up to a tangency that changes the value by less than the sampling's O(h^2).

    Parameters
    ----------
    rod : RodState
    n_samples : int, optional
        If > 1, also sample :meth:`RodState.curvature` and return the larger value (a
        safety net; the closed form is exact).

    Returns
    -------
    float
    """
    from ..rod.kernels import CHART_WRENCH, clamped_peak

    EI = float(rod.EI)
    kmax = max(abs(float(rod.base_moment)), abs(float(rod.tip_moment))) / EI
    if rod.chart == CHART_WRENCH:
        kmax = max(kmax, _wrench_interior_peak(rod))
    elif rod.chart > CHART_WRENCH:  # an elastica window: closed form
        kmax = max(kmax, clamped_peak(int(rod.chart), np.asarray(rod.coords, dtype=float)) / float(rod.length))
    else:
        lam = math.sqrt(max(float(rod.R), 0.0) / EI)
        peak = 2.0 * abs(float(rod.ku)) * lam
        kmax = max(kmax, peak if float(rod.phis) <= 0.0 else peak * abs(math.cos(float(rod.phis))))
    if n_samples > 1:
        kmax = max(kmax, float(np.max(np.abs(rod.curvature(n_samples)))))
    return kmax


#: samples of the tangent angle used to bracket the direction of peak curvature (wrench chart)
_BRACKET_SAMPLES = 257


def _wrench_interior_peak(rod: Any) -> float:
    """Interior peak curvature of a rod in the wrench chart (see :func:`rod_max_curvature`),
    0 when its tangent never points along ``-F``."""
    fx, fy = (float(v) for v in rod.tip_force)
    R = math.hypot(fx, fy)
    if R == 0.0:
        return 0.0
    th = rod.profile(_BRACKET_SAMPLES)["theta"]
    target = math.atan2(-fy, -fx)
    # does theta(s) cross target + 2 pi j between two samples (or touch it at one)?
    lo, hi = np.minimum(th[:-1], th[1:]), np.maximum(th[:-1], th[1:])
    j = np.ceil((lo - target) / (2.0 * math.pi))
    if not np.any(target + 2.0 * math.pi * j <= hi):
        return 0.0
    EI = float(rod.EI)
    k0 = float(rod.base_moment) / EI
    ft0 = fx * math.cos(th[0]) + fy * math.sin(th[0])
    return math.sqrt(max(k0 * k0 + 2.0 * (ft0 + R) / EI, 0.0))


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def inputs_out_of_range(mechanism: Any, inputs: Sequence[float]) -> list[tuple[int, str]]:
    """Legs whose input lies outside their ``range``, with a reason for each.

    Parameters
    ----------
    mechanism : Mechanism
    inputs : sequence of three floats
        Inputs in internal units (m, rad for revolute legs).

    Returns
    -------
    list of (int, str)
        ``(leg number from 1, reason)``; the reason shows display units (m or deg).
    """
    out: list[tuple[int, str]] = []
    for i, (leg, u) in enumerate(zip(mechanism.legs, inputs), 1):
        if leg.range is None or bool(leg.in_range(u)):
            continue
        lo, hi = (leg.to_display(v) for v in leg.range)
        msg = f"input {i} = {_fmt(leg.to_display(u))} {leg.input_unit} outside range [{_fmt(lo)}, {_fmt(hi)}]"
        out.append((i, msg))
    return out


# --------------------------------------------------------------------------------------
# the check
# --------------------------------------------------------------------------------------
def check_feasibility(
    mechanism: Any,
    solution: Any,
    *,
    n_samples: int = 200,
    max_strain: float | None = None,
    clearance: float = 0.0,
    tip_exclusion: float | None = None,
) -> Feasibility:
    """Run all feasibility checks on one equilibrium (see the module docstring).

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism the solution belongs to (rod radii, leg ranges, platform, limits).
    solution : Solution
        One equilibrium (``pose``, ``inputs``, ``rods``).
    n_samples : int, optional
        Points per rod centre line for the geometric checks (>= 3).
    max_strain : float, optional
        Allowable bending strain; overrides ``mechanism.max_strain``.
    clearance : float, optional
        Extra gap (m, >= 0) required between rods, within a rod and between a rod and
        the platform.
    tip_exclusion : float, optional
        Arc length (m) before each rod's pin exempt from the platform check; default
        ``r_i + clearance + 0.05 * shortest platform edge``.

    Returns
    -------
    Feasibility

    Raises
    ------
    ValueError
        For ``n_samples < 3``, a negative clearance or tip exclusion, or a non-positive
        ``max_strain``.
    """
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 3:
        raise ValueError(f"n_samples must be an integer >= 3, got {n_samples!r}")
    clearance = float(clearance)
    if not (math.isfinite(clearance) and clearance >= 0.0):
        raise ValueError(f"clearance must be a finite number >= 0, got {clearance!r}")
    if tip_exclusion is not None and not (math.isfinite(float(tip_exclusion)) and float(tip_exclusion) >= 0.0):
        raise ValueError(f"tip_exclusion must be a finite number >= 0, got {tip_exclusion!r}")
    limit = mechanism.max_strain if max_strain is None else float(max_strain)
    if limit is not None and not (math.isfinite(limit) and limit > 0.0):
        raise ValueError(f"max_strain must be a finite number > 0, got {max_strain!r}")

    rods = tuple(solution.rods)
    radii = [leg.rod.radius for leg in mechanism.legs]
    r = [0.0 if ri is None else float(ri) for ri in radii]
    scale = max([float(mechanism.length_scale)] + [float(rod.length) for rod in rods])
    touch = TOUCH_RTOL * scale
    shapes = [np.asarray(rod.shape(int(n_samples)), dtype=float) for rod in rods]
    reasons: list[str] = []
    skipped: list[str] = []

    # 1. rod-rod
    rod_collisions: list[tuple[int, int]] = []
    rod_distances: list[float] = []
    for i1, j1 in _PAIRS1:
        i, j = i1 - 1, j1 - 1
        n_cross, d = polyline_crossings(shapes[i], shapes[j], touch=touch)
        rod_distances.append(d)
        need = r[i] + r[j] + clearance
        if n_cross:
            rod_collisions.append((i1, j1))
            reasons.append(f"rods {i1} and {j1} intersect")
        elif d < need:
            rod_collisions.append((i1, j1))
            reasons.append(f"rods {i1} and {j1} collide: distance {_fmt(d)} m < {_fmt(need)} m")
    min_rod_distance = min(rod_distances)

    # 2. self-intersection / self-contact
    self_hits: list[int] = []
    self_counts: list[int] = []
    for i, (rod, P) in enumerate(zip(rods, shapes)):
        r_eff = r[i] + 0.5 * clearance
        h = float(rod.length) / (n_samples - 1)
        gap = max(2, 1 + math.ceil(math.pi * r_eff / h)) if h > 0 else 2
        n_cross, _ = self_crossings(P, min_gap=2, touch=touch, within=touch)
        d_contact = math.inf
        if r_eff > 0.0 and not n_cross:
            _, d_contact = self_crossings(P, min_gap=gap, touch=touch, within=2.0 * r_eff)
        self_counts.append(n_cross)
        if n_cross:
            self_hits.append(i + 1)
            reasons.append(f"rod {i + 1} self-intersects")
        elif d_contact < 2.0 * r_eff:
            self_hits.append(i + 1)
            reasons.append(f"rod {i + 1} self-contact: distance {_fmt(d_contact)} m < {_fmt(2.0 * r_eff)} m")

    # 3. rod-platform
    B = np.asarray(mechanism.platform.world(np.asarray(solution.pose, dtype=float)), dtype=float)
    edges = np.hypot(*(np.roll(B, -1, axis=0) - B).T)
    platform_hits: list[int] = []
    platform_distances: list[float] = []
    for i, (rod, P) in enumerate(zip(rods, shapes)):
        cut = (r[i] + clearance + TIP_EXCLUSION_FRACTION * float(edges.min())) if tip_exclusion is None \
            else float(tip_exclusion)
        Q = truncate(P, float(rod.length), cut)
        inside, d = polyline_platform(Q, B, tol=touch)
        platform_distances.append(d)
        need = r[i] + clearance
        if inside:
            platform_hits.append(i + 1)
            reasons.append(f"rod {i + 1} crosses the platform")
        elif d < need:
            platform_hits.append(i + 1)
            reasons.append(f"rod {i + 1} touches the platform: distance {_fmt(d)} m < {_fmt(need)} m")

    # 4. strain
    kmax = [rod_max_curvature(rod) for rod in rods]
    strains: list[float | None] = [None if radii[i] is None else r[i] * kmax[i] for i in range(3)]
    known = [s for s in strains if s is not None]
    worst = max(known) if known else None
    if limit is None:
        skipped.append("strain: no allowable strain given (max_strain / [limits] max_strain)")
    for i, s in enumerate(strains):
        if s is None:
            if limit is not None:
                skipped.append(f"strain: rod {i + 1} has no radius")
        elif limit is not None and s > limit:
            reasons.append(f"strain {_fmt(s)} > {_fmt(limit)} on rod {i + 1}")

    # 5. actuator strokes
    bad_inputs = inputs_out_of_range(mechanism, solution.inputs)
    reasons.extend(msg for _, msg in bad_inputs)

    return Feasibility(
        feasible=not reasons,
        reasons=tuple(reasons),
        max_strain=worst,
        min_rod_distance=float(min_rod_distance),
        strains=tuple(strains),
        max_curvatures=tuple(float(k) for k in kmax),
        strain_limit=None if limit is None else float(limit),
        rod_collisions=tuple(rod_collisions),
        rod_distances=tuple(float(d) for d in rod_distances),
        self_intersecting=tuple(self_hits),
        self_crossings=tuple(self_counts),
        platform_collisions=tuple(platform_hits),
        platform_distances=tuple(float(d) for d in platform_distances),
        inputs_out_of_range=tuple(i for i, _ in bad_inputs),
        skipped=tuple(skipped),
        n_samples=int(n_samples),
        clearance=clearance,
    )


def check_solutions(mechanism: Any, solutions: Iterable[Any], **kwargs: Any) -> tuple[Feasibility, ...]:
    """:func:`check_feasibility` on every solution (e.g. a :class:`KinematicsResult`).

    Parameters
    ----------
    mechanism : Mechanism
    solutions : iterable of Solution
    **kwargs
        Passed to :func:`check_feasibility`.

    Returns
    -------
    tuple of Feasibility
        In the order of ``solutions``.
    """
    return tuple(check_feasibility(mechanism, s, **kwargs) for s in solutions)
