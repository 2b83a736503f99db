"""Numerical edge cases: a rod at full reach, straight rods, zero and huge loads, stiffness over
six orders of magnitude, determinism; no NaN or inf leaves a result."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import flexkin


def test_rod_at_full_reach_is_the_straight_rod():
    r = flexkin.solve_rod((1.0, 0.0), 1.0, 1.0)
    assert len(r) == 1 and r.solutions[0].R == 0.0 and "any axial force" in r.message
    assert r.solutions[0].tip == pytest.approx((1.0, 0.0), abs=1e-15)


def test_rod_just_inside_full_reach_is_the_buckled_column():
    """Tip 1e-7 L short of full reach on the axis: the clamped-pinned column just past its
    Euler load 20.19 EI/L^2, buckled either way (two mirror images)."""
    r = flexkin.solve_rod((1.0 - 1e-7, 0.0), 1.0, 1.0)
    assert len(r) == 2
    for s in r.solutions:
        assert s.R == pytest.approx(4.493409457909064**2, rel=1e-5)
    assert r.solutions[0].tip_force[1] == pytest.approx(-r.solutions[1].tip_force[1], rel=1e-6)


def _scaled_EI(mech, factor):
    legs = tuple(dataclasses.replace(leg, rod=dataclasses.replace(leg.rod, EI=leg.rod.EI * factor)) for leg in mech.legs)
    return dataclasses.replace(mech, legs=legs)


@pytest.mark.parametrize("factor", [1e-3, 1e3])
def test_unloaded_geometry_independent_of_stiffness(examples_dir, factor):
    """Without load the equilibria are homogeneous in EI: same poses and inputs, forces x EI."""
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    pose = (0.05, 0.02, np.radians(20))
    a = flexkin.ik(mech, pose, load=(0, 0, 0))
    b = flexkin.ik(_scaled_EI(mech, factor), pose, load=(0, 0, 0))
    assert len(a) == len(b) == 8
    for s, t in zip(a.solutions, b.solutions):
        assert np.allclose(s.inputs, t.inputs, atol=1e-9)
        assert np.allclose(np.array(t.rods[0].tip_force), factor * np.array(s.rods[0].tip_force), rtol=1e-7,
                           atol=1e-9 * factor)
        assert s.stable == t.stable


def test_zero_load_is_the_default_for_an_unloaded_file(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    pose = (0.05, 0.02, np.radians(20))
    a, b = flexkin.ik(mech, pose), flexkin.ik(mech, pose, load=(0.0, 0.0, 0.0))
    assert [s.inputs for s in a.solutions] == [s.inputs for s in b.solutions]


@pytest.mark.parametrize("load", [(1e4, 0.0, 0.0), (0.0, -1e6, 0.0), (0.0, 0.0, 1e5)])
def test_loads_far_beyond_capacity_give_a_clean_answer(examples_dir, load):
    mech = flexkin.load_mechanism(examples_dir / "unit_3pfr.toml")
    res = flexkin.ik(mech, (0.0, 0.0, 0.3), load=load, max_mode=1)
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert res.message or len(res) >= 0
    for s in res.solutions:
        assert np.all(np.isfinite(s.pose)) and np.all(np.isfinite(s.inputs)) and s.residual <= 1e-10
    assert d["problem"] == "ik"


def test_determinism(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "mixed_legs.toml")
    a = flexkin.ik(mech, (0.0, 0.0, 0.1))
    b = flexkin.ik(mech, (0.0, 0.0, 0.1))
    assert [(s.pose, s.inputs, s.modes) for s in a.solutions] == [(s.pose, s.inputs, s.modes) for s in b.solutions]
