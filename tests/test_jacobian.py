"""Kinematic Jacobians (paper §4.4, Eq. 16) against central differences of the IK and FK solvers."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flexkin
from flexkin.solve.finish import refine
from flexkin.system import System

CASES = [("unit_3pfr.toml", (0.05, 0.02, 0.35)), ("unit_3rfr.toml", (0.05, -0.03, 0.2)),
         ("mixed_legs.toml", (0.0, 0.0, 0.1)), ("prototype_3pfr.toml", (0.0, 0.0, np.radians(90)))]


def _regular(res, limit=1e4):
    return [s for s in res.solutions if np.isfinite(s.jacobian.cond) and s.jacobian.cond < limit
            and s.jacobian.J_IK is not None]


@pytest.mark.parametrize("example, pose", CASES)
def test_jacobians_match_central_differences_of_the_solvers(example, pose, examples_dir):
    mech = flexkin.load_mechanism(examples_dir / example)
    m = System.from_mechanism(mech)
    lay = m.layout
    res = flexkin.ik(mech, pose)
    w = np.array(res.load)
    sols = _regular(res)
    assert sols
    Su = m.input_scale()
    Sx = np.array([m.L_ref, m.L_ref, 1.0])
    for sol in sols[:: max(1, len(sols) // 5)]:
        J_IK, J_FK = sol.jacobian.J_IK, sol.jacobian.J_FK
        x0, ch = np.array(sol.x), np.array(sol.charts)[None]

        def resolve(fixed, cols, delta):
            X = x0.copy()
            X[cols] += delta
            out = refine(m, mech, X[None], ch, w, 6, fixed)
            return out[0]

        def central(h):
            fk_ = np.zeros((3, 3))  # d(inputs)/d(pose) from the IK solver
            ik_ = np.zeros((3, 3))  # d(pose)/d(inputs) from the FK solver
            for j in range(3):
                dx = np.eye(3)[j] * h * Sx[j]
                a, b = resolve("pose", lay.pose, dx), resolve("pose", lay.pose, -dx)
                fk_[:, j] = (np.array(a.inputs) - np.array(b.inputs)) / (2 * h) / Su
                du = np.eye(3)[j] * h * Su[j]
                a, b = resolve("inputs", lay.inputs, du), resolve("inputs", lay.inputs, -du)
                d = np.array(a.pose) - np.array(b.pose)
                d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
                ik_[:, j] = d / (2 * h) / Sx
            return fk_, ik_

        # central differences with Richardson extrapolation (error O(h^4))
        (f1, i1), (f2, i2) = central(2e-6), central(1e-6)
        fd_fk, fd_ik = (4 * f2 - f1) / 3, (4 * i2 - i1) / 3
        assert np.max(np.abs(fd_fk - J_FK)) <= 1e-5 * np.max(np.abs(J_FK))
        assert np.max(np.abs(fd_ik - J_IK)) <= 1e-5 * np.max(np.abs(J_IK))
        assert sol.jacobian.det_ik == pytest.approx(np.linalg.det(J_IK), rel=1e-9)
        assert sol.jacobian.det_fk * sol.jacobian.det_ik == pytest.approx(1.0, rel=1e-8)


@pytest.mark.parametrize("example, pose", CASES)
def test_jik_times_jfk_is_identity(example, pose, examples_dir):
    mech = flexkin.load_mechanism(examples_dir / example)
    res = flexkin.ik(mech, pose)
    sols = _regular(res, 1e8)
    assert sols
    for s in sols:
        J = s.jacobian.J_IK @ s.jacobian.J_FK
        assert np.max(np.abs(J - np.eye(3))) < 1e-8 * s.jacobian.cond


def test_fk_singularity_where_the_output_stiffness_is_singular(examples_dir):
    """det J_FK = 0 and a singular platform stiffness (actuators locked) occur together: along
    the equilibria of the prototype, the smallest singular values of J_FK and of the stiffness
    matrix (dimensionless) vanish together."""
    from flexkin.analysis.stability import output_stiffness

    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    m = System.from_mechanism(mech)
    res = flexkin.ik(mech, (0.0, 0.0, np.radians(90)))
    S = np.array([m.L_ref, m.L_ref, 1.0])
    for s in res.solutions:
        K = output_stiffness(m, np.array([s.x]), np.array([s.charts]), np.zeros(3))[0]
        H = K * S[:, None] * S[None, :] / (m.F_ref * m.L_ref)
        sv_h = np.linalg.svd(H, compute_uv=False)
        svd_fk = np.linalg.svd(s.jacobian.J_FK, compute_uv=False)
        assert (sv_h[-1] < 1e-6) == (svd_fk[-1] < 1e-6)


def test_jacobian_in_json(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    d = json.loads(json.dumps(flexkin.fk(mech, (0.025, 0.025, 0.025), load=(0, 0, 0)).to_dict()))
    for s in d["solutions"]:
        assert set(s["jacobian"]) >= {"det_ik", "det_fk", "cond"}
        assert isinstance(s["stable"], bool) and isinstance(s["stability_margin"], float)
