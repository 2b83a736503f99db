"""Refinement of Kirchhoff equilibria into the planar Cosserat model by homotopy (paper §4.2, §8).

Every Kirchhoff solution (from :func:`flexkin.ik` or :func:`flexkin.fk`) is the tau = 0 point
of the homotopy ``H(z, tau) = 0`` of :mod:`flexkin.cosserat.system`, in which tau multiplies
the axial and shear compliances and the distributed loads (self-weight ``rho A g`` plus an
optional uniform load).  Each is followed to tau = 1 by pseudo-arclength continuation
(:mod:`flexkin.cosserat.continuation`), all branches batched through one compiled shooting
kernel.  A branch that turns back in tau ended at a fold: its solution merged with another
one and does not exist in the refined model.  Around every fold a short multi-start at
tau = 1 looks for solutions that exist only in the refined model; each one found is followed
down in tau, and is reported ``"born"`` when it turns at a fold (its birth tau) instead of
reaching the Kirchhoff model.  Every refined solution is classified stable / unstable /
unresolved by the discretised second variation (:mod:`flexkin.cosserat.stability`) and
verified by re-integrating with twice the Runge–Kutta steps.

"No solution" is an answer (statuses in the result), never an exception; bad input raises
``ValueError`` naming the problem.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from .continuation import Abort, BranchEnd, ContinuationOptions, _Counter, branch, newton_fixed, run_batched
from .params import CosseratParams, line_loads
from .results import RefinedRod, RefinedSolution, RefineResult
from .rod import rod_shape
from .stability import smallest_eigenvalue_batch, verdict
from .system import TWO_PI, Layout, MechData, canonical, evaluate, initial_segments, make_layout, scale_vector

__all__ = ["refine", "ContinuationOptions"]

#: scaled distance below which two solutions are the same
_SAME = 1e-6
#: largest strain bound (|v - e1| <= c |n|max) for which a branch is followed
_MAX_STRAIN = 0.5
#: verification threshold on the scaled residual re-integrated with twice the steps
_VERIFY = 1e-8


# --------------------------------------------------------------------------------------
def _vec(value: Any, n: int, what: str) -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected {n} numbers, got {value!r}") from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected {n} finite numbers, got {value!r}")
    return tuple(float(x) for x in a)


def _as_params(params: Any) -> tuple[CosseratParams, CosseratParams, CosseratParams]:
    if isinstance(params, CosseratParams):
        return (params, params, params)
    try:
        ps = tuple(params)
    except TypeError:
        raise ValueError(f"params: expected a CosseratParams or one per leg, got {params!r}") from None
    if len(ps) != 3 or not all(isinstance(p, CosseratParams) for p in ps):
        raise ValueError(f"params: expected a CosseratParams or a sequence of three, got {params!r}")
    return ps  # type: ignore[return-value]


def _mech_data(mech: Any, problem: str, params, f: NDArray[np.float64], load, sols) -> MechData:
    legs = getattr(mech, "legs", None)
    plat = getattr(mech, "platform", None)
    if legs is None or len(legs) != 3 or plat is None:
        raise ValueError("mech: expected a flexkin Mechanism with three legs and a platform")
    b = np.asarray(plat.attach, dtype=float)
    if b.shape != (3, 2):
        raise ValueError("mech.platform.attach: expected three (x, y) points")
    joints = [getattr(leg, "joint", "pinned") for leg in legs]
    for i, j in enumerate(joints):
        if j not in ("pinned", "clamped"):
            raise ValueError(f"leg[{i + 1}].joint: expected 'pinned' or 'clamped', got {j!r}")
    beta = np.array([float(getattr(leg, "tip_angle", 0.0) or 0.0) for leg in legs])
    try:
        EI = np.array([float(leg.rod.EI) for leg in legs])
        kinds = tuple(leg.actuation for leg in legs)
    except AttributeError as e:
        raise ValueError(f"mech.legs: not flexkin legs ({e})") from None
    lengths = [float(r.length) for s in sols for r in s.rods]
    Lref = float(np.mean(lengths)) if lengths else 1.0
    return MechData(
        problem=problem, legs=tuple(legs), kinds=kinds, b=b,
        load=np.asarray(load, dtype=float), EI=EI, clamped=np.array([j == "clamped" for j in joints]),
        beta=beta, ce=np.array([p.axial_compliance for p in params]),
        cs=np.array([p.shear_compliance for p in params]), f=f, Lref=Lref, EIref=float(np.mean(EI)),
    )


def _check_solution(s: Any, k: int) -> None:
    for attr in ("pose", "inputs", "rods"):
        if not hasattr(s, attr):
            raise ValueError(f"solutions[{k}]: not a flexkin Solution (no {attr!r})")
    if len(s.rods) != 3:
        raise ValueError(f"solutions[{k}]: expected three rods")
    try:
        vals = np.concatenate([np.asarray(s.pose, float).reshape(3), np.asarray(s.inputs, float).reshape(3)]
                              + [np.r_[r.tip_force, r.base_moment, r.tip, r.tip_angle, r.length] for r in s.rods])
    except (AttributeError, TypeError, ValueError) as e:
        raise ValueError(f"solutions[{k}]: not a flexkin Solution ({e})") from None
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"solutions[{k}]: non-finite pose, inputs or rod data")


# --------------------------------------------------------------------------------------
class _Problem:
    """Per-branch data (fixed part, 2 pi wraps, layout) and the batched evaluation."""

    def __init__(self, md: MechData) -> None:
        self.md = md
        self.fixed: dict[Any, NDArray[np.float64]] = {}
        self.wrap: dict[Any, NDArray[np.float64]] = {}
        self.layout: dict[Any, Layout] = {}
        self.evaluations = 0
        self.rounds = 0

    def add(self, key, fixed, wrap, layout) -> None:
        self.fixed[key], self.wrap[key], self.layout[key] = fixed, wrap, layout

    def inherit(self, key, parent) -> None:
        self.add(key, self.fixed[parent], self.wrap[parent], self.layout[parent])

    def __call__(self, keys, Zhat, tau, jac, doubled: bool = False):
        fx = np.array([self.fixed[k] for k in keys])
        wr = np.array([self.wrap[k] for k in keys])
        lays = [self.layout[k].doubled() if doubled else self.layout[k] for k in keys]
        self.evaluations += len(keys)
        self.rounds += 1
        ev = evaluate(self.md, list(Zhat), np.asarray(tau, float), fx, wr, lays, jac=jac)
        if not jac:
            return ev
        R = [r if sb <= _MAX_STRAIN else
             f"strains beyond {_MAX_STRAIN:g} at tau = {t:.6g}: outside the linear constitutive law"
             for r, sb, t in zip(ev.R, ev.strain_bound, np.asarray(tau, float))]
        return R, ev.Jz, ev.Jt

    def canon(self, key, z) -> NDArray[np.float64]:
        """``z`` of branch ``key`` in the mechanism-wide scaling (first 12 unknowns)."""
        return canonical(self.md, self.layout[key], z)

    @property
    def fixed_scale(self) -> NDArray[np.float64]:
        """Scale of the fixed part: the pose (IK) or the inputs (FK)."""
        md = self.md
        if md.problem == "ik":
            return np.array([md.Lref, md.Lref, 1.0])
        return md.input_scales()

    def same_fixed(self, a, b) -> bool:
        """Whether branches ``a`` and ``b`` hold the same pose (IK) / inputs (FK) fixed."""
        return bool(np.max(np.abs(self.fixed[a] - self.fixed[b]) / self.fixed_scale) < 1e-9)


def _run(prob: _Problem, gens: dict) -> dict:
    return run_batched(gens, lambda keys, Z, tau, jac: prob(keys, Z, tau, jac))


# --------------------------------------------------------------------------------------
def refine(mech: Any, solutions: Any, *, params: CosseratParams | Sequence[CosseratParams],
           gravity: Sequence[float] | None = None, distributed_load: Sequence[float] | None = None,
           problem: str | None = None, load: Sequence[float] | None = None, tol: float = 1e-12,
           stability: bool = True, born_search: bool = True, elements: int = 32,
           options: ContinuationOptions | None = None) -> RefineResult:
    """Follow Kirchhoff solutions into the Cosserat model (extension, shear, distributed loads).

    Parameters
    ----------
    mech : flexkin Mechanism (``legs`` with ``actuation``, ``clamp(u)``, ``rod.EI``; optional
        ``joint`` / ``tip_angle`` for clamped tips; ``platform.attach``; ``load``).
    solutions : a :class:`flexkin.KinematicsResult` (its ``problem`` and ``load`` are used) or a
        sequence of :class:`flexkin.Solution`; each IK solution keeps its pose fixed, each FK
        solution its inputs.
    params : one :class:`CosseratParams` for every leg, or three.
    gravity : (gx, gy) in-plane gravity (m/s^2), weighting each rod by ``mass_per_length g``.
    distributed_load : (fx, fy) N/m, or one pair per leg, added to each leg's
        ``params.distributed_load``.
    problem : ``"ik"`` or ``"fk"``; required when ``solutions`` is a plain sequence.
    load : (Fx, Fy, Mz) on the platform at P; default the result's / the mechanism's load.
    tol : target global error of the shooting integration (relative to the rod length).
    stability : classify the refined solutions (discretised second variation).
    born_search : multi-start around folds for solutions that exist only in the refined model.
    elements : least number of finite elements per rod of the coarser stability mesh (more for rods
        under large forces: 8 per unit of ``L sqrt(R/EI)``; the finer mesh has twice as many).
    options : continuation step control (:class:`ContinuationOptions`).

    Returns
    -------
    RefineResult
        One :class:`RefinedSolution` per input solution (same order) and the born ones.
    """
    t0 = time.perf_counter()
    if hasattr(solutions, "solutions") and hasattr(solutions, "problem"):
        problem = solutions.problem if problem is None else problem
        load = getattr(solutions, "load", None) if load is None else load
        sols = tuple(solutions.solutions)
    else:
        try:
            sols = tuple(solutions)
        except TypeError:
            raise ValueError("solutions: expected a KinematicsResult or a sequence of Solution") from None
    if problem not in ("ik", "fk"):
        raise ValueError(f"problem: expected 'ik' or 'fk', got {problem!r}")
    load = _vec(getattr(mech, "load", (0.0, 0.0, 0.0)) if load is None else load, 3, "load")
    ps = _as_params(params)
    grav = None if gravity is None else _vec(gravity, 2, "gravity")
    f = line_loads(ps, grav, distributed_load)
    if not (isinstance(tol, (int, float)) and 0 < tol < 1e-3):
        raise ValueError(f"tol: expected a number in (0, 1e-3), got {tol!r}")
    if not (isinstance(elements, (int, np.integer)) and 4 <= elements <= 4096):
        raise ValueError(f"elements: expected an integer in [4, 4096], got {elements!r}")
    opts = ContinuationOptions() if options is None else options
    for k, s in enumerate(sols):
        _check_solution(s, k)
    md = _mech_data(mech, problem, ps, f, load, sols)
    prob = _Problem(md)

    # ---- start points ------------------------------------------------------------------
    starts, fixeds, lays, tips = [], [], [], []
    for k, s in enumerate(sols):
        pose = np.asarray(s.pose, float)
        u = np.asarray(s.inputs, float)
        Z = np.concatenate([np.r_[r.tip_force[0], r.tip_force[1], r.base_moment] for r in s.rods]
                           + [u if problem == "ik" else pose])
        fixed = pose if problem == "ik" else u
        wrap = np.array([TWO_PI * round((r.tip_angle - pose[2] - md.beta[i]) / TWO_PI) if md.clamped[i] else 0.0
                         for i, r in enumerate(s.rods)])
        lay = make_layout(md, Z, fixed, tol)
        prob.add(("main", k), fixed, wrap, lay)
        starts.append(Z)
        fixeds.append(fixed)
        lays.append(lay)
        tips.append([np.r_[r.tip, r.tip_angle, r.tip_force, float(getattr(r, "tip_moment", 0.0) or 0.0)]
                     for r in s.rods])
    full = (initial_segments(md, starts, np.array(fixeds).reshape(-1, 3), lays, tips=np.array(tips))
            if sols else [])
    z0 = {k: full[k] / scale_vector(md, lays[k]) for k in range(len(sols))}

    ends: dict[int, BranchEnd] = _run(prob, {("main", k): branch(z0[k], 0.0, +1, opts) for k in z0})
    ends = {key[1]: e for key, e in ends.items()}

    # ---- suspected branch jumping: two branches at the same refined solution -------------
    reruns = 0
    for _ in range(2):
        dup = _duplicates(prob, ends, [("main", k) for k in ends])
        if not dup:
            break
        reruns += len(dup)
        tight = replace(opts, ds0=min(opts.ds0, 0.05), ds_max=min(opts.ds_max, 0.05),
                        max_correction=min(opts.max_correction, 0.01))
        again = _run(prob, {("main", k): branch(z0[k], 0.0, +1, tight) for k in dup})
        for key, e in again.items():
            ends[key[1]] = e
    dup_final = _duplicates(prob, ends, [("main", k) for k in ends])

    # ---- born at folds: multi-start at tau = 1 around every fold -----------------------------
    born_ends: dict[Any, BranchEnd] = {}
    starts_tried = 0
    if born_search:
        gens = {}
        for k, e in ends.items():
            for j, fold in enumerate(e.folds):
                for a in (0.0, 0.02, -0.02, 0.1, -0.1, 0.3, -0.3):
                    key = ("ms", k, j, a)
                    prob.inherit(key, ("main", k))
                    gens[key] = _multistart(fold.z + a * fold.null, opts)
        starts_tried = len(gens)
        found = _run(prob, gens) if gens else {}
        refined = [(("main", k), e.z) for k, e in ends.items() if e.status == "reached"]
        cands = []
        for key, (ok, z) in found.items():
            if ok and _match(prob, key, z, refined) is None and _match(prob, key, z, cands) is None:
                cands.append((key, z))
        gens = {}
        for j, (key, z) in enumerate(cands):
            bkey = ("born", j)
            prob.inherit(bkey, key)
            gens[bkey] = branch(z, 1.0, -1, opts)
        born_ends = _run(prob, gens) if gens else {}
        born_z = {("born", j): z for j, (_, z) in enumerate(cands)}
    else:
        born_z = {}

    # ---- final data at tau = 1 -----------------------------------------------------------
    final_keys = [("main", k) for k, e in ends.items() if e.status == "reached"]
    final_z = {("main", k): ends[k].z for k, e in ends.items() if e.status == "reached"}
    for key, e in born_ends.items():
        if e.status in ("reached", "returned"):
            final_keys.append(key)
            final_z[key] = born_z[key]
    data = _final_data(prob, final_keys, final_z, ps, stability, elements, tol)

    # ---- assemble results ------------------------------------------------------------------
    results = []
    for k, s in enumerate(sols):
        e = ends[k]
        results.append(_result(prob, k, ("main", k), s, e, data.get(("main", k)), ends, z0, dup_final, sols))
    kept = [key for key, e in born_ends.items() if e.status in ("reached", "returned")]
    position = {key: j for j, key in enumerate(kept)}
    born = tuple(_born_result(prob, key, born_ends[key], data[key], born_z, position) for key in kept)
    n_ref = sum(r.status == "refined" for r in results)
    n_fold = sum(r.status == "fold" for r in results)
    n_fail = sum(r.status == "failed" for r in results)
    msg = (f"{n_ref} of {len(results)} solutions refined to tau = 1, {n_fold} ended at a fold, "
           f"{n_fail} failed; {sum(b.status == 'born' for b in born)} born at a fold")
    if not results:
        msg = "no Kirchhoff solutions given: nothing to refine"
    diag = {"evaluations": prob.evaluations, "batched_rounds": prob.rounds, "reruns_for_jumping": reruns,
            "multistart_starts": starts_tried,
            "rk_steps": {k: list(prob.layout[("main", k)].steps) for k in ends},
            "segments": {k: list(prob.layout[("main", k)].segments) for k in ends}}
    return RefineResult(problem=problem, mechanism=mech, load=load, gravity=grav, params=ps,
                        line_loads=tuple((float(a), float(b)) for a, b in f), solutions=tuple(results),
                        born=born, message=msg, elapsed=time.perf_counter() - t0, diagnostics=diag)


# --------------------------------------------------------------------------------------
def _multistart(z, opts):
    cnt = _Counter()
    try:
        ok, zf, R, _, _ = yield from newton_fixed(z, 1.0, opts, cnt, max_iter=40, damped=True)
    except Abort:
        return False, z
    return ok, zf


def _match(prob: _Problem, key, z, others) -> Any:
    cz = prob.canon(key, z)
    for okey, oz in others:
        if oz is None or not prob.same_fixed(key, okey):
            continue
        if float(np.max(np.abs(cz - prob.canon(okey, oz)))) < _SAME:
            return okey
    return None


def _duplicates(prob: _Problem, ends: dict, keys) -> list[int]:
    """Indices of reached branches that share their refined solution with another branch."""
    reached = [key for key in keys if ends[key[1]].status == "reached"]
    if len(reached) < 2:
        return []
    fx = np.array([prob.fixed[k] for k in reached])
    zs = np.array([prob.canon(k, ends[k[1]].z) for k in reached])
    same_f = np.max(np.abs(fx[:, None] - fx[None]) / prob.fixed_scale, -1) < 1e-9
    same_z = np.max(np.abs(zs[:, None] - zs[None]), -1) < _SAME
    hit = same_f & same_z
    np.fill_diagonal(hit, False)
    return sorted(reached[i][1] for i in np.nonzero(hit.any(1))[0])


def _modes(m: NDArray[np.float64], clamped: bool) -> int:
    """Inflection points on (0, L] (SPEC §2): the sign changes of the bending moment strictly
    inside the rod, plus 1 for a pinned tip (a clamped tip is not an inflection)."""
    inner = m[1:-1]
    thr = 1e-9 * max(float(np.max(np.abs(m))), 1e-300)
    sgn = np.sign(inner[np.abs(inner) > thr])
    return int((0 if clamped else 1) + np.count_nonzero(sgn[1:] != sgn[:-1]))


def _final_data(prob: _Problem, keys, zs, ps, stability, elements, tol) -> dict:
    """Tip data, verification and stability of every solution at tau = 1."""
    if not keys:
        return {}
    md = prob.md
    Zhat = [zs[k] for k in keys]
    one = np.ones(len(keys))
    ev = prob(keys, Zhat, one, False)
    ev2 = prob(keys, Zhat, one, False, doubled=True)
    Z = np.array([zh[:12] * scale_vector(md, prob.layout[k])[:12] for zh, k in zip(Zhat, keys)])
    n0 = Z[:, :9].reshape(-1, 3, 3)
    S = len(keys)
    # elements per rod: at least ``elements``, and ~8 per unit of L sqrt(R/EI) (the wave number
    # of a rod under force R), rounded up to a multiple of 16 so that solutions share meshes
    Rmax = np.hypot(n0[..., 0], n0[..., 1]) + np.hypot(md.f[:, 0], md.f[:, 1])[None] * ev.length
    g = np.max(ev.length * np.sqrt(Rmax / md.EI[None]), axis=1)
    nels = np.maximum(elements, 16 * np.ceil(8.0 * g / 16.0)).astype(int)
    r = md.attach(ev.pose)                                     # (S, 3, 2)
    tails = np.zeros((S, 3, 3, 4))
    ntail = np.zeros((S, 3), dtype=np.int64)
    for i in range(3):
        rx, ry = r[:, i, 0] / md.Lref, r[:, i, 1] / md.Lref
        if md.clamped[i]:
            ntail[:, i] = 3
            tails[:, i, 0, 0] = 1.0
            tails[:, i, 1, 1] = 1.0
            tails[:, i, 0, 2] = -ry
            tails[:, i, 1, 2] = rx
            tails[:, i, 2, 2] = 1.0
        else:
            ntail[:, i] = 4
            tails[:, i, 2, 0] = 1.0
            tails[:, i, 0, 1] = 1.0
            tails[:, i, 1, 2] = 1.0
            tails[:, i, 0, 3] = -ry
            tails[:, i, 1, 3] = rx
    geo = np.zeros((S, 4))
    geo[:, :3] = 1.0
    geo[:, 3] = -(r * ev.state[..., 3:5]).sum((1, 2)) / (md.EIref / md.Lref)
    rods_s = np.stack([np.broadcast_to(md.EI, (S, 3)), np.broadcast_to(md.ce, (S, 3)),
                       np.broadcast_to(md.cs, (S, 3)), ev.length], -1)
    verdicts = [None] * S
    strains = np.zeros((S, 3, 2))
    modes = np.ones((S, 3), dtype=int)
    for nel in np.unique(nels):
        J = np.nonzero(nels == nel)[0]
        shp = rod_shape(ev.clamp[J], ev.clamp_angle[J], ev.length[J], md.EI[None], n0[J, :, :2], n0[J, :, 2],
                        axial_compliance=md.ce[None], shear_compliance=md.cs[None], line_load=md.f[None],
                        tau=1.0, n_points=4 * int(nel) + 1, tol=tol)
        strains[J, :, 0] = np.max(np.abs(shp.axial_strain), -1)
        strains[J, :, 1] = np.max(np.abs(shp.shear_strain), -1)
        for jj, j in enumerate(J):
            for i in range(3):
                modes[j, i] = _modes(shp.moment[jj, i], bool(md.clamped[i]))
        if not stability:
            continue
        fields = np.stack([shp.theta, shp.force[..., 0], shp.force[..., 1]], -1)  # (|J|, 3, npts, 3)
        lam = []
        for ne, stride in ((int(nel), 4), (2 * int(nel), 2)):
            mid = np.ascontiguousarray(fields[:, :, stride // 2::stride][:, :, :ne])
            lam.append(smallest_eigenvalue_batch(mid, ne, np.ascontiguousarray(rods_s[J]),
                                                 np.ascontiguousarray(tails[J]), np.ascontiguousarray(ntail[J]),
                                                 np.ascontiguousarray(geo[J]), md.Lref, md.EIref))
        for jj, j in enumerate(J):
            verdicts[j] = verdict(float(lam[0][0][jj]), float(lam[1][0][jj]), int(lam[1][1][jj]))
    out = {}
    for j, key in enumerate(keys):
        rods = []
        for i in range(3):
            st = ev.state[j, i]
            rods.append(RefinedRod(
                clamp=(float(ev.clamp[j, i, 0]), float(ev.clamp[j, i, 1])),
                clamp_angle=float(ev.clamp_angle[j, i]), length=float(ev.length[j, i]),
                base_force=(float(n0[j, i, 0]), float(n0[j, i, 1])), base_moment=float(n0[j, i, 2]),
                tip=(float(st[0]), float(st[1])), tip_angle=float(st[2]),
                tip_force=(float(st[3]), float(st[4])), tip_moment=float(st[5]),
                energy=float(ev.quad[j, i, 0]), load_potential=float(ev.quad[j, i, 1]),
                elongation=float(ev.quad[j, i, 2]),
                max_axial_strain=float(strains[j, i, 0]), max_shear_strain=float(strains[j, i, 1]),
                mode=int(modes[j, i]), steps=int(prob.layout[key].steps[i]),
            ))
        out[key] = {
            "rods": tuple(rods), "pose": tuple(float(x) for x in ev.pose[j]),
            "inputs": tuple(float(x) for x in ev.inputs[j]),
            "residual": float(np.max(np.abs(ev.R[j]))), "verification": float(np.max(np.abs(ev2.R[j]))),
            "verdict": verdicts[j],
        }
    return out


def _shifts(md: MechData, pose, inputs, kpose, kinputs):
    dpos = float(math.hypot(pose[0] - kpose[0], pose[1] - kpose[1]))
    drot = float(math.degrees(pose[2] - kpose[2]))
    du = tuple(float(leg.to_display(a - b)) for a, b, leg in zip(inputs, kinputs, md.legs))
    return dpos, drot, du


def _stab_fields(v):
    if v is None:
        return dict(stable=None, stability_margin=None, stability_error=None, stability_index=None,
                    stability_note="stability not computed")
    return dict(stable=v.stable, stability_margin=v.margin, stability_error=v.error, stability_index=v.index,
                stability_note=v.note)


def _sid(sol: Any, k: int) -> int:
    """The id of input solution ``sol`` (its 1-based position ``k + 1`` when it has none)."""
    sid = getattr(sol, "id", 0)
    return int(sid) if isinstance(sid, (int, np.integer)) and sid >= 1 else k + 1


def _result(prob, k, key, sol, e: BranchEnd, d, ends, z0, dup, sols: Sequence[Any] = ()) -> RefinedSolution:
    md = prob.md
    kpose = tuple(float(x) for x in sol.pose)
    kin = tuple(float(x) for x in sol.inputs)
    kst = getattr(sol, "stable", None)
    fold_tau = e.folds[0].tau if e.folds else None
    common = dict(id=_sid(sol, k), position=k, kirchhoff_pose=kpose, kirchhoff_inputs=kin, kirchhoff_stable=kst,
                  continuation_steps=e.steps, evaluations=e.evaluations, fold_tau=fold_tau)
    if e.status == "reached":
        dpos, drot, du = _shifts(md, d["pose"], d["inputs"], kpose, kin)
        note = e.note
        if k in dup:
            note = (note + "; " if note else "") + "same refined solution as another branch (possible jump)"
        if e.det_changes:
            note = (note + "; " if note else "") + f"det(H_z) changed sign {e.det_changes}x without a fold"
        if len(e.folds) >= 2:
            note = (note + "; " if note else "") + f"passed {len(e.folds)} folds before reaching tau = 1"
        ver = d["verification"]
        return RefinedSolution(
            status="refined", reached=True, tau_end=1.0, merged_with=None, pose=d["pose"], inputs=d["inputs"],
            position_shift=dpos, rotation_shift_deg=drot, input_shift=du, rods=d["rods"],
            residual=d["residual"], verification_residual=ver, verified=bool(ver <= _VERIFY),
            energy=float(sum(r.energy for r in d["rods"])),
            load_potential=float(sum(r.load_potential for r in d["rods"])), note=note,
            **_stab_fields(d["verdict"]), **common)
    merged = None
    note = e.note
    if e.status == "returned":
        for j, zj in z0.items():
            if j != k and prob.same_fixed(key, ("main", j)) and float(
                    np.max(np.abs(prob.canon(key, e.z) - prob.canon(("main", j), zj)))) < _SAME:
                merged = _sid(sols[j], j) if j < len(sols) else j + 1
                break
        note = (f"branch turned back at a fold (tau = {fold_tau:.6g}) and returned to the Kirchhoff model at "
                + (f"solution {merged}" if merged is not None else "a Kirchhoff solution not in the input")
                + (f"; {e.note}" if e.note else ""))
        status, tau_end = "fold", (fold_tau if fold_tau is not None else 0.0)
    else:
        status, tau_end = "failed", float(e.tau)
        if e.folds:
            note += f"; a fold was passed at tau = {fold_tau:.6g}"
    return RefinedSolution(
        status=status, reached=False, tau_end=float(tau_end), merged_with=merged, pose=None, inputs=None,
        position_shift=None, rotation_shift_deg=None, input_shift=None, rods=(), residual=None,
        verification_residual=None, verified=False, energy=None, load_potential=None, note=note,
        **_stab_fields(None), **common)


def _born_result(prob, key, e: BranchEnd, d, born_z, position) -> RefinedSolution:
    """A solution found by the multi-start: born at a fold (its branch, followed down in tau, turned
    back to tau = 1) or connected to a Kirchhoff solution that was not listed."""
    if e.status == "reached":
        status = "born"
        fold_tau = e.folds[0].tau if e.folds else None
        partner = None
        for okey, oz in born_z.items():
            if okey != key and okey in position and prob.same_fixed(key, okey) and float(
                    np.max(np.abs(prob.canon(key, e.z) - prob.canon(okey, oz)))) < _SAME:
                partner = position[okey] + 1
        note = ("exists only in the refined model: born at a fold"
                + (f" at tau = {fold_tau:.6g}" if fold_tau is not None else "")
                + (f" together with born solution {partner}" if partner is not None else ""))
    else:
        status, fold_tau, partner = "unlisted", None, None
        note = "connected to a Kirchhoff solution that was not in the input"
    ver = d["verification"]
    return RefinedSolution(
        id=None, status=status, reached=True, tau_end=1.0, fold_tau=fold_tau, merged_with=partner,
        pose=d["pose"], inputs=d["inputs"], kirchhoff_pose=None, kirchhoff_inputs=None, position_shift=None,
        rotation_shift_deg=None, input_shift=None, rods=d["rods"], kirchhoff_stable=None,
        residual=d["residual"], verification_residual=ver, verified=bool(ver <= _VERIFY),
        energy=float(sum(r.energy for r in d["rods"])), load_potential=float(sum(r.load_potential for r in d["rods"])),
        continuation_steps=e.steps, evaluations=e.evaluations, note=note, **_stab_fields(d["verdict"]))
