"""One planar Cosserat rod (flexkin.cosserat.rod): shooting, Jacobians, classical results.

References used below
---------------------
* Timoshenko & Gere, *Theory of Elastic Stability*, 2nd ed. (1961), §2.13: a vertical column
  clamped at its foot buckles under its own weight when ``q L^3 / EI = 7.837``, the root of
  ``J_{-1/3}((2/3) sqrt(q L^3 / EI)) = 0`` (Greenhill 1881) — computed here from the Bessel
  function to full precision.
* Small-deflection cantilever: ``P L^3/(3 EI) + P L/(kappa G A)`` (Timoshenko beam) and the
  heavy cantilever ``q L^4 / (8 EI)``.
* Large-deflection heavy cantilever: no citable table of the heavy elastica was available
  offline, so the reference is an independent high-accuracy solution of the classical
  inextensible formulation ``EI th'' = q (L - s) cos th`` (``th(0) = 0, th'(L) = 0``, weight
  ``q`` per length downwards) by
  ``scipy.integrate.solve_bvp`` (collocation, a different method and formulation), plus the
  finite-element oracle of ``tests/cosserat_oracle.py`` for the extensible, shearable case.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize
import scipy.special

import flexkin
from flexkin.cosserat import CosseratParams, auto_steps, rod_shape, shoot
from flexkin.cosserat.params import circular_shear_coefficient

import cosserat_oracle as oracle


# ---- helpers --------------------------------------------------------------------------------
def _free_tip_moment0(L, EI, n0, f=(0.0, 0.0), alpha=0.0, ce=0.0, cs=0.0, m0=0.0):
    """Base moment m0 making m(L) = 0 (free tip), by Newton on the analytic d m(L) / d m0."""
    for _ in range(50):
        r = shoot((0.0, 0.0), alpha, L, EI, n0, m0, axial_compliance=ce, shear_compliance=cs,
                  line_load=f, tau=1.0)
        dm = r.d_start[5, 5]
        step = -r.tip_moment / dm
        m0 += step
        if abs(step) < 1e-15 * max(1.0, abs(m0)):
            break
    return m0, shoot((0.0, 0.0), alpha, L, EI, n0, m0, axial_compliance=ce, shear_compliance=cs,
                     line_load=f, tau=1.0)


#: chart points (v, phis) of flexkin's unified chart (phis < pi/2; lower phis = higher d-modes)
CHART = [(0.3, 0.5), (1.0, 1.2), (-2.0, 0.2), (0.5, -3.0), (0.1, -5.0), (2.5, -1.0), (-1.5, -4.0),
         (0.05, 1.5), (3.0, 0.9), (-0.7, -2.5), (1.7, -7.5), (-3.0, -10.0)]


# ---- the integrator (its table: tests/test_dop853.py) ---------------------------------------
@pytest.mark.parametrize("v, phis", CHART)
def test_kirchhoff_limit_matches_closed_form(v, phis):
    """tau = 0 (and rigid section, no load, tau = 1) reproduce flexkin's elliptic closed form."""
    st = flexkin.RodState.from_chart(v, phis, 0.9, 0.27, (0.1, -0.2), 0.7)
    L, EI = st.length, st.EI
    for kw in ({"tau": 0.0, "axial_compliance": 1e-3, "shear_compliance": 2e-3, "line_load": (3.0, -4.0)},
               {"tau": 1.0}):
        r = shoot(st.clamp, st.clamp_angle, L, EI, st.tip_force, st.base_moment, jacobian=False, **kw)
        assert np.max(np.abs(r.tip - st.tip)) < 1e-10 * L
        assert abs(r.tip_moment) < 1e-10 * EI / L
        assert abs(math.remainder(r.tip_angle - st.tip_angle, 2 * math.pi)) < 1e-10
        assert np.max(np.abs(r.tip_force - st.tip_force)) == 0.0  # n is constant without load
        assert abs(r.energy - st.energy) < 1e-10 * max(st.energy, EI / L)
        assert r.elongation == 0.0 and r.load_potential == 0.0


def test_kirchhoff_shape_matches_closed_form():
    st = flexkin.RodState.from_chart(1.0, -4.0, 0.9, 0.27, (0.0, 0.0), 0.2)
    if not (hasattr(st, "shape") and hasattr(st, "curvature")):  # pragma: no cover - optional RodState API
        pytest.skip("RodState.shape / curvature not available")
    shp = rod_shape(st.clamp, st.clamp_angle, st.length, st.EI, st.tip_force, st.base_moment, tau=0.0,
                    n_points=51)
    ref = st.shape(51)
    assert np.max(np.abs(shp.points - ref)) < 1e-10
    assert np.max(np.abs(shp.moment / st.EI - st.curvature(51))) < 1e-9


def test_step_count_controls_the_error():
    """The automatic step count meets its tolerance on hard rods (mode 3, large forces)."""
    for v, phis in [(2.5, -1.0), (-3.0, -10.0), (1.7, -7.5)]:
        st = flexkin.RodState.from_chart(v, phis, 1.0, 1.0)
        for tol in (1e-8, 1e-12):
            r = shoot(st.clamp, st.clamp_angle, 1.0, 1.0, st.tip_force, st.base_moment, tau=0.0, tol=tol,
                      jacobian=False)
            assert np.max(np.abs(r.tip - st.tip)) < 10 * tol
        n_lo = auto_steps(1.0, 1.0, st.tip_force, st.base_moment, tol=1e-8)
        n_hi = auto_steps(1.0, 1.0, st.tip_force, st.base_moment, tol=1e-12)
        assert n_hi > n_lo


# ---- analytic Jacobians -----------------------------------------------------------------------
def test_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    A, alpha, L, EI = np.array([0.2, -0.1]), 0.4, 0.8, 0.5
    n0, m0 = np.array([0.7, -1.3]), 0.6
    kw = dict(axial_compliance=0.02, shear_compliance=0.05, line_load=(0.4, -2.0), steps=60)
    tau = 0.7
    r = shoot(A, alpha, L, EI, n0, m0, tau=tau, **kw)
    x0 = np.r_[A, alpha, n0, m0]

    def tip(x, L=L, tau=tau):
        return shoot(x[0:2], x[2], L, EI, x[3:5], x[5], tau=tau, jacobian=False, **kw).state

    h = 1e-6
    fd = np.column_stack([(tip(x0 + h * e) - tip(x0 - h * e)) / (2 * h) for e in np.eye(6)])
    assert np.max(np.abs(fd - r.d_start)) < 1e-7 * np.max(np.abs(r.d_start))
    fdL = (tip(x0, L=L + h) - tip(x0, L=L - h)) / (2 * h)
    assert np.max(np.abs(fdL - r.d_length)) < 1e-7 * np.max(np.abs(r.d_length))
    fdt = (tip(x0, tau=tau + h) - tip(x0, tau=tau - h)) / (2 * h)
    assert np.max(np.abs(fdt - r.d_tau)) < 1e-7 * np.max(np.abs(r.d_tau))
    # batched call equals single calls
    B = rng.normal(size=(4, 2))
    rb = shoot(B, alpha, L, EI, n0, m0, tau=tau, **kw)
    for j in range(4):
        rj = shoot(B[j], alpha, L, EI, n0, m0, tau=tau, **kw)
        assert np.array_equal(rb.state[j], rj.state) and np.array_equal(rb.d_start[j], rj.d_start)


# ---- classical results ----------------------------------------------------------------------
def test_pure_tension_is_exact():
    L, EI, EA, F, alpha = 0.908, 0.27, 4.8e5, 37.0, 0.3
    d = np.array([math.cos(alpha), math.sin(alpha)])
    r = shoot((1.0, 2.0), alpha, L, EI, F * d, 0.0, axial_compliance=1 / EA, shear_compliance=1 / 1.6e5)
    expected = np.array([1.0, 2.0]) + (L + F * L / EA) * d
    # exact up to rounding accumulated over the Runge-Kutta steps
    assert np.max(np.abs(r.tip - expected)) < 2e-13
    assert abs(r.elongation - F * L / EA) < 1e-12 * F * L / EA
    assert abs(r.energy - F ** 2 * L / (2 * EA)) < 1e-12 * F ** 2 * L / (2 * EA)
    assert abs(r.tip_angle - alpha) < 1e-15 and r.tip_moment == 0.0


@pytest.mark.parametrize("kGA_ratio", [10.0, 1e3])
def test_small_deflection_cantilever_with_shear(kGA_ratio):
    """Tip deflection P L^3/(3EI) + P L/(kappa G A) for a small transverse tip load."""
    L, EI = 1.3, 2.0
    kGA = kGA_ratio * EI / L ** 2
    P = 1e-5 * EI / L ** 2
    m0, r = _free_tip_moment0(L, EI, (0.0, -P), cs=1 / kGA, m0=-P * L)
    delta = -r.tip[1]
    expected = P * L ** 3 / (3 * EI) + P * L / kGA
    assert abs(delta - expected) < 1e-8 * expected
    assert abs(m0 + P * L) < 1e-8 * P * L


def test_small_deflection_heavy_cantilever():
    L, EI, q = 0.9, 0.27, 1e-6
    f = (0.0, -q)
    n0 = (0.0, -q * L)                  # n(L) = n(0) - f L = 0: free tip
    _, r = _free_tip_moment0(L, EI, n0, f=f, m0=-q * L ** 2 / 2)
    expected = q * L ** 4 / (8 * EI)
    assert abs(-r.tip[1] - expected) < 1e-8 * expected
    assert np.max(np.abs(r.tip_force)) < 1e-18


def test_greenhill_heavy_column():
    """Critical self-weight of a clamped-free vertical column (Timoshenko & Gere §2.13)."""
    L, EI = 1.0, 1.0
    j = scipy.optimize.brentq(lambda x: scipy.special.jv(-1.0 / 3.0, x), 1.0, 2.5)
    q_ref = 9.0 / 4.0 * j ** 2                         # 7.8373...
    assert abs(q_ref - 7.837) < 1e-3                   # the textbook value

    def dmL_dm0(q):  # straight column pointing up, weight q down; free tip: n0 = f L
        r = shoot((0.0, 0.0), math.pi / 2, L, EI, (0.0, -q * L), 0.0, line_load=(0.0, -q), tol=1e-13)
        return r.d_start[5, 5]

    q_cr = scipy.optimize.brentq(dmL_dm0, 5.0, 10.0, xtol=1e-13)
    assert abs(q_cr - q_ref) < 1e-9 * q_ref


def _heavy_elastica_bvp(qL3):
    """Independent reference: EI th'' = q (L - s) cos th, th(0)=0, th'(L)=0; L = EI = 1."""
    s = np.linspace(0.0, 1.0, 201)

    def fun(s, y):
        th, k, x, yy = y
        return np.vstack([k, qL3 * (1.0 - s) * np.cos(th), np.cos(th), np.sin(th)])

    def bc(ya, yb):
        return np.array([ya[0], yb[1], ya[2], ya[3]])

    y0 = np.zeros((4, s.size))
    y0[2] = s
    sol = scipy.integrate.solve_bvp(fun, bc, s, y0, tol=1e-11, max_nodes=200000)
    assert sol.status == 0
    return sol.y[2, -1], sol.y[3, -1], sol.y[0, -1]


@pytest.mark.parametrize("qL3", [1.0, 3.0, 10.0])
def test_large_deflection_heavy_cantilever(qL3):
    x_ref, y_ref, th_ref = _heavy_elastica_bvp(qL3)
    m0, r = _free_tip_moment0(1.0, 1.0, (0.0, -qL3), f=(0.0, -qL3), m0=-qL3 / 2)
    assert abs(r.tip[0] - x_ref) < 1e-8 and abs(r.tip[1] - y_ref) < 1e-8
    assert abs(r.tip_angle - th_ref) < 1e-8
    assert y_ref < -0.1                                 # genuinely large deflection


def test_extensible_heavy_cantilever_against_fe_oracle():
    """Extension, shear and weight together: the FE oracle converges (O(h^2)) to the shooting tip."""
    L, EI, EA, kGA, q = 1.0, 1.0, 60.0, 25.0, 4.0
    _, r = _free_tip_moment0(L, EI, (0.0, -q * L), f=(0.0, -q), ce=1 / EA, cs=1 / kGA, m0=-q * L / 2)
    tips = [oracle.cantilever(L, EI, EA, kGA, q=(0.0, -q), N=N)[0] for N in (32, 64)]
    e32, e64 = (np.max(np.abs(t - r.tip)) for t in tips)
    assert e64 < 0.3 * e32                              # second order: ratio ~ 1/4
    extrap = tips[1] + (tips[1] - tips[0]) / 3.0
    assert np.max(np.abs(extrap - r.tip)) < 0.05 * e64
    # and the Kirchhoff rod is clearly different (the effect is resolved)
    _, rk = _free_tip_moment0(L, EI, (0.0, -q * L), f=(0.0, -q), m0=-q * L / 2)
    assert np.max(np.abs(rk.tip - r.tip)) > 100 * e64


def test_energy_and_load_potential_quadratures():
    """The carried quadratures equal Simpson integrals of the sampled fields."""
    L, EI, ce, cs, f = 0.8, 0.4, 0.01, 0.03, np.array([0.5, -1.5])
    shp = rod_shape((0.0, 0.0), 0.3, L, EI, (0.4, 0.9), 0.2, axial_compliance=ce, shear_compliance=cs,
                    line_load=f, n_points=401)
    th, n, m = shp.theta, shp.force, shp.moment
    nt = n[:, 0] * np.cos(th) + n[:, 1] * np.sin(th)
    nn = -n[:, 0] * np.sin(th) + n[:, 1] * np.cos(th)
    dens = m ** 2 / (2 * EI) + 0.5 * (ce * nt ** 2 + cs * nn ** 2)
    U = scipy.integrate.simpson(dens, x=shp.s)
    W = -scipy.integrate.simpson(shp.points @ f, x=shp.s)
    assert abs(U - shp.energy[-1]) < 1e-10 and abs(W - shp.load_potential[-1]) < 1e-10
    assert np.allclose(shp.axial_strain, ce * nt) and np.allclose(shp.shear_strain, cs * nn)


def test_params_from_material():
    p = CosseratParams.from_material(68e9, 1.5e-3, G=25.5e9, density=6450.0)
    A = math.pi * 1.5e-3 ** 2
    assert abs(p.EA - 68e9 * A) < 1e-6 * p.EA and abs(p.EA - 4.8e5) < 0.01 * 4.8e5   # paper §7
    assert abs(p.GA - 1.8e5) < 0.01 * 1.8e5
    nu = 68e9 / (2 * 25.5e9) - 1
    assert abs(p.shear_coefficient - 6 * (1 + nu) / (7 + 6 * nu)) < 1e-15
    assert circular_shear_coefficient(None) == 0.9
    assert abs(p.mass_per_length - 6450.0 * A) < 1e-15
    assert p.line_load((0.0, -9.81)) == pytest.approx((0.0, -9.81 * 6450.0 * A), rel=1e-15)
    k = CosseratParams.kirchhoff()
    assert k.axial_compliance == 0.0 and k.shear_compliance == 0.0 and k.line_load((0, -9.81)) == (0.0, 0.0)
    for bad in (dict(EA=-1.0), dict(GA=0.0), dict(mass_per_length=-1.0), dict(distributed_load=(1.0,)),
                dict(EA=float("nan"))):
        with pytest.raises(ValueError):
            CosseratParams(**bad)
    with pytest.raises(ValueError, match="poisson"):
        CosseratParams.from_material(1e9, 1e-3, poisson=0.7)


def test_bad_rod_input_raises():
    with pytest.raises(ValueError, match="length"):
        shoot((0, 0), 0.0, -1.0, 1.0, (0, 0), 0.0)
    with pytest.raises(ValueError, match="EI"):
        shoot((0, 0), 0.0, 1.0, 0.0, (0, 0), 0.0)
    with pytest.raises(ValueError, match="compliance"):
        shoot((0, 0), 0.0, 1.0, 1.0, (0, 0), 0.0, axial_compliance=-1.0)
    with pytest.raises(ValueError, match="base_force"):
        shoot((0, 0), 0.0, 1.0, 1.0, (np.nan, 0), 0.0)
