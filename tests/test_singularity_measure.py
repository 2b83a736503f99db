"""The singularity measures sing_ik, sing_fk (issue 27, item 7): dimensionless and scale-free,
of order 0.1-1 at a healthy pose of a real-scale design, smooth along a path, equal to their
closed form in the singular values of J_IK, unchanged when the mechanism is scaled and its
stiffness changed, and zero where an IK singularity (a fold located by the corrector) and an
FK singularity (located by the stability margin, an independent computation) lie."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

import flexkin
from flexkin import follow_path
from flexkin.mechanism import mechanism_from_dict

TH = np.radians(20.0)


@pytest.fixture(scope="module")
def prototype(examples_dir):
    return flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")


def test_healthy_prototype_pose_reads_order_one(prototype):
    """The prototype at (0.1 m, 0.1 m, 90 deg): the stable equilibria have homogeneous condition
    numbers 2.6-11 and margins 5-14.  The column-scaled determinants of the Newton matrices
    read 1e-8..1e-9 there; the measures must read like a well-conditioned pose."""
    res = flexkin.ik(prototype, (0.1, 0.1, np.radians(90)))
    stable = [s for s in res.solutions if s.stable and s.indices.cond < 12]
    assert len(stable) >= 4
    for s in stable:
        assert 0.05 < abs(s.jacobian.sing_ik) <= 1.0
        assert 0.05 < abs(s.jacobian.sing_fk) <= 1.0
        d = s.to_dict()["jacobian"]
        assert d["sing_ik"] == pytest.approx(s.jacobian.sing_ik) and d["sing_fk"] == pytest.approx(s.jacobian.sing_fk)


@pytest.mark.parametrize("example, pose", [("prototype_3pfr.toml", (0.1, 0.1, np.radians(90))),
                                           ("unit_3rfr.toml", (0.05, -0.03, 0.2)),
                                           ("mixed_legs.toml", (0.0, 0.0, 0.1)),
                                           pytest.param("mixed_clamped.toml", (0.02, -0.05, 0.1),
                                                        marks=pytest.mark.slow)])
def test_closed_form_in_the_singular_values_of_J_IK(example, pose, examples_dir):
    """|sing_ik| = prod s/sqrt(1+s^2), |sing_fk| = prod 1/sqrt(1+s^2) over the singular values s
    of J_IK (computed by another route: A_FK^-1 G_rho), and |sing_fk/sing_ik| = |det J_FK|."""
    res = flexkin.ik(flexkin.load_mechanism(examples_dir / example), pose)
    sols = [s for s in res.solutions if s.jacobian.J_IK is not None and s.jacobian.cond < 1e6]
    assert sols
    for s in sols:
        sv = np.linalg.svd(s.jacobian.J_IK, compute_uv=False)
        assert abs(s.jacobian.sing_ik) == pytest.approx(np.prod(sv / np.sqrt(1 + sv**2)), rel=1e-7)
        assert abs(s.jacobian.sing_fk) == pytest.approx(np.prod(1 / np.sqrt(1 + sv**2)), rel=1e-7)
        assert abs(s.jacobian.sing_fk / s.jacobian.sing_ik) == pytest.approx(abs(s.jacobian.det_fk), rel=1e-7)


def test_smooth_along_a_path_of_the_prototype(prototype):
    """From (0.2, 0, 90 deg) to (0.2, 0.3, 90 deg) following a stable equilibrium (condition
    2.3-3, margin > 13): the column-scaled determinants change by up to 2.2x per step (0.015 in
    t); the measures by less than 10 %."""
    p = follow_path(prototype, (0.2, 0.0, np.radians(90)), (0.2, 0.3, np.radians(90)), steps=20, solution=8)
    assert p.complete and np.all(p.stable)
    for g in (p.sing_ik, p.sing_fk):
        r = np.abs(g[1:] / g[:-1])
        assert np.all(np.maximum(r, 1 / r) < 1.1)
        assert np.all(np.abs(g) > 0.05)


def _scaled(data: dict, s: float, e: float) -> dict:
    """The mechanism file with every length x s and Young's modulus x e."""
    out = {"name": f"x{s:g}", "rod": {"length": s * data["rod"]["length"], "E": e * data["rod"]["E"],
                                      "radius": s * data["rod"]["radius"]},
           "platform": {"attach": [[s * x, s * y] for x, y in data["platform"]["attach"]]},
           "leg": [dict(leg, origin=[s * leg["origin"][0], s * leg["origin"][1]]) for leg in data["leg"]]}
    return out


def test_unchanged_by_size_and_stiffness(examples_dir):
    """The prototype scaled by 3 with E x 10: the same equilibria at the scaled pose, and the
    same sing_ik, sing_fk (sign included)."""
    data = tomllib.loads((examples_dir / "prototype_3pfr.toml").read_text())
    out = {}
    for s, e in ((1.0, 1.0), (3.0, 10.0)):
        mech = mechanism_from_dict(_scaled(data, s, e), source=f"x{s:g}")
        res = flexkin.ik(mech, (0.1 * s, 0.1 * s, np.radians(90)))
        out[s] = sorted(res.solutions, key=lambda q: tuple(np.round(np.array(q.inputs) / s, 7)))
    a, b = out[1.0], out[3.0]
    assert len(a) == len(b) >= 20
    for sa, sb in zip(a, b):
        assert np.allclose(np.array(sb.inputs) / 3.0, sa.inputs, atol=1e-8)
        assert sb.jacobian.sing_ik == pytest.approx(sa.jacobian.sing_ik, rel=1e-6, abs=1e-12)
        assert sb.jacobian.sing_fk == pytest.approx(sa.jacobian.sing_fk, rel=1e-6, abs=1e-12)


@pytest.fixture(scope="module")
def rfr_path(examples_dir):
    """The unit 3-RFR followed from (0, 0, 20 deg) towards (0.3, 0.1, 20 deg): it loses
    stability near t = 0.55 and folds back near t = 0.73."""
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    a, b = np.array([0.0, 0.0, TH]), np.array([0.3, 0.1, TH])
    return mech, a, b, follow_path(mech, a, b, steps=30)


def test_zero_at_an_fk_singularity_located_by_the_stability_margin(rfr_path):
    """Bisection on the sign of the stability margin (the second variation's smallest
    eigenvalue, not a Jacobian) locates where stability is lost; sing_fk vanishes there and
    sing_ik does not."""
    mech, a, b, r = rfr_path
    ev = next(e for e in r.events if e.kind == "stability_lost")
    j = int(np.flatnonzero(np.isclose(r.t, ev.t_lo))[0])
    assert abs(r.sing_fk[j]) > 1e-3
    sol, lo, hi = r.sample_solutions()[j], ev.t_lo, ev.t_hi
    for _ in range(14):  # bracket of 1/30/2^14 ~ 2e-6 in t
        mid = 0.5 * (lo + hi)
        p = follow_path(mech, a + lo * (b - a), a + mid * (b - a), steps=1, solution=sol)
        assert p.complete
        if p.margin[-1] > 0:
            lo, sol = mid, p.sample_solutions()[-1]
        else:
            hi = mid
    assert abs(sol.jacobian.sing_fk) < 2e-4 * abs(r.sing_fk[0])  or abs(sol.jacobian.sing_fk) < 1e-5
    assert abs(sol.jacobian.sing_ik) > 0.1 * abs(r.sing_ik[0])


def test_zero_at_the_fold_where_the_corrector_stops(rfr_path):
    """Near the end of the branch: a 2000-step path from one coarse step before it ends where the
    corrector fails (within 1/2000/64 of t); sing_ik falls from 0.06 to below 1e-3 there, and the
    fold predicted from the coarse path's measure (the stop reason) agrees with it."""
    mech, a, b, r = rfr_path
    assert r.message.startswith("continuation stopped: IK singularity: the branch folds back at t = ")
    t_pred = float(r.message.split("at t = ")[1].split()[0])
    t0 = float(r.t[-2])
    j = len(r.t) - 2
    f = follow_path(mech, a + t0 * (b - a), b, steps=2000, solution=r.sample_solutions()[j])
    assert not f.complete
    t_end = t0 + float(f.t[-1]) * (1 - t0)
    assert abs(f.sing_ik[-1]) < 1e-3 < 0.05 < abs(r.sing_ik[0])
    assert abs(t_pred - t_end) < 2e-3
