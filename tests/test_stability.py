"""Stability (paper §4.3): classical elastica results, the reduced Hessian against finite
differences of the potential, and the paper's Table 1.

References: Euler loads of the cantilever (pi^2 EI / 4 L^2, (2n-1)^2 pi^2 EI / 4 L^2) and of
the clamped-pinned column (20.1907 EI/L^2, root of tan(x) = x: x = 4.49341), Timoshenko &
Gere, *Theory of elastic stability*, §2.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipk

import flexkin
from flexkin.analysis.stability import output_stiffness, rod_stability
from flexkin.system import System
from flexkin.rod.closed_form import tip_chart
from flexkin.solve.rod_inverse import refine_rod
from flexkin.rod.state import RodState

CANTILEVER = np.pi**2 / 4
CLAMPED_PINNED = 4.493409457909064**2  # 20.1907...


def straight_compressed(P: float, L: float = 1.0, EI: float = 1.0, clamp_angle: float = 0.0) -> RodState:
    """Straight rod under an axial compressive tip force P (chart: k = 0, Phi = lambda L)."""
    return RodState.from_chart(0.0, np.pi / 2 - np.sqrt(P * L**2 / EI), L, EI, (0.0, 0.0), clamp_angle)


def buckled_cantilever(P: float, q: int) -> RodState:
    """Cantilever (unit rod) buckled in mode q under the axial dead load P: tip force along -x,
    so psi = pi and phi1 = -(q - 1) pi; lambda L = (2q - 1) K(k)."""
    k = brentq(lambda k: (2 * q - 1) * ellipk(k * k) - np.sqrt(P), 1e-12, 1 - 1e-15)
    return RodState.from_chart(np.arctanh(k), -(q - 1) * np.pi, 1.0, 1.0)


@pytest.mark.parametrize("L, EI, angle", [(1.0, 1.0, 0.0), (0.3, 2e-3, 1.1), (2.0, 50.0, -2.5)])
@pytest.mark.parametrize("factor, stable", [(0.9, True), (1.1, False)])
def test_cantilever_axial_dead_load(L, EI, angle, factor, stable):
    rod = straight_compressed(factor * CANTILEVER * EI / L**2, L, EI, angle)
    assert np.hypot(*rod.tip_force) == pytest.approx(factor * CANTILEVER * EI / L**2, rel=1e-12)
    st = rod_stability(rod, "free")
    assert st.stable is stable
    # the smallest eigenvalue of int eta'^2 - P eta^2 (eta(0) = 0, unit rod) is (pi/2)^2 - P
    assert st.margin == pytest.approx((1 - factor) * CANTILEVER, rel=1e-8)


@pytest.mark.parametrize("factor, stable", [(0.9, True), (1.1, False)])
@pytest.mark.parametrize("tip", ["slider", "pinned"])
def test_column_tip_on_axial_slider(factor, stable, tip):
    """Lateral motion blocked, rotation free: the clamped-pinned column."""
    rod = straight_compressed(factor * CLAMPED_PINNED)
    st = rod_stability(rod, tip, slider_angle=0.0)
    assert st.stable is stable
    assert st.index == (0 if stable else 1)
    assert st.margin == pytest.approx((1 - factor) * CLAMPED_PINNED, rel=1e-8)


@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_clamped_clamped_column(factor):
    """Both ends clamped (tangents along the axis): Euler load 4 pi^2 EI/L^2 (Timoshenko & Gere
    §2.6); the smallest eigenvalue is 4 pi^2 - P."""
    st = rod_stability(straight_compressed(factor * 4 * np.pi**2), "clamped")
    assert st.stable is (factor < 1)
    assert st.margin == pytest.approx((1 - factor) * 4 * np.pi**2, rel=1e-8)


def test_critical_loads_by_root_finding():
    """The loads where the smallest eigenvalue crosses zero match the classical values."""
    def crit(tip, lo, hi):
        return brentq(lambda P: rod_stability(straight_compressed(P), tip, slider_angle=0.0).margin, lo, hi,
                      xtol=1e-12)
    assert crit("free", 1.0, 4.0) == pytest.approx(CANTILEVER, rel=1e-9)
    assert crit("slider", 10.0, 30.0) == pytest.approx(CLAMPED_PINNED, rel=1e-9)
    assert crit("clamped", 30.0, 50.0) == pytest.approx(4 * np.pi**2, rel=1e-9)


def test_higher_euler_loads_counted():
    """The index of the straight cantilever counts the Euler loads below P."""
    for P, n in [(2.0, 0), (10.0, 1), (30.0, 2), (70.0, 3)]:  # (2n-1)^2 pi^2/4 = 2.47, 22.2, 61.7
        assert rod_stability(straight_compressed(P), "free").index == n


def test_buckled_cantilever_first_mode_stable_second_unstable():
    P = 30.0  # above the second Euler load 9 pi^2/4 = 22.2
    r1, r2 = buckled_cantilever(P, 1), buckled_cantilever(P, 2)
    for r, q in ((r1, 1), (r2, 2)):
        assert r.mode == q
        assert r.tip_force[0] == pytest.approx(-P, rel=1e-9) and abs(r.tip_force[1]) < 1e-9
    assert rod_stability(r1, "free").stable
    s2 = rod_stability(r2, "free")
    assert not s2.stable and s2.index == 1
    assert not rod_stability(straight_compressed(P), "free").stable


def test_rod_stability_rejects_bad_tip():
    with pytest.raises(ValueError, match="tip must be"):
        rod_stability(straight_compressed(1.0), "glued")
    with pytest.raises(ValueError, match="slider_angle"):
        rod_stability(straight_compressed(1.0), "slider")


# ---- the tip stiffness and the reduced Hessian ------------------------------------------------------

CHART = np.array([[0.3, 0.1], [-1.0, -2.0], [2.0, -3.5], [0.05, 1.2], [-3.0, -0.7]])


def _potential(mech, m, sol, w, pose):
    """V(pose) = sum U_i - F.P - M theta with every rod re-solved, pinned at B_i(pose)."""
    A, alpha, L = m.clamps(np.array(sol.inputs)[None])
    c, s = np.cos(pose[2]), np.sin(pose[2])
    V = -w[0] * pose[0] - w[1] * pose[1] - w[2] * pose[2]
    for i in range(3):
        b = m.attach[i]
        B = pose[:2] + np.array([c * b[0] - s * b[1], s * b[0] + c * b[1]])
        ca, sa = np.cos(alpha[0, i]), np.sin(alpha[0, i])
        loc = np.array([[ca, sa], [-sa, ca]]) @ (B - A[0, i]) / L[0, i]
        r = refine_rod(np.array([[sol.rods[i].v, sol.rods[i].phis]]), loc)
        assert r.converged[0]
        V += float(tip_chart(*r.z[0]).energy) * m.EI[i] / L[0, i]
    return V


@pytest.mark.parametrize("example, pose", [("unit_3rfr.toml", (0.05, -0.03, 0.2)),
                                           ("mixed_legs.toml", (0.0, 0.0, 0.1))])
def test_output_stiffness_is_the_hessian_of_the_potential(example, pose, examples_dir):
    """The platform's stiffness with the actuators locked (from the equation system's Jacobian)
    equals the Hessian of the potential over the pose, by finite differences with every rod
    re-solved in closed form."""
    mech = flexkin.load_mechanism(examples_dir / example)
    m = System.from_mechanism(mech)
    res = flexkin.ik(mech, pose)
    w = np.array(res.load)
    checked = 0
    # rods close to taut (k' small) or nearly straight (k small) are nearly inextensible
    # along their chord: finite steps of the pose would pull them beyond reach, so the check
    # uses the solutions without them
    ks = [np.abs(np.array([r.ku for r in s.rods])) for s in res.solutions]
    slack = [s for s, k in zip(res.solutions, ks) if np.all((k > 0.1) & (np.sqrt(1 - k**2) > 1e-2))]
    for sol in slack[:: max(1, len(slack) // 4)]:
        K = output_stiffness(m, np.array([sol.x]), np.array([sol.charts]), w)[0]
        S = np.array([m.L_ref, m.L_ref, 1.0])
        H = K * S[:, None] * S[None, :] / (m.F_ref * m.L_ref)
        h = 2e-4 * S
        q0 = np.array(sol.pose)
        Hfd = np.zeros((3, 3))
        for a in range(3):
            for b in range(3):
                ea, eb = np.eye(3)[a] * h[a], np.eye(3)[b] * h[b]
                Hfd[a, b] = (_potential(mech, m, sol, w, q0 + ea + eb) - _potential(mech, m, sol, w, q0 + ea - eb)
                             - _potential(mech, m, sol, w, q0 - ea + eb)
                             + _potential(mech, m, sol, w, q0 - ea - eb)) / (4 * h[a] * h[b])
        Hfd = Hfd * S[:, None] * S[None, :] / (m.F_ref * m.L_ref)
        # the gradient of V vanishes at an equilibrium (Eq. 15 with the SPEC §2 sign)
        assert np.max(np.abs(H - Hfd)) <= 1e-4 * np.max(np.abs(H)) + 1e-6
        checked += 1
    assert checked >= 2


def test_table1_solutions_are_stable(examples_dir):
    """Paper Table 1: both FK solutions at rho = 25 mm were measured on the bench."""
    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    res = flexkin.fk(mech, (0.025, 0.025, 0.025), load=(0, 0, 0))
    for target in (90.0, -75.7):
        hits = [s for s in res.solutions if s.modes == (1, 1, 1)
                and abs(np.degrees(s.pose[2]) - target) < 1.0 and np.hypot(*s.pose[:2]) < 1e-3]
        assert len(hits) == 1
        assert hits[0].stable is True and hits[0].stability_index == 0 and hits[0].stability_margin > 0


def test_stability_fields_consistent(examples_dir):
    """stable <=> index 0 <=> margin > 0, and every verdict is resolved."""
    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    res = flexkin.ik(mech, (0, 0, np.radians(90)))
    for s in res.solutions:
        assert s.stable is not None
        assert s.stable == (s.stability_index == 0) == (s.stability_margin > 0)
        assert abs(s.stability_margin) > 3 * s.stability.resolution
    # the Table 2 solution (rho = 25 mm, mode 111) is stable
    assert any(s.stable and s.modes == (1, 1, 1) and abs(s.inputs[0] - 0.025) < 1e-3 for s in res.solutions)


def test_pinned_index_is_not_a_count_of_determinant_zeros(examples_dir):
    """A looped mode-2 rod of the unit 3-RFR at (0.2, 0, 0): its Jacobi determinant
    det[dm; dr] vanishes twice on (0, L), yet with its tip pinned it is stable (the second
    zero is crossed backwards).  Independent check: a direct finite-difference
    discretisation of the constrained second variation (null space of the tip constraint)."""
    from scipy.linalg import null_space

    from flexkin.rod.closed_form import tangent_angles

    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    res = flexkin.ik(mech, (0.2, 0.0, 0.0))
    checked = backwards = 0
    for s in res.solutions:
        if s.modes != (2, 2, 2) and s.modes != (1, 1, 1):
            continue
        for r in s.rods:
            N = 500
            sn = np.arange(1, N + 1) / N
            th = tangent_angles(np.array([r.v]), np.array([r.phis]), np.concatenate([[0.0], sn]))[0][1:]
            t = tip_chart(r.v, r.phis)
            q = float(t.fx) * np.cos(th) + float(t.fy) * np.sin(th)
            h = 1.0 / N
            Q = np.diag(np.full(N, 2.0 / h))
            Q[-1, -1] = 1.0 / h
            i = np.arange(N - 1)
            Q[i, i + 1] = Q[i + 1, i] = -1.0 / h
            w = np.full(N, h)
            w[-1] = h / 2
            Q += np.diag(w * q)
            Z = null_space(np.stack([-np.sin(th) * w, np.cos(th) * w]))
            ev_free = np.linalg.eigvalsh(Q) / h  # mass matrix h I: eigenvalues of the continuum
            ev_pin = np.linalg.eigvalsh(Z.T @ Q @ Z) / h
            if min(np.min(np.abs(ev_free)), np.min(np.abs(ev_pin))) < 0.5:
                continue  # too close to a singularity for this discretisation
            assert rod_stability(r, "free").index == np.sum(ev_free < 0)
            assert rod_stability(r, "pinned").index == np.sum(ev_pin < 0)
            checked += 1
            backwards += np.sum(ev_free < 0) > np.sum(ev_pin < 0)
    assert checked >= 5 and backwards >= 1
