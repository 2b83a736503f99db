"""Validation of the independent stability oracle ``tests/stability_oracle.py`` on classical results.

These tests are about the ORACLE (a converged finite-difference discretisation with a
constrained Hessian), not about flexkin's stability code, which the main library's tests will
compare against this oracle.  Classical yardsticks:

* straight cantilever under an axial compressive dead load p EI/L^2: constrained eigenvalues
  mu_k = ((2k - 1) pi/2)^2 - p exactly (units EI/L with the oracle's mass), critical load
  pi^2/4;
* straight clamped column with its tip on an axial slider (lateral motion blocked, rotation
  free): the clamped-pinned Euler load 20.1907 EI/L^2 (tan kL = kL);
* post-buckling of the cantilever (dead load): first-mode elastica stable, second mode
  unstable (index 1), straight rod unstable (index = number of Euler loads passed); the
  smallest eigenvalue of a buckled shape is compared with an independent Sturm-Liouville
  shooting of the continuous second variation;
* post-buckling of the clamped-slider column (supercritical: first buckled mode stable);
* internal consistency: the O(N) banded KKT-inertia path equals the dense null-space
  eigenproblem; the Lagrangian Hessian equals finite differences of the potential along
  constrained curves (checks the multiplier signs and the platform terms);
* mechanism: every IK solution of examples/unit_3rfr.toml at a tests/test_ik.py pose is a
  discrete equilibrium to O(h^2) (pose and tip forces converge like N^-2 to flexkin's values);
  the mechanism index equals the sum of the pinned-rod indices plus the index of the
  continuous pose stiffness (tip forces re-solved by ODE shooting, finite differences).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import null_space
from scipy.optimize import brentq

sys.path.insert(0, os.path.dirname(__file__))
import stability_oracle as S

try:
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}

ROOT = Path(__file__).resolve().parents[1]
PI2_4 = math.pi**2 / 4.0
EULER_CP = 4.493409457909064**2  # clamped-pinned: (kL)^2 with tan kL = kL -> 20.190728556...
ROD = S.RodSpec((0.0, 0.0), 0.0, 1.0, 1.0)


def record(key: str, value) -> None:
    REPORT[f"stability oracle: {key}"] = str(value)
    print(f"[stability oracle] {key}: {value}")


def cantilever(p, rod=ROD, **kw):
    e = np.array([math.cos(rod.clamp_angle), math.sin(rod.clamp_angle)])
    return S.single_rod_stability(rod, S.Tip.free(-p * rod.EI / rod.length**2 * e), **kw)


def slider(p, rod=ROD, **kw):
    e = np.array([math.cos(rod.clamp_angle), math.sin(rod.clamp_angle)])
    tip = np.asarray(rod.clamp) + rod.length * e
    return S.single_rod_stability(rod, S.Tip.slider(tip, e, -p * rod.EI / rod.length**2 * e), **kw)


# ======================================================================================
# 1. straight columns: verdicts and exact eigenvalues
# ======================================================================================
@pytest.mark.parametrize("f", [0.9, 1.1])
def test_cantilever_straight(f):
    p = f * PI2_4
    r = cantilever(p, n_low=3)
    assert r.converged
    assert r.stable == (f < 1.0)
    assert r.index == (0 if f < 1.0 else 1)
    exact = np.array([((2 * k - 1) * math.pi / 2) ** 2 - p for k in (1, 2, 3)])
    # extrapolated smallest eigenvalue: essentially exact; raw N = 400 values: O(h^2)
    assert abs(r.min_eig - exact[0]) < 1e-7
    rel = np.abs(r.eigs - exact) / np.abs(exact)
    assert np.all(rel < 2e-3 * np.array([1, 1, 1]) * (np.arange(1, 4) ** 2)), rel
    # second-order convergence: error ratio N/2 -> N close to 4
    ratio = (r.min_eig_coarse - exact[0]) / (r.min_eig_fine - exact[0])
    assert 3.9 < ratio < 4.1, ratio
    record(f"cantilever p={f}*pi^2/4: mu1 (N=200, 400, extrap, exact)",
           f"{r.min_eig_coarse:.9f}, {r.min_eig_fine:.9f}, {r.min_eig:.11f}, {exact[0]:.11f}")


@pytest.mark.parametrize("f", [0.9, 1.1])
def test_slider_straight(f):
    p = f * 20.19
    r = slider(p, n_low=2)
    assert r.converged
    assert r.stable == (f < 1.0)
    assert r.index == (0 if f < 1.0 else 1)
    assert abs(r.min_eig - (EULER_CP - p)) < 1e-6
    ratio = (r.min_eig_coarse - (EULER_CP - p)) / (r.min_eig_fine - (EULER_CP - p))
    assert 3.8 < ratio < 4.2, ratio
    record(f"slider p={f}*20.19: mu1 (N=200, 400, extrap, exact)",
           f"{r.min_eig_coarse:.9f}, {r.min_eig_fine:.9f}, {r.min_eig:.11f}, {EULER_CP - p:.11f}")


def test_invariance_under_rigid_motion_and_scaling():
    """Clamp moved and rotated, L = 0.7 m, EI = 3 N m^2: dimensionless eigenvalues unchanged."""
    rod = S.RodSpec((0.3, -1.2), 2.2, 0.7, 3.0)
    for f in (0.7, 1.3):
        a = cantilever(f * PI2_4, rod)
        b = cantilever(f * PI2_4)
        assert a.index == b.index
        assert abs(a.min_eig - b.min_eig) < 1e-8 * max(1.0, abs(b.min_eig))
        c = slider(f * EULER_CP, rod)
        d = slider(f * EULER_CP)
        assert c.index == d.index
        assert abs(c.min_eig - d.min_eig) < 1e-7 * max(1.0, abs(d.min_eig))


# ======================================================================================
# 2. critical loads from the sign change of min_eig
# ======================================================================================
def test_critical_loads():
    t0 = time.perf_counter()
    # Brent on the extrapolated smallest eigenvalue (N = 200 / 400)
    pc = S.critical_load(lambda p: cantilever(p), 0.5 * PI2_4, 1.5 * PI2_4)
    ps = S.critical_load(lambda p: slider(p), 15.0, 25.0)
    # plain bisection on the verdict at a fixed resolution (no extrapolation), N = 200
    pcb = S.critical_load(lambda p: cantilever(p, N=200), 0.5 * PI2_4, 1.5 * PI2_4, use="verdict", rtol=1e-6)
    psb = S.critical_load(lambda p: slider(p, N=200), 15.0, 25.0, use="verdict", rtol=1e-6)
    dt = time.perf_counter() - t0
    e = [abs(pc / PI2_4 - 1), abs(ps / EULER_CP - 1), abs(pcb / PI2_4 - 1), abs(psb / EULER_CP - 1)]
    record("critical loads (cantilever, slider) by Brent on extrapolated mu1",
           f"{pc:.10f} (rel err {e[0]:.1e}), {ps:.10f} (rel err {e[1]:.1e})")
    record("critical loads by bisection on the verdict at N=200",
           f"{pcb:.7f} (rel err {e[2]:.1e}), {psb:.7f} (rel err {e[3]:.1e}); all four in {dt:.1f} s")
    assert e[0] < 1e-7 and e[1] < 1e-7
    assert e[2] < 1e-3 and e[3] < 1e-3
    assert abs(ps - 20.19) / 20.19 < 1e-3


# ======================================================================================
# 3. post-buckling
# ======================================================================================
def sl_lowest(state: S.ContinuousRod, rod=ROD):
    """Smallest eigenvalue of -EI phi'' + (n . e(theta)) phi = mu (EI/L^2) phi, phi(0) = 0,
    phi'(L) = 0, along the continuous rod (free tip), by shooting (independent of the oracle)."""
    L, EI = rod.length, rod.EI
    nx, ny = state.tip_force

    def phi_L(mu):
        def f(_s, y):
            th, m, ph, dph = y
            c, s = math.cos(th), math.sin(th)
            return [m / EI, nx * s - ny * c, dph, ((nx * c + ny * s) - mu * EI / L**2) * ph / EI]

        sol = solve_ivp(f, (0, L), [rod.clamp_angle, state.base_moment, 0.0, 1.0], method="DOP853",
                        rtol=1e-12, atol=1e-12)
        return sol.y[3, -1]

    lo = -math.hypot(nx, ny) * L**2 / EI - 1.0
    assert phi_L(lo) > 0
    mu = lo
    while phi_L(mu + 0.25) > 0:
        mu += 0.25
    return brentq(phi_L, mu, mu + 0.25, xtol=1e-13)


@pytest.mark.parametrize("f", [2.0, 3.0])
def test_cantilever_postbuckling_first_mode(f):
    p = f * PI2_4
    sols = S.single_rod_equilibria(ROD, S.Tip.free((-p, 0.0)))
    modes = sorted(s.mode for s in sols)
    assert modes == [0, 1, 1], modes  # straight + the two mirror first-mode elasticas
    for s in sols:
        r = S.single_rod_stability(ROD, S.Tip.free((-p, 0.0)), state=s)
        assert r.converged
        if s.mode == 0:
            assert not r.stable and r.index == 1
            assert abs(r.min_eig - (PI2_4 - p)) < 1e-7
        else:
            assert r.stable and r.index == 0
            mu = sl_lowest(s)
            assert abs(r.min_eig - mu) < 1e-6 * max(1.0, abs(mu)), (r.min_eig, mu)
            # the discrete equilibrium is the elastica to O(h^2)
            assert abs(r.equilibrium.base_moments[0] - s.base_moment) < 1e-4 * abs(s.base_moment)
    mu1 = [S.single_rod_stability(ROD, S.Tip.free((-p, 0.0)), state=s).min_eig for s in sols if s.mode == 1]
    record(f"cantilever {f}x pi^2/4: first-mode elastica mu1 (oracle, Sturm-Liouville)",
           f"{mu1[0]:.9f}, {sl_lowest(next(s for s in sols if s.mode == 1)):.9f}")


def test_cantilever_second_mode():
    f = 12.0  # a second mode exists only beyond 9 pi^2/4
    p = f * PI2_4
    sols = S.single_rod_equilibria(ROD, S.Tip.free((-p, 0.0)))
    assert sorted(s.mode for s in sols) == [0, 1, 1, 2, 2]
    got = {}
    for s in sols:
        r = S.single_rod_stability(ROD, S.Tip.free((-p, 0.0)), state=s)
        assert r.converged
        got.setdefault(s.mode, []).append((r.stable, r.index, r.min_eig))
        if s.mode:
            mu = sl_lowest(s)
            assert abs(r.min_eig - mu) < 1e-6 * max(1.0, abs(mu)), (s.mode, r.min_eig, mu)
    assert all(v[:2] == (False, 2) for v in got[0])  # straight, beyond the second Euler load
    assert all(v[:2] == (True, 0) for v in got[1])
    assert all(v[:2] == (False, 1) for v in got[2])
    record("cantilever 12x pi^2/4: (stable, index, mu1) per mode", {k: v[0] for k, v in got.items()})


def test_slider_postbuckling():
    """Clamped column with an axial slider at 1.5x Euler: supercritical, first buckled mode stable."""
    p = 1.5 * EULER_CP
    tip = S.Tip.slider((1.0, 0.0), (1.0, 0.0), (-p, 0.0))
    sols = S.single_rod_equilibria(ROD, tip)
    first = [s for s in sols if s.mode == 1]
    straight = [s for s in sols if s.mode == 0]
    assert len(first) == 2 and len(straight) == 1
    for s in first:
        assert abs(s.tip[1]) < 1e-9 and abs(s.tip_moment) < 1e-9
        r = S.single_rod_stability(ROD, tip, state=s)
        assert r.converged and r.stable and r.index == 0
    r0 = S.single_rod_stability(ROD, tip, state=straight[0])
    assert not r0.stable and r0.index == 1
    verdicts = []
    for s in sols:
        r = S.single_rod_stability(ROD, tip, state=s)
        verdicts.append((s.mode, r.index))
    record("slider 1.5x Euler: (mode, index) of every equilibrium found", verdicts)


@pytest.mark.slow
def test_pinned_rod_branches():
    """Tip pinned at (0.8 L, 0): the first buckled shape (d-mode 2) is stable, d-mode 3 unstable."""
    tip = S.Tip.pinned((0.8, 0.0))
    sols = S.single_rod_equilibria(ROD, tip)
    res = [(s.mode, S.single_rod_stability(ROD, tip, state=s).index) for s in sols]
    record("pinned (0.8, 0): (mode, index)", res)
    assert sorted(res) == [(2, 0), (2, 0), (3, 1), (3, 1)]


# ======================================================================================
# 4. internal consistency
# ======================================================================================
def _unit_3rfr():
    import flexkin

    return flexkin.load_mechanism(str(ROOT / "examples" / "unit_3rfr.toml"))


def _ik(pose_deg):
    import flexkin

    x, y, th = pose_deg
    return flexkin.ik(_unit_3rfr(), (x, y, math.radians(th)), load=(0.0, 0.0, 0.0), max_mode=2)


def test_banded_equals_dense():
    mech = _unit_3rfr()
    res = _ik((0.2, 0.0, 0.0))
    for sol in res.solutions[:6]:
        a = S.solution_stability(mech, sol, (0, 0, 0), N=60, n_low=3)
        b = S.solution_stability(mech, sol, (0, 0, 0), N=60, n_low=3, method="dense")
        assert a.index == b.index and a.index_coarse == b.index_coarse
        assert np.allclose(a.eigs, b.eigs, rtol=1e-8, atol=1e-8), (a.eigs, b.eigs)
    for f in (0.9, 1.1, 3.0):
        a = slider(f * EULER_CP, N=80, n_low=3)
        b = slider(f * EULER_CP, N=80, n_low=3, method="dense")
        assert a.index == b.index and np.allclose(a.eigs, b.eigs, rtol=1e-8, atol=1e-8)


def _project(prob, z, A_fun, iters=30):
    """Newton projection of z onto g(z) = 0 along range(A^T) (minimum-norm corrections)."""
    z = z.copy()
    for _ in range(iters):
        g = prob.constraint(z)
        if np.max(np.abs(g)) < 1e-15:
            break
        A = A_fun(z)
        z -= A.T @ np.linalg.solve(A @ A.T, g)
    return z


def test_hessian_against_finite_differences():
    """v^T H_W v = d^2/dt^2 V(z(t)) along constrained curves through a discrete equilibrium."""
    rng = np.random.default_rng(3)
    mech = _unit_3rfr()
    sol = _ik((0.2, 0.0, 0.0)).solutions[0]
    load = (0.3, -0.2, 0.05)  # a load also exercises the -F.P - M theta_p terms (the
    # equilibrium is re-solved by the discrete Newton from the unloaded shape)
    rods = S.mechanism_rods(mech, sol.inputs)
    cases = []
    prob = S._mechanism_problem(rods, mech.platform.attach, load, 24)
    th = [S.sample_rod(r, sol.rods[i].tip_force, sol.rods[i].base_moment, 24)[0] for i, r in enumerate(rods)]
    eq = prob.newton(prob.pack(th, sol.pose), np.ravel([r.tip_force for r in sol.rods]))
    assert eq.converged
    cases.append((prob, eq))
    p = 1.5 * EULER_CP
    sp = S._single_problem(ROD, S.Tip.slider((1.0, 0.0), (1.0, 0.0), (-p, 0.0)), 24)
    s1 = next(s for s in S.single_rod_equilibria(ROD, S.Tip.slider((1.0, 0.0), (1.0, 0.0), (-p, 0.0)))
              if s.mode == 1)
    eq1 = sp.newton(sp.pack([S.sample_rod(ROD, s1.tip_force, s1.base_moment, 24)[0]], []))
    assert eq1.converged
    cases.append((sp, eq1))
    worst = 0.0
    for prob, eq in cases:
        z0 = prob.pack(eq.thetas, eq.q)
        H = prob.hess_dense(z0, eq.lam)
        A = prob.jac(z0)
        Z = null_space(A)
        for _ in range(4):
            v = Z @ rng.standard_normal(Z.shape[1])
            v /= np.max(np.abs(v))
            t = 1e-3
            Vp = prob.potential(_project(prob, z0 + t * v, prob.jac))
            Vm = prob.potential(_project(prob, z0 - t * v, prob.jac))
            V0 = prob.potential(z0)
            fd = (Vp - 2 * V0 + Vm) / t**2
            ex = float(v @ H @ v)
            err = abs(fd - ex) / max(1.0, abs(ex))
            worst = max(worst, err)
            assert err < 1e-4, (fd, ex)
    record("Lagrangian Hessian vs FD along constrained curves (max rel err)", f"{worst:.1e}")


# ======================================================================================
# 5. the mechanism check (examples/unit_3rfr.toml, pose of tests/test_ik.py)
# ======================================================================================
def _check_mechanism_pose(pose_deg, label, file="unit_3rfr.toml", load=(0.0, 0.0, 0.0)):
    from ik_oracle import Geom

    import flexkin

    mech = flexkin.load_mechanism(str(ROOT / "examples" / file))
    x, y, th = pose_deg
    t0 = time.perf_counter()
    res = flexkin.ik(mech, (x, y, math.radians(th)), load=load, max_mode=2)
    t_ik = time.perf_counter() - t0
    assert res.solutions
    L = Geom.of(mech).L_ref
    verdicts = []
    t0 = time.perf_counter()
    for sol in res.solutions:
        r = S.solution_stability(mech, sol, load)
        n = np.array([rs.tip_force for rs in sol.rods])
        scale = max(float(np.mean([rs.EI for rs in sol.rods])) / L**2, float(np.max(np.abs(n))))
        eqf, eqc = r.equilibrium, r.equilibrium_coarse
        assert eqf.converged and eqc.converged, (eqf.residual, eqc.residual)
        dp_f = float(np.max(np.abs(eqf.q - np.array(sol.pose)) / [L, L, 1.0]))
        dp_c = float(np.max(np.abs(eqc.q - np.array(sol.pose)) / [L, L, 1.0]))
        dn_f = float(np.max(np.abs(eqf.tip_forces - n))) / scale
        dn_c = float(np.max(np.abs(eqc.tip_forces - n))) / scale
        # same equilibrium: discretisation-size differences that shrink like N^-2
        assert dp_f < 5e-4 and dn_f < 2e-3, (sol.modes, dp_f, dn_f)
        for c, f in ((dp_c, dp_f), (dn_c, dn_f)):
            if c > 1e-8:  # (a difference may vanish by symmetry)
                assert c / max(f, 1e-300) > 3.0, (sol.modes, dp_c, dp_f, dn_c, dn_f)
        assert r.converged and r.index == r.index_coarse
        verdicts.append((sol.mode_label, r.stable, r.index, round(r.min_eig, 5)))
    dt = time.perf_counter() - t0
    n_st = sum(v[1] for v in verdicts)
    record(f"{label}: {len(verdicts)} IK solutions, stable / unstable",
           f"{n_st} / {len(verdicts) - n_st}  (ik {t_ik:.1f} s, oracle {dt:.1f} s)")
    record(f"{label}: (modes, stable, index, min_eig) per solution", verdicts)
    return res, verdicts


def test_mechanism_unit_3rfr():
    _check_mechanism_pose((0.05, 0.02, 20.0), "unit_3rfr at (0.05, 0.02, 20 deg)")


def test_mechanism_unit_3rfr_mixed_pose():
    _check_mechanism_pose((0.2, 0.0, 0.0), "unit_3rfr at (0.2, 0, 0 deg)")


def test_mechanism_mixed_legs_loaded():
    """Prismatic + revolute + length legs and a non-zero load (the file's [load])."""
    import flexkin

    load = tuple(flexkin.load_mechanism(str(ROOT / "examples" / "mixed_legs.toml")).load)
    assert any(load)
    _check_mechanism_pose((0.02, -0.01, 15.0), f"mixed_legs at (0.02, -0.01, 15 deg), load {load}",
                          file="mixed_legs.toml", load=load)


@pytest.mark.slow
def test_mechanism_unit_3rfr_many_solutions():
    _check_mechanism_pose((0.0, 0.05, 0.0), "unit_3rfr at (0, 0.05, 0 deg)")


# ---- index decomposition: mechanism = pinned rods + continuous pose stiffness ----------------
def _shoot_pinned(rod: S.RodSpec, n0, m00, B, iters=12):
    """Continuous clamped-pinned rod with tip at B: Newton on (n, m0) with variational equations.

    Returns the tip force n and the tip stiffness dn/dB (2x2, the Hessian of the rod's energy
    as a function of its pinned tip position), from the converged sensitivities.
    """
    EI = rod.EI

    def f(_s, y):
        th, m = y[2], y[3]
        c, s = math.cos(th), math.sin(th)
        nx, ny = p[0], p[1]
        S_ = y[4:].reshape(4, 3)  # d(x, y, th, m)/d(nx, ny, m0)
        dS = np.empty((4, 3))
        dS[0] = -s * S_[2]
        dS[1] = c * S_[2]
        dS[2] = S_[3] / EI
        dS[3] = (nx * c + ny * s) * S_[2] + np.array([s, -c, 0.0])
        return np.concatenate([[c, s, m / EI, nx * s - ny * c], dS.ravel()])

    p = np.array([n0[0], n0[1], m00], float)
    for it in range(iters + 1):
        y0 = np.zeros(16)
        y0[:4] = [rod.clamp[0], rod.clamp[1], rod.clamp_angle, p[2]]
        y0[4 + 3 * 3 + 2] = 1.0  # dm/dm0
        y = solve_ivp(f, (0, rod.length), y0, method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
        r = np.array([y[0] - B[0], y[1] - B[1], y[3]])
        J = y[4:].reshape(4, 3)[[0, 1, 3]]
        if it == iters:
            break
        dp = np.linalg.solve(J, -r)
        p += dp
        if np.max(np.abs(dp) / (1.0 + np.abs(p))) < 1e-14:
            iters = it + 1  # one more pass for the Jacobian at the converged point
    # (dB, 0) = J dp  ->  dn/dB = first two rows / columns of J^-1
    Ji = np.linalg.inv(J)
    return p[:2].copy(), Ji[:2, :2], float(np.max(np.abs(r[:2]))) / rod.length + abs(r[2]) * rod.length / EI


def _pose_stiffness(mech, sol, load):
    """Hessian of V*(q) = sum_i E_i*(B_i(q)) - F.P - M theta_p: the pose stiffness with every rod
    re-solved by shooting as a continuous clamped-pinned rod (independent of the discretisation).

    grad V* = sum_i J_i^T n_i - (F, M), J_i = dB_i/dq = [I, (-a_y, a_x)];
    K = sum_i J_i^T (dn_i/dB_i) J_i - diag(0, 0, sum_i a_i . n_i).
    """
    rods = S.mechanism_rods(mech, sol.inputs)
    b = np.asarray(mech.platform.attach, float)
    q = np.array(sol.pose, float)
    c, s = math.cos(q[2]), math.sin(q[2])
    a = b @ np.array([[c, s], [-s, c]])  # rows: Rot(theta_p) b_i
    K = np.zeros((3, 3))
    grad = -np.asarray(load, float)
    asym = 0.0
    for i, rod in enumerate(rods):
        n, Sn, res = _shoot_pinned(rod, sol.rods[i].tip_force, sol.rods[i].base_moment, q[:2] + a[i])
        assert res < 1e-9
        d = 1.0 / np.sqrt(np.abs(np.diag(Sn)))
        Ss = d[:, None] * Sn * d[None, :]
        asym = max(asym, float(abs(Ss[0, 1] - Ss[1, 0])))
        Ji = np.array([[1.0, 0.0, -a[i, 1]], [0.0, 1.0, a[i, 0]]])
        K += Ji.T @ (0.5 * (Sn + Sn.T)) @ Ji
        K[2, 2] -= float(a[i] @ n)
        grad += Ji.T @ n
    fs = float(np.mean([r.EI for r in rods])) / float(np.mean([r.length for r in rods])) ** 2
    assert np.max(np.abs(grad)) < 1e-7 * max(fs, max(r.R for r in sol.rods))  # an equilibrium
    return rods, K, asym


MIXED_LOAD = (0.0, -0.05, 0.002)  # examples/mixed_legs.toml's [load]


@pytest.mark.parametrize("file, pose_deg, load, which", [
    ("unit_3rfr.toml", (0.2, 0.0, 0.0), (0.0, 0.0, 0.0), slice(0, 17, 3)),
    ("mixed_legs.toml", (0.02, -0.01, 15.0), MIXED_LOAD, slice(0, 24, 5)),
])
def test_mechanism_index_decomposition(file, pose_deg, load, which):
    """index(mechanism) = sum_i index(rod i pinned at B_i) + n_neg(d^2 V*/dq^2) (Haynsworth)."""
    import flexkin

    mech = flexkin.load_mechanism(str(ROOT / "examples" / file))
    x, y, th = pose_deg
    sols = flexkin.ik(mech, (x, y, math.radians(th)), load=load, max_mode=2).solutions[which]
    assert sols
    rows = []
    for sol in sols:
        r = S.solution_stability(mech, sol, load)
        rods, K, asym = _pose_stiffness(mech, sol, load)
        assert asym < 1e-6  # a pinned rod's tip stiffness is a Hessian: symmetric
        B = [rs.tip for rs in sol.rods]
        idx_rods = [S.single_rod_stability(rod, S.Tip.pinned(B[i]),
                                           state=S.ContinuousRod(sol.rods[i].tip_force, sol.rods[i].base_moment)).index
                    for i, rod in enumerate(rods)]
        d = 1.0 / np.sqrt(np.abs(np.diag(K)))
        kq = np.linalg.eigvalsh(d[:, None] * K * d[None, :])  # same inertia as K (congruence)
        assert np.min(np.abs(kq)) > 1e-6 * np.max(np.abs(kq))
        n_k = int(np.sum(kq < 0))
        rows.append((sol.mode_label, r.index, idx_rods, n_k))
        assert r.index == sum(idx_rods) + n_k, rows[-1]
    record(f"index decomposition, {file} at {pose_deg}: (modes, mech index, pinned-rod indices, "
           "pose-stiffness index)", rows)


@pytest.mark.slow
def test_mechanism_index_decomposition_all():
    test_mechanism_index_decomposition("unit_3rfr.toml", (0.2, 0.0, 0.0), (0.0, 0.0, 0.0), slice(None))
    test_mechanism_index_decomposition("unit_3rfr.toml", (0.05, 0.02, 20.0), (0.0, 0.0, 0.0), slice(None))
    test_mechanism_index_decomposition("mixed_legs.toml", (0.02, -0.01, 15.0), MIXED_LOAD, slice(None))
