"""Forward kinematics: paper Table 1, ODE verification, IK <-> FK round trips, edge cases.

The verification integrates every rod from its clamp with the reported tip force and base
moment (tests/ik_oracle.py, independent of flexkin's solvers).
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.mechanism import symmetric_mechanism

import ik_oracle as O

ROOT = Path(__file__).resolve().parents[1]
PROTO = ROOT / "examples" / "prototype_3pfr.toml"


@functools.lru_cache(maxsize=None)
def _fk(name: str, inputs: tuple[float, ...], load: tuple[float, ...] | None = None):
    mech = _mech(name)
    return mech, flexkin.fk(mech, inputs, load=load)


@functools.lru_cache(maxsize=None)
def _mech(name: str):
    if name == "prototype":
        return flexkin.load_mechanism(PROTO)
    if name == "mixed":
        return flexkin.load_mechanism(ROOT / "examples" / "mixed_legs.toml")
    return symmetric_mechanism(name)


def test_table1_prototype():
    """Paper Table 1 (theory): rho = 0.025 m on every leg gives (0, 0, 90 deg) and (0, 0, -75.7 deg)."""
    _, res = _fk("prototype", (0.025, 0.025, 0.025))
    assert res.complete
    poses = np.array([s.pose for s in res.solutions if s.modes == (1, 1, 1)])
    th = np.degrees(poses[:, 2])
    near_center = np.hypot(poses[:, 0], poses[:, 1]) < 1e-3
    assert np.any(near_center & (np.abs(th - 90.0) < 0.5))
    assert np.any(near_center & (np.abs(th + 76.0) < 1.0))


def _verify(mech, res, load):
    L_ref = O.Geom.of(mech).L_ref
    checks = O.verify_many(mech, res.solutions, load)
    for s, v in zip(res.solutions, checks):
        kp = min(math.sqrt(max(1.0 - r.k * r.k, 1e-300)) for r in s.rods)
        assert v["tip_error"] <= 1e-8 * L_ref, (s.mode_label, v)
        assert v["tip_moment"] <= 1e-6 * max(1.0, (1e-4 / kp) ** 2), (s.mode_label, v)
        assert v["eq_force"] <= 1e-8 and v["eq_moment"] <= 1e-8, (s.mode_label, v)
    return len(checks)


@pytest.mark.parametrize("name, pose, load", [
    ("prototype", (0.0, 0.0, math.radians(90)), None),
    ("revolute", (0.05, 0.02, math.radians(20)), None),
    ("prismatic", (0.05, -0.03, math.radians(20)), None),
    ("mixed", (0.02, -0.01, math.radians(15)), (0.03, 0.02, -0.001)),
])
def test_round_trip_ik_to_fk_and_verified(name, pose, load):
    """FK at the inputs of an IK solution (same load) contains its pose; every FK solution is
    an equilibrium by ODE integration, and IK at its pose contains its inputs."""
    mech = _mech(name)
    ik = flexkin.ik(mech, pose, load=load)
    assert ik.solutions
    sol = ik.solutions[0]  # lowest d-modes, least energy
    _, res = _fk(name, sol.inputs, load)
    assert res.complete
    assert any(np.max(np.abs(np.array(s.pose) - np.array(sol.pose))) < 1e-8 for s in res.solutions)
    w = np.asarray(mech.load if load is None else load, float)
    assert _verify(mech, res, w) == len(res)
    for s in res.solutions[:4]:
        back = flexkin.ik(mech, s.pose, load=load)
        assert any(np.max(np.abs(np.array(b.inputs) - np.array(s.inputs))) < 1e-8 for b in back.solutions)


def test_cannot_assemble_is_an_answer():
    mech = _mech("prototype")
    res = flexkin.fk(mech, (-3.0, 3.0, 0.0))
    assert res.solutions == () and "assemble" in res.message


@pytest.mark.parametrize("inputs", [(0.0, 0.0), (0.0, float("nan"), 0.0), "abc"])
def test_bad_inputs_raise(inputs):
    with pytest.raises(ValueError):
        flexkin.fk(_mech("prototype"), inputs)


def test_bad_max_mode_and_length_input_raise():
    with pytest.raises(ValueError):
        flexkin.fk(_mech("prototype"), (0.0, 0.0, 0.0), max_mode=0)
    with pytest.raises(ValueError):
        flexkin.fk(_mech("length"), (0.8, -0.1, 0.8))


def test_json_contract_inputs_in_degrees_for_revolute_legs():
    mech = _mech("revolute")
    sol = flexkin.ik(mech, (0.05, 0.02, math.radians(20))).solutions[0]
    _, res = _fk("revolute", sol.inputs, None)
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["problem"] == "fk" and d["inputs"] == pytest.approx([math.degrees(u) for u in sol.inputs])
    for s in d["solutions"]:
        assert set(s) >= {"pose", "inputs", "modes", "stable", "residual", "rods", "jacobian"}
        assert s["inputs"] == pytest.approx(d["inputs"])
