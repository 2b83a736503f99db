"""The seam chart: rods near straight under tension (|k| -> 1), where the unified chart needs
v -> +-infinity and a rod meets its own mirror image."""

from __future__ import annotations

import numpy as np
import pytest

import flexkin
from flexkin import follow_path
from flexkin.rod.closed_form import chart_to_seam, seam_to_chart, tip_chart, tip_seam


def test_seam_chart_agrees_with_the_unified_chart():
    rng = np.random.default_rng(5)
    v = rng.uniform(-10, 10, 500)
    ph = rng.uniform(0.02, 1.55, 500)
    ps, chi = chart_to_seam(v, ph)
    a, b = tip_chart(v, ph), tip_seam(ps, chi)
    for k in ("x", "y", "theta", "m0", "energy"):
        assert np.max(np.abs(getattr(a, k) - getattr(b, k)) / (1 + np.abs(getattr(a, k)))) < 1e-10, k
    assert np.max(np.abs(a.R - b.R) / (1 + a.R)) < 1e-10
    v2, ph2 = seam_to_chart(ps, chi)
    assert np.max(np.abs(v2 - v)) < 1e-8 and np.max(np.abs(ph2 - ph)) < 1e-12


@pytest.mark.parametrize("chi", [0.2, 0.9, 1.4])
def test_straight_rod_under_tension_is_a_regular_point(chi):
    """At psi_s = 0 the rod is straight (tip (1, 0), force along the axis, no moment), and the
    tip and force are smooth (linear) in psi_s across it: the mirror image is the neighbour."""
    t0 = tip_seam(np.array(0.0), np.array(chi))
    assert float(t0.x) == pytest.approx(1.0, abs=1e-15) and abs(float(t0.y)) < 1e-15
    assert float(t0.R) == pytest.approx(np.arctanh(np.sin(chi)) ** 2, rel=1e-12)  # F(chi | 1) = atanh(sin chi)
    h = 1e-4
    f = lambda p: np.array([float(getattr(tip_seam(np.array(p), np.array(chi)), k)) for k in ("y", "m0")]
                           + [float(tip_seam(np.array(p), np.array(chi)).fy)])
    left, mid, right = f(-h), f(0.0), f(h)
    # odd in psi_s, with equal one-sided slopes (no kink)
    assert np.allclose(left, -right, rtol=1e-9, atol=1e-14)
    slope_r = (right - mid) / h
    slope_l = (mid - left) / h
    assert np.allclose(slope_r, slope_l, rtol=1e-6)
    assert np.all(np.abs(slope_r) > 1e-3)


def test_path_passes_a_rod_straight_under_tension(examples_dir):
    """unit 3-PFR from (0, 0, 20 deg) along x: rod 2 becomes straight under tension near
    t = 0.44 (its platform point crosses its guide line); the continuation passes through
    without a chart event, and the full IK beyond contains the followed solution."""
    mech = flexkin.load_mechanism(examples_dir / "unit_3pfr.toml")
    a, b = np.array([0.0, 0.0, np.radians(20)]), np.array([0.8, 0.0, np.radians(20)])
    r = follow_path(mech, a, b, steps=40)
    assert r.t[-1] > 0.8
    assert not any(e.kind == "chart_seam" for e in r.events)
    j = int(np.argmin(np.abs(r.t - 0.5)))
    res = flexkin.ik(mech, r.poses[j])
    assert min(np.max(np.abs(np.array(s.inputs) - r.inputs[j])) for s in res.solutions) < 1e-8
