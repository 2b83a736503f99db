"""Mechanism-level Cosserat refinement (flexkin.cosserat.refine) against independent checks.

* tau = 0 identity: with a rigid, weightless section the refinement returns the Kirchhoff
  solutions unchanged, and its stability verdicts (discretised second variation, written
  independently of flexkin's Kirchhoff stability code) agree with flexkin's.
* The refined equilibria and their stability are compared with the independent discrete
  beam of ``tests/cosserat_oracle.py`` (energy minimisation, staggered grid, its own Hessian):
  poses converge like O(h^2) to the refined ones and every refined stable solution is a local
  minimum of the discrete energy (unstable ones are saddles with the same Morse index).
* The paper's prototype (§7, Tables 1 and 2) moves by the small amount the paper predicts.
* Folds: a pair of IK solutions near the workspace boundary merges under self-weight.
* FK(IK) round trip on a mechanism with prismatic, revolute and length-actuated legs.
* Clamped rod-platform joints (through a duck-typed mechanism, the joint attributes being
  read with getattr defaults).
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

import flexkin
from flexkin.cosserat import ContinuationOptions, CosseratParams, refine, rod_shape
from flexkin.cosserat.continuation import branch, run_batched
from flexkin.cosserat.params import line_loads

import cosserat_oracle as oracle

try:
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}

NITINOL = CosseratParams.from_material(68e9, 1.5e-3, G=25.5e9)   # paper §7: EA 4.8e5 N, GA 1.8e5 N
SOFT = CosseratParams(EA=1e3, GA=1e3 / 0.9, shear_coefficient=0.9, mass_per_length=0.03)
G = (0.0, -9.81)


@pytest.fixture(scope="module")
def mechs(examples_dir):
    return {name: flexkin.load_mechanism(examples_dir / f"{name}.toml")
            for name in ("prototype_3pfr", "unit_3pfr", "mixed_legs")}


def _oracle(mech, sol, params, gravity, N, eigen=True):
    """Solve the refined solution's FK (its inputs locked) with the oracle from its shapes."""
    f = line_loads((params,) * 3, gravity, None)
    rods, shapes = [], []
    for i, leg in enumerate(mech.legs):
        rr = sol.rods[i]
        rods.append(oracle.OracleRod(clamp=rr.clamp, clamp_angle=rr.clamp_angle, length=rr.length, EI=leg.rod.EI,
                                     EA=params.EA, kGA=params.GA * params.shear_coefficient, load=tuple(f[i]),
                                     clamped_tip=getattr(leg, "joint", "pinned") == "clamped",
                                     tip_angle=getattr(leg, "tip_angle", 0.0)))
        shp = rod_shape(rr.clamp, rr.clamp_angle, rr.length, leg.rod.EI, rr.base_force, rr.base_moment,
                        axial_compliance=params.axial_compliance, shear_compliance=params.shear_compliance,
                        line_load=f[i], n_points=4 * N + 1)
        sg = np.linspace(0.0, 1.0, 4 * N + 1)
        shapes.append(lambda s, shp=shp, sg=sg: (np.interp(s, sg, shp.points[:, 0]),
                                                 np.interp(s, sg, shp.points[:, 1]), np.interp(s, sg, shp.theta)))
    return oracle.solve_mechanism(rods, mech.platform.attach, mech.load, np.array(sol.pose), shapes, N=N,
                                  eigen=eigen)


def _check_against_oracle(mech, sol, params, gravity, Ns=(24, 48, 96)):
    """The oracle's equilibria converge to the refined pose and share its stability.

    Returns the oracle's pose error on the finest mesh and that of its Richardson extrapolation.
    """
    outs = [_oracle(mech, sol, params, gravity, N, eigen=N < 96) for N in Ns]
    assert all(o.converged for o in outs)
    e = [float(np.max(np.abs(o.pose - np.asarray(sol.pose)))) for o in outs]
    # each halving of h at least halves the distance to the refined pose (O(h^2) expected):
    # the discrete equilibria converge to the refined one, not to a nearby different pose
    assert e[2] <= 0.5 * e[1] + 1e-10 and e[1] <= 0.5 * e[0] + 1e-10, e
    fine, mid = outs[2], outs[1]
    if sol.stable is not None:     # the discrete Hessian (N = 24, 48) has the refined stability
        a, b = outs[0], outs[1]
        assert (b.min_eigenvalue > 0) == sol.stable and (a.min_eigenvalue > 0) == sol.stable
        assert b.index == sol.stability_index
        tol = 2 * abs(b.min_eigenvalue - a.min_eigenvalue) + 0.01 * abs(sol.stability_margin)
        assert abs(b.min_eigenvalue - sol.stability_margin) < tol + 3 * sol.stability_error
    extrap = fine.pose + (fine.pose - mid.pose) / 3.0
    return e[2], float(np.max(np.abs(extrap - np.asarray(sol.pose))))


# ---- tau = 0 identity and agreement with flexkin's stability ------------------------------------
def test_kirchhoff_params_give_back_the_kirchhoff_solutions(mechs):
    mech = mechs["unit_3pfr"]
    res = flexkin.ik(mech, (0.05, -0.02, math.radians(10.0)))
    assert len(res.solutions) > 50
    some = res.solutions[::3]  # every third: all d-modes and both verdicts, a third of the time
    r = refine(mech, some, problem="ik", load=res.load, params=CosseratParams.kirchhoff())
    assert len(r.solutions) == len(some)
    assert {s.modes for s in some} == {s.modes for s in res.solutions}
    agree = resolved = 0
    for s, k in zip(r.solutions, some):
        assert s.status == "refined" and s.verified
        assert s.position_shift == 0.0 and s.rotation_shift_deg == 0.0
        assert max(abs(d) for d in s.input_shift) < 1e-10
        for rod, kr in zip(s.rods, k.rods):
            assert np.max(np.abs(np.subtract(rod.tip_force, kr.tip_force))) < 1e-8 * max(1.0, np.hypot(*kr.tip_force))
            assert abs(rod.energy - kr.energy) < 1e-9 * max(1.0, kr.energy)
        assert s.modes == k.modes
        if s.stable is not None and k.stable is not None:
            resolved += 1
            agree += s.stable == k.stable
    assert resolved >= 0.9 * len(some) and agree == resolved
    REPORT["cosserat tau=0 stability agreement (unit 3-PFR)"] = f"{agree}/{resolved} resolved verdicts agree"


# ---- the paper's prototype ------------------------------------------------------------------------
@pytest.mark.parametrize("theta_deg, rho_table", [(60.0, -0.007), (90.0, 0.025), (120.0, 0.058)])
def test_prototype_table2_ik(mechs, theta_deg, rho_table):
    mech = mechs["prototype_3pfr"]
    res = flexkin.ik(mech, (0.0, 0.0, math.radians(theta_deg)))
    r = refine(mech, res, params=NITINOL)
    assert all(s.status == "refined" and s.verified for s in r.solutions)
    # the Table 2 solution: stable, mode 111, rho1 = rho2 = rho3
    k = min((s for s in res.solutions if s.stable and s.modes == (1, 1, 1)),
            key=lambda s: np.max(np.abs(np.subtract(s.inputs, rho_table))))
    s = r.solutions[res.solutions.index(k)]
    assert np.max(np.abs(np.subtract(s.inputs, rho_table))) < 1e-3
    assert s.stable is True and s.modes == (1, 1, 1)
    shift = max(abs(d) for d in s.input_shift)
    strain = max(max(rr.max_axial_strain, rr.max_shear_strain) for rr in s.rods)
    L = 0.908
    assert 1e-9 < shift < 1e-5 * L                       # paper §7: departures of order 1e-5
    assert 1e-8 < strain < 1e-5
    REPORT[f"cosserat prototype IK theta={theta_deg:g}"] = (
        f"Table-2 solution: |d rho| = {shift:.3g} m, max strain {strain:.3g}; over all {len(r.solutions)} "
        f"solutions max |d rho| = {max(max(abs(d) for d in x.input_shift) for x in r.solutions):.3g} m")
    # stability verdicts: the refinement never contradicts a resolved Kirchhoff verdict here
    for x, kk in zip(r.solutions, res.solutions):
        if x.stable is not None and kk.stable is not None:
            assert x.stable == kk.stable


def test_prototype_table1_fk(mechs):
    mech = mechs["prototype_3pfr"]
    res = flexkin.fk(mech, (0.025, 0.025, 0.025))
    r = refine(mech, res, params=NITINOL)
    stable = [s for s in r.solutions if s.stable]
    assert all(s.status == "refined" and s.verified for s in r.solutions)
    th = sorted(math.degrees(s.pose[2]) for s in stable)
    assert any(abs(t - 90.0) < 0.2 for t in th) and any(abs(t + 75.7) < 1.0 for t in th)
    for s in stable:
        assert s.position_shift < 1e-5 and abs(s.rotation_shift_deg) < 1e-3
    REPORT["cosserat prototype FK rho=0.025"] = "; ".join(
        f"theta {math.degrees(s.pose[2]):.3f} deg: |dP| = {s.position_shift:.3g} m, dtheta = "
        f"{s.rotation_shift_deg:.3g} deg" for s in stable)


def _prototype_oracle(mechs, count):
    mech = mechs["prototype_3pfr"]
    res = flexkin.ik(mech, (0.0, 0.0, math.radians(90.0)))
    r = refine(mech, res, params=NITINOL)
    stable = [s for s in r.solutions if s.stable]
    assert len(stable) >= 8
    worst = max(_check_against_oracle(mech, s, NITINOL, None)[0] for s in stable[:count])
    return len(stable[:count]), worst


def test_prototype_stable_solutions_are_oracle_minima(mechs):
    _prototype_oracle(mechs, 3)


@pytest.mark.slow
def test_all_prototype_stable_solutions_are_oracle_minima(mechs):
    n, worst = _prototype_oracle(mechs, 1000)
    REPORT["cosserat prototype stable IK solutions vs FE oracle"] = f"{n} minima, worst pose error (N=96) {worst:.2g}"


# ---- large Cosserat effects: soft rods under self-weight -----------------------------------------
@pytest.fixture(scope="module")
def soft(mechs):
    mech = mechs["unit_3pfr"]
    res = flexkin.ik(mech, (0.05, -0.02, math.radians(10.0)), max_mode=1)
    return mech, res, refine(mech, res, params=SOFT, gravity=G)


def _soft_against_oracle(soft, count):
    mech, res, r = soft
    reached = [s for s in r.solutions if s.reached]
    assert len(reached) >= 6 and any(s.stable for s in reached) and any(s.stable is False for s in reached)
    pick = ([s for s in reached if s.stable][:(count + 1) // 2]
            + [s for s in reached if s.stable is False][:count // 2])
    worst = 0.0
    for s in pick:
        assert s.verified and s.residual < 1e-9
        err, err_x = _check_against_oracle(mech, s, SOFT, G)
        worst = max(worst, err_x)
        # the Cosserat effect (vs Kirchhoff) is resolved by the extrapolated oracle
        assert max(abs(d) for d in s.input_shift) > 20 * err_x
    return len(pick), worst


def test_soft_refinement_against_oracle(soft):
    _soft_against_oracle(soft, 3)


@pytest.mark.slow
def test_all_soft_refinements_against_oracle(soft):
    n, worst = _soft_against_oracle(soft, 1000)
    REPORT["cosserat soft unit 3-PFR vs FE oracle"] = (
        f"{n} refined solutions, worst extrapolated oracle pose error {worst:.2g} m")


def test_result_is_json_without_nan(soft):
    _, _, r = soft
    text = json.dumps(r.to_dict(), allow_nan=False)
    back = json.loads(text)
    assert len(back["solutions"]) == len(r.solutions) and back["problem"] == "refine-ik"


# ---- folds ----------------------------------------------------------------------------------
def _boundary_pose(mech):
    """A pose just inside the IK workspace boundary of unit_3pfr (x ~ 0.4736, y = 0, theta = 0)."""
    lo, hi = 0.47, 0.48
    n_in = len(flexkin.ik(mech, (lo, 0.0, 0.0), max_mode=1).solutions)
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        if len(flexkin.ik(mech, (mid, 0.0, 0.0), max_mode=1).solutions) >= n_in:
            lo = mid
        else:
            hi = mid
    return (lo - 1e-4, 0.0, 0.0)


@pytest.mark.slow
def test_fold_merges_a_pair_near_the_workspace_boundary(mechs):
    mech = mechs["unit_3pfr"]
    res = flexkin.ik(mech, _boundary_pose(mech), max_mode=1)
    p = CosseratParams(EA=1e4, GA=1e4, mass_per_length=0.002)
    r = refine(mech, res, params=p, gravity=G)
    folds = [s for s in r.solutions if s.status == "fold"]
    assert len(folds) == 2
    a, b = folds
    assert a.merged_with == b.id and b.merged_with == a.id
    assert 0.0 < a.fold_tau < 1.0 and abs(a.fold_tau - b.fold_tau) < 1e-6
    assert a.pose is None and a.rods == () and a.stable is None
    assert r.diagnostics["multistart_starts"] > 0 and r.born == ()
    # the opposite weight keeps both
    r2 = refine(mech, res, params=p, gravity=(0.0, 9.81))
    assert all(s.status == "refined" for s in r2.solutions)
    # given only one of the pair, its branch still ends at the fold, partner not listed
    r3 = refine(mech, [res.solutions[a.id - 1]], params=p, gravity=G, problem="ik")
    assert r3.solutions[0].status == "fold" and r3.solutions[0].merged_with is None
    assert abs(r3.solutions[0].fold_tau - a.fold_tau) < 1e-6
    REPORT["cosserat fold test"] = f"pair {a.id},{b.id} merges at tau = {a.fold_tau:.8f}"


def _toy(keys, Z, tau, jac, sign):
    """H(z, tau) = z^2 + sign (tau - 1/2): a fold at tau = 1/2."""
    R = [np.array([z[0] ** 2 + sign * (t - 0.5)]) for z, t in zip(Z, tau)]
    Jz = [np.array([[2.0 * z[0]]]) for z in Z]
    Jt = [np.array([float(sign)]) for _ in Z]
    return R, Jz, Jt


def test_continuation_finds_folds_on_a_toy_problem():
    opts = ContinuationOptions()
    # annihilation: z^2 = 1/2 - tau, from z = +sqrt(1/2) at tau = 0 -> fold at 1/2 -> back to -sqrt(1/2)
    out = run_batched({0: branch(np.array([math.sqrt(0.5)]), 0.0, +1, opts)},
                      lambda k, Z, t, j: _toy(k, Z, t, j, +1))[0]
    assert out.status == "returned" and abs(out.z[0] + math.sqrt(0.5)) < 1e-10
    assert len(out.folds) == 1 and abs(out.folds[0].tau - 0.5) < 1e-8
    # birth: z^2 = tau - 1/2, followed down from tau = 1 -> fold at 1/2 -> back up to tau = 1
    out = run_batched({0: branch(np.array([math.sqrt(0.5)]), 1.0, -1, opts)},
                      lambda k, Z, t, j: _toy(k, Z, t, j, -1))[0]
    assert out.status == "reached" and abs(out.z[0] + math.sqrt(0.5)) < 1e-10
    assert abs(out.folds[0].tau - 0.5) < 1e-8


# ---- all leg types, FK o IK -----------------------------------------------------------------------
def test_fk_ik_round_trip_mixed_legs(mechs):
    mech = mechs["mixed_legs"]
    p = CosseratParams.from_material(68e9, 1.5e-3, G=25.5e9, density=6450.0)
    gravity = (0.0, -9.81 * 20)        # 20 g, for visible effects
    res = flexkin.ik(mech, (0.0, 0.0, math.radians(80.0)), max_mode=1)
    r = refine(mech, res, params=p, gravity=gravity)
    done = [s for s in r.solutions if s.status == "refined" and s.stable]
    assert done
    s = done[0]
    assert s.position_shift == 0.0 and max(abs(d) for d in s.input_shift) > 1e-6
    fk = flexkin.fk(mech, s.inputs, max_mode=1)
    rf = refine(mech, fk, params=p, gravity=gravity)
    d = [np.max(np.abs(np.subtract(x.pose, s.pose))) for x in rf.solutions if x.reached]
    assert min(d) < 1e-9
    twin = rf.solutions[int(np.argmin([np.max(np.abs(np.subtract(x.pose, s.pose))) if x.reached else np.inf
                                       for x in rf.solutions]))]
    assert twin.stable == s.stable
    for a, b in zip(twin.rods, s.rods):
        assert np.max(np.abs(np.subtract(a.tip_force, b.tip_force))) < 1e-7


def test_system_jacobian_matches_finite_differences(mechs):
    """Analytic Jacobian of the assembled equations (all leg types, multiple shooting, IK and FK)."""
    system = importlib.import_module("flexkin.cosserat.system")
    rm = importlib.import_module("flexkin.cosserat.refinement")
    mech = mechs["mixed_legs"]
    p = CosseratParams(EA=2e3, GA=1e3, mass_per_length=0.05)
    f = line_loads((p,) * 3, G, None)
    sol = flexkin.ik(mech, (0.0, 0.0, math.radians(80.0))).solutions[0]
    rng = np.random.default_rng(0)
    for problem in ("ik", "fk"):
        md = rm._mech_data(mech, problem, (p,) * 3, f, (0.01, -0.02, 0.003), [sol])
        Z = np.concatenate([np.r_[r.tip_force, r.base_moment] for r in sol.rods]
                           + [np.asarray(sol.inputs if problem == "ik" else sol.pose)])
        fixed = np.asarray(sol.pose if problem == "ik" else sol.inputs)
        for lay in (system.Layout((40, 40, 40), (1, 1, 1)), system.Layout((40, 60, 40), (2, 3, 1), 3.0)):
            z = system.initial_segments(md, [Z], fixed[None], [lay], tau=0.3)[0]
            zh = z / system.scale_vector(md, lay) + 0.01 * rng.normal(size=lay.size)

            def R(zz, t=0.7):
                return system.evaluate(md, [zz], np.array([t]), fixed[None], np.zeros((1, 3)), [lay], False).R[0]

            ev = system.evaluate(md, [zh], np.array([0.7]), fixed[None], np.zeros((1, 3)), [lay], True)
            h = 1e-6
            fd = np.column_stack([(R(zh + h * e) - R(zh - h * e)) / (2 * h) for e in np.eye(lay.size)])
            assert np.max(np.abs(fd - ev.Jz[0])) < 1e-7 * np.max(np.abs(ev.Jz[0]))
            fdt = (R(zh, 0.7 + h) - R(zh, 0.7 - h)) / (2 * h)
            assert np.max(np.abs(fdt - ev.Jt[0])) < 1e-7 * np.max(np.abs(ev.Jt[0]))


def test_clamp_derivatives_are_the_affine_coefficients(mechs):
    """MechData.clamps gives the derivatives of the (affine) clamp map exactly: they match the
    central differences it used to take, for every kind of leg, and do not depend on u."""
    rm = importlib.import_module("flexkin.cosserat.refinement")
    mech = mechs["mixed_legs"]
    p = CosseratParams(EA=2e3, GA=1e3)
    sol = flexkin.ik(mech, (0.0, 0.0, math.radians(80.0))).solutions[0]
    md = rm._mech_data(mech, "fk", (p,) * 3, line_loads((p,) * 3, G, None), (0.0, 0.0, 0.0), [sol])
    u = np.array([sol.inputs, np.asarray(sol.inputs) + 0.3, [-2.0, 5.0, 0.7]])
    A, al, L, dA, dal, dL = md.clamps(u, deriv=True)
    for i, leg in enumerate(mech.legs):
        hp = 1e-4 * np.maximum(1.0, np.abs(u[:, i]))  # the old step
        ap, tp, lp = leg.clamp(u[:, i] + hp)
        am, tm, lm = leg.clamp(u[:, i] - hp)
        assert np.allclose(dA[:, i], (ap - am) / (2 * hp)[:, None], rtol=1e-9, atol=1e-12)
        assert np.allclose(dal[:, i], (tp - tm) / (2 * hp), rtol=1e-9, atol=1e-12)
        assert np.allclose(dL[:, i], (lp - lm) / (2 * hp), rtol=1e-9, atol=1e-12)
        assert np.all(dA[:, i] == dA[0, i]) and np.all(dal[:, i] == dal[0, i]) and np.all(dL[:, i] == dL[0, i])
    assert {leg.actuation for leg in mech.legs} == {"prismatic", "revolute", "length"}


# ---- clamped rod-platform joints -------------------------------------------------------------------
def _welded(mechs, joints):
    """unit_3pfr with some rods welded to the platform at the tangent of a Kirchhoff solution.

    A stable pinned Kirchhoff solution has zero tip moments, so welding a rod at its tip tangent
    (``tip_angle = th_i(L) - theta``) keeps it an equilibrium: the Kirchhoff start of a
    mechanism with clamped joints.  The legs are flexkin Legs with ``joint``/``tip_angle`` when
    the model has them, duck-typed otherwise (the refinement reads both with getattr defaults).
    """
    base = mechs["unit_3pfr"]
    res = flexkin.ik(base, (0.05, -0.02, math.radians(10.0)), max_mode=1)
    sol = next(s for s in res.solutions if s.stable and s.modes == (1, 1, 1))
    betas = [float(r.tip_angle - sol.pose[2]) for r in sol.rods]
    try:
        legs = tuple(dataclasses.replace(leg, joint=j, tip_angle=b) for leg, j, b in zip(base.legs, joints, betas))
        mech = dataclasses.replace(base, legs=legs)
    except (TypeError, ValueError):   # a model without clamped joints
        legs = tuple(SimpleNamespace(actuation=leg.actuation, clamp=leg.clamp, rod=leg.rod, joint=j, tip_angle=b)
                     for leg, j, b in zip(base.legs, joints, betas))
        mech = SimpleNamespace(name="welded", legs=legs, platform=base.platform, load=base.load)
    return mech, sol


@pytest.mark.parametrize("joints", [("clamped",) * 3, ("pinned", "clamped", "pinned")])
def test_clamped_joints_against_oracle(mechs, joints):
    mech, sol = _welded(mechs, joints)
    p = CosseratParams(EA=300.0, GA=300.0, mass_per_length=0.05)
    for problem in ("fk", "ik"):
        r = refine(mech, [sol], params=p, gravity=G, problem=problem)
        s = r.solutions[0]
        assert s.status == "refined" and s.verified and s.stable is True
        for i, rod in enumerate(s.rods):
            if joints[i] == "clamped":
                assert abs(rod.tip_angle - s.pose[2] - mech.legs[i].tip_angle) < 1e-10
                assert abs(rod.tip_moment) > 1e-4
            else:
                assert abs(rod.tip_moment) < 1e-10
        # platform balance including the tip moments (SPEC §2)
        B = [np.array(rr.tip) - np.array(s.pose[:2]) for rr in s.rods]
        assert np.max(np.abs(sum(np.array(rr.tip_force) for rr in s.rods))) < 1e-10
        assert abs(sum(Bi[0] * rr.tip_force[1] - Bi[1] * rr.tip_force[0] + rr.tip_moment
                       for Bi, rr in zip(B, s.rods))) < 1e-10
        if problem == "fk":
            _, err_x = _check_against_oracle(mech, s, p, G)
            assert s.position_shift > 20 * err_x


# ---- answers, never exceptions; bad input raises ----------------------------------------------
def test_empty_and_bad_input(mechs):
    mech = mechs["unit_3pfr"]
    r = refine(mech, [], params=SOFT, problem="ik")
    assert r.solutions == () and r.born == () and "nothing" in r.message
    res = flexkin.ik(mech, (0.0, 0.0, 0.0), max_mode=1)
    with pytest.raises(ValueError, match="problem"):
        refine(mech, list(res.solutions), params=SOFT)
    with pytest.raises(ValueError, match="params"):
        refine(mech, res, params=1.0)
    with pytest.raises(ValueError, match="gravity"):
        refine(mech, res, params=SOFT, gravity=(1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match="distributed_load"):
        refine(mech, res, params=SOFT, distributed_load=(np.nan, 0.0))
    with pytest.raises(ValueError, match="solutions"):
        refine(mech, [object()], params=SOFT, problem="ik")
    with pytest.raises(ValueError, match="load"):
        refine(mech, res, params=SOFT, load=(1.0, 2.0))


def test_absurd_load_gives_answers_not_exceptions(mechs):
    """Rods far beyond the linear law (strain > 0.5): failed branches with reasons, no NaN."""
    mech = mechs["unit_3pfr"]
    res = flexkin.ik(mech, (0.0, 0.0, 0.0), max_mode=1)
    p = CosseratParams(EA=5.0, GA=5.0, mass_per_length=1.0)
    r = refine(mech, res, params=p, gravity=G, options=ContinuationOptions(max_steps=40))
    assert len(r.solutions) == len(res.solutions)
    assert any(s.status != "refined" for s in r.solutions)
    for s in r.solutions:
        if not s.reached:
            assert s.note and s.pose is None
    json.dumps(r.to_dict(), allow_nan=False)
